//! Compares the atlas unwrappers on one mesh (docs/GEOMETRY.md, "Unwrappers compared"):
//!
//! `cargo run --release -p igi-geometry --example unwrap_compare -- MESH RES [GUTTER] [SUBDIVIDE]`
//!
//! For the projected charts, uvunwrap and xatlas: charts, coverage (covered texels over the atlas),
//! area-weighted L2 stretch (Sander et al. 2001, each triangle's map from surface to texels
//! divided by the atlas's texel size; 1 = isometric), texels claimed by two charts, the time to
//! build the atlas, and an FNV-1a hash of its UVs (same input, same hash). SUBDIVIDE splits
//! every triangle into four that many times first (a denser mesh of the same surface).

use igi_geometry::atlas::{build_atlas_with, AtlasOptions, Unwrapper};
use igi_geometry::TriMesh;
use std::time::Instant;

fn subdivide(m: &TriMesh) -> TriMesh {
    let mut positions = m.positions.clone();
    let mut mid = std::collections::HashMap::new();
    let mut indices = Vec::with_capacity(m.indices.len() * 4);
    for t in &m.indices {
        let e = [0, 1, 2].map(|k| {
            let (a, b) = (t[k].min(t[(k + 1) % 3]), t[k].max(t[(k + 1) % 3]));
            *mid.entry((a, b)).or_insert_with(|| {
                let (p, q) = (positions[a as usize], positions[b as usize]);
                positions.push([0, 1, 2].map(|i: usize| 0.5 * (p[i] + q[i])));
                positions.len() as u32 - 1
            })
        });
        indices.extend([
            [t[0], e[0], e[2]],
            [e[0], t[1], e[1]],
            [e[2], e[1], t[2]],
            [e[0], e[1], e[2]],
        ]);
    }
    TriMesh {
        positions,
        indices,
        ..TriMesh::default()
    }
}

/// Area-weighted L2 stretch of the surface-to-texel map, in units of the texel size.
fn l2_stretch(m: &TriMesh, res: f64, texel: f64) -> f64 {
    let uv = m.uvs.as_ref().unwrap();
    let (mut num, mut den) = (0.0, 0.0);
    for t in &m.indices {
        let p = t.map(|i| m.positions[i as usize].map(f64::from));
        let q = t.map(|i| uv[i as usize].map(|v| f64::from(v) * res * texel));
        let a2 =
            (q[1][0] - q[0][0]) * (q[2][1] - q[0][1]) - (q[2][0] - q[0][0]) * (q[1][1] - q[0][1]);
        let e1 = [0, 1, 2].map(|k| p[1][k] - p[0][k]);
        let e2 = [0, 1, 2].map(|k| p[2][k] - p[0][k]);
        let c = [
            e1[1] * e2[2] - e1[2] * e2[1],
            e1[2] * e2[0] - e1[0] * e2[2],
            e1[0] * e2[1] - e1[1] * e2[0],
        ];
        let area = 0.5 * (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
        if area <= 0.0 {
            continue;
        }
        if a2.abs() < 1e-300 {
            continue;
        }
        // Sander's Ss, St: partial derivatives of the 3D position over the 2D parameters
        let ss = [0, 1, 2].map(|k| {
            (p[0][k] * (q[1][1] - q[2][1])
                + p[1][k] * (q[2][1] - q[0][1])
                + p[2][k] * (q[0][1] - q[1][1]))
                / a2
        });
        let st = [0, 1, 2].map(|k| {
            (p[0][k] * (q[2][0] - q[1][0])
                + p[1][k] * (q[0][0] - q[2][0])
                + p[2][k] * (q[1][0] - q[0][0]))
                / a2
        });
        let a = ss.iter().map(|v| v * v).sum::<f64>();
        let c2 = st.iter().map(|v| v * v).sum::<f64>();
        num += area * (a + c2) / 2.0;
        den += area;
    }
    (num / den).sqrt()
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 3 {
        eprintln!("usage: unwrap_compare MESH RES [GUTTER] [SUBDIVIDE]");
        std::process::exit(2);
    }
    let mut mesh = igi_geometry::read_mesh(args[1].as_ref()).unwrap_or_else(|e| {
        eprintln!("{e}");
        std::process::exit(1)
    });
    let res: u32 = args[2].parse().expect("RES");
    let gutter: u32 = args.get(3).map_or(1, |g| g.parse().expect("GUTTER"));
    for _ in 0..args.get(4).map_or(0, |s| s.parse().expect("SUBDIVIDE")) {
        mesh = subdivide(&mesh);
    }
    mesh.uvs = None;
    mesh.normals = None;
    mesh.compute_vertex_normals();
    println!(
        "{}: {} triangles, atlas {res}, gutter {gutter}",
        args[1],
        mesh.indices.len()
    );
    for u in [Unwrapper::Projected, Unwrapper::Uvunwrap, Unwrapper::Xatlas] {
        let t0 = Instant::now();
        let r = build_atlas_with(
            &mesh,
            AtlasOptions {
                resolution: res,
                gutter,
            },
            u,
        );
        let dt = t0.elapsed().as_secs_f64();
        match r {
            Ok(a) => {
                let mut h: u64 = 0xcbf29ce484222325;
                for v in a.mesh.uvs.as_ref().unwrap().iter().flatten() {
                    for b in v.to_le_bytes() {
                        h = (h ^ u64::from(b)).wrapping_mul(0x100000001b3);
                    }
                }
                println!(
                    "{u:?}: {} charts, coverage {:.1} %, L2 stretch {:.3}, overlap {} texels, texel {:.3e}, {dt:.2} s, uv hash {h:016x}",
                    a.charts,
                    100.0 * a.coverage_fraction(),
                    l2_stretch(&a.mesh, res as f64, a.texel_size),
                    a.overlap_texels,
                    a.texel_size
                );
            }
            Err(e) => println!("{u:?}: fails after {dt:.2} s: {e}"),
        }
    }
}
