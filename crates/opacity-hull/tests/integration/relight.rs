//! Relighting from one-light-at-a-time images (Matusik et al. 2002, Sec. 5, Eq. 3) against
//! igi's own path tracer: a diffuse sphere with a small glossy sphere beside it, seen by 4
//! views (64 x 64); each view's light images are renders under a single sun of irradiance 1
//! (disk radiance 1 / solid angle) at the light's direction, direct light only; the truth is a
//! render of the same scene under a new, smooth lighting file (a low-frequency lat-long sky).
//! The hull is built from the true silhouettes, the reflectance field compressed by PCA to 1 %
//! RMS, and view 0 relit (library, and through the surfel renderer) and compared with the
//! truth on the pixels of the diffuse sphere.

use glam::{DVec3, Vec3};
use igi_brdf::Lobe;
use igi_camera::{Camera, WorldToCamera};
use igi_formats::lighting::LightingRadiance;
use igi_geometry::TriMesh;
use igi_imaging::{HdrImage, Mask};
use igi_opacity_hull::build::{build, load_relit_model, BuildOptions};
use igi_opacity_hull::lightweights::light_weights;
use igi_opacity_hull::reflectance::read_fields;
use igi_opacity_hull::render::{render, RenderOptions as SplatOptions};
use igi_render::{render_image, Lighting, Material, RenderOptions, Scene, Sun};
use std::f64::consts::PI;
use std::path::{Path, PathBuf};

const SIZE: u32 = 64;
const VIEWS: usize = 4;

fn sphere(centre: [f32; 3], r: f32) -> TriMesh {
    let mut m = igi_geometry::procedural::uv_sphere(24, 48, r);
    for p in &mut m.positions {
        for k in 0..3 {
            p[k] += centre[k];
        }
    }
    m
}

/// Object 0: the diffuse sphere; object 1: the glossy one.
fn scene() -> Scene {
    let glossy = Material {
        albedo: igi_render::Albedo::Constant(Vec3::new(0.1, 0.12, 0.15)),
        lobes: vec![Lobe {
            rho: Vec3::splat(2.0),
            cxy: -1.0,
            cz: 1.0,
            n: 40.0,
        }],
        lobe_map: None,
    };
    Scene::new(vec![
        (
            "diffuse".into(),
            sphere([0.0, 0.0, 0.0], 0.3),
            Material::lambertian(Vec3::new(0.7, 0.5, 0.3)),
        ),
        ("glossy".into(), sphere([0.27, -0.27, -0.14], 0.12), glossy),
    ])
    .unwrap()
}

/// View `v`: azimuth 90 degrees apart (plus 20), 25 degrees up, 2 m away.
fn camera(v: usize) -> Camera {
    let az = (20.0 + 90.0 * v as f64).to_radians();
    let el = 25f64.to_radians();
    let eye = DVec3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin()) * 2.0;
    let c = (SIZE as f64 - 1.0) / 2.0;
    let mut cam = Camera::pinhole(SIZE, SIZE, 100.0, 100.0, c, c);
    cam.pose = WorldToCamera::look_at(eye, DVec3::ZERO, DVec3::Z).unwrap();
    cam
}

/// The paper's layout: 4 elevations x 15 azimuths 24 degrees apart, turning with the view.
fn rings_4x15(v: usize) -> Vec<[f64; 3]> {
    let mut out = Vec::new();
    for (k, el) in [60.0f64, 25.0, -10.0, -45.0].iter().enumerate() {
        for a in 0..15 {
            let az = (24.0 * a as f64 + 6.0 * k as f64 + 90.0 * v as f64).to_radians();
            let el = el.to_radians();
            out.push([el.cos() * az.cos(), el.cos() * az.sin(), el.sin()]);
        }
    }
    out
}

/// 15 lights on a Fibonacci spiral over the whole sphere (8 above the horizon, 7 below),
/// turned with the view. The environment lights the object from below too (its lower half is
/// the ground's light), and the Voronoi quadrature needs lights there: a model of the
/// quadrature alone (clamped cosine over random normals, this sky) gives 3.5 % relative RMS for
/// this layout and 8 % for 11 lights above the horizon and 4 below.
fn spread_15(v: usize) -> Vec<[f64; 3]> {
    let golden = PI * (3.0 - 5f64.sqrt());
    (0..15)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / 15.0;
            let r = (1.0 - z * z).sqrt();
            let phi = golden * i as f64 + (PI / 2.0) * v as f64;
            [r * phi.cos(), r * phi.sin(), z]
        })
        .collect()
}

/// The object id seen through each pixel centre (None: background).
fn ids(scene: &Scene, cam: &Camera) -> Vec<Option<u32>> {
    let mut out = Vec::with_capacity((SIZE * SIZE) as usize);
    for y in 0..SIZE {
        for x in 0..SIZE {
            let (o, d) = cam.pixel_ray(x as f64, y as f64);
            out.push(
                scene
                    .intersect(o.as_vec3(), d.as_vec3())
                    .map(|h| scene.surface_point(&h).object),
            );
        }
    }
    out
}

fn mask_of(ids: &[Option<u32>], keep: impl Fn(u32) -> bool) -> Mask {
    Mask {
        width: SIZE as usize,
        height: SIZE as usize,
        data: ids.iter().map(|i| i.is_some_and(&keep)).collect(),
    }
}

fn shoot(scene: &Scene, lighting: &Lighting, cam: &Camera, spp: u32, seed: u64) -> HdrImage {
    let opts = RenderOptions {
        spp,
        seed,
        indirect: 0,
        russian_roulette: false,
        stratified: false,
        adaptive: false,
    };
    render_image(scene, lighting, cam, &opts, &|_| {})
        .unwrap()
        .mean
}

/// A single sun of irradiance 1 toward `d`.
fn one_light(d: [f64; 3]) -> Lighting {
    let dir = Vec3::new(d[0] as f32, d[1] as f32, d[2] as f32);
    let probe = Sun::new(dir, Vec3::ONE, 0.53).unwrap();
    let sun = Sun::new(dir, Vec3::splat(1.0 / probe.solid_angle()), 0.53).unwrap();
    Lighting {
        environment: None,
        sun: Some(sun),
    }
}

/// The new lighting: a smooth sky, brighter and bluer above, warmer toward +X.
fn write_lighting(dir: &Path) -> PathBuf {
    let map = igi_imaging::latlong::map_from_fn(64, 32, |d| {
        [
            0.55 + 0.3 * d.z + 0.15 * d.x,
            0.55 + 0.35 * d.z,
            0.55 + 0.4 * d.z - 0.1 * d.y,
        ]
    });
    igi_imaging::write_exr(&dir.join("sky.exr"), &map).unwrap();
    let path = dir.join("sky.toml");
    std::fs::write(&path, "[environment]\nmap = \"sky.exr\"\nscale = 2.0\n").unwrap();
    path
}

/// Write a rig of the 4 views with the given light layout; returns the rig file.
fn write_rig(dir: &Path, scene: &Scene, layout: &dyn Fn(usize) -> Vec<[f64; 3]>) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let mut text =
        String::from("[object]\nbbox_min = [-0.45, -0.45, -0.4]\nbbox_max = [0.45, 0.45, 0.4]\n");
    for v in 0..VIEWS {
        let cam = camera(v);
        cam.save(&dir.join(format!("c{v}.json"))).unwrap();
        mask_of(&ids(scene, &cam), |_| true)
            .save_png(&dir.join(format!("m{v}.png")))
            .unwrap();
        let mut lights = Vec::new();
        for (i, d) in layout(v).iter().enumerate() {
            // the same pixel samples for every light of a view, as a camera integrates the same
            // pixel area whatever the light (independent jitter per light would add
            // incompressible noise at every edge)
            let img = shoot(scene, &one_light(*d), &cam, 8, v as u64);
            igi_imaging::write_exr(&dir.join(format!("l{v}_{i}.exr")), &img).unwrap();
            lights.push(format!(
                "{{ direction = [{}, {}, {}], image = \"l{v}_{i}.exr\" }}",
                d[0], d[1], d[2]
            ));
        }
        text += &format!(
            "\n[[view]]\nid = \"v{v}\"\ncamera = \"c{v}.json\"\nphoto = \"l{v}_0.exr\"\nmask = \"m{v}.png\"\nlights = [{}]\n",
            lights.join(", ")
        );
    }
    let rig = dir.join("rig.toml");
    std::fs::write(&rig, text).unwrap();
    rig
}

/// Relative RMS of `a` against `truth` over the mask's pixels (all channels).
fn relative_rms(a: &HdrImage, truth: &HdrImage, mask: &Mask) -> f64 {
    let (mut e, mut t) = (0.0f64, 0.0f64);
    for (i, _) in mask.data.iter().enumerate().filter(|(_, &m)| m) {
        for c in 0..3 {
            e += (a.pixels[i][c] as f64 - truth.pixels[i][c] as f64).powi(2);
            t += (truth.pixels[i][c] as f64).powi(2);
        }
    }
    (e / t).sqrt()
}

struct Measured {
    ratio: f64,
    ratio_kept: f64,
    relative_rms: f64,
    mean_components: f64,
    diffuse: f64,
    diffuse_splat: f64,
    glossy: f64,
    /// Seconds of the build's reflectance stage, and of loading the relit model.
    field_s: f64,
    relit_load_s: f64,
}

/// Build from the rig, relight view 0 under `lighting` and compare with `truth`.
fn measure(
    rig: &Path,
    out: &Path,
    lighting: &Path,
    truth: &HdrImage,
    ids: &[Option<u32>],
) -> Measured {
    let rig = igi_camera::Rig::load(rig).unwrap();
    let opts = BuildOptions {
        volume_orders: 2,
        volume_resolution: 32,
        ..Default::default()
    };
    let report = build(&rig, out, opts, &mut |_| {}).unwrap();
    let r = report.reflectance.expect("a reflectance field");
    let light = LightingRadiance::load(lighting).unwrap();
    let fields = read_fields(out).unwrap().unwrap();
    let f = &fields[0];
    let relit = f.relight(&light_weights(&light, &f.directions).unwrap());
    // pixels whose whole footprint is the diffuse sphere: a boundary pixel of the truth also
    // averages in the sky behind the object, which the relit object (premultiplied) lacks
    let diffuse = mask_of(ids, |o| o == 0).erode(1.0);
    let clock = std::time::Instant::now();
    let model = load_relit_model(out, &light).unwrap();
    let relit_load_s = clock.elapsed().as_secs_f64();
    let (splat, _alpha) = render(&model, &camera(0), SplatOptions::default());
    Measured {
        ratio: r.ratio,
        ratio_kept: r.ratio_kept,
        relative_rms: r.relative_rms,
        mean_components: r.mean_components,
        diffuse: relative_rms(&relit, truth, &diffuse),
        diffuse_splat: relative_rms(&splat, truth, &diffuse),
        glossy: relative_rms(&relit, truth, &mask_of(ids, |o| o == 1).erode(1.0)),
        field_s: r.seconds,
        relit_load_s,
    }
}

/// The scene, the lighting file, the truth of view 0 under it (2048 spp: 0.72 % relative
/// RMS noise on the diffuse pixels, measured between two seeds) and view 0's object ids.
fn setup(dir: &Path) -> (Scene, PathBuf, HdrImage, Vec<Option<u32>>) {
    let scene = scene();
    let lighting = write_lighting(dir);
    let truth = shoot(
        &scene,
        &Lighting::load(&lighting).unwrap(),
        &camera(0),
        2048,
        7,
    );
    let ids0 = ids(&scene, &camera(0));
    assert!(mask_of(&ids0, |o| o == 0).erode(1.0).count() > 500);
    (scene, lighting, truth, ids0)
}

fn run(layout: &dyn Fn(usize) -> Vec<[f64; 3]>, name: &str) -> Measured {
    let t = tempfile::tempdir().unwrap();
    let (scene, lighting, truth, ids0) = setup(t.path());
    let rig = write_rig(&t.path().join("rig"), &scene, layout);
    let m = measure(&rig, &t.path().join("hull"), &lighting, &truth, &ids0);
    eprintln!(
        "{name}: {:.2}x fewer numbers than the light images ({:.2}x than their kept blocks), PCA RMS {:.4} of the mean, {:.2} components a block; diffuse relative RMS {:.4} (splatted {:.4}), glossy {:.4}; PCA {:.2} s, relit model {:.3} s",
        m.ratio,
        m.ratio_kept,
        m.relative_rms,
        m.mean_components,
        m.diffuse,
        m.diffuse_splat,
        m.glossy,
        m.field_s,
        m.relit_load_s
    );
    m
}

/// 4 views x 60 lights (the paper's 4 x 15 per view): every goal is met. Measured: 11.80x
/// fewer numbers (3.55x than the kept blocks), 12.88 components a block, PCA RMS 1.00 % of
/// the mean; diffuse 1.09 % (splatted through the surfels 1.38 %), glossy 25.6 %.
#[test]
fn sixty_lights_a_view_relight_within_3_percent_and_compress_10x() {
    let m = run(&rings_4x15, "4 x 60 lights");
    assert!(m.relative_rms <= 0.01, "PCA RMS {}", m.relative_rms);
    assert!(m.ratio >= 10.0, "stored {:.2}x fewer numbers", m.ratio);
    assert!(m.diffuse <= 0.03, "diffuse relative RMS {}", m.diffuse);
    assert!(
        m.diffuse_splat <= 0.03,
        "splatted diffuse relative RMS {}",
        m.diffuse_splat
    );
}

/// 4 views x 15 lights: the relighting goal is met (measured diffuse 2.83 %, splatted 2.62 %;
/// glossy 74 %: 15 lights cannot place a highlight), the PCA at 1 % RMS stores 7.56x fewer
/// numbers (2.27x than the kept blocks, 6.12 components a block). With L = 15 lights a
/// component costs n + L = 207 numbers against the block's L n = 2880, so a block must keep
/// at most 1.4 components for 10x on the kept blocks: the 10x goal needs more lights (60 meet
/// it above); see `fifteen_lights_compress_10x` (ignored) for the goal itself.
#[test]
fn fifteen_lights_a_view_relight_within_3_percent() {
    let m = run(&spread_15, "4 x 15 lights");
    assert!(m.relative_rms <= 0.01, "PCA RMS {}", m.relative_rms);
    assert!(m.diffuse <= 0.03, "diffuse relative RMS {}", m.diffuse);
    assert!(
        m.diffuse_splat <= 0.03,
        "splatted diffuse relative RMS {}",
        m.diffuse_splat
    );
    // the measured level (7.56x), not the goal
    assert!(m.ratio >= 7.0, "stored {:.2}x fewer numbers", m.ratio);
}

/// The 10x goal at 15 lights a view: not met (7.56x, see above).
#[test]
#[ignore = "not met with 15 lights a view: 7.56x (the PCA's per-component cost n + L)"]
fn fifteen_lights_compress_10x() {
    let m = run(&spread_15, "4 x 15 lights");
    assert!(m.ratio >= 10.0, "stored {:.2}x fewer numbers", m.ratio);
}
