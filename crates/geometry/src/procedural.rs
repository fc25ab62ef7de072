//! Procedural test sites: the embedded default scene of the toolkit.
//!
//! [`colonnade_site`] builds a small outdoor site in world Z-up metres: gently undulating
//! terrain (40 x 40 m), a three-step stylobate, a row of six tapered columns, a back wall and
//! an architrave slab on top. Every mesh has per-vertex normals and UVs in [0, 1] laid out
//! without overlap (one chart per planar face or cylinder part, with margins), so it can carry
//! a per-texel albedo texture. `detail` scales every tessellation linearly, so the triangle
//! count grows as `detail^2`: 5,448 triangles at detail 1 (4,296 without the terrain), 27.2
//! million at detail 75 (20.7 million without the terrain). [`colonnade_field`] repeats the
//! colonnade on a grid 20 m apart over a larger terrain, for sites that span many voxels.

use crate::mesh::grid_triangles;
use crate::mesh::TriMesh;

/// Deterministic tiny RNG (SplitMix64) so the generator needs no dependency.
struct SplitMix(u64);
impl SplitMix {
    fn next_f64(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }
}

#[derive(Default)]
struct Builder {
    p: Vec<[f32; 3]>,
    n: Vec<[f32; 3]>,
    uv: Vec<[f32; 2]>,
    idx: Vec<[u32; 3]>,
}

fn normalize(v: [f64; 3]) -> [f64; 3] {
    let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    [v[0] / l, v[1] / l, v[2] / l]
}

/// A UV rectangle (u0, v0, u1, v1).
#[derive(Clone, Copy)]
struct Rect([f64; 4]);

/// Tile `k` of a `g x g` grid of the unit square with a margin, as a UV rectangle.
fn tile(k: usize, count: usize) -> Rect {
    let g = (count as f64).sqrt().ceil() as usize;
    let s = 1.0 / g as f64;
    let m = 0.04 * s;
    let (i, j) = (k / g, k % g);
    Rect([
        j as f64 * s + m,
        i as f64 * s + m,
        (j + 1) as f64 * s - m,
        (i + 1) as f64 * s - m,
    ])
}

impl Builder {
    fn vert(&mut self, p: [f64; 3], n: [f64; 3], uv: [f64; 2]) -> u32 {
        self.p.push(p.map(|x| x as f32));
        self.n.push(n.map(|x| x as f32));
        self.uv.push(uv.map(|x| x as f32));
        (self.p.len() - 1) as u32
    }

    /// A planar rectangle `o + s*ex + t*ey`, s,t in [0, 1], split into `nu x nv` quads,
    /// facing `ex x ey`.
    fn grid(&mut self, o: [f64; 3], ex: [f64; 3], ey: [f64; 3], nu: usize, nv: usize, r: Rect) {
        let n = normalize(crate::mesh::cross(ex, ey));
        let base = self.p.len() as u32;
        for j in 0..=nv {
            for i in 0..=nu {
                let (s, t) = (i as f64 / nu as f64, j as f64 / nv as f64);
                let p = [0, 1, 2].map(|k| o[k] + s * ex[k] + t * ey[k]);
                let uv = [
                    r.0[0] + s * (r.0[2] - r.0[0]),
                    r.0[1] + t * (r.0[3] - r.0[1]),
                ];
                self.vert(p, n, uv);
            }
        }
        self.idx.extend(grid_triangles(base, nu, nv));
    }

    /// An axis-aligned box, `per_m` quads per metre on each face, faces drawn into tiles
    /// `first_tile..` of a `tiles`-tile layout. The bottom face only when `bottom`.
    fn aabox(
        &mut self,
        lo: [f64; 3],
        hi: [f64; 3],
        per_m: f64,
        first_tile: usize,
        tiles: usize,
        bottom: bool,
    ) {
        let d = [hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]];
        let cells = |l: f64| ((l * per_m).ceil() as usize).max(1);
        let (x, y, z) = ([d[0], 0.0, 0.0], [0.0, d[1], 0.0], [0.0, 0.0, d[2]]);
        let neg = |v: [f64; 3]| v.map(|c| -c);
        // (origin, ex, ey, len ex, len ey): each face wound counter-clockwise seen from outside
        let faces = [
            ([lo[0], lo[1], hi[2]], x, y, d[0], d[1]),      // top +z
            ([lo[0], lo[1], lo[2]], x, z, d[0], d[2]),      // front -y
            ([hi[0], hi[1], lo[2]], neg(x), z, d[0], d[2]), // back +y
            ([hi[0], lo[1], lo[2]], y, z, d[1], d[2]),      // right +x
            ([lo[0], hi[1], lo[2]], neg(y), z, d[1], d[2]), // left -x
            ([lo[0], hi[1], lo[2]], x, neg(y), d[0], d[1]), // bottom -z
        ];
        for (k, (o, ex, ey, lx, ly)) in faces.into_iter().enumerate() {
            if k == 5 && !bottom {
                continue;
            }
            self.grid(o, ex, ey, cells(lx), cells(ly), tile(first_tile + k, tiles));
        }
    }

    fn finish(self) -> TriMesh {
        TriMesh {
            positions: self.p,
            normals: Some(self.n),
            uvs: Some(self.uv),
            colors: None,
            indices: self.idx,
        }
    }
}

/// Terrain height at (x, y): zero on and near the temple platforms (centred at `centres`,
/// |x| <= 8, |y| <= 5.5 around each), undulating outside.
fn terrain_height(x: f64, y: f64, waves: &[(f64, f64, f64, f64)], centres: &[[f64; 2]]) -> f64 {
    // distance outside the nearest platform rectangle
    let r = centres
        .iter()
        .map(|c| {
            let dx = ((x - c[0]).abs() - 8.0).max(0.0);
            let dy = ((y - c[1]).abs() - 5.5).max(0.0);
            (dx * dx + dy * dy).sqrt()
        })
        .fold(f64::INFINITY, f64::min);
    let w = (r / 6.0).clamp(0.0, 1.0);
    let w = w * w * (3.0 - 2.0 * w);
    let h: f64 = waves
        .iter()
        .map(|&(a, kx, ky, ph)| a * (kx * x + ky * y + ph).sin())
        .sum();
    w * h
}

/// Build the colonnade site. `seed` varies the terrain; `detail >= 1` scales tessellation.
/// Returns named meshes: `terrain`, `stylobate`, `column_00`..`column_05`, `wall`, `architrave`.
pub fn colonnade_site(seed: u64, detail: u32) -> Vec<(String, TriMesh)> {
    let d = detail.max(1) as usize;
    let waves = waves(seed);
    let mut out = Vec::new();
    out.push((
        "terrain".to_string(),
        terrain(40.0, 24 * d, &waves, &[[0.0, 0.0]]),
    ));
    out.extend(structures(d));
    out
}

/// A field of `grid x grid` colonnades 20 m apart on one terrain (20 m wider than the field,
/// tessellated as densely per metre as [`colonnade_site`]'s), for scale tests that need many
/// voxels: `colonnade_field(seed, detail, 1)` is `colonnade_site(seed, detail)`. The meshes of
/// the colonnade in row `i`, column `j` are suffixed `_i_j` (no suffix when `grid` is 1).
pub fn colonnade_field(seed: u64, detail: u32, grid: u32) -> Vec<(String, TriMesh)> {
    let grid = grid.max(1) as usize;
    if grid == 1 {
        return colonnade_site(seed, detail);
    }
    let d = detail.max(1) as usize;
    let spacing = 20.0;
    let size = spacing * grid as f64 + 20.0;
    let centres: Vec<[f64; 2]> = (0..grid * grid)
        .map(|k| {
            let (i, j) = (k / grid, k % grid);
            let off = |a: usize| (a as f64 - (grid - 1) as f64 / 2.0) * spacing;
            [off(j), off(i)]
        })
        .collect();
    let mut out = vec![(
        "terrain".to_string(),
        terrain(
            size,
            (24.0 * d as f64 * size / 40.0).round() as usize,
            &waves(seed),
            &centres,
        ),
    )];
    for (k, c) in centres.iter().enumerate() {
        for (name, mut m) in structures(d) {
            for p in &mut m.positions {
                p[0] += c[0] as f32;
                p[1] += c[1] as f32;
            }
            out.push((format!("{name}_{}_{}", k / grid, k % grid), m));
        }
    }
    out
}

/// The terrain's undulation, from the seed.
fn waves(seed: u64) -> Vec<(f64, f64, f64, f64)> {
    let mut rng = SplitMix(seed ^ 0x1234_5678_9ABC_DEF0);
    (0..4)
        .map(|k| {
            let a = 0.35 / (k as f64 + 1.0);
            let ang = rng.next_f64() * std::f64::consts::TAU;
            let freq = 0.12 * (k as f64 + 1.0);
            (
                a,
                freq * ang.cos(),
                freq * ang.sin(),
                rng.next_f64() * std::f64::consts::TAU,
            )
        })
        .collect()
}

/// A `size x size` m terrain centred on the origin, `n x n` cells.
fn terrain(size: f64, n: usize, waves: &[(f64, f64, f64, f64)], centres: &[[f64; 2]]) -> TriMesh {
    let mut b = Builder::default();
    for j in 0..=n {
        for i in 0..=n {
            let (s, t) = (i as f64 / n as f64, j as f64 / n as f64);
            let (x, y) = (-size / 2.0 + s * size, -size / 2.0 + t * size);
            let h = 1e-3;
            let z = terrain_height(x, y, waves, centres);
            let gx = (terrain_height(x + h, y, waves, centres)
                - terrain_height(x - h, y, waves, centres))
                / (2.0 * h);
            let gy = (terrain_height(x, y + h, waves, centres)
                - terrain_height(x, y - h, waves, centres))
                / (2.0 * h);
            b.vert([x, y, z], normalize([-gx, -gy, 1.0]), [s, t]);
        }
    }
    b.idx.extend(grid_triangles(0, n, n));
    b.finish()
}

/// The temple at the origin: stylobate, six columns, wall, architrave.
fn structures(d: usize) -> Vec<(String, TriMesh)> {
    let per_m = d as f64;
    // stylobate: three steps of 0.3 m, each inset by 0.4 m
    let mut b = Builder::default();
    for k in 0..3 {
        let (hx, hy) = (7.0 - 0.4 * k as f64, 4.5 - 0.4 * k as f64);
        let (z0, z1) = (0.3 * k as f64, 0.3 * (k + 1) as f64);
        b.aabox([-hx, -hy, z0], [hx, hy, z1], per_m, 5 * k, 15, false);
    }
    let mut out = vec![("stylobate".to_string(), b.finish())];
    // columns: a row along x at y = -2
    for c in 0..6 {
        out.push((
            format!("column_{c:02}"),
            column(-5.0 + 2.0 * c as f64, -2.0, d),
        ));
    }
    // back wall and architrave slab
    let mut b = Builder::default();
    b.aabox([-6.0, 2.0, 0.9], [6.0, 2.6, 6.9], per_m, 0, 5, false);
    out.push(("wall".to_string(), b.finish()));
    let mut b = Builder::default();
    b.aabox([-6.3, -2.7, 5.9], [6.3, 2.6, 6.8], per_m, 0, 6, true);
    out.push(("architrave".to_string(), b.finish()));
    out
}

/// A column of the temple centred at (`cx`, `cy`): base on the top step (z = 0.9), 5 m tall,
/// tapered, `24 d` sides and `8 d` rings; its side in uv rect [0,1] x [0.34,1], its caps below.
fn column(cx: f64, cy: f64, d: usize) -> TriMesh {
    let (z0, height, r0) = (0.9, 5.0, 0.45);
    let sides = 24 * d;
    let rings = 8 * d;
    let taper = 0.12;
    let radius = |t: f64| r0 * (1.0 - taper * t);
    let mut b = Builder::default();
    for j in 0..=rings {
        let t = j as f64 / rings as f64;
        for i in 0..=sides {
            let a = std::f64::consts::TAU * i as f64 / sides as f64;
            let r = radius(t);
            let nrm = normalize([a.cos(), a.sin(), r0 * taper / height]);
            b.vert(
                [cx + r * a.cos(), cy + r * a.sin(), z0 + t * height],
                nrm,
                [0.01 + 0.98 * i as f64 / sides as f64, 0.34 + 0.65 * t],
            );
        }
    }
    b.idx.extend(grid_triangles(0, sides, rings));
    // caps: discs in uv rects [0,0.5]x[0,0.32] (bottom) and [0.5,1]x[0,0.32] (top)
    for (top, uc) in [(false, 0.25), (true, 0.75)] {
        let t = if top { 1.0 } else { 0.0 };
        let (z, r) = (z0 + t * height, radius(t));
        let nz = if top { 1.0 } else { -1.0 };
        let centre = b.vert([cx, cy, z], [0.0, 0.0, nz], [uc, 0.16]);
        let first = b.p.len() as u32;
        for i in 0..sides {
            let a = std::f64::consts::TAU * i as f64 / sides as f64;
            b.vert(
                [cx + r * a.cos(), cy + r * a.sin(), z],
                [0.0, 0.0, nz],
                [uc + 0.15 * a.cos(), 0.16 + 0.15 * a.sin()],
            );
        }
        for i in 0..sides as u32 {
            let (p, q) = (first + i, first + (i + 1) % sides as u32);
            b.idx
                .push(if top { [centre, p, q] } else { [centre, q, p] });
        }
    }
    b.finish()
}

/// A UV-less latitude-longitude sphere of radius `r` about the origin (poles on the Z axis),
/// `rings` bands of `segments` quads (triangles at the poles), with vertex normals: the glossy
/// test object of the surface-light-field tests.
pub fn uv_sphere(rings: usize, segments: usize, r: f32) -> TriMesh {
    let mut m = TriMesh::default();
    for i in 0..=rings {
        let th = std::f32::consts::PI * i as f32 / rings as f32;
        for j in 0..segments {
            let ph = std::f32::consts::TAU * j as f32 / segments as f32;
            m.positions.push([
                r * th.sin() * ph.cos(),
                r * th.sin() * ph.sin(),
                r * th.cos(),
            ]);
        }
    }
    let n = segments as u32;
    for i in 0..rings as u32 {
        for j in 0..n {
            let (a, b) = (i * n + j, i * n + (j + 1) % n);
            if i > 0 {
                m.indices.push([a, a + n, b]);
            }
            if i + 1 < rings as u32 {
                m.indices.push([b, a + n, b + n]);
            }
        }
    }
    m.compute_vertex_normals();
    m
}

/// `n` nearly uniform unit directions (a Fibonacci sphere), turned by `offset` radians in
/// azimuth: camera placements around an object.
pub fn fibonacci_directions(n: usize, offset: f32) -> Vec<glam::Vec3> {
    (0..n)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f32 + 0.5) / n as f32;
            let phi = i as f32 * 2.399_963 + offset;
            let r = (1.0 - z * z).sqrt();
            glam::Vec3::new(r * phi.cos(), r * phi.sin(), z)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sphere_and_directions_are_what_they_say() {
        let m = uv_sphere(8, 16, 0.5);
        let normals = m.normals.as_ref().unwrap();
        for (p, n) in m.positions.iter().zip(normals) {
            let p = glam::Vec3::from_array(*p);
            assert!((p.length() - 0.5).abs() < 1e-5);
            assert!(glam::Vec3::from_array(*n).dot(p) > 0.0, "outward normals");
        }
        assert_eq!(m.indices.len(), 2 * 16 * (8 - 1));
        let d = fibonacci_directions(500, 0.3);
        assert!(d.iter().all(|v| (v.length() - 1.0).abs() < 1e-5));
        assert!(
            d.iter().sum::<glam::Vec3>().length() / 500.0 < 0.01,
            "nearly uniform"
        );
    }

    #[test]
    fn site_is_valid_deterministic_and_scales_quadratically() {
        let a = colonnade_site(7, 1);
        let b = colonnade_site(7, 1);
        let c = colonnade_site(8, 1);
        assert_eq!(a.len(), 10);
        let tris = |s: &[(String, TriMesh)]| s.iter().map(|(_, m)| m.indices.len()).sum::<usize>();
        for ((na, ma), (_, mb)) in a.iter().zip(&b) {
            ma.validate().unwrap();
            assert_eq!(ma, mb, "{na} not deterministic");
            for uv in ma.uvs.as_ref().unwrap() {
                assert!(
                    (0.0..=1.0).contains(&uv[0]) && (0.0..=1.0).contains(&uv[1]),
                    "{na} uv {uv:?}"
                );
            }
            for n in ma.normals.as_ref().unwrap() {
                let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
                assert!((l - 1.0).abs() < 1e-5);
            }
        }
        assert_ne!(a[0].1, c[0].1, "seed changes the terrain");
        let t1 = tris(&a);
        let t3 = tris(&colonnade_site(7, 3));
        let ratio = t3 as f64 / t1 as f64;
        assert!((7.0..=9.5).contains(&ratio), "{t1} -> {t3}");
    }

    #[test]
    fn a_field_of_one_is_the_site_and_larger_fields_tile_it() {
        assert_eq!(colonnade_field(4, 1, 1), colonnade_site(4, 1));
        let site = colonnade_site(4, 1);
        let field = colonnade_field(4, 1, 3);
        let tris = |s: &[(String, TriMesh)], terrain: bool| {
            s.iter()
                .filter(|(n, _)| (n == "terrain") == terrain)
                .map(|(_, m)| m.indices.len())
                .sum::<usize>()
        };
        assert_eq!(tris(&field, false), 9 * tris(&site, false));
        // an 80 m terrain as densely tessellated as the 40 m one: 4x the triangles
        assert_eq!(tris(&field, true), 4 * tris(&site, true));
        let wall_11 = &field.iter().find(|(n, _)| n == "wall_1_1").unwrap().1;
        let wall = &site.iter().find(|(n, _)| n == "wall").unwrap().1;
        assert_eq!(
            wall_11.positions, wall.positions,
            "the middle colonnade sits at the origin"
        );
        let wall_02 = &field.iter().find(|(n, _)| n == "wall_0_2").unwrap().1;
        assert_eq!(wall_02.positions[0][0], wall.positions[0][0] + 20.0);
        assert_eq!(wall_02.positions[0][1], wall.positions[0][1] - 20.0);
        // terrain is flat under every platform
        let t = &field[0].1;
        for p in &t.positions {
            let near = (-1..=1).any(|i| {
                (-1..=1).any(|j| {
                    (p[0] - 20.0 * i as f32).abs() <= 8.0 && (p[1] - 20.0 * j as f32).abs() <= 5.5
                })
            });
            if near {
                assert_eq!(p[2], 0.0);
            }
        }
    }

    #[test]
    fn face_normals_agree_with_winding_and_areas_are_right() {
        let site = colonnade_site(1, 2);
        for (name, m) in &site {
            let nrm = m.normals.as_ref().unwrap();
            for t in 0..m.indices.len() {
                let [a, b, c] = m.triangle(t).map(|p| p.map(f64::from));
                let f = crate::mesh::cross(crate::mesh::sub(b, a), crate::mesh::sub(c, a));
                let vn = nrm[m.indices[t][0] as usize].map(f64::from);
                let dot = f[0] * vn[0] + f[1] * vn[1] + f[2] * vn[2];
                assert!(dot > 0.0, "{name} triangle {t} is wound against its normal");
            }
        }
        // the wall is a 12 x 0.6 x 6 box without bottom: 2*(12*6) + 2*(0.6*6) + 12*0.6
        let wall = &site.iter().find(|(n, _)| n == "wall").unwrap().1;
        assert!(
            (wall.total_area() - (144.0 + 7.2 + 7.2)).abs() < 1e-3,
            "{}",
            wall.total_area()
        );
    }

    #[test]
    fn uv_charts_do_not_overlap() {
        // rasterise every triangle's UVs into a 256^2 grid by sampling texel centres; no texel twice
        let site = colonnade_site(3, 1);
        let res = 256usize;
        for (name, m) in &site {
            let uv = m.uvs.as_ref().unwrap();
            let mut hit = vec![0u8; res * res];
            for tri in &m.indices {
                let [a, b, c] = tri.map(|i| uv[i as usize].map(f64::from));
                let (lo_x, hi_x) = (a[0].min(b[0]).min(c[0]), a[0].max(b[0]).max(c[0]));
                let (lo_y, hi_y) = (a[1].min(b[1]).min(c[1]), a[1].max(b[1]).max(c[1]));
                let den = (b[1] - c[1]) * (a[0] - c[0]) + (c[0] - b[0]) * (a[1] - c[1]);
                if den.abs() < 1e-15 {
                    continue;
                }
                for y in (lo_y * res as f64) as usize..=((hi_y * res as f64) as usize).min(res - 1)
                {
                    for x in
                        (lo_x * res as f64) as usize..=((hi_x * res as f64) as usize).min(res - 1)
                    {
                        let (px, py) =
                            ((x as f64 + 0.5) / res as f64, (y as f64 + 0.5) / res as f64);
                        let l1 = ((b[1] - c[1]) * (px - c[0]) + (c[0] - b[0]) * (py - c[1])) / den;
                        let l2 = ((c[1] - a[1]) * (px - c[0]) + (a[0] - c[0]) * (py - c[1])) / den;
                        let l3 = 1.0 - l1 - l2;
                        // strictly inside (shared edges are hit by both neighbours otherwise)
                        if l1 > 1e-9 && l2 > 1e-9 && l3 > 1e-9 {
                            hit[y * res + x] += 1;
                        }
                    }
                }
            }
            let overlaps = hit.iter().filter(|&&h| h > 1).count();
            assert_eq!(overlaps, 0, "{name}: {overlaps} texels covered twice");
            assert!(
                hit.iter().filter(|&&h| h > 0).count() > res * res / 10,
                "{name} uses little of its atlas"
            );
        }
    }
}
