//! Silhouette and edge pose refinement in the pipeline: the photographs of a synthetic site are
//! path-traced from the true cameras; the survey's cameras are then perturbed by 2-5 px of
//! reprojection error (as a PnP pose from a few clicked points would be), refined against the
//! photographs with `igi_capture::refine`, and the site is solved with the true, the perturbed
//! and the refined cameras.

use glam::{DMat3, DVec3, Vec3};
use igi_camera::camera::{points_in_frame, reprojection_rms};
use igi_camera::{Camera, WorldToCamera};
use igi_capture::refine::{refine_pose, RefineOptions};
use igi_raycast::rt_scene_of;
use igi_reflect::parts::build_parts;
use igi_reflect::solver::truth_from_scene;
use igi_reflect::truth::{scene_with_albedo, truth_atlas};
use igi_reflect::Photo;
use igi_reflect::{SolveOptions, SolveResult};
use igi_render::sky::{clear_sky, overcast_sky, sun_direction};
use igi_render::{render_image, RenderOptions};
use igi_synth::survey::{ground_and_block, LightingSpec};
use rand::{Rng, SeedableRng};

/// `cam` moved by a random rigid motion scaled so that `points` reproject `target_px` off (RMS).
fn perturbed(cam: &Camera, points: &[DVec3], target_px: f64, seed: u64) -> Camera {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    let mut unit = || {
        DVec3::new(
            rng.gen_range(-1.0..1.0),
            rng.gen_range(-1.0..1.0),
            rng.gen_range(-1.0..1.0),
        )
        .normalize()
    };
    let (axis, shift) = (unit(), unit());
    let at = |s: f64| {
        let r = DMat3::from_axis_angle(axis, 0.01 * s);
        Camera {
            pose: WorldToCamera {
                r: r * cam.pose.r,
                t: r * cam.pose.t + shift * (0.05 * s),
            },
            ..cam.clone()
        }
    };
    let mut s = 1.0;
    for _ in 0..4 {
        s *= target_px / reprojection_rms(cam, &at(s), points).unwrap();
    }
    at(s)
}

fn solve_mae(
    parts: Vec<igi_reflect::parts::Part>,
    photos: &[Photo],
    truth: &igi_reflect::solver::Truth,
    res: u32,
) -> f32 {
    let opts = SolveOptions {
        atlas_resolution: res,
        max_iterations: 2,
        min_iterations: 2,
        spp: vec![32, 64],
        ..SolveOptions::default()
    };
    let ids: Vec<String> = photos.iter().map(|p| p.id.clone()).collect();
    let done = igi_reflect::solve_in_memory(
        SolveResult::fresh(parts, ids, &opts),
        photos,
        None,
        Some(truth),
        &opts,
    )
    .unwrap();
    let m = done.report.iterations.last().unwrap().truth_mae.unwrap();
    m.iter().sum::<f32>() / 3.0
}

#[test]
fn refinement_from_2_to_5_px_reaches_half_a_pixel_and_the_albedo_of_true_poses() {
    let res = 32;
    let parts = build_parts(ground_and_block(), res).unwrap();
    let truth_atlases: Vec<Vec<Vec3>> = parts
        .iter()
        .map(|p| {
            truth_atlas(p, |x| {
                Vec3::new(0.3 + 0.2 * (0.5 * x.x).sin(), 0.4, 0.25 + 0.1 * x.z)
            })
        })
        .collect();
    let scene = scene_with_albedo(&parts, &truth_atlases).unwrap();
    let sun = sun_direction(40.0, 30.0);
    let lightings = [
        LightingSpec {
            name: "sunny".into(),
            sky: clear_sky(64, 32, sun, 0.6, Vec3::splat(0.08)),
            sun: Some((sun, Vec3::new(6.0e4, 5.7e4, 5.2e4))),
        },
        LightingSpec {
            name: "overcast".into(),
            sky: overcast_sky(64, 32, 2.0, Vec3::splat(0.15)),
            sun: None,
        },
    ];
    let surface: Vec<DVec3> = parts
        .iter()
        .flat_map(|p| p.cache.texels.iter().map(|t| t.position.as_dvec3()))
        .collect();
    let meshes: Vec<_> = ground_and_block().into_iter().map(|(_, m)| m).collect();
    let rt = rt_scene_of(&meshes).unwrap();
    let (mut truth_photos, mut rough_photos, mut refined_photos) =
        (Vec::new(), Vec::new(), Vec::new());
    let mut worst = 0.0f64;
    for (k, az) in [20.0f32, 140.0, 260.0].iter().enumerate() {
        let a = az.to_radians();
        let eye = Vec3::new(6.5 * a.cos(), 6.5 * a.sin(), 3.5);
        for (li, l) in lightings.iter().enumerate() {
            let i = 2 * k + li;
            let camera =
                Camera::look_at(eye.as_dvec3(), DVec3::new(0.0, 0.0, 0.5), 128, 96, 70.0).unwrap();
            let ([t, r, f], after) = photo_three_ways((k, i), camera, l, &scene, &surface, &rt);
            worst = worst.max(after);
            truth_photos.push(t);
            rough_photos.push(r);
            refined_photos.push(f);
        }
    }
    assert!(
        worst <= 0.5,
        "worst reprojection RMS after refinement {worst:.3} px (goal 0.5)"
    );

    let truth = truth_from_scene(&parts, &scene);
    let fresh = || build_parts(ground_and_block(), res).unwrap();
    let mae_true = solve_mae(fresh(), &truth_photos, &truth, res);
    let mae_rough = solve_mae(fresh(), &rough_photos, &truth, res);
    let mae_refined = solve_mae(fresh(), &refined_photos, &truth, res);
    eprintln!(
        "albedo MAE: true poses {mae_true:.4}, perturbed {mae_rough:.4}, refined {mae_refined:.4}"
    );
    assert!(
        mae_refined <= 1.10 * mae_true,
        "refined-pose MAE {mae_refined} vs true-pose {mae_true} (goal within 10 %)"
    );
    assert!(
        mae_rough > mae_refined,
        "perturbed poses should be worse: {mae_rough} vs {mae_refined}"
    );
}

/// Photo `i` (view `k` under `l`): rendered from the true `camera`, whose pose is then
/// perturbed by 2 to 5 px and refined against it. Returns the photo with the true, the
/// perturbed and the refined camera, and the refined reprojection RMS in frame.
fn photo_three_ways(
    (k, i): (usize, usize),
    camera: Camera,
    l: &LightingSpec,
    scene: &igi_render::Scene,
    surface: &[DVec3],
    rt: &igi_raycast::RtScene,
) -> ([Photo; 3], f64) {
    let lighting = l.lighting().unwrap();
    let opts = RenderOptions {
        spp: 128,
        seed: 40 + i as u64,
        indirect: 2,
        russian_roulette: false,
        stratified: false,
        adaptive: false,
    };
    let image = render_image(scene, &lighting, &camera, &opts, &|_| {})
        .unwrap()
        .mean;
    let target = 2.0 + 3.0 * i as f64 / 5.0; // 2 to 5 px
    let seen = points_in_frame(&camera, surface);
    let rough = perturbed(&camera, &seen, target, 100 + i as u64);
    let (refined, report) = refine_pose(&image, &rough, rt, &RefineOptions::default()).unwrap();
    let before = reprojection_rms(&camera, &rough, &seen).unwrap();
    let after = reprojection_rms(&camera, &refined, &seen).unwrap();
    let all_after = reprojection_rms(&camera, &refined, surface).unwrap();
    eprintln!(
        "photo {i} ({}): reprojection RMS in frame {before:.2} px -> {after:.3} px \
         (all {} texels in front: {all_after:.3} px); {report:?}",
        l.name,
        surface.len()
    );
    assert!(
        (before - target).abs() < 0.05,
        "perturbation {before} px (wanted {target})"
    );
    let id = format!("cam{k}-{}", l.name);
    let truth_photo = Photo {
        id: id.clone(),
        image: image.clone(),
        camera,
        lighting: l.lighting().unwrap(),
    };
    let rough_photo = Photo {
        id: id.clone(),
        image: image.clone(),
        camera: rough,
        lighting: l.lighting().unwrap(),
    };
    let refined_photo = Photo {
        id,
        image,
        camera: refined,
        lighting,
    };
    ([truth_photo, rough_photo, refined_photo], after)
}
