//! Integrator tests with analytic answers: white furnace, sun-lit diffuse and glossy planes,
//! irradiance, the sun 1e5 times the sky, determinism, and NaN-free outputs in stiff cases.

use crate::integrator::*;
use crate::lighting::{Environment, Lighting, Sun};
use crate::scene::{Material, Scene, SurfacePoint};
use glam::{DMat3, DVec3, Vec2, Vec3};
use igi_brdf::{LafortuneRef, Lobe};
use igi_camera::{Camera, WorldToCamera};
use igi_geometry::TriMesh;
use igi_imaging::HdrImage;
use std::f32::consts::PI;

pub(crate) fn quad(z: f32, half: f32) -> TriMesh {
    TriMesh {
        positions: vec![
            [-half, -half, z],
            [half, -half, z],
            [half, half, z],
            [-half, half, z],
        ],
        normals: None,
        uvs: Some(vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]),
        colors: None,
        indices: vec![[0, 1, 2], [0, 2, 3]],
    }
}

/// Axis-aligned box (12 triangles, outward winding).
pub(crate) fn cube(lo: Vec3, hi: Vec3) -> TriMesh {
    let p = |x: bool, y: bool, z: bool| {
        [
            if x { hi.x } else { lo.x },
            if y { hi.y } else { lo.y },
            if z { hi.z } else { lo.z },
        ]
    };
    let positions = vec![
        p(false, false, false),
        p(true, false, false),
        p(true, true, false),
        p(false, true, false),
        p(false, false, true),
        p(true, false, true),
        p(true, true, true),
        p(false, true, true),
    ];
    let indices = vec![
        [0, 2, 1],
        [0, 3, 2],
        [4, 5, 6],
        [4, 6, 7],
        [0, 1, 5],
        [0, 5, 4],
        [1, 2, 6],
        [1, 6, 5],
        [2, 3, 7],
        [2, 7, 6],
        [3, 0, 4],
        [3, 4, 7],
    ];
    TriMesh {
        positions,
        normals: None,
        uvs: None,
        colors: None,
        indices,
    }
}

/// UV sphere with smooth normals.
pub(crate) fn sphere(c: Vec3, r: f32, n_theta: u32, n_phi: u32) -> TriMesh {
    let mut positions = Vec::new();
    let mut normals = Vec::new();
    for i in 0..=n_theta {
        let th = PI * i as f32 / n_theta as f32;
        for j in 0..=n_phi {
            let ph = 2.0 * PI * j as f32 / n_phi as f32;
            let n = Vec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos());
            positions.push((c + n * r).to_array());
            normals.push(n.to_array());
        }
    }
    let mut indices = Vec::new();
    let row = n_phi + 1;
    for i in 0..n_theta {
        for j in 0..n_phi {
            let (a, b, cc, d) = (
                i * row + j,
                i * row + j + 1,
                (i + 1) * row + j,
                (i + 1) * row + j + 1,
            );
            indices.push([a, cc, d]); // degenerate at the poles: dropped by Scene::new
            indices.push([a, d, b]);
        }
    }
    TriMesh {
        positions,
        normals: Some(normals),
        uvs: None,
        colors: None,
        indices,
    }
}

/// Camera at `eye` looking straight down (-Z), image x along +X.
pub(crate) fn down_camera(eye: Vec3, w: u32, h: u32, f: f64) -> Camera {
    let r = DMat3::from_cols(
        DVec3::new(1.0, 0.0, 0.0),
        DVec3::new(0.0, -1.0, 0.0),
        DVec3::new(0.0, 0.0, -1.0),
    );
    let c = eye.as_dvec3();
    let mut cam = Camera::pinhole(w, h, f, f, (w as f64 - 1.0) / 2.0, (h as f64 - 1.0) / 2.0);
    cam.pose = WorldToCamera { r, t: -(r * c) };
    cam
}

/// A Lambertian ground quad of half-size `half` (albedo `ground`) with a Lambertian box from
/// `lo` to `hi` (albedo `box_albedo`) on it.
fn ground_and_box(half: f32, ground: Vec3, lo: Vec3, hi: Vec3, box_albedo: Vec3) -> Scene {
    Scene::new(vec![
        (
            "ground".into(),
            quad(0.0, half),
            Material::lambertian(ground),
        ),
        ("box".into(), cube(lo, hi), Material::lambertian(box_albedo)),
    ])
    .unwrap()
}

fn pt_on(scene: &Scene, p: Vec3) -> SurfacePoint {
    scene
        .trace_point(p + Vec3::Z * 1.0, -Vec3::Z)
        .expect("point on the surface")
}

fn sun_from_zenith(angle_deg: f32, radiance: f32) -> Sun {
    let a = angle_deg.to_radians();
    Sun::new(
        Vec3::new(a.sin(), 0.0, a.cos()),
        Vec3::splat(radiance),
        0.53,
    )
    .unwrap()
}

#[test]
fn white_furnace_sphere_under_uniform_sky() {
    // Flat-shaded (geometric normals): with interpolated normals a grazing view can see a facet
    // whose shading normal faces away, which legitimately loses energy at the silhouette.
    let mut ball = sphere(Vec3::ZERO, 1.0, 24, 48);
    ball.normals = None;
    let scene = Scene::new(vec![(
        "sphere".into(),
        ball,
        Material::lambertian(Vec3::ONE),
    )])
    .unwrap();
    assert!(scene.skipped_triangles > 0); // the pole triangles
    let lighting = Lighting::uniform(Vec3::ONE);
    let cam = down_camera(Vec3::new(0.0, 0.0, 4.0), 24, 24, 30.0);
    let opts = RenderOptions {
        spp: 64,
        seed: 1,
        indirect: 2,
        russian_roulette: false,
        stratified: false,
        adaptive: false,
    };
    let out = render_ok(&scene, &lighting, &cam, opts);
    // Every pixel (sphere or sky) must be 1 within noise; the sphere is convex, so there are
    // no interreflections and light sampling of a uniform sky is exact up to MC noise.
    let mut max_dev = 0f32;
    for (m, s) in out.mean.pixels.iter().zip(&out.stderr.pixels) {
        for c in 0..3 {
            let z = (m[c] - 1.0).abs() / s[c].max(1e-4);
            max_dev = max_dev.max(z);
            assert!((m[c] - 1.0).abs() < 0.2, "pixel {m:?} se {s:?}");
        }
    }
    let mean: f64 =
        out.mean.pixels.iter().map(|p| p[1] as f64).sum::<f64>() / out.mean.pixels.len() as f64;
    assert!((mean - 1.0).abs() < 0.005, "mean {mean}");
    assert!(max_dev < 5.0, "max deviation {max_dev} standard errors");
}

#[test]
fn white_furnace_concave_scene_with_many_bounces() {
    // A unit-albedo ground with a box on it: concave corners need many bounces to reach 1.
    let scene = ground_and_box(
        20.0,
        Vec3::ONE,
        Vec3::new(-1.0, -1.0, 0.0),
        Vec3::new(1.0, 1.0, 2.0),
        Vec3::ONE,
    );
    let lighting = Lighting::uniform(Vec3::ONE);
    let points = vec![
        pt_on(&scene, Vec3::new(1.05, 0.0, 0.0)),
        pt_on(&scene, Vec3::new(3.0, 2.0, 0.0)),
    ];
    let targets = vec![Vec3::new(3.0, 0.0, 1.0), Vec3::new(0.0, 5.0, 3.0)];
    let opts = RenderOptions {
        spp: 4000,
        seed: 3,
        indirect: 1000,
        russian_roulette: true,
        stratified: false,
        adaptive: false,
    };
    let est = radiance_toward(&scene, &lighting, &points, &targets, &opts).unwrap();
    for e in &est {
        assert!((e.mean.y - 1.0).abs() < 4.0 * e.stderr.y + 1e-3, "{e:?}");
        assert!(e.stderr.y < 0.02, "{e:?}");
    }
    // With direct light only (K = 0) the corner point is clearly darker than 1.
    let opts0 = RenderOptions {
        indirect: 0,
        russian_roulette: false,
        stratified: false,
        adaptive: false,
        ..opts
    };
    let est0 = radiance_toward(&scene, &lighting, &points[..1], &targets[..1], &opts0).unwrap();
    assert!(est0[0].mean.y < 0.75, "{:?}", est0[0]);
}

#[test]
fn diffuse_plane_under_the_sun_matches_rho_over_pi_times_e() {
    let rho = Vec3::new(0.2, 0.5, 0.8);
    let scene = Scene::new(vec![(
        "ground".into(),
        quad(0.0, 100.0),
        Material::lambertian(rho),
    )])
    .unwrap();
    for zenith in [0.0f32, 30.0, 75.0] {
        let sun = sun_from_zenith(zenith, 1.0e5);
        let lighting = Lighting {
            environment: None,
            sun: Some(sun),
        };
        let e_sun = 1.0e5 * sun.solid_angle() * zenith.to_radians().cos();
        let expect = rho / PI * e_sun;
        let p = pt_on(&scene, Vec3::new(0.3, -0.2, 0.0));
        let targets = [Vec3::new(-3.0, 1.0, 2.0)];
        let opts = RenderOptions {
            spp: 256,
            seed: 9,
            ..Default::default()
        };
        let e = radiance_toward(&scene, &lighting, &[p], &targets, &opts).unwrap()[0];
        let rel = ((e.mean - expect) / expect).abs().max_element();
        assert!(rel < 2e-3, "zenith {zenith}: {:?} vs {expect:?}", e.mean);
        // Irradiance query agrees: E = L_sun * omega * cos.
        let ir = irradiance(&scene, &lighting, &[p.position], &[Vec3::Z], &opts).unwrap()[0];
        assert!(
            (ir.mean.x / e_sun - 1.0).abs() < 2e-3,
            "{:?} vs {e_sun}",
            ir.mean
        );
    }
}

#[test]
fn glossy_plane_under_the_sun_matches_the_brdf_value() {
    let lobe = Lobe {
        rho: Vec3::splat(0.8),
        cxy: -1.0,
        cz: 1.0,
        n: 20.0,
    };
    let mut mat = Material::lambertian(Vec3::splat(0.1));
    mat.lobes = vec![lobe];
    let scene = Scene::new(vec![("ground".into(), quad(0.0, 100.0), mat)]).unwrap();
    let sun = sun_from_zenith(40.0, 1.0e4);
    let lighting = Lighting {
        environment: None,
        sun: Some(sun),
    };
    let p = pt_on(&scene, Vec3::ZERO);
    // Near the mirror direction (the sun is at +X): view from -X side, slightly off-specular.
    let a = 45f32.to_radians();
    let wo = Vec3::new(-a.sin(), 0.0, a.cos());
    let brdf = LafortuneRef {
        rho_d: Vec3::splat(0.1),
        lobes: &[lobe],
    };
    let f = brdf.eval(sun.direction, wo);
    let expect = f * 1.0e4 * sun.solid_angle() * sun.direction.z;
    let opts = RenderOptions {
        spp: 512,
        seed: 2,
        ..Default::default()
    };
    let e = radiance_toward(&scene, &lighting, &[p], &[wo * 10.0], &opts).unwrap()[0];
    let rel = ((e.mean - expect) / expect).abs().max_element();
    assert!(rel < 5e-3, "{:?} vs {expect:?}", e.mean);
}

#[test]
fn irradiance_under_uniform_sky_and_in_a_corner() {
    let scene = Scene::new(vec![(
        "ground".into(),
        quad(0.0, 50.0),
        Material::lambertian(Vec3::splat(0.5)),
    )])
    .unwrap();
    let lighting = Lighting::uniform(Vec3::splat(2.0));
    let opts = RenderOptions {
        spp: 2000,
        seed: 4,
        ..Default::default()
    };
    // Facing up just above the ground: E = pi * L.
    let e = irradiance(
        &scene,
        &lighting,
        &[Vec3::new(0.0, 0.0, 1e-3)],
        &[Vec3::Z],
        &opts,
    )
    .unwrap()[0];
    assert!(
        (e.mean.x - 2.0 * PI).abs() < 4.0 * e.stderr.x + 1e-3,
        "{e:?}"
    );
    // Facing sideways: half sees the sky (L = 2), half the ground (L_out = rho * E_ground / pi
    // = 0.5 * 2 pi / pi = 1, with one bounce, direct-lit ground), so E = pi/2 * 2 + pi/2 * 1.
    let e = irradiance(
        &scene,
        &lighting,
        &[Vec3::new(0.0, 0.0, 1e-2)],
        &[Vec3::X],
        &opts,
    )
    .unwrap()[0];
    let expect = PI / 2.0 * 2.0 + PI / 2.0 * 1.0;
    assert!(
        (e.mean.x - expect).abs() < 4.0 * e.stderr.x + 2e-3 * expect,
        "{e:?} vs {expect}"
    );
}

#[test]
fn bright_sun_over_dim_sky_has_no_fireflies_and_noise_falls_as_one_over_spp() {
    // A glossy ground and a box under a sky of radiance 1 and a sun 1e5 times brighter.
    let mut ground = Material::lambertian(Vec3::splat(0.3));
    ground.lobes = vec![Lobe {
        rho: Vec3::splat(0.5),
        cxy: -1.0,
        cz: 1.0,
        n: 50.0,
    }];
    let scene = Scene::new(vec![
        ("ground".into(), quad(0.0, 20.0), ground),
        (
            "box".into(),
            cube(Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, 1.0, 1.5)),
            Material::lambertian(Vec3::splat(0.6)),
        ),
    ])
    .unwrap();
    let lighting = Lighting {
        environment: Some(Environment::constant(Vec3::ONE)),
        sun: Some(sun_from_zenith(35.0, 1.0e5)),
    };
    let cam = down_camera(Vec3::new(0.0, 0.0, 8.0), 16, 16, 10.0);
    let se_mean = |spp: u32, seed: u64| {
        let out = render_image(
            &scene,
            &lighting,
            &cam,
            &RenderOptions {
                spp,
                seed,
                indirect: 2,
                russian_roulette: false,
                stratified: false,
                adaptive: false,
            },
            &|_| {},
        )
        .unwrap();
        assert_eq!(out.bad_samples, 0);
        assert!(out.mean.pixels.iter().flatten().all(|v| v.is_finite()));
        let var: f64 = out
            .stderr
            .pixels
            .iter()
            .map(|p| (p[1] as f64).powi(2))
            .sum::<f64>()
            / out.stderr.pixels.len() as f64;
        let max = out.mean.pixels.iter().map(|p| p[1]).fold(0f32, f32::max);
        (var, max, out)
    };
    let (v16, max16, a) = se_mean(16, 1);
    let (v256, max256, b) = se_mean(256, 2);
    // Variance of the mean scales as 1/spp (ratio 16), within sampling error of the variance.
    let ratio = v16 / v256;
    assert!(ratio > 10.0 && ratio < 25.0, "variance ratio {ratio}");
    // Fireflies would show as a maximum far above the sunlit Lambertian + lobe level:
    // E_sun = 1e5 * 6.7e-5 * cos 35 ~ 5.5; the brightest real value is the lobe's highlight.
    let e_sun = 1.0e5 * lighting.sun.unwrap().solid_angle() * 35f32.to_radians().cos();
    let bound = e_sun * (0.3 / PI + 0.5 * 3.0) + 10.0;
    assert!(
        max16 < bound && max256 < bound,
        "max {max16} {max256} bound {bound}"
    );
    // Independent renders agree within their noise.
    let mut z2 = 0.0;
    for i in 0..a.mean.pixels.len() {
        let d = (a.mean.pixels[i][1] - b.mean.pixels[i][1]) as f64;
        let s2 = (a.stderr.pixels[i][1] as f64).powi(2) + (b.stderr.pixels[i][1] as f64).powi(2);
        z2 += d * d / s2.max(1e-12);
    }
    let chi = z2 / a.mean.pixels.len() as f64;
    assert!(chi < 2.0, "mean squared z-score between renders {chi}");
}

#[test]
fn renders_are_deterministic_per_seed() {
    let scene = ground_and_box(
        5.0,
        Vec3::splat(0.5),
        Vec3::splat(-0.5),
        Vec3::splat(0.5),
        Vec3::splat(0.7),
    );
    let lighting = Lighting {
        environment: Some(Environment::constant(Vec3::ONE)),
        sun: Some(sun_from_zenith(20.0, 1e3)),
    };
    let cam = down_camera(Vec3::new(0.0, 0.0, 5.0), 12, 10, 8.0);
    let opts = RenderOptions {
        spp: 4,
        seed: 42,
        ..Default::default()
    };
    let a = render_image(&scene, &lighting, &cam, &opts, &|_| {}).unwrap();
    let b = render_image(&scene, &lighting, &cam, &opts, &|_| {}).unwrap();
    let c = render_image(
        &scene,
        &lighting,
        &cam,
        &RenderOptions { seed: 43, ..opts },
        &|_| {},
    )
    .unwrap();
    assert_eq!(a.mean.pixels, b.mean.pixels);
    assert_eq!(a.stderr.pixels, b.stderr.pixels);
    assert_ne!(a.mean.pixels, c.mean.pixels);
}

#[test]
fn no_nan_for_grazing_views_zero_albedo_degenerate_triangles_and_extreme_lobes() {
    let scene = stiff_scene();
    assert!(scene.skipped_triangles >= 2);
    let lighting = Lighting {
        environment: Some(Environment::constant(Vec3::ONE)),
        sun: Some(sun_from_zenith(89.7, 1e5)),
    };
    let cam = grazing_camera();
    let out = render_image(
        &scene,
        &lighting,
        &cam,
        &RenderOptions {
            spp: 16,
            seed: 5,
            indirect: 3,
            russian_roulette: true,
            stratified: false,
            adaptive: false,
        },
        &|_| {},
    )
    .unwrap();
    assert_eq!(out.bad_samples, 0);
    assert!(out
        .mean
        .pixels
        .iter()
        .chain(&out.stderr.pixels)
        .flatten()
        .all(|v| v.is_finite() && *v >= 0.0));
    // Queries at grazing directions and exactly along the surface.
    let p = SurfacePoint {
        position: Vec3::new(5.0, 5.0, 0.0),
        ng: Vec3::Z,
        ns: Vec3::Z,
        uv: Vec2::ZERO,
        object: 0,
        prim: 0,
    };
    let targets = [
        Vec3::new(50.0, 5.0, 0.0),
        Vec3::new(50.0, 5.0, 1e-4),
        Vec3::new(5.0, 5.0, 0.0),
    ];
    let est = radiance_toward(
        &scene,
        &lighting,
        &[p, p, p],
        &targets,
        &RenderOptions {
            spp: 8,
            ..Default::default()
        },
    )
    .unwrap();
    for e in est {
        assert!(e.mean.is_finite() && e.stderr.is_finite(), "{e:?}");
    }
    let ir = irradiance(
        &scene,
        &lighting,
        &[Vec3::new(0.0, 0.0, 1.0)],
        &[Vec3::ZERO],
        &RenderOptions::default(),
    )
    .unwrap();
    assert_eq!(ir[0].mean, Vec3::ZERO);
}

/// Ground with degenerate, duplicate and collinear triangles (black), a box of extreme lobes
/// (an exponent of 5000 and a mirror-like lobe) and a white sphere.
fn stiff_scene() -> Scene {
    let mut ground = quad(0.0, 10.0);
    // Degenerate and duplicate triangles.
    ground.indices.push([0, 0, 1]);
    ground.indices.push([0, 1, 2]);
    ground.positions.push([1.0, 1.0, 0.0]);
    ground.uvs.as_mut().unwrap().push([0.5, 0.5]);
    ground.indices.push([0, 2, 4]); // collinear: (-10,-10), (10,10), (1,1)
    let mut shiny = Material::lambertian(Vec3::ZERO);
    shiny.lobes = vec![
        Lobe {
            rho: Vec3::splat(1.0),
            cxy: -1.0,
            cz: 1.0,
            n: 5000.0,
        },
        Lobe {
            rho: Vec3::splat(0.5),
            cxy: 0.9,
            cz: 0.9,
            n: 3.0,
        },
    ];
    Scene::new(vec![
        ("ground".into(), ground, Material::lambertian(Vec3::ZERO)),
        (
            "box".into(),
            cube(Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, 1.0, 1.0)),
            shiny,
        ),
        (
            "sphere".into(),
            sphere(Vec3::new(3.0, 0.0, 1.0), 1.0, 8, 16),
            Material::lambertian(Vec3::ONE),
        ),
    ])
    .unwrap()
}

/// A camera a millimetre above the ground looking along +X, at grazing incidence.
fn grazing_camera() -> Camera {
    // Eye a millimetre above the ground looking along +X (R rows: camera x =
    // -Y, camera y = -Z, camera z = +X; DMat3::from_cols takes the columns of R).
    let rows = DMat3::from_cols(
        DVec3::new(0.0, 0.0, 1.0),
        DVec3::new(-1.0, 0.0, 0.0),
        DVec3::new(0.0, -1.0, 0.0),
    );
    let c = DVec3::new(-8.0, 0.0, 1e-3);
    let mut cam = Camera::pinhole(20, 12, 10.0, 10.0, 9.5, 5.5);
    cam.pose = WorldToCamera {
        r: rows,
        t: -(rows * c),
    };
    cam
}

#[test]
fn stratified_first_vertex_is_unbiased_and_far_less_noisy_beside_an_occluder() {
    // A grey ground beside a box, under a sky brighter toward one horizon plus a sun: the
    // estimate mixes a smooth sky integral, the box's visibility edge and one bounce.
    let scene = ground_and_box(
        20.0,
        Vec3::splat(0.4),
        Vec3::new(0.5, -1.0, 0.0),
        Vec3::new(1.5, 1.0, 1.2),
        Vec3::splat(0.7),
    );
    let (w, h) = (64, 32);
    let sky: Vec<[f32; 3]> = (0..w * h)
        .map(|i| {
            let u = (i % w) as f32 / w as f32;
            let v = (i / w) as f32 / h as f32;
            let l = if v < 0.5 {
                0.3 + 2.0 * u * (1.0 - v)
            } else {
                0.0
            };
            [l, l * 0.9, l * 0.8]
        })
        .collect();
    let lighting = Lighting {
        environment: Some(Environment::from_scaled(w, h, &sky)),
        sun: Some(sun_from_zenith(50.0, 2.0e3)),
    };
    let pt = PathTracer::new(&scene, &lighting, &RenderOptions::default());
    let strat = PathTracer::new(
        &scene,
        &lighting,
        &RenderOptions {
            stratified: true,
            adaptive: false,
            ..Default::default()
        },
    );
    let sp = pt_on(&scene, Vec3::new(0.2, 0.3, 0.0));
    let wo = Vec3::new(-0.3, 0.1, 1.0).normalize();
    let reference = pt.lo_estimate(&sp, wo, None, 1 << 18, &mut crate::sampling::Rng::new(9, 0));

    let runs = 96;
    let spp = 64;
    let (mut sq_random, mut sq_strat, mut sum_strat, mut se_strat) = (0.0, 0.0, 0.0, 0.0);
    for i in 0..runs {
        let r = pt.lo_estimate(&sp, wo, None, spp, &mut crate::sampling::Rng::new(1, i));
        let s = strat.lo_estimate(&sp, wo, None, spp, &mut crate::sampling::Rng::new(2, i));
        assert!(s.mean.is_finite() && s.stderr.is_finite());
        sq_random += ((r.mean.y - reference.mean.y) as f64).powi(2);
        sq_strat += ((s.mean.y - reference.mean.y) as f64).powi(2);
        sum_strat += s.mean.y as f64;
        se_strat += s.stderr.y as f64;
    }
    let rms_random = (sq_random / runs as f64).sqrt();
    let rms_strat = (sq_strat / runs as f64).sqrt();
    // Unbiased: the mean of the stratified runs agrees with the reference within its noise.
    let mean_strat = sum_strat / runs as f64;
    let noise = (rms_strat.powi(2) / runs as f64 + (reference.stderr.y as f64).powi(2)).sqrt();
    assert!(
        (mean_strat - reference.mean.y as f64).abs() < 4.0 * noise,
        "stratified mean {mean_strat} against {:?} (noise {noise})",
        reference
    );
    // Far less noisy than independent samples, and the reported standard error bounds it.
    assert!(
        rms_strat < 0.5 * rms_random,
        "RMS error stratified {rms_strat}, random {rms_random}"
    );
    let reported = se_strat / runs as f64;
    assert!(
        rms_strat < reported,
        "stratified RMS error {rms_strat} above its reported standard error {reported}"
    );
}

#[test]
fn stratified_renders_are_unbiased_less_noisy_and_their_stderr_bounds_the_noise() {
    let scene = ground_and_box(
        20.0,
        Vec3::splat(0.3),
        Vec3::new(-1.0, -1.0, 0.0),
        Vec3::new(1.0, 1.0, 1.5),
        Vec3::splat(0.6),
    );
    let lighting = Lighting {
        environment: Some(Environment::constant(Vec3::ONE)),
        sun: Some(sun_from_zenith(35.0, 1.0e4)),
    };
    let cam = down_camera(Vec3::new(0.0, 0.0, 8.0), 24, 24, 12.0);
    let render = |spp: u32, seed: u64, stratified: bool| {
        let opts = RenderOptions {
            spp,
            seed,
            stratified,
            ..Default::default()
        };
        render_ok(&scene, &lighting, &cam, opts)
    };
    let (s1, s2) = (render(64, 1, true), render(64, 2, true));
    let (r1, r2) = (render(64, 3, false), render(64, 4, false));
    let reference = render(4096, 5, false);
    let g = |img: &HdrImage, i: usize| img.pixels[i][1] as f64;
    let n = s1.mean.pixels.len();
    let diff2 = |a: &HdrImage, b: &HdrImage| {
        (0..n).map(|i| (g(a, i) - g(b, i)).powi(2)).sum::<f64>() / n as f64
    };
    // less noisy: the spread between two seeds
    let (noise_s, noise_r) = (diff2(&s1.mean, &s2.mean), diff2(&r1.mean, &r2.mean));
    assert!(
        noise_s < 0.5 * noise_r,
        "stratified {noise_s}, independent {noise_r}"
    );
    // unbiased: against the reference, z-scores with the independent reference's noise and the
    // stratified images' own measured noise (half the squared seed-to-seed difference)
    let z2 = (0..n)
        .map(|i| {
            let d = 0.5 * (g(&s1.mean, i) + g(&s2.mean, i)) - g(&reference.mean, i);
            let v = 0.25 * (g(&s1.mean, i) - g(&s2.mean, i)).powi(2)
                + g(&reference.stderr, i).powi(2)
                + 1e-12;
            d * d / v
        })
        .sum::<f64>()
        / n as f64;
    assert!(z2 < 3.0, "mean squared z against the reference {z2}");
    let bias = (0..n)
        .map(|i| 0.5 * (g(&s1.mean, i) + g(&s2.mean, i)) - g(&reference.mean, i))
        .sum::<f64>()
        / (0..n).map(|i| g(&reference.mean, i)).sum::<f64>();
    assert!(bias.abs() < 0.003, "relative bias {bias}");
    // the reported standard error bounds the seed-to-seed noise from above
    let reported = (0..n)
        .map(|i| g(&s1.stderr, i).powi(2) + g(&s2.stderr, i).powi(2))
        .sum::<f64>()
        / n as f64;
    assert!(
        noise_s <= reported,
        "noise {noise_s} above reported {reported}"
    );
}

/// `render_image` that must neither fail nor drop a sample.
fn render_ok(
    scene: &Scene,
    lighting: &Lighting,
    cam: &Camera,
    opts: RenderOptions,
) -> RenderOutput {
    let out = render_image(scene, lighting, cam, &opts, &|_| {}).unwrap();
    assert_eq!(out.bad_samples, 0, "{opts:?}");
    out
}

/// A tower casting a long shadow on the ground under a low, strong sun: the shadow, lit by a dim
/// sky and the bounce off the tower's sunlit side, is far noisier relative to its radiance than
/// the sunlit ground. Cameras above x = -1.5 see both.
fn tower_in_low_sun() -> (Scene, Lighting) {
    let scene = ground_and_box(
        20.0,
        Vec3::splat(0.4),
        Vec3::new(0.0, -1.0, 0.0),
        Vec3::new(1.5, 1.0, 3.0),
        Vec3::splat(0.6),
    );
    let lighting = Lighting {
        environment: Some(Environment::constant(Vec3::splat(0.05))),
        sun: Some(sun_from_zenith(60.0, 2.0e4)),
    };
    (scene, lighting)
}

#[test]
fn adaptive_renders_are_unbiased_and_spend_their_rays_where_the_noise_is() {
    let (scene, lighting) = tower_in_low_sun();
    let cam = down_camera(Vec3::new(-1.5, 0.0, 8.0), 32, 32, 30.0);
    let render = |spp: u32, seed: u64, adaptive: bool| {
        let opts = RenderOptions {
            spp,
            seed,
            adaptive,
            ..Default::default()
        };
        render_ok(&scene, &lighting, &cam, opts)
    };
    let (a1, a2) = (render(64, 1, true), render(64, 2, true));
    let (u1, u2) = (render(64, 3, false), render(64, 4, false));
    let reference = render(4096, 5, false);
    let g = |img: &HdrImage, i: usize| img.pixels[i][1] as f64;
    let n = a1.mean.pixels.len();
    // the same rays (pilot included) within 10 %
    let ratio = (a1.rays + a2.rays) as f64 / (u1.rays + u2.rays) as f64;
    assert!(
        (0.9..1.1).contains(&ratio),
        "rays adaptive / uniform {ratio}"
    );
    // the summed relative variance (half the squared seed-to-seed difference over the
    // reference's square) falls
    let rel_var = |a: &HdrImage, b: &HdrImage| {
        (0..n)
            .map(|i| 0.5 * (g(a, i) - g(b, i)).powi(2) / g(&reference.mean, i).powi(2))
            .sum::<f64>()
    };
    let (va, vu) = (rel_var(&a1.mean, &a2.mean), rel_var(&u1.mean, &u2.mean));
    eprintln!("rays ratio {ratio}, relative variance adaptive {va}, uniform {vu}");
    assert!(
        va < 0.7 * vu,
        "relative variance adaptive {va}, uniform {vu}"
    );
    // unbiased, and each pixel's standard error (its own samples) is honest: z-scores against
    // the reference with unit spread
    let z2 = (0..n)
        .map(|i| {
            let d = g(&a1.mean, i) - g(&reference.mean, i);
            d * d / (g(&a1.stderr, i).powi(2) + g(&reference.stderr, i).powi(2) + 1e-12)
        })
        .sum::<f64>()
        / n as f64;
    assert!(
        (0.6..1.6).contains(&z2),
        "mean squared z against the reference {z2}"
    );
    let bias = (0..n)
        .map(|i| 0.5 * (g(&a1.mean, i) + g(&a2.mean, i)) - g(&reference.mean, i))
        .sum::<f64>()
        / (0..n).map(|i| g(&reference.mean, i)).sum::<f64>();
    assert!(bias.abs() < 0.003, "relative bias {bias}");
    // too few samples for a pilot is an error, not a uniform render
    let few = RenderOptions {
        spp: 8,
        adaptive: true,
        ..Default::default()
    };
    assert!(matches!(
        render_image(&scene, &lighting, &cam, &few, &|_| {}),
        Err(crate::RenderError::AdaptiveSpp(8, 16))
    ));
}

/// `f` run on a rayon pool of `threads` threads.
fn on_threads<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(f)
}

#[test]
fn renders_are_the_same_bytes_whatever_the_thread_count() {
    let (scene, lighting) = tower_in_low_sun();
    let cam = down_camera(Vec3::new(-1.5, 0.0, 8.0), 20, 16, 20.0);
    for (stratified, adaptive) in [(false, false), (true, false), (true, true)] {
        let opts = RenderOptions {
            spp: 16,
            seed: 3,
            stratified,
            adaptive,
            ..Default::default()
        };
        let on = |threads: usize| {
            on_threads(threads, || {
                render_image(&scene, &lighting, &cam, &opts, &|_| {}).unwrap()
            })
        };
        let (one, three) = (on(1), on(3));
        assert_eq!(one.mean.pixels, three.mean.pixels, "{opts:?}");
        assert_eq!(one.stderr.pixels, three.stderr.pixels, "{opts:?}");
        assert_eq!(one.rays, three.rays, "{opts:?}");
    }
    // two images sharing one adaptive budget
    let other = down_camera(Vec3::new(6.0, 6.0, 6.0), 12, 10, 20.0);
    let jobs = [(&cam, 5), (&other, 6)].map(|(camera, seed)| RenderJob {
        camera,
        lighting: &lighting,
        seed,
    });
    let opts = RenderOptions {
        spp: 16,
        stratified: true,
        adaptive: true,
        ..Default::default()
    };
    let on = |threads: usize| {
        on_threads(threads, || {
            render_images(&scene, &jobs, &opts, &|_, _| {}).unwrap()
        })
    };
    for (a, b) in on(1).iter().zip(&on(3)) {
        assert_eq!(a.mean.pixels, b.mean.pixels);
        assert_eq!((a.rays, a.samples), (b.rays, b.samples));
    }
}

#[test]
fn images_rendered_together_share_one_budget_by_their_noise() {
    let (scene, lighting) = tower_in_low_sun();
    // the tower's long shadow (lit by the dim sky alone: noisy) and open sunlit ground (calm)
    let shade = down_camera(Vec3::new(-1.5, 0.0, 8.0), 32, 32, 30.0);
    let open = down_camera(Vec3::new(6.0, 6.0, 6.0), 32, 32, 30.0);
    let opts = RenderOptions {
        spp: 64,
        adaptive: true,
        ..Default::default()
    };
    let jobs = [
        RenderJob {
            camera: &shade,
            lighting: &lighting,
            seed: 1,
        },
        RenderJob {
            camera: &open,
            lighting: &lighting,
            seed: 2,
        },
    ];
    let together = render_images(&scene, &jobs, &opts, &|_, _| {}).unwrap();
    let alone: Vec<RenderOutput> = jobs
        .iter()
        .map(|j| {
            let o = RenderOptions {
                seed: j.seed,
                ..opts
            };
            render_ok(&scene, j.lighting, j.camera, o)
        })
        .collect();
    let uniform: Vec<RenderOutput> = jobs
        .iter()
        .map(|j| {
            let o = RenderOptions {
                spp: 1024,
                seed: j.seed + 10,
                adaptive: false,
                ..opts
            };
            render_ok(&scene, j.lighting, j.camera, o)
        })
        .collect();
    let rays = |v: &[RenderOutput]| v.iter().map(|o| o.rays).sum::<u64>() as f64;
    let ratio = rays(&together) / rays(&alone);
    assert!(
        (0.95..1.05).contains(&ratio),
        "rays together / alone {ratio}"
    );
    // the noisy view takes samples from the calm one
    let (s_together, s_alone) = (
        [together[0].samples, together[1].samples],
        [alone[0].samples, alone[1].samples],
    );
    assert!(
        s_together[0] as f64 > 1.2 * s_alone[0] as f64
            && (s_together[1] as f64) < 0.8 * s_alone[1] as f64,
        "samples together {s_together:?}, alone {s_alone:?}"
    );
    // each image is still an unbiased estimate: its mean within 1 % of a uniform render's
    for (t, u) in together.iter().zip(&uniform) {
        assert_eq!(t.bad_samples, 0);
        let mean = |img: &HdrImage| img.pixels.iter().map(|p| p[1] as f64).sum::<f64>();
        let rel = mean(&t.mean) / mean(&u.mean) - 1.0;
        assert!(rel.abs() < 0.01, "image mean off by {rel:+.4}");
    }
}
