//! Matting on captures made by igi's own path tracer (issue 12): an object with sub-pixel
//! strands, a diffuse sphere and a glossy sphere on a turntable in front of the Eq. 1 backdrops.
//!
//! The backdrop is a distant display behind the object: the environment holds, in every
//! direction within 60 degrees of the camera's axis, the Eq. 1 pattern at the camera pixel that
//! direction projects to (one display pixel per camera pixel); a second display lies under the
//! turntable (directions more than 17 degrees below the horizon, 200 display pixels per unit of
//! the direction's tangent), as in the paper's rig; a grey sky of radiance 0.5 is elsewhere. So
//! the camera sees the pattern directly where nothing is in front of it, the glossy sphere
//! reflects the lower display over its lower half, and the displays light the object, as
//! monitors do.
//! Each pixel is 4 x 4 stratified rays through igi-render's `PathTracer`; the true alpha is the
//! fraction of those rays that hit the object. The captures go through a rig file and
//! `load_views`, as a user's would.

use glam::{DVec3, Vec3};
use igi_brdf::Lobe;
use igi_camera::rig::{BackdropPair, RigObject, RigView};
use igi_camera::{Camera, Rig, WorldToCamera};
use igi_geometry::TriMesh;
use igi_imaging::{latlong, HdrImage};
use igi_opacity_hull::backdrop::{pattern_value, LAMBDAS};
use igi_opacity_hull::views::{load_views, MatteOptions, View};
use igi_render::sampling::Rng;
use igi_render::{Albedo, Environment, Lighting, Material, PathTracer, RenderOptions, Scene};
use std::path::Path;

const W: u32 = 80;
const H: u32 = 64;
const S: usize = 4;
/// Object ids in the scene: strands, diffuse sphere, glossy sphere.
const GLOSSY: u32 = 2;

fn camera() -> Camera {
    let mut c = Camera::pinhole(W, H, 70.0, 70.0, 39.5, 31.5);
    c.pose = WorldToCamera::look_at(DVec3::new(0.0, -3.0, 0.3), DVec3::ZERO, DVec3::Z).unwrap();
    c
}

/// A box between `lo` and `hi` (12 triangles).
fn cuboid(lo: [f32; 3], hi: [f32; 3]) -> TriMesh {
    let p = |i: usize| {
        [
            if i & 1 == 0 { lo[0] } else { hi[0] },
            if i & 2 == 0 { lo[1] } else { hi[1] },
            if i & 4 == 0 { lo[2] } else { hi[2] },
        ]
    };
    let quads = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    TriMesh {
        positions: (0..8).map(p).collect(),
        normals: None,
        uvs: None,
        colors: None,
        indices: quads
            .iter()
            .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
            .collect(),
    }
}

/// The object turned by `angle` about Z: five strands 1 cm wide (about a quarter pixel), a
/// diffuse sphere and a glossy sphere.
fn object(angle: f32) -> Scene {
    let mut strands = TriMesh {
        positions: vec![],
        normals: None,
        uvs: None,
        colors: None,
        indices: vec![],
    };
    for k in 0..5 {
        let x = -0.8 + 0.4 * k as f32;
        strands.append(&cuboid([x, 0.3, -0.7], [x + 0.01, 0.31, 0.7]));
    }
    let mut diffuse = igi_geometry::procedural::uv_sphere(24, 48, 0.3);
    let mut glossy = igi_geometry::procedural::uv_sphere(24, 48, 0.35);
    diffuse.positions.iter_mut().for_each(|p| p[0] -= 0.4);
    glossy.positions.iter_mut().for_each(|p| p[0] += 0.35);
    let turn = glam::Mat3::from_rotation_z(angle);
    let parts = [strands, diffuse, glossy].map(|mut m| {
        for p in &mut m.positions {
            *p = (turn * Vec3::from_array(*p)).to_array();
        }
        m
    });
    let gloss = Material {
        albedo: Albedo::Constant(Vec3::splat(0.1)),
        lobes: vec![Lobe {
            rho: Vec3::splat(20.0),
            cxy: -1.0,
            cz: 1.0,
            n: 300.0,
        }],
        lobe_map: None,
    };
    let [strands, diffuse, glossy] = parts;
    Scene::new(vec![
        (
            "strands".into(),
            strands,
            Material::lambertian(Vec3::new(0.7, 0.6, 0.4)),
        ),
        (
            "diffuse".into(),
            diffuse,
            Material::lambertian(Vec3::new(0.2, 0.5, 0.3)),
        ),
        ("glossy".into(), glossy, gloss),
    ])
    .unwrap()
}

/// The backdrop display for (lambda, n) behind the object, as a lat-long environment.
fn backdrop_lighting(cam: &Camera, lambda: f64, n: i32) -> Lighting {
    let img = latlong::map_from_fn(1024, 512, |d| {
        let d = d.as_dvec3();
        let dc = cam.pose.r * d;
        let display = if dc.z > 0.5 * dc.length() {
            Some(
                cam.intrinsics
                    .to_pixel(glam::DVec2::new(dc.x / dc.z, dc.y / dc.z)),
            )
        } else if d.z < -0.3 {
            Some(glam::DVec2::new(d.x, d.y) / -d.z * 200.0)
        } else {
            None
        };
        display.map_or([0.5; 3], |px| {
            [0, 1, 2].map(|i| (pattern_value(px.x, px.y, i, lambda, n) / 255.0) as f32)
        })
    });
    Lighting {
        environment: Some(Environment::from_image(&img, 1.0).unwrap()),
        sun: None,
    }
}

/// Per pixel: the backdrop alone, the object in front of it, the true alpha and whether every
/// ray hit the glossy sphere.
struct Capture {
    backdrop: HdrImage,
    object: HdrImage,
    alpha: Vec<f32>,
    glossy: Vec<bool>,
}

fn capture(scene: &Scene, cam: &Camera, lighting: &Lighting) -> Capture {
    let opts = RenderOptions {
        spp: 1,
        seed: 5,
        indirect: 1,
        russian_roulette: false,
        stratified: false,
        adaptive: false,
    };
    let pt = PathTracer::new(scene, lighting, &opts);
    let (w, h) = (W as usize, H as usize);
    let mut c = Capture {
        backdrop: HdrImage::new(w, h),
        object: HdrImage::new(w, h),
        alpha: vec![0.0; w * h],
        glossy: vec![false; w * h],
    };
    for i in 0..w * h {
        let (mut r, mut o, mut hits, mut gloss) = (Vec3::ZERO, Vec3::ZERO, 0, 0);
        for s in 0..S * S {
            let u = (i % w) as f64 - 0.5 + ((s % S) as f64 + 0.5) / S as f64;
            let v = (i / w) as f64 - 0.5 + ((s / S) as f64 + 0.5) / S as f64;
            let (origin, dir) = cam.pixel_ray(u, v);
            let (origin, dir) = (origin.as_vec3(), dir.as_vec3());
            let mut rng = Rng::new(9, (i * S * S + s) as u64);
            r += lighting.escaped(dir);
            o += pt.li(origin, dir, &mut rng, &mut 0);
            if let Some(hit) = scene.intersect(origin, dir) {
                hits += 1;
                gloss += (hit.geom == GLOSSY) as usize;
            }
        }
        let k = 1.0 / (S * S) as f32;
        c.backdrop.pixels[i] = (r * k).to_array();
        c.object.pixels[i] = (o * k).to_array();
        c.alpha[i] = hits as f32 * k;
        c.glossy[i] = gloss == S * S;
    }
    c
}

/// Render the six captures of each turntable position, write them with a rig file, and return
/// the rig and the true alpha and glossy pixels of each view.
/// Per view: the true alpha and the pixels wholly on the glossy sphere.
type Truth = Vec<(Vec<f32>, Vec<bool>)>;

fn make_rig(dir: &Path, angles: &[f32]) -> (Rig, Truth) {
    let cam = camera();
    let lights: Vec<(f64, i32, Lighting)> = LAMBDAS
        .iter()
        .flat_map(|&l| [1, -1].map(|n| (l, n, backdrop_lighting(&cam, l, n))))
        .collect();
    cam.save(&dir.join("cam.json")).unwrap();
    let mut views = Vec::new();
    let mut truth = Vec::new();
    for (k, &angle) in angles.iter().enumerate() {
        let scene = object(angle);
        let mut pairs = Vec::new();
        for (lambda, n, lighting) in &lights {
            let c = capture(&scene, &cam, lighting);
            let name = |what: &str| format!("v{k}-{what}-{lambda}-{n}.exr");
            igi_imaging::write_exr(&dir.join(name("bg")), &c.backdrop).unwrap();
            igi_imaging::write_exr(&dir.join(name("obj")), &c.object).unwrap();
            if pairs.is_empty() {
                igi_imaging::write_exr(&dir.join(format!("v{k}.exr")), &c.object).unwrap();
                truth.push((c.alpha.clone(), c.glossy.clone()));
            }
            pairs.push(BackdropPair {
                lambda: *lambda,
                n: *n,
                backdrop: name("bg").into(),
                object: name("obj").into(),
            });
        }
        views.push(RigView {
            id: format!("v{k}"),
            camera: "cam.json".into(),
            photo: format!("v{k}.exr").into(),
            mask: None,
            backdrops: pairs,
            lights: vec![],
        });
    }
    let rig = Rig {
        object: RigObject {
            bbox_min: [-1.0; 3],
            bbox_max: [1.0; 3],
        },
        views,
        path: dir.join("rig.toml"),
    };
    (rig, truth)
}

/// Load the rig keeping only the pairs whose lambda passes `keep`.
fn mattes(rig: &Rig, keep: impl Fn(f64) -> bool) -> Vec<View> {
    let mut r = rig.clone();
    for v in &mut r.views {
        v.backdrops.retain(|b| keep(b.lambda));
    }
    let path = r.path.with_file_name("rig-subset.toml");
    r.save(&path).unwrap();
    load_views(&Rig::load(&path).unwrap(), MatteOptions::default()).unwrap()
}

/// The pixels of the box around the object's true coverage.
fn object_box(alpha: &[f32]) -> Vec<usize> {
    let (w, h) = (W as usize, H as usize);
    let covered: Vec<usize> = (0..w * h).filter(|&i| alpha[i] > 0.0).collect();
    let (x0, x1) = covered
        .iter()
        .fold((w, 0), |(a, b), &i| (a.min(i % w), b.max(i % w)));
    let (y0, y1) = covered
        .iter()
        .fold((h, 0), |(a, b), &i| (a.min(i / w), b.max(i / w)));
    (y0..=y1)
        .flat_map(|y| (x0..=x1).map(move |x| y * w + x))
        .collect()
}

fn mean_abs(ids: &[usize], matte: &[f32], truth: &[f32]) -> f64 {
    ids.iter()
        .map(|&i| (matte[i] - truth[i]).abs() as f64)
        .sum::<f64>()
        / ids.len() as f64
}

#[test]
fn path_traced_captures_give_true_alpha() {
    let dir = tempfile::tempdir().unwrap();
    let (rig, truth) = make_rig(dir.path(), &[0.0, 0.7, 1.4]);
    rig.save(&rig.path).unwrap();
    let all = mattes(&rig, |_| true);
    for (k, (alpha, glossy)) in truth.iter().enumerate() {
        let m = &all[k].matte;
        assert!(
            m.valid.iter().all(|v| *v),
            "every pixel has backdrop signal"
        );
        let background: Vec<usize> = (0..alpha.len()).filter(|&i| alpha[i] == 0.0).collect();
        let bg_err = background
            .iter()
            .map(|&i| m.alpha[i].abs())
            .fold(0.0f32, f32::max);
        let boxed = object_box(alpha);
        let partial = alpha.iter().filter(|a| **a > 0.0 && **a < 1.0).count();
        let mae = mean_abs(&boxed, &m.alpha, alpha);
        eprintln!(
            "view {k}: background max error {bg_err:.2e} ({} px), box MAE {mae:.4} ({} px, {partial} partly covered), {} glossy px",
            background.len(),
            boxed.len(),
            glossy.iter().filter(|g| **g).count()
        );
        assert!(bg_err <= 1e-4, "view {k}: background alpha error {bg_err}");
        assert!(mae <= 0.02, "view {k}: box MAE {mae}");
        assert!(partial > 20, "view {k}: the strands cover pixels partly");
    }
    // the maximum over three lambdas against each lambda alone, on the glossy sphere
    let glossy_err = |views: &[View]| {
        let (mut s, mut n) = (0.0, 0);
        for (k, (alpha, glossy)) in truth.iter().enumerate() {
            let ids: Vec<usize> = (0..alpha.len()).filter(|&i| glossy[i]).collect();
            s += mean_abs(&ids, &views[k].matte.alpha, alpha) * ids.len() as f64;
            n += ids.len();
        }
        s / n as f64
    };
    let best = glossy_err(&all);
    for lambda in LAMBDAS {
        let one = glossy_err(&mattes(&rig, |l| l == lambda));
        eprintln!(
            "glossy sphere alpha MAE: lambda {lambda} alone {one:.4}, max over three {best:.4}"
        );
        assert!(best < 0.5 * one, "lambda {lambda}: {one} vs max {best}");
    }
}
