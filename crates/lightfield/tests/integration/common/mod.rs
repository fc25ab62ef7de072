//! The synthetic glossy bunny: the Stanford bunny (../shared/data, turned Z up) with a
//! procedural albedo and one Lafortune lobe (n = 60) under a real light probe, photographed by
//! igi's own path tracer from many views on a sphere, plus held-out views.

#![allow(dead_code)]

use glam::{DVec3, Vec3};
use igi_brdf::Lobe;
use igi_camera::{Camera, WorldToCamera};
use igi_geometry::atlas::{build_atlas, Atlas, AtlasOptions};
use igi_geometry::TriMesh;
use igi_imaging::HdrImage;
use igi_render::{
    render_image, Albedo, Environment, Lighting, Material, RenderOptions, Scene, Texture,
};

pub struct Synth {
    pub atlas: Atlas,
    pub scene: Scene,
    pub lighting: Lighting,
    pub views: Vec<(Camera, HdrImage)>,
    pub held_out: Vec<(Camera, HdrImage)>,
    pub view_dirs: Vec<Vec3>,
}

/// The bunny, Z up, centred, about 1 unit tall, with vertex normals.
pub fn bunny() -> TriMesh {
    let path = igi_testkit::shared_data("meshes/stanford_bunny/reconstruction/bun_zipper_res3.ply");
    let mut m = igi_geometry::read_mesh(&path).expect("bunny");
    let (lo, hi) = m.bounds().unwrap();
    let c = [
        (lo[0] + hi[0]) / 2.0,
        (lo[1] + hi[1]) / 2.0,
        (lo[2] + hi[2]) / 2.0,
    ];
    let s = 1.0 / (hi[1] - lo[1]);
    for p in &mut m.positions {
        // Y up -> Z up: (x, y, z) -> (x, -z, y)
        *p = [(p[0] - c[0]) * s, -(p[2] - c[2]) * s, (p[1] - c[1]) * s];
    }
    m.normals = None;
    m.compute_vertex_normals();
    m
}

/// A procedural albedo of position (smooth colour stripes).
pub fn albedo(p: Vec3) -> Vec3 {
    let t = (6.0 * p.z + 3.0 * p.x).sin() * 0.5 + 0.5;
    Vec3::new(0.15 + 0.35 * t, 0.2 + 0.15 * (1.0 - t), 0.25)
}

/// `n` directions on the unit sphere (Fibonacci), rotated by `offset` in azimuth.
pub use igi_geometry::procedural::fibonacci_directions as sphere_dirs;

/// A camera at distance `dist` along `dir` looking at the origin.
pub fn camera_toward(dir: Vec3, dist: f64, size: u32) -> Camera {
    let mut cam = Camera::pinhole(
        size,
        size,
        size as f64 * 1.6,
        size as f64 * 1.6,
        (size as f64 - 1.0) / 2.0,
        (size as f64 - 1.0) / 2.0,
    );
    let eye = dir.as_dvec3() * dist;
    let up = if dir.z.abs() > 0.95 {
        DVec3::X
    } else {
        DVec3::Z
    };
    cam.pose = WorldToCamera::look_at(eye, DVec3::ZERO, up).unwrap();
    cam
}

/// The bunny photographed from `n_views` directions at `spp` samples a pixel (the capture's
/// seeds count up from `capture_seed`) and from `held_out_dirs` at `truth_spp` (seeds from 9000).
pub fn make(
    n_views: usize,
    held_out_dirs: &[Vec3],
    size: u32,
    (spp, capture_seed): (u32, u64),
    truth_spp: u32,
) -> Synth {
    let mut mesh = bunny();
    mesh.uvs = None;
    let atlas = build_atlas(
        &mesh,
        AtlasOptions {
            resolution: 160,
            gutter: 1,
        },
    )
    .expect("atlas");
    let mut tex = HdrImage::new(atlas.resolution, atlas.resolution);
    for (i, p) in atlas.position.pixels.iter().enumerate() {
        tex.pixels[i] = albedo(Vec3::from_array(*p)).to_array();
    }
    let lobe = Lobe {
        rho: Vec3::splat(4.0),
        cxy: -1.0,
        cz: 1.0,
        n: 60.0,
    };
    let material = Material {
        albedo: Albedo::Texture(Texture::from_image(&tex)),
        lobes: vec![lobe],
        lobe_map: None,
    };
    let scene = Scene::new(vec![("bunny".into(), atlas.mesh.clone(), material)]).expect("scene");
    let probe = igi_imaging::read_image(&igi_testkit::shared_data(
        "light_probes/probulator_latlong_256x128/pisa.hdr",
    ))
    .expect("probe");
    let lighting = Lighting {
        environment: Some(Environment::from_image(&probe, 1.0).expect("env")),
        sun: None,
    };
    let shoot = |dirs: &[Vec3], spp: u32, seed: u64| -> Vec<(Camera, HdrImage)> {
        dirs.iter()
            .enumerate()
            .map(|(i, d)| {
                let cam = camera_toward(*d, 3.0, size);
                let opts = RenderOptions {
                    spp,
                    seed: seed + i as u64,
                    indirect: 1,
                    russian_roulette: false,
                    stratified: false,
                    adaptive: false,
                };
                let img = render_image(&scene, &lighting, &cam, &opts, &|_| {})
                    .expect("render")
                    .mean;
                (cam, img)
            })
            .collect()
    };
    let view_dirs = sphere_dirs(n_views, 0.0);
    let views = shoot(&view_dirs, spp, capture_seed);
    let held_out = shoot(held_out_dirs, truth_spp, 9000);
    Synth {
        atlas,
        scene,
        lighting,
        views,
        held_out,
        view_dirs,
    }
}

/// PSNR (dB) of `img` against `truth` over the pixels where `alpha` is 1 and so is it at all 8
/// neighbours: the truth's silhouette pixels mix the object with the background (the path
/// tracer integrates over the pixel), which no point-sampled render reproduces.
pub fn psnr(img: &HdrImage, alpha: &[f32], truth: &HdrImage) -> f64 {
    let (w, h) = (img.width as i64, img.height as i64);
    let inner = |i: usize| {
        let (x, y) = (i as i64 % w, i as i64 / w);
        (-1..=1).all(|dy| {
            (-1..=1).all(|dx| {
                let (a, b) = (x + dx, y + dy);
                a >= 0 && b >= 0 && a < w && b < h && alpha[(b * w + a) as usize] > 0.5
            })
        })
    };
    let mut a = img.clone();
    let mut b = truth.clone();
    for i in 0..alpha.len() {
        a.valid[i] = inner(i);
        b.valid[i] = a.valid[i];
    }
    igi_render::compare_images(&a, &b, None, None)
        .expect("compare")
        .psnr_db
}
