//! `igi slf render` speed: a 512 x 512 frame of a PFA q = 2 field on the bunny's atlas
//! (docs/BENCHMARKS.md): `slf_render_512_pfa_q2` with the mesh's Embree scene built for the
//! frame (as `igi slf render` does), `slf_frame_512_pfa_q2` with it built once (a viewer). The field's values do not change the work per pixel, so the prototypes
//! and coefficients are seeded pseudo-random numbers.
//!
//!     cargo bench -p igi-lightfield --bench slf_render

use criterion::{criterion_group, criterion_main, Criterion};
use glam::{DVec3, Vec3};
use igi_camera::{Camera, WorldToCamera};
use igi_geometry::atlas::{build_atlas, AtlasOptions};
use igi_lightfield::field::{Coding, RenderSlfOptions, SurfaceLightField};
use igi_lightfield::{grid_points, Octahedron, Pfa};
use rand::{Rng, SeedableRng};

fn bench(c: &mut Criterion) {
    let mut mesh = igi_geometry::read_mesh(&igi_testkit::shared_data(
        "meshes/stanford_bunny/reconstruction/bun_zipper_res2.ply",
    ))
    .unwrap();
    let (lo, hi) = mesh.bounds().unwrap();
    let s = 1.0 / (hi[1] - lo[1]);
    for p in &mut mesh.positions {
        *p = [
            (p[0] - (lo[0] + hi[0]) / 2.0) * s,
            -(p[2] - (lo[2] + hi[2]) / 2.0) * s,
            (p[1] - (lo[1] + hi[1]) / 2.0) * s,
        ];
    }
    mesh.normals = None;
    mesh.compute_vertex_normals();
    let atlas = build_atlas(
        &mesh,
        AtlasOptions {
            resolution: 512,
            gutter: 2,
        },
    )
    .unwrap();
    let (texels, pts) = grid_points(&atlas);
    let oct = Octahedron::new(3);
    let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
    let prototypes = (0..3)
        .map(|_| {
            (0..oct.len())
                .map(|_| Vec3::new(rng.gen(), rng.gen(), rng.gen()))
                .collect()
        })
        .collect();
    let coefficients = (0..pts.len())
        .map(|_| {
            let a: f32 = rng.gen();
            let b: f32 = rng.gen::<f32>() * (1.0 - a);
            vec![a, b, 1.0 - a - b]
        })
        .collect();
    let field = SurfaceLightField::new(
        oct,
        atlas.resolution,
        texels,
        pts.iter().map(|_| Vec3::splat(0.2)).collect(),
        pts.iter().map(|p| p.normal).collect(),
        Coding::Pfa(Pfa {
            prototypes,
            coefficients,
            energy_history: vec![],
        }),
    );
    let mut cam = Camera::pinhole(512, 512, 820.0, 820.0, 255.5, 255.5);
    cam.pose = WorldToCamera::look_at(DVec3::new(2.2, 1.4, 0.9), DVec3::ZERO, DVec3::Z).unwrap();
    eprintln!(
        "{} grid points, {} triangles",
        pts.len(),
        atlas.mesh.indices.len()
    );
    let opts = RenderSlfOptions::default();
    c.bench_function("slf_render_512_pfa_q2", |b| {
        b.iter(|| field.render(&atlas.mesh, &cam, &opts).unwrap())
    });
    // a frame of an interactive viewer: the mesh's Embree scene built once
    let renderer = field.renderer(&atlas.mesh).unwrap();
    c.bench_function("slf_frame_512_pfa_q2", |b| {
        b.iter(|| renderer.render(&cam, &opts))
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = bench
}
criterion_main!(benches);
