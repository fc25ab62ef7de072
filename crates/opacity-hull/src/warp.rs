//! The baseline a new view must beat: the nearest input photo warped to the new camera through
//! the hull's geometry.
//!
//! For each pixel of the new camera that the hull covers, the hull's depth gives a surface point;
//! the point is projected into the input view whose direction from the object's centre is nearest
//! the new camera's, and that photo is looked up bilinearly where the view sees the point (its
//! own hull depth within a tolerance). Pixels the hull does not cover, that the view does not see
//! or that fall outside its frame are left black and marked invalid.

use crate::raster::{rasterize_depth, DepthBuffer};
use crate::views::View;
use glam::{DVec2, DVec3};
use igi_camera::Camera;
use igi_geometry::TriMesh;
use igi_imaging::{HdrImage, Mask};

/// A warped photo: colour where `valid`, black elsewhere, and which view it came from.
#[derive(Clone, Debug)]
pub struct Warped {
    pub image: HdrImage,
    pub valid: Mask,
    pub view: String,
}

/// The view whose direction from `centre` makes the smallest angle with the camera's (ties: the
/// first).
pub fn nearest_view<'a>(views: &[&'a View], camera: &Camera, centre: DVec3) -> Option<&'a View> {
    let dir = (camera.center_world() - centre).normalize_or_zero();
    views
        .iter()
        .map(|v| {
            let d = (v.camera.center_world() - centre).normalize_or_zero();
            (d.dot(dir), *v)
        })
        .fold(None, |best: Option<(f64, &View)>, (c, v)| match best {
            Some((bc, _)) if bc >= c => best,
            _ => Some((c, v)),
        })
        .map(|(_, v)| v)
}

/// Warp `view`'s photo to `camera` through `mesh`; `depth_tolerance` (metres, camera depth) is
/// how far behind the view's own nearest surface a point may lie and still count as seen.
pub fn warp_view(mesh: &TriMesh, view: &View, camera: &Camera, depth_tolerance: f64) -> Warped {
    let target = rasterize_depth(mesh, camera);
    let source = rasterize_depth(mesh, &view.camera);
    let (w, h) = (target.width, target.height);
    let mut image = HdrImage::new(w, h);
    let mut valid = Mask::new(w, h);
    for y in 0..h {
        for x in 0..w {
            let Some(p) = surface_point(&target, camera, x, y) else {
                continue;
            };
            if let Some(c) = look_up(view, &source, p, depth_tolerance) {
                image.pixels[y * w + x] = c;
                valid.data[y * w + x] = true;
            }
        }
    }
    Warped {
        image,
        valid,
        view: view.id.clone(),
    }
}

/// The world point a covered pixel of the depth buffer shows.
fn surface_point(depth: &DepthBuffer, camera: &Camera, x: usize, y: usize) -> Option<DVec3> {
    let z = depth.depth[y * depth.width + x] as f64;
    if !z.is_finite() {
        return None;
    }
    let xn = camera
        .intrinsics
        .to_normalized(DVec2::new(x as f64, y as f64))?;
    Some(
        camera
            .pose
            .inverse()
            .apply(DVec3::new(xn.x * z, xn.y * z, z)),
    )
}

/// The photo's colour at `p` when the view sees it.
fn look_up(view: &View, depth: &DepthBuffer, p: DVec3, tolerance: f64) -> Option<[f32; 3]> {
    let z = view.camera.pose.apply(p).z;
    let q = view.camera.project(p)?;
    if !view.camera.in_frame(q) {
        return None;
    }
    let (ix, iy) = (q.x.round() as usize, q.y.round() as usize);
    let nearest = depth.depth[iy * depth.width + ix] as f64;
    if z > nearest + tolerance {
        return None;
    }
    view.photo.bilinear(q.x as f32, q.y as f32)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::backdrop::Matte;
    use igi_camera::camera::WorldToCamera;

    fn cam(eye: DVec3) -> Camera {
        let mut c = Camera::pinhole(64, 64, 60.0, 60.0, 31.5, 31.5);
        c.pose = WorldToCamera::look_at(eye, DVec3::ZERO, DVec3::Y).unwrap();
        c
    }

    /// A unit square in the plane z = 0, facing +Z.
    fn square() -> TriMesh {
        let positions = vec![
            [-0.5, -0.5, 0.0],
            [0.5, -0.5, 0.0],
            [0.5, 0.5, 0.0],
            [-0.5, 0.5, 0.0],
        ];
        TriMesh {
            positions,
            normals: None,
            uvs: None,
            colors: None,
            indices: vec![[0, 1, 2], [0, 2, 3]],
        }
    }

    /// A view of the square whose photo is the world x coordinate of the point it shows.
    fn view(eye: DVec3) -> View {
        let camera = cam(eye);
        let mut photo = HdrImage::new(64, 64);
        for y in 0..64 {
            for x in 0..64 {
                let (o, d) = camera.pixel_ray(x as f64, y as f64);
                let t = -o.z / d.z;
                let px = (o + d * t).x as f32;
                photo.pixels[y * 64 + x] = [px, 0.0, 1.0];
            }
        }
        View {
            id: format!("{eye}"),
            camera,
            photo,
            matte: Matte::invalid(64, 64),
            silhouette: Mask::new(64, 64),
            known: Mask::new(64, 64),
            carves: Mask::new(64, 64),
        }
    }

    #[test]
    fn a_plane_warps_to_the_colour_of_the_same_point() {
        let (a, b) = (
            view(DVec3::new(0.3, -0.2, 2.0)),
            view(DVec3::new(-1.0, 0.0, 2.0)),
        );
        let target = cam(DVec3::new(0.2, 0.0, 1.8));
        let refs = [&a, &b];
        let near = nearest_view(&refs, &target, DVec3::ZERO).unwrap();
        assert_eq!(near.id, a.id);
        let warped = warp_view(&square(), near, &target, 0.01);
        let mut n = 0;
        for y in 0..64 {
            for x in 0..64 {
                if !warped.valid.data[y * 64 + x] {
                    continue;
                }
                let (o, d) = target.pixel_ray(x as f64, y as f64);
                let truth = (o + d * (-o.z / d.z)).x as f32;
                let got = warped.image.pixels[y * 64 + x][0];
                // the photo is linear in x across the plane, so bilinear lookup is exact
                // up to the depth buffer's f32 depth
                assert!((got - truth).abs() < 2e-3, "({x},{y}) {got} vs {truth}");
                n += 1;
            }
        }
        assert!(n > 1000, "{n} warped pixels");
    }

    #[test]
    fn points_the_view_cannot_see_stay_invalid() {
        // a lid at z = 0.5 hides the square at z = 0 from a view above both
        let above = view(DVec3::new(0.0, 0.0, 2.0));
        let mut both = square();
        let mut lid = square();
        lid.positions.iter_mut().for_each(|p| p[2] = 0.5);
        both.append(&lid);
        let depth = rasterize_depth(&both, &above.camera);
        assert!(look_up(&above, &depth, DVec3::new(0.1, 0.0, 0.0), 0.01).is_none());
        assert!(look_up(&above, &depth, DVec3::new(0.1, 0.0, 0.5), 0.01).is_some());
        // outside the view's frame
        assert!(look_up(&above, &depth, DVec3::new(5.0, 0.0, 0.5), 0.01).is_none());
        // every pixel the target sees of the lid warps
        let target = cam(DVec3::new(0.1, 0.0, 2.0));
        let warped = warp_view(&both, &above, &target, 0.01);
        let cover = rasterize_depth(&lid, &target).coverage();
        let missing = (0..64 * 64)
            .filter(|&i| cover.data[i] && !warped.valid.data[i])
            .count();
        assert!(missing <= 64, "{missing} lid pixels not warped");
    }
}
