//! Triangle rasterisation of a mesh into a camera: coverage (the hull's silhouette) and a depth
//! buffer (surfel visibility). Pixel centres at integer coordinates; a pixel is covered when its
//! centre lies inside a projected triangle (either winding). Vertices are projected with the
//! camera's distortion; edges are straight in the image (exact without distortion).

use igi_camera::Camera;
use igi_geometry::TriMesh;
use igi_imaging::Mask;

/// Camera-space depth (z) of the nearest surface per pixel, `f32::INFINITY` where none.
#[derive(Clone, Debug)]
pub struct DepthBuffer {
    pub width: usize,
    pub height: usize,
    pub depth: Vec<f32>,
}

impl DepthBuffer {
    /// The pixels the mesh covers.
    pub fn coverage(&self) -> Mask {
        Mask {
            width: self.width,
            height: self.height,
            data: self.depth.iter().map(|d| d.is_finite()).collect(),
        }
    }
}

/// Rasterise every triangle of `mesh` seen by `camera` (triangles with a vertex behind the
/// camera are skipped) into a depth buffer.
pub fn rasterize_depth(mesh: &TriMesh, camera: &Camera) -> DepthBuffer {
    let (w, h) = (camera.width as usize, camera.height as usize);
    let mut depth = vec![f32::INFINITY; w * h];
    let proj: Vec<Option<[f64; 3]>> = mesh
        .positions
        .iter()
        .map(|p| {
            let pw = glam::DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64);
            let z = camera.pose.apply(pw).z;
            if !(z > 0.0) {
                return None;
            }
            camera.project(pw).map(|px| [px.x, px.y, z])
        })
        .collect();
    for t in &mesh.indices {
        let (Some(a), Some(b), Some(c)) = (
            proj[t[0] as usize],
            proj[t[1] as usize],
            proj[t[2] as usize],
        ) else {
            continue;
        };
        fill_triangle(a, b, c, w, h, &mut depth);
    }
    DepthBuffer {
        width: w,
        height: h,
        depth,
    }
}

fn fill_triangle(a: [f64; 3], b: [f64; 3], c: [f64; 3], w: usize, h: usize, depth: &mut [f32]) {
    let area = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
    if !(area.abs() > 1e-12) {
        return;
    }
    let x0 = a[0].min(b[0]).min(c[0]).ceil().max(0.0);
    let x1 = a[0].max(b[0]).max(c[0]).floor().min(w as f64 - 1.0);
    let y0 = a[1].min(b[1]).min(c[1]).ceil().max(0.0);
    let y1 = a[1].max(b[1]).max(c[1]).floor().min(h as f64 - 1.0);
    if x0 > x1 || y0 > y1 {
        return;
    }
    let edge = |p: [f64; 3], q: [f64; 3], x: f64, y: f64| {
        (q[0] - p[0]) * (y - p[1]) - (q[1] - p[1]) * (x - p[0])
    };
    for y in y0 as usize..=y1 as usize {
        for x in x0 as usize..=x1 as usize {
            let (fx, fy) = (x as f64, y as f64);
            let (w0, w1, w2) = (
                edge(b, c, fx, fy) / area,
                edge(c, a, fx, fy) / area,
                edge(a, b, fx, fy) / area,
            );
            if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 {
                continue;
            }
            // perspective-correct depth: interpolate 1/z
            let inv_z = w0 / a[2] + w1 / b[2] + w2 / c[2];
            let z = (1.0 / inv_z) as f32;
            let d = &mut depth[y * w + x];
            if z < *d {
                *d = z;
            }
        }
    }
}

/// IoU of two masks counted only over `known` pixels.
pub fn iou_over(a: &Mask, b: &Mask, known: &Mask) -> f64 {
    let (mut inter, mut union) = (0usize, 0usize);
    for i in 0..a.data.len() {
        if known.data[i] {
            inter += (a.data[i] && b.data[i]) as usize;
            union += (a.data[i] || b.data[i]) as usize;
        }
    }
    if union == 0 {
        1.0
    } else {
        inter as f64 / union as f64
    }
}

/// Fraction of `sil`'s known pixels that `cover` misses.
pub fn uncovered_fraction(sil: &Mask, cover: &Mask, known: &Mask) -> f64 {
    let (mut n, mut miss) = (0usize, 0usize);
    for i in 0..sil.data.len() {
        if known.data[i] && sil.data[i] {
            n += 1;
            miss += (!cover.data[i]) as usize;
        }
    }
    if n == 0 {
        0.0
    } else {
        miss as f64 / n as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_square_covers_exactly_its_pixel_centres_at_the_right_depth() {
        // a 1 x 1 square at z = 2 seen by a camera with f = 100: 50 px wide, centred at (50, 50)
        let cam = Camera::pinhole(100, 100, 100.0, 100.0, 50.0, 50.0);
        let m = TriMesh {
            positions: vec![
                [-0.25, -0.25, 2.0],
                [0.25, -0.25, 2.0],
                [0.25, 0.25, 2.0],
                [-0.25, 0.25, 2.0],
            ],
            indices: vec![[0, 1, 2], [0, 2, 3]],
            ..Default::default()
        };
        let d = rasterize_depth(&m, &cam);
        // x from 37.5 to 62.5: centres 38..=62 -> 25 columns and rows
        assert_eq!(d.coverage().count(), 25 * 25);
        assert!(d.depth[50 * 100 + 50] == 2.0 && d.depth[37 * 100 + 50].is_infinite());
    }
}
