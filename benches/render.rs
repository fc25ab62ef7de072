//! Render benchmarks (issue 3): raw Embree rays/s against the rays/s the path tracer achieves
//! on the same scene, and path-traced samples/s.
//!
//! Scene: `datasets/fixtures/outdoor` (the Mitsuba reference scene) when present, else the
//! procedural colonnade site. Run: `cargo bench --bench render`. Besides criterion's groups it
//! prints the path tracer / raw Embree ratio from the two timed alternately (best of 15 rounds
//! each), which a loaded machine disturbs far less than groups run one after the other.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use glam::Vec3;
use igi_raycast::RaySegment;
use igi_render::sampling::Rng;
use igi_render::{render_image, Lighting, Material, RenderOptions, Scene, Sun};
use rayon::prelude::*;
use std::path::Path;

fn load() -> (Scene, Lighting, igi_camera::Camera) {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("datasets/fixtures/outdoor");
    if dir.join("scene.toml").exists() {
        let (s, l) = Scene::load(&dir.join("scene.toml")).expect("fixture scene");
        let c = igi_camera::Camera::load(&dir.join("camera.json")).expect("fixture camera");
        return (s, l, c);
    }
    let objects = igi_geometry::procedural::colonnade_site(1, 2)
        .into_iter()
        .map(|(n, m)| (n, m, Material::lambertian(Vec3::splat(0.5))))
        .collect();
    let s = Scene::new(objects).unwrap();
    let l = Lighting {
        environment: Some(igi_render::Environment::constant(Vec3::splat(1000.0))),
        sun: Some(Sun::new(Vec3::new(0.3, -0.5, 0.8), Vec3::splat(6e4), 0.53).unwrap()),
    };
    let mut c = igi_camera::Camera::pinhole(128, 128, 120.0, 120.0, 63.5, 63.5);
    let r = glam::DMat3::from_cols(glam::DVec3::X, -glam::DVec3::Z, glam::DVec3::Y).transpose();
    let r = glam::DMat3::from_cols(r.x_axis, r.y_axis, r.z_axis);
    c.pose = igi_camera::WorldToCamera {
        r,
        t: -(r * glam::DVec3::new(0.0, -20.0, 3.0)),
    };
    (s, l, c)
}

/// Incoherent rays like the path tracer's: camera rays through random pixel positions and,
/// for each, a uniformly random direction from its first hit (half closest-hit, half shadow).
fn make_rays(scene: &Scene, cam: &igi_camera::Camera, n: usize) -> Vec<RaySegment> {
    let mut rng = Rng::new(7, 0);
    let mut rays = Vec::with_capacity(2 * n);
    for _ in 0..n {
        let (o, d) = cam.pixel_ray(
            rng.uniform() as f64 * cam.width as f64,
            rng.uniform() as f64 * cam.height as f64,
        );
        let (o, d) = (o.as_vec3(), d.as_vec3());
        rays.push(RaySegment {
            origin: o,
            dir: d,
            tnear: 0.0,
            tfar: f32::INFINITY,
        });
        if let Some(sp) = scene.trace_point(o, d) {
            let z = rng.uniform();
            let phi = std::f32::consts::TAU * rng.uniform();
            let r = (1.0 - z * z).sqrt();
            let mut w = Vec3::new(r * phi.cos(), r * phi.sin(), z);
            if w.dot(sp.ng) < 0.0 {
                w = -w;
            }
            rays.push(RaySegment {
                origin: sp.position + sp.ng * 1e-4,
                dir: w,
                tnear: 0.0,
                tfar: f32::INFINITY,
            });
        }
    }
    rays
}

fn bench(c: &mut Criterion) {
    let (scene, lighting, cam) = load();
    let rays = make_rays(&scene, &cam, 1 << 15);
    let rt = scene.rt();

    let mut g = c.benchmark_group("embree_raw");
    g.sample_size(20);
    g.throughput(Throughput::Elements(rays.len() as u64));
    g.bench_function("intersect_single_rayon", |b| {
        b.iter(|| {
            rays.par_chunks(256)
                .map(|ch| {
                    ch.iter()
                        .filter(|r| rt.intersect(r.origin, r.dir, r.tnear, r.tfar).is_some())
                        .count()
                })
                .sum::<usize>()
        })
    });
    g.bench_function("intersect_stream_rayon", |b| {
        b.iter(|| {
            rays.par_chunks(256)
                .map(|ch| rt.intersect_batch(ch, false).iter().flatten().count())
                .sum::<usize>()
        })
    });
    g.bench_function("occluded_single_rayon", |b| {
        b.iter(|| {
            rays.par_chunks(256)
                .map(|ch| {
                    ch.iter()
                        .filter(|r| rt.occluded(r.origin, r.dir, r.tnear, r.tfar))
                        .count()
                })
                .sum::<usize>()
        })
    });
    g.finish();

    // Path tracer: count the rays of one render, then time renders with that throughput.
    let mut small = cam.clone();
    small.width = 64;
    small.height = 64;
    small.intrinsics.fx *= 0.5;
    small.intrinsics.fy *= 0.5;
    small.intrinsics.cx = 31.5;
    small.intrinsics.cy = 31.5;
    let opts = RenderOptions {
        spp: 4,
        seed: 1,
        indirect: 2,
        russian_roulette: false,
        stratified: false,
        adaptive: false,
    };
    let rays_per_render = render_image(&scene, &lighting, &small, &opts, &|_| {})
        .unwrap()
        .rays;
    // The ratio the issue asks for, robust to a shared machine's load: raw single rays and the
    // path tracer timed alternately, round after round, each at its best round.
    let (mut raw_best, mut pt_best) = (f64::INFINITY, f64::INFINITY);
    for _ in 0..15 {
        let t = std::time::Instant::now();
        let hits: usize = rays
            .par_chunks(256)
            .map(|ch| {
                ch.iter()
                    .filter(|r| rt.intersect(r.origin, r.dir, r.tnear, r.tfar).is_some())
                    .count()
            })
            .sum();
        raw_best = raw_best.min(t.elapsed().as_secs_f64());
        std::hint::black_box(hits);
        let t = std::time::Instant::now();
        std::hint::black_box(render_image(&scene, &lighting, &small, &opts, &|_| {}).unwrap());
        pt_best = pt_best.min(t.elapsed().as_secs_f64());
    }
    let (raw, pt) = (
        rays.len() as f64 / raw_best / 1e6,
        rays_per_render as f64 / pt_best / 1e6,
    );
    println!(
        "interleaved, best of 15: raw Embree {raw:.2} M rays/s, path tracer {pt:.2} M rays/s \
         ({} rays a render, {:.2} a sample): ratio {:.3}",
        rays_per_render,
        rays_per_render as f64 / (64.0 * 64.0 * 4.0),
        pt / raw
    );

    let mut g = c.benchmark_group("path_tracer");
    g.sample_size(10);
    g.throughput(Throughput::Elements(rays_per_render));
    g.bench_function("rays_64x64_4spp_K2", |b| {
        b.iter(|| render_image(&scene, &lighting, &small, &opts, &|_| {}).unwrap())
    });
    g.throughput(Throughput::Elements(64 * 64 * 4));
    g.bench_function("samples_64x64_4spp_K2", |b| {
        b.iter(|| render_image(&scene, &lighting, &small, &opts, &|_| {}).unwrap())
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
