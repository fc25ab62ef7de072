//! igi-brdf throughput: Lafortune eval / pdf / sample, the staged LM fit of one material, and
//! Lensch clustering of lumitexels (`IGI_BENCH_LUMITEXELS`, default 1e4).
//! `cargo bench --bench brdf`

use criterion::{black_box, criterion_group, criterion_main, BatchSize, Criterion, Throughput};
use glam::{Vec2, Vec3};
use igi_brdf::cluster::separated_materials;
use igi_brdf::{
    cluster, fit_material, BrdfSample, ClusterOptions, FitOptions, Frame, Lafortune, Lumitexel,
};
use igi_synth::sample_frame::{specular_lobe, stone};

fn dir(theta_deg: f32, phi_deg: f32) -> Vec3 {
    let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
    Vec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
}

fn material(n_spec: f32) -> Lafortune {
    let rho = Vec3::splat(0.5 * (n_spec + 2.0) / std::f32::consts::TAU);
    stone(specular_lobe(rho, n_spec))
}

/// Deterministic quasi-random directions (golden-ratio sequences), upper hemisphere.
fn dirs(n: usize) -> Vec<(Vec3, Vec3)> {
    (0..n)
        .map(|i| {
            let a = (i as f32 * 0.618_034).fract();
            let b = (i as f32 * 0.754_877_7).fract();
            let c = (i as f32 * 0.569_840_3).fract();
            let d = (i as f32 * 0.362_437_6).fract();
            (dir(85.0 * a, 360.0 * b), dir(85.0 * c, 360.0 * d))
        })
        .collect()
}

fn bench_model(c: &mut Criterion) {
    let pairs = dirs(4096);
    let mut g = c.benchmark_group("lafortune");
    g.throughput(Throughput::Elements(pairs.len() as u64));
    for n in [30.0f32, 1.0e4] {
        let m = material(n);
        g.bench_function(format!("eval n={n}"), |b| {
            b.iter(|| {
                let r = m.as_ref();
                let mut s = Vec3::ZERO;
                for &(l, v) in &pairs {
                    s += r.eval(l, v);
                }
                black_box(s)
            })
        });
        g.bench_function(format!("eval_pdf n={n}"), |b| {
            b.iter(|| {
                let r = m.as_ref();
                let mut s = 0.0;
                for &(l, v) in &pairs {
                    let (f, p) = r.eval_pdf(l, v);
                    s += f.x + p;
                }
                black_box(s)
            })
        });
        g.bench_function(format!("sample n={n}"), |b| {
            b.iter(|| {
                let r = m.as_ref();
                let mut s = 0.0;
                for (i, &(_, v)) in pairs.iter().enumerate() {
                    let u = (i as f32 * 0.618_034).fract();
                    if let Some(x) = r.sample(
                        v,
                        u,
                        Vec2::new(
                            (i as f32 * 0.754_877_7).fract(),
                            (i as f32 * 0.569_84).fract(),
                        ),
                    ) {
                        s += x.pdf;
                    }
                }
                black_box(s)
            })
        });
    }
    g.finish();
}

fn bench_fit(c: &mut Criterion) {
    let mut g = c.benchmark_group("fit");
    g.sample_size(10);
    for (name, n, count) in [
        ("glossy n=60, 136 samples", 60.0f32, 136usize),
        ("stiff n=1e4, 200 samples", 1.0e4, 200),
    ] {
        let m = material(n);
        let mut pairs = dirs(count - 40);
        for i in 0..40 {
            let t = 10.0 + 1.5 * i as f32;
            let p = 9.0 * i as f32;
            pairs.push((
                dir(t, p),
                dir(
                    t + 0.05 * (i % 7) as f32 - 0.15,
                    p + 180.0 + 0.1 * (i % 5) as f32 - 0.2,
                ),
            ));
        }
        let samples: Vec<BrdfSample> = pairs
            .iter()
            .map(|&(l, v)| BrdfSample {
                material: "m".into(),
                light: l,
                view: v,
                value: m.as_ref().eval(l, v) * std::f32::consts::PI,
            })
            .collect();
        g.bench_function(name, |b| {
            b.iter_batched(
                || samples.clone(),
                |s| black_box(fit_material("m", &s, &FitOptions::default()).unwrap().rms),
                BatchSize::SmallInput,
            )
        });
    }
    g.finish();
}

/// `IGI_BENCH_LUMITEXELS` (default 1e4; 1e5 takes minutes per iteration) lumitexels of 3 materials (matte red, glossy blue, retroreflective grey; the clustering
/// test's materials), 10 samples each (half of the views near the mirror direction), random
/// normals, 3% noise; k = 3, default options (fits capped at 3000 samples).
fn bench_cluster(c: &mut Criterion) {
    let mats = separated_materials();
    let count: usize = std::env::var("IGI_BENCH_LUMITEXELS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(10_000);
    let q = |i: usize, k: f32| (i as f32 * k).fract();
    let lts: Vec<Lumitexel> = (0..count)
        .map(|t| {
            let m = &mats[t % 3];
            let normal = dir(60.0 * q(t, 0.618_034), 360.0 * q(t, 0.754_877_7));
            let f = Frame::from_normal(normal);
            let samples = (0..10)
                .map(|s| {
                    let i = t * 10 + s;
                    let (lt, lp) = (80.0 * q(i, 0.569_840_3), 360.0 * q(i, 0.362_437_6));
                    let l = dir(lt, lp);
                    let v = if s % 2 == 0 {
                        dir(80.0 * q(i, 0.281_717), 360.0 * q(i, 0.131_986))
                    } else {
                        dir(
                            (lt + 16.0 * q(i, 0.281_717) - 8.0).clamp(0.0, 85.0),
                            lp + 180.0 + 16.0 * q(i, 0.131_986) - 8.0,
                        )
                    };
                    let noise =
                        Vec3::new(q(i, 0.427_8), q(i, 0.912_3), q(i, 0.334_1)) * 2.0 - Vec3::ONE;
                    let val =
                        m.as_ref().eval(l, v) * std::f32::consts::PI * (Vec3::ONE + 0.03 * noise);
                    (f.to_world(l), f.to_world(v), val)
                })
                .collect();
            Lumitexel {
                position: Vec3::ZERO,
                normal,
                samples,
            }
        })
        .collect();
    let opts = ClusterOptions {
        k: 3,
        ..ClusterOptions::default()
    };
    let mut g = c.benchmark_group("cluster");
    g.sample_size(10);
    g.throughput(Throughput::Elements(count as u64));
    g.bench_function(format!("{count} lumitexels x 10 samples, k=3"), |b| {
        b.iter(|| black_box(cluster(&lts, &opts).unwrap().brdfs.len()))
    });
    g.finish();
}

criterion_group!(benches, bench_model, bench_fit, bench_cluster);
criterion_main!(benches);
