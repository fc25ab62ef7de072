//! Write the procedural colonnade site as binary PLY, for scale tests of `igi prepare`.
//!
//! ```text
//! cargo run --release -p igi-geometry --example gen_site -- OUT_DIR [DETAIL] [SEED]
//! ```
//! Writes `OUT_DIR/site.ply` (stylobate, columns, wall, architrave) and `OUT_DIR/terrain.ply`.
//! The triangle count grows as DETAIL^2: DETAIL 1 gives 4,296 site + 1,152 terrain triangles;
//! DETAIL 75 gives 20.7 million site + 6.5 million terrain triangles.

use igi_geometry::{procedural, write_ply, TriMesh};
use std::path::PathBuf;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 2 {
        eprintln!("usage: gen_site OUT_DIR [DETAIL] [SEED]");
        std::process::exit(2);
    }
    let out = PathBuf::from(&args[1]);
    let detail: u32 = args
        .get(2)
        .map_or(1, |s| s.parse().expect("DETAIL must be an integer"));
    let seed: u64 = args
        .get(3)
        .map_or(1, |s| s.parse().expect("SEED must be an integer"));
    std::fs::create_dir_all(&out).expect("cannot create the output folder");
    let mut site = TriMesh::default();
    let mut terrain = None;
    for (name, mesh) in procedural::colonnade_site(seed, detail) {
        if name == "terrain" {
            terrain = Some(mesh);
        } else {
            site.append(&mesh);
        }
    }
    let terrain = terrain.expect("the generator makes a terrain");
    write_ply(&out.join("site.ply"), &site).expect("write site.ply");
    write_ply(&out.join("terrain.ply"), &terrain).expect("write terrain.ply");
    println!(
        "{}: site {} triangles, terrain {} triangles, total {}",
        out.display(),
        site.indices.len(),
        terrain.indices.len(),
        site.indices.len() + terrain.indices.len()
    );
}
