//! End-to-end solve on a synthetic survey with known albedo: photos path-traced by igi-render
//! from a true albedo atlas under a sunny and an overcast sky, then recovered by the solver.

use glam::{DVec3, Vec3};
use igi_camera::Camera;
use igi_reflect::parts::build_parts;
use igi_reflect::solver::{truth_from_scene, NoProgress};
use igi_reflect::truth::truth_atlas;
use igi_reflect::{SolveOptions, SolveResult};
use igi_render::sky::{clear_sky, overcast_sky, sun_direction};
use igi_render::RenderOptions;
use igi_synth::survey::{ground_and_block, write_survey, LightingSpec, ShotSpec};
use igi_workflow::Survey;

#[test]
fn solve_recovers_known_albedo_from_synthetic_photos_and_resumes() {
    let dir = tempfile::tempdir().unwrap();
    write_synthetic_survey(dir.path());
    let (photos, parts, truth) = load_survey(dir.path());
    let opts = SolveOptions {
        atlas_resolution: 32,
        max_iterations: 1,
        spp: vec![32, 128],
        ..SolveOptions::default()
    };
    let ids: Vec<String> = photos.iter().map(|p| p.id.clone()).collect();
    let out = dir.path().join("result");
    std::fs::create_dir_all(&out).unwrap();
    let start = SolveResult::fresh(parts, ids, &opts);
    start.write_geometry(&out).unwrap();
    let mut first = igi_reflect::solve(
        start,
        &photos,
        None,
        Some(&truth),
        &opts,
        &NoProgress,
        &mut |r| r.write_state(&out),
    )
    .unwrap();
    assert_eq!(first.report.iterations.len(), 1);
    let it1 = first.report.iterations[0].clone();

    check_checkpoint_transactions(&mut first, dir.path());

    let done = resume_for_two_more(&out, &first, &photos, &truth, opts);
    assert_eq!(done.report.iterations[0].observations, it1.observations);
    check_final_iteration(&done);
    check_z_scores(&done, &truth);
    check_result_folder(&out, &done);
}

/// The ground and block survey: a smooth true albedo, six photos (three views under a sunny and
/// an overcast sky) with the truth scene.
fn write_synthetic_survey(dir: &std::path::Path) {
    let meshes = ground_and_block();
    let parts = build_parts(meshes, 32).unwrap();
    // A smooth albedo field: texel-scale patterns are blurred by the photos' pixel footprints,
    // which is a limit of the atlas resolution, not of the solver.
    let truth: Vec<Vec<Vec3>> = parts
        .iter()
        .map(|p| {
            truth_atlas(p, |x| {
                Vec3::new(0.3 + 0.2 * (0.5 * x.x).sin(), 0.4, 0.25 + 0.1 * x.z)
            })
        })
        .collect();
    let sun = sun_direction(40.0, 30.0);
    let lightings = vec![
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
    let mut shots = Vec::new();
    for (k, az) in [20.0f32, 140.0, 260.0].iter().enumerate() {
        let a = az.to_radians();
        let eye = Vec3::new(6.5 * a.cos(), 6.5 * a.sin(), 3.5);
        for (li, l) in lightings.iter().enumerate() {
            shots.push(ShotSpec {
                id: format!("cam{k}-{}", l.name),
                camera: Camera::look_at(eye.as_dvec3(), DVec3::new(0.0, 0.0, 0.5), 96, 96, 70.0)
                    .unwrap(),
                lighting: li,
            });
        }
    }
    write_survey(
        dir,
        &parts,
        &truth,
        &lightings,
        &lightings,
        &shots,
        &RenderOptions {
            spp: 256,
            seed: 11,
            ..RenderOptions::default()
        },
        &|_, _| {},
    )
    .unwrap();
}

/// The survey's photos, its parts at a 32-texel atlas, and the truth looked up in its scene.
fn load_survey(
    dir: &std::path::Path,
) -> (
    Vec<igi_reflect::Photo>,
    Vec<igi_reflect::Part>,
    igi_reflect::solver::Truth,
) {
    let survey = Survey::load(dir).unwrap();
    assert_eq!(survey.photos.len(), 6);
    let photos: Vec<_> = survey.photos.iter().map(|p| p.load().unwrap()).collect();
    let meshes: Vec<_> = survey
        .meshes
        .iter()
        .map(|m| {
            (
                m.file_stem().unwrap().to_string_lossy().into_owned(),
                igi_geometry::read_mesh(m).unwrap(),
            )
        })
        .collect();
    let parts = build_parts(meshes, 32).unwrap();
    let (truth_scene, _) = igi_render::Scene::load(&dir.join("truth/scene.toml")).unwrap();
    let truth = truth_from_scene(&parts, &truth_scene);
    let found = truth
        .texels
        .iter()
        .flatten()
        .filter(|t| t.is_some())
        .count();
    let total: usize = parts.iter().map(|p| p.cache.texels.len()).sum();
    // texel centres exactly on the open border of the ground can miss it; all others hit
    assert!(
        found as f64 > 0.95 * total as f64,
        "truth lookup found {found} of {total} texels"
    );
    (photos, parts, truth)
}

/// Resumes the one-iteration result in `out` from disk for two more iterations (as a killed
/// and restarted run would).
fn resume_for_two_more(
    out: &std::path::Path,
    first: &SolveResult,
    photos: &[igi_reflect::Photo],
    truth: &igi_reflect::solver::Truth,
    opts: SolveOptions,
) -> SolveResult {
    let resumed = SolveResult::load(out).unwrap();
    assert_eq!(resumed.report.iterations.len(), 1);
    let rho = |r: &SolveResult| {
        r.parts
            .iter()
            .flat_map(|p| p.rho.clone())
            .collect::<Vec<_>>()
    };
    for (a, b) in rho(&resumed).iter().zip(&rho(first)) {
        assert!(
            (*a - *b).abs().max_element() < 1e-3,
            "EXR round trip of the state: {a} vs {b}"
        );
    }
    let opts3 = SolveOptions {
        max_iterations: 3,
        min_iterations: 3,
        ..opts
    };
    igi_reflect::solve(
        resumed,
        photos,
        None,
        Some(truth),
        &opts3,
        &NoProgress,
        &mut |r| r.write_state(out),
    )
    .unwrap()
}

/// After three iterations the albedo error is small, the residual has fallen, the error has
/// not grown, and every part was seen.
fn check_final_iteration(done: &SolveResult) {
    let its = &done.report.iterations;
    assert_eq!(its.len(), 3, "resumed after iteration 1 and ran 2 and 3");
    for r in its {
        eprintln!(
            "iteration {}: spp {}, {:.2} s, obs {}, residual {:.4} ({:.2}%), delta {:.4}, MAE {:?}, RMS {:?}",
            r.iteration, r.spp, r.wall_s, r.observations, r.residual_rms, 100.0 * r.residual_rel_rms, r.delta_rho, r.truth_mae, r.truth_rms
        );
    }
    let mae = its.last().unwrap().truth_mae.expect("texels seen twice");
    // The initial guess (0.5 grey) is far off; after the iterations the error is small.
    let mae0 = its[0].truth_mae.unwrap();
    assert!(
        mae.iter().all(|m| *m < 0.01),
        "final rho_d MAE per channel {mae:?} (goal 0.01)"
    );
    assert!(
        its.last().unwrap().residual_rel_rms < its[0].residual_rel_rms,
        "residual falls"
    );
    assert!(
        mae0.iter().zip(&mae).all(|(a, b)| b <= a),
        "error does not grow: {mae0:?} -> {mae:?}"
    );
    assert!(done
        .parts
        .iter()
        .flat_map(|p| &p.rho)
        .all(|v| v.is_finite() && v.min_element() >= 0.0 && v.max_element() <= 1.0));
    for p in &done.report.parts {
        assert!(p.seen_texels > 0, "{} seen", p.name);
    }
}

/// The standard errors round-trip through the result folder `out`; a result written before
/// they existed loads with every standard error unknown; the folder re-renders as a scene.
fn check_result_folder(out: &std::path::Path, done: &SolveResult) {
    // the standard errors round-trip through the result folder; a result written before they
    // existed (no NAME_stderr.exr) loads with every standard error unknown
    let back = SolveResult::load(out).unwrap();
    for (b, d) in back.parts.iter().zip(&done.parts) {
        assert_eq!(b.stderr, d.stderr);
    }
    for p in &done.parts {
        std::fs::remove_file(out.join(format!("parts/{}_stderr.exr", p.name()))).unwrap();
    }
    let old = SolveResult::load(out).unwrap();
    assert!(old
        .parts
        .iter()
        .flat_map(|p| &p.stderr)
        .all(|s| *s == igi_reflect::UNKNOWN_STDERR));
    // the result folder re-renders as a scene
    let scene_file = igi_reflect::load_result_scene(out).unwrap();
    let (scene, _) = igi_render::Scene::load(&scene_file).unwrap();
    assert_eq!(scene.objects.len(), 2);
}

/// The standard errors of `rho_d` explain its error against the truth: over texels seen at
/// least twice, the z-scores `(rho_d - truth) / stderr` (every channel) have a spread near 1.
/// The spread is the robust one, 1.4826 times the median absolute z (1 for a standard normal;
/// the plain standard deviation is printed too, but a texel seen by two photos has a spread
/// estimate with one degree of freedom, whose z follows a heavy-tailed t distribution).
fn check_z_scores(state: &SolveResult, truth: &igi_reflect::solver::Truth) {
    for p in &state.parts {
        for t in &p.part.cache.texels {
            let i = t.index as usize;
            if p.observations[i] >= 2 {
                assert!(
                    p.stderr[i].min_element() >= 0.0,
                    "seen twice but no standard error"
                );
            }
        }
    }
    let z = igi_reflect::solver::z_scores(state, truth).expect("texels seen twice");
    eprintln!(
        "z-scores over {} texel channels seen twice: robust spread {:.3}, rms {:.3}, 95th percentile |z| {:.3}",
        z.count, z.robust_spread, z.rms, z.p95_abs
    );
    assert!(z.count > 300, "{} z-scores", z.count);
    assert!(
        (0.7..=1.5).contains(&z.robust_spread) && (0.7..=1.5).contains(&z.rms),
        "z spread: {z:?} (goal 0.7 to 1.5)"
    );
}

/// Glossy materials: the photographs are rendered with per-texel Lafortune lobes that a BRDF
/// basis infers from each texel's true albedo; the solver, given the same basis, infers the
/// lobes from its current albedo at every texel, recovers the albedo, and writes per-texel lobe
/// maps that re-render.
#[test]
fn glossy_lobes_inferred_per_texel_from_the_basis_are_recovered_and_written() {
    use igi_render::Scene;
    let dir = tempfile::tempdir().unwrap();
    let meshes = ground_and_block();
    let res = 32;
    let parts = build_parts(meshes, res as u32).unwrap();
    let basis = two_material_basis();
    let truth: Vec<Vec<Vec3>> = parts
        .iter()
        .map(|p| {
            truth_atlas(p, |x| {
                Vec3::new(0.3 + 0.2 * (0.5 * x.x).sin(), 0.35, 0.25 + 0.1 * x.z)
            })
        })
        .collect();
    let truth_scene = glossy_scene(&parts, &truth, &basis, res);
    let photos = glossy_photos(&truth_scene);
    let gt = truth_from_scene(&parts, &truth_scene);
    let opts = SolveOptions {
        atlas_resolution: res as u32,
        max_iterations: 3,
        min_iterations: 3,
        spp: vec![32, 128],
        ..SolveOptions::default()
    };
    let ids: Vec<String> = photos.iter().map(|p| p.id.clone()).collect();
    let out = dir.path().join("result");
    std::fs::create_dir_all(&out).unwrap();
    let start = SolveResult::fresh(parts, ids.clone(), &opts);
    start.write_geometry(&out).unwrap();
    let done = igi_reflect::solve(
        start,
        &photos,
        Some(&basis),
        Some(&gt),
        &opts,
        &NoProgress,
        &mut |r| r.write_state(&out),
    )
    .unwrap();
    let mae = done.report.iterations.last().unwrap().truth_mae.unwrap();
    eprintln!("glossy: rho_d MAE {mae:?}");
    assert!(mae.iter().all(|m| *m < 0.015), "glossy rho_d MAE {mae:?}");
    // without the basis the solver takes the glossy photos for Lambertian and is further off
    let start = SolveResult::fresh(
        build_parts(ground_and_block(), res as u32).unwrap(),
        ids,
        &opts,
    );
    let lambertian = igi_reflect::solve_in_memory(start, &photos, None, Some(&gt), &opts).unwrap();
    let mae_l = lambertian
        .report
        .iterations
        .last()
        .unwrap()
        .truth_mae
        .unwrap();
    eprintln!("glossy photos solved as Lambertian: rho_d MAE {mae_l:?}");
    assert!(
        mae_l.iter().sum::<f32>() > 1.5 * mae.iter().sum::<f32>(),
        "{mae_l:?} vs {mae:?}"
    );
    check_lobe_maps(&done, &out, &basis);
    let (scene, _) = Scene::load(&igi_reflect::load_result_scene(&out).unwrap()).unwrap();
    assert!(scene.objects.iter().all(|o| o
        .material
        .lobe_map
        .as_ref()
        .is_some_and(|m| m.per_texel == 1 && m.width == res)));
    check_export_keeps_lobes(dir.path(), &out, &scene);
}

/// A dark and a light glossy material.
fn two_material_basis() -> igi_brdf::Basis {
    use igi_brdf::{Basis, Lafortune, Lobe};
    Basis::new(vec![
        (
            "dark".into(),
            Lafortune {
                rho_d: Vec3::new(0.12, 0.11, 0.1),
                lobes: vec![Lobe {
                    rho: Vec3::splat(0.25),
                    cxy: -1.0,
                    cz: 1.0,
                    n: 12.0,
                }],
            },
        ),
        (
            "light".into(),
            Lafortune {
                rho_d: Vec3::new(0.7, 0.62, 0.55),
                lobes: vec![Lobe {
                    rho: Vec3::splat(0.05),
                    cxy: -1.0,
                    cz: 1.0,
                    n: 4.0,
                }],
            },
        ),
    ])
    .unwrap()
}

/// The truth scene: every texel of `parts` with its true albedo and the lobes the basis infers
/// from it.
fn glossy_scene(
    parts: &[igi_reflect::Part],
    truth: &[Vec<Vec3>],
    basis: &igi_brdf::Basis,
    res: usize,
) -> igi_render::Scene {
    use igi_brdf::Lobe;
    use igi_render::{Albedo, LobeMap, Material, Scene, Texture};
    let lobe_map = |rho: &[Vec3]| {
        let lobes: Vec<Lobe> = rho.iter().flat_map(|r| basis.infer(*r).lobes).collect();
        LobeMap {
            width: res,
            height: res,
            per_texel: 1,
            lobes,
        }
    };
    let objects = parts
        .iter()
        .zip(truth)
        .map(|(p, t)| {
            let m = Material {
                albedo: Albedo::Texture(Texture {
                    width: res,
                    height: res,
                    texels: t.clone(),
                }),
                lobes: vec![],
                lobe_map: Some(lobe_map(t)),
            };
            (p.name.clone(), p.mesh.clone(), m)
        })
        .collect();
    Scene::new(objects).unwrap()
}

/// Six photos of the truth scene: three views under a sunny and an overcast sky.
fn glossy_photos(truth_scene: &igi_render::Scene) -> Vec<igi_reflect::Photo> {
    use igi_reflect::Photo;
    use igi_render::{render_image, RenderOptions};
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
    let mut photos = Vec::new();
    for (k, az) in [20.0f32, 140.0, 260.0].iter().enumerate() {
        let a = az.to_radians();
        let eye = Vec3::new(6.5 * a.cos(), 6.5 * a.sin(), 3.5);
        for (li, l) in lightings.iter().enumerate() {
            let camera =
                Camera::look_at(eye.as_dvec3(), DVec3::new(0.0, 0.0, 0.5), 96, 96, 70.0).unwrap();
            let lighting = l.lighting().unwrap();
            let opts = RenderOptions {
                spp: 256,
                seed: 40 + (2 * k + li) as u64,
                indirect: 2,
                russian_roulette: false,
                stratified: false,
                adaptive: false,
            };
            let image = render_image(truth_scene, &lighting, &camera, &opts, &|_| {})
                .unwrap()
                .mean;
            photos.push(Photo {
                id: format!("cam{k}-{}", l.name),
                image,
                camera,
                lighting,
            });
        }
    }
    photos
}

/// Per-texel lobe maps: written, and the lobes of each texel are the basis's for its albedo.
fn check_lobe_maps(done: &SolveResult, out: &std::path::Path, basis: &igi_brdf::Basis) {
    for p in &done.parts {
        let name = p.name();
        let rho =
            igi_imaging::read_image(&out.join(format!("parts/{name}_lobe0_rho.exr"))).unwrap();
        let shape =
            igi_imaging::read_image(&out.join(format!("parts/{name}_lobe0_shape.exr"))).unwrap();
        for t in p.part.cache.texels.iter().step_by(7) {
            let want = basis.infer(p.rho[t.index as usize]).lobes[0];
            let k = t.index as usize;
            assert!(
                (Vec3::from_array(rho.pixels[k]) - want.rho)
                    .abs()
                    .max_element()
                    < 1e-5
            );
            assert!((shape.pixels[k][2] - want.n).abs() < 1e-3 * want.n);
        }
    }
}

/// The export keeps the lobes: its scene file holds the result's lobe maps texel for texel,
/// and the Mitsuba scene says that it leaves them out.
fn check_export_keeps_lobes(
    dir: &std::path::Path,
    out: &std::path::Path,
    scene: &igi_render::Scene,
) {
    use igi_render::Scene;
    let exported = dir.join("export");
    igi_export::export(out, igi_export::ExportFormat::Mitsuba, &exported).unwrap();
    let (again, _) = Scene::load(&exported.join("scene.toml")).unwrap();
    assert_eq!(again.objects.len(), scene.objects.len());
    for (a, b) in scene.objects.iter().zip(&again.objects) {
        let (ma, mb) = (&a.material, &b.material);
        assert_eq!(
            ma.lobe_map.as_ref().map(|m| &m.lobes),
            mb.lobe_map.as_ref().map(|m| &m.lobes)
        );
        assert_eq!((&a.positions, &a.triangles), (&b.positions, &b.triangles));
    }
    let xml = std::fs::read_to_string(exported.join("scene.xml")).unwrap();
    assert!(
        xml.contains("APPROXIMATION") && xml.contains("2 per-texel specular lobe maps"),
        "{xml}"
    );
}

/// A checkpoint killed before its commit point leaves the previous one; one killed after it
/// (staged `report.json` written, files half moved) is refused by readers and rolled forward
/// by `recover`; never a mix of one iteration's albedo and another's report.
fn check_checkpoint_transactions(state: &mut SolveResult, tmp: &std::path::Path) {
    let out = tmp.join("transactions");
    std::fs::create_dir_all(&out).unwrap();
    state.write_geometry(&out).unwrap();
    let changed: Vec<bool> = state.parts.iter().map(|p| p.changed).collect();
    state.set_changed(true);
    state.write_state(&out).unwrap();
    for (p, c) in state.parts.iter_mut().zip(changed) {
        p.changed = c;
    }
    let name = state.parts[0].name();
    let rho_file = format!("{name}_rho_d.exr");
    let staged = out.join("staged");
    let grey = |v: f32| {
        let r = state.parts[0].resolution();
        let mut im = igi_imaging::HdrImage::new(r, r);
        im.pixels.iter_mut().for_each(|p| *p = [v; 3]);
        im
    };
    // killed before the commit point: the staged atlas is dropped
    std::fs::create_dir_all(staged.join("parts")).unwrap();
    igi_imaging::write_exr(&staged.join("parts").join(&rho_file), &grey(0.25)).unwrap();
    SolveResult::recover(&out).unwrap();
    assert!(!staged.exists());
    let back = SolveResult::load(&out).unwrap();
    assert_eq!(
        back.parts[0].rho[0], state.parts[0].rho[0],
        "the previous checkpoint is kept"
    );
    // killed after the commit point, with the atlas already moved and the report not yet
    std::fs::create_dir_all(staged.join("parts")).unwrap();
    let mut report = state.report.clone();
    report.converged = !report.converged;
    let json = serde_json::to_string_pretty(&report).unwrap();
    std::fs::write(staged.join("report.json"), json).unwrap();
    igi_imaging::write_exr(&out.join("parts").join(&rho_file), &grey(0.25)).unwrap();
    let e = SolveResult::load(&out)
        .err()
        .expect("a half-committed folder is refused");
    assert!(
        e.to_string().contains("run the same `igi solve` again"),
        "{e}"
    );
    SolveResult::recover(&out).unwrap();
    assert!(!staged.exists());
    let fwd = SolveResult::load(&out).unwrap();
    assert_eq!(
        fwd.report.converged, report.converged,
        "the staged report is in place"
    );
    assert!(fwd.parts[0]
        .rho
        .iter()
        .all(|v| (*v - glam::Vec3::splat(0.25)).abs().max_element() < 1e-6));
}
