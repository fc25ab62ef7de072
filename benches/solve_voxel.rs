//! Solve time for one voxel at the paper's scale (issue 7), and the error-against-run-time
//! curve over sample schedules and iterations.
//!
//! The scene follows the paper's multiresolution load: the solved voxel (a 4.3 m patch of
//! rubble-like relief with a low wall, 800K triangles, a 512x512 atlas), its 8 neighbours on
//! the ground at 160K triangles each, and the next two rings of 40 voxels at 40K each (2.9 M
//! triangles in all). Eleven photographs (320x240) look at the voxel from all sides, each under
//! its own clear sky and sun (as when every photograph has its own probe capture), rendered by
//! igi-render from a known albedo at 64 spp. Two indirect bounces. Every schedule solves the
//! voxel from 0.5 grey; the report gives wall time and the rho_d error against the truth.
//!
//! Run: `cargo bench --bench solve_voxel` (writes target/solve_voxel.json; set
//! `IGI_BENCH_QUICK=1` for a 1/16-size scene that finishes in seconds).
use glam::Vec3;
use igi_camera::Camera;
use igi_geometry::TriMesh;
use igi_reflect::parts::build_parts;
use igi_reflect::solver::Truth;
use igi_reflect::truth::{scene_with_albedo, truth_atlas};
use igi_reflect::Photo;
use igi_reflect::{SolveOptions, SolveResult};
use igi_render::sky::{clear_sky, sun_direction};
use igi_render::{render_image, Environment, Lighting, RenderOptions, Sun};
use std::time::Instant;

const VOXEL: f32 = 4.3;

fn height(x: f32, y: f32) -> f32 {
    0.08 * (3.1 * x).sin() * (2.3 * y).cos()
        + 0.03 * (11.0 * x + 0.5).sin() * (9.0 * y).sin()
        + 0.015 * (37.0 * x).cos() * (31.0 * y + 1.0).sin()
}

/// A height field over the voxel at (i, j) with `n x n` quads (2 n^2 triangles); the voxel at
/// (0, 0) also gets a low wall (two faces) so it has occlusion and interreflection.
fn voxel_mesh(i: i32, j: i32, n: usize, wall: bool) -> TriMesh {
    let (x0, y0) = (
        i as f32 * VOXEL - VOXEL / 2.0,
        j as f32 * VOXEL - VOXEL / 2.0,
    );
    let mut m = TriMesh {
        positions: vec![],
        normals: None,
        uvs: None,
        colors: None,
        indices: vec![],
    };
    let grid = |m: &mut TriMesh, n: usize, f: &dyn Fn(f32, f32) -> [f32; 3]| {
        let base = m.positions.len() as u32;
        for b in 0..=n {
            for a in 0..=n {
                m.positions
                    .push(f(a as f32 / n as f32, b as f32 / n as f32));
            }
        }
        let w = (n + 1) as u32;
        for b in 0..n as u32 {
            for a in 0..n as u32 {
                let q = base + b * w + a;
                m.indices.push([q, q + 1, q + w + 1]);
                m.indices.push([q, q + w + 1, q + w]);
            }
        }
    };
    if wall {
        // 80% of the triangles on the ground, 20% on the wall's two faces
        let ng = (n as f32 * 0.894) as usize;
        grid(&mut m, ng, &|s, t| {
            let (x, y) = (x0 + s * VOXEL, y0 + t * VOXEL);
            [x, y, height(x, y)]
        });
        let nw = ((n * n - ng * ng) as f32 / 2.0).sqrt() as usize;
        for (y, sign) in [(0.6f32, 1.0f32), (0.9, -1.0)] {
            grid(&mut m, nw, &|s, t| {
                let s = if sign > 0.0 { s } else { 1.0 - s };
                [x0 + 0.5 + s * 3.3, y, 1.6 * t]
            });
        }
    } else {
        grid(&mut m, n, &|s, t| {
            let (x, y) = (x0 + s * VOXEL, y0 + t * VOXEL);
            [x, y, height(x, y)]
        });
    }
    m.compute_vertex_normals();
    m
}

fn albedo(p: Vec3) -> Vec3 {
    let s = |f: f32| 0.5 + 0.5 * f.sin();
    Vec3::new(
        0.2 + 0.5 * s(1.3 * p.x + 0.4 * p.z),
        0.2 + 0.4 * s(1.1 * p.y - 0.7 * p.z + 1.0),
        0.15 + 0.3 * s(0.9 * (p.x + p.y) + 2.0),
    )
}

/// The bench scene: the solved voxel (part 0) and its three rings of neighbours, with their
/// triangle counts (voxel, others).
struct SiteScene {
    parts: Vec<igi_reflect::Part>,
    voxel_triangles: usize,
    other_triangles: usize,
}

fn build_scene(quick: bool, atlas: u32) -> SiteScene {
    let scale = if quick { 4 } else { 1 };
    // triangles per voxel: 2 n^2
    let (n0, n1, n2) = (633 / scale, 283 / scale, 141 / scale);
    let t_build = Instant::now();
    let centre = vec![("voxel".to_string(), voxel_mesh(0, 0, n0, true))];
    let mut others = Vec::new();
    for j in -3i32..=3 {
        for i in -3i32..=3 {
            let ring = i.abs().max(j.abs());
            if ring == 0 {
                continue;
            }
            let n = if ring == 1 { n1 } else { n2 };
            others.push((format!("v{i}_{j}"), voxel_mesh(i, j, n, false)));
        }
    }
    let tri = |v: &[(String, TriMesh)]| v.iter().map(|(_, m)| m.indices.len()).sum::<usize>();
    let (t0, t_other) = (tri(&centre), tri(&others));
    let mut parts = build_parts(centre, atlas).unwrap();
    parts.extend(build_parts(others, 64).unwrap());
    eprintln!(
        "scene: voxel {t0} triangles ({} covered texels of {atlas}^2), others {t_other} triangles, built in {:.1} s",
        parts[0].cache.texels.len(),
        t_build.elapsed().as_secs_f64()
    );
    SiteScene {
        parts,
        voxel_triangles: t0,
        other_triangles: t_other,
    }
}

/// Eleven photos of the voxel from all sides, each under its own sky and sun.
fn render_photos(truth_scene: &igi_render::Scene) -> Vec<Photo> {
    let t_photo = Instant::now();
    let photos: Vec<Photo> = (0..11)
        .map(|k| {
            let az = k as f32 * 360.0 / 11.0;
            let a = az.to_radians();
            let eye = Vec3::new(7.5 * a.cos(), 7.5 * a.sin(), 3.0 + 1.5 * (k % 3) as f32);
            let target = Vec3::new(0.0, 0.0, 0.4).as_dvec3();
            let camera = Camera::look_at(eye.as_dvec3(), target, 320, 240, 55.0).unwrap();
            let sun = sun_direction(25.0 + 4.0 * k as f32, 15.0 + 30.0 * k as f32);
            let lighting = Lighting {
                environment: Some(
                    Environment::from_image(&clear_sky(64, 32, sun, 0.6, Vec3::splat(0.08)), 1.0)
                        .unwrap(),
                ),
                sun: Some(Sun::new(sun, Vec3::new(6.0e4, 5.7e4, 5.2e4), 0.53).unwrap()),
            };
            let opts = RenderOptions {
                spp: 64,
                seed: 100 + k as u64,
                indirect: 2,
                russian_roulette: false,
                stratified: false,
                adaptive: false,
            };
            let image = render_image(truth_scene, &lighting, &camera, &opts, &|_| {})
                .unwrap()
                .mean;
            Photo {
                id: format!("p{k:02}"),
                image,
                camera,
                lighting,
            }
        })
        .collect();
    eprintln!(
        "photos rendered in {:.1} s",
        t_photo.elapsed().as_secs_f64()
    );
    photos
}

/// The true albedo of the solved voxel's texels (the other parts have none).
fn voxel_truth(parts: &[igi_reflect::Part]) -> Truth {
    Truth::from_texels(texel_truth(parts))
}

/// Per part and texel, the true albedo of the solved voxel (the other parts have none).
fn texel_truth(parts: &[igi_reflect::Part]) -> Vec<Vec<Option<Vec3>>> {
    parts
        .iter()
        .enumerate()
        .map(|(i, p)| {
            p.cache
                .texels
                .iter()
                .map(|t| {
                    if i == 0 {
                        Some(albedo(t.position))
                    } else {
                        None
                    }
                })
                .collect()
        })
        .collect()
}

/// Solves the voxel from 0.5 grey with the sample schedule `spp` for `iters` iterations (the
/// other voxels keep the true albedo `truth`); prints the curve and returns its JSON row.
fn run_schedule(
    parts: &[igi_reflect::Part],
    truth: &[Vec<Vec3>],
    photos: &[Photo],
    gt: &Truth,
    atlas: u32,
    (spp, iters): (Vec<u32>, u32),
) -> serde_json::Value {
    let opts = SolveOptions {
        atlas_resolution: atlas,
        max_iterations: iters,
        min_iterations: iters,
        spp: spp.clone(),
        parts: Some(vec!["voxel".into()]),
        ..SolveOptions::default()
    };
    let ids = photos.iter().map(|p| p.id.clone()).collect();
    // the other voxels keep the true albedo (as if already solved)
    let mut start = SolveResult::fresh(parts.to_vec(), ids, &opts);
    for (p, t) in start.parts.iter_mut().zip(truth).skip(1) {
        p.rho.clone_from(t);
    }
    let t = Instant::now();
    let r = igi_reflect::solve_in_memory(start, photos, None, Some(gt), &opts).unwrap();
    let wall = t.elapsed().as_secs_f64();
    let mut curve = Vec::new();
    for it in &r.report.iterations {
        let mae = it.truth_mae.unwrap_or([f32::NAN; 3]);
        eprintln!(
            "  spp {:?}: iteration {} ({} spp) at {:.1} s: {} observations, rho_d MAE {:.4} {:.4} {:.4}, RMS {:.4}",
            spp,
            it.iteration,
            it.spp,
            it.cumulative_s,
            it.observations,
            mae[0],
            mae[1],
            mae[2],
            it.truth_rms.unwrap_or(f32::NAN)
        );
        curve.push(serde_json::json!({"iteration": it.iteration, "spp": it.spp, "cumulative_s": it.cumulative_s, "observations": it.observations, "mae": mae, "rms": it.truth_rms}));
    }
    println!(
        "schedule {spp:?} x {iters}: {wall:.1} s, final RMS {:.4}",
        r.report
            .iterations
            .last()
            .and_then(|i| i.truth_rms)
            .unwrap_or(f32::NAN)
    );
    serde_json::json!({"spp": spp, "iterations": iters, "wall_s": wall, "curve": curve})
}

fn main() {
    let quick = std::env::var("IGI_BENCH_QUICK").is_ok();
    let atlas = if quick { 128 } else { 512 };
    let site = build_scene(quick, atlas);
    let parts = &site.parts;
    let truth: Vec<Vec<Vec3>> = parts.iter().map(|p| truth_atlas(p, albedo)).collect();
    let truth_scene = scene_with_albedo(parts, &truth).unwrap();
    let photos = render_photos(&truth_scene);
    let gt = voxel_truth(parts);
    let schedules: Vec<(Vec<u32>, u32)> = vec![
        (vec![4], 1),
        (vec![4, 16], 2),
        (vec![8, 32], 2),
        (vec![4, 16, 64], 3),
        (vec![16, 64], 2),
        (vec![16, 64, 256], 3),
    ];
    let rows: Vec<serde_json::Value> = schedules
        .into_iter()
        .map(|s| run_schedule(parts, &truth, &photos, &gt, atlas, s))
        .collect();
    let out = serde_json::json!({
        "voxel_triangles": site.voxel_triangles, "other_triangles": site.other_triangles,
        "atlas": atlas, "covered_texels": parts[0].cache.texels.len(), "photos": 11,
        "indirect": 2, "threads": rayon::current_num_threads(), "schedules": rows,
    });
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("target/solve_voxel.json");
    std::fs::write(&path, serde_json::to_string_pretty(&out).unwrap()).unwrap();
    eprintln!("wrote {}", path.display());
}
