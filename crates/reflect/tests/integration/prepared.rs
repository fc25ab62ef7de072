//! The voxel-by-voxel solve over a prepared site (`igi prepare` output): every voxel solved
//! against the multiresolution load of the site, checkpointed after each voxel, resumable
//! mid-iteration with the same result as an uninterrupted run.

use glam::{DVec3, Vec3};
use igi_camera::Camera;
use igi_geometry::{PrepareOptions, SiteStore, TriMesh};
use igi_reflect::parts::prepared_parts;
use igi_reflect::solver::{truth_from_scene, NoProgress};
use igi_reflect::truth::truth_atlas;
use igi_reflect::{ReflectError, SolveOptions, SolveResult};
use igi_render::sky::{clear_sky, overcast_sky, sun_direction};
use igi_render::RenderOptions;
use igi_synth::survey::{write_survey, LightingSpec, ShotSpec};
use igi_workflow::Survey;
use std::path::Path;

/// A smooth albedo field (detail far coarser than a texel, so the photos resolve it).
fn albedo(p: Vec3) -> Vec3 {
    Vec3::new(
        0.35 + 0.25 * (0.4 * p.x).sin(),
        0.3 + 0.15 * (0.5 * p.y + 0.3 * p.z).cos(),
        0.2 + 0.06 * p.z.min(6.0),
    )
}

fn prepare_site(out: &Path) -> SiteStore {
    let mut site = TriMesh::default();
    let mut terrain = None;
    for (name, m) in igi_geometry::procedural::colonnade_site(3, 1) {
        if name == "terrain" {
            terrain = Some(m);
        } else {
            site.append(&m);
        }
    }
    let (site, rep) = igi_geometry::repair::repair(&site);
    let mut opts = PrepareOptions::default();
    opts.atlas.resolution = 48;
    igi_geometry::prepare(site, terrain, rep, out, "colonnade", &opts, &|_, _| {}).unwrap();
    SiteStore::open(out).unwrap()
}

struct Colonnade {
    store: SiteStore,
    voxels: usize,
    photos: Vec<igi_reflect::Photo>,
    truth: igi_reflect::solver::Truth,
}

/// The colonnade prepared in voxels (at least 8, plus the terrain), photographed from four
/// sides under a sunny and an overcast sky, with the truth of its albedo.
fn colonnade(dir: &Path) -> Colonnade {
    let store = prepare_site(&dir.join("site.igi"));
    let voxels = store.voxel_ids().len();
    assert!(voxels >= 8, "{voxels} voxels");
    let parts = prepared_parts(&store).unwrap();
    assert_eq!(parts.len(), voxels + 1, "voxels and the terrain");
    assert!(
        parts.iter().all(|p| p.mesh.indices.is_empty()),
        "no mesh is loaded for the parts themselves"
    );
    let truth: Vec<Vec<Vec3>> = parts.iter().map(|p| truth_atlas(p, albedo)).collect();
    let sun = sun_direction(35.0, 50.0);
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
    for (k, az) in [-60.0f32, -120.0, 30.0, 150.0].iter().enumerate() {
        let a = az.to_radians();
        let eye = Vec3::new(16.0 * a.cos(), 14.0 * a.sin(), 7.0);
        for (li, l) in lightings.iter().enumerate() {
            shots.push(ShotSpec {
                id: format!("cam{k}-{}", l.name),
                camera: Camera::look_at(eye.as_dvec3(), DVec3::new(0.0, 0.0, 2.5), 128, 96, 75.0)
                    .unwrap(),
                lighting: li,
            });
        }
    }
    let sdir = dir.join("survey");
    write_survey(
        &sdir,
        &parts,
        &truth,
        &lightings,
        &lightings,
        &shots,
        &RenderOptions {
            spp: 128,
            seed: 5,
            ..RenderOptions::default()
        },
        &|_, _| {},
    )
    .unwrap();
    let survey = Survey::load(&sdir).unwrap();
    assert!(survey.meshes.is_empty());
    assert_eq!(
        survey
            .prepared
            .as_deref()
            .map(|p| p.join("manifest.json").is_file()),
        Some(true)
    );
    let photos: Vec<_> = survey.photos.iter().map(|p| p.load().unwrap()).collect();
    let (truth_scene, _) = igi_render::Scene::load(&sdir.join("truth/scene.toml")).unwrap();
    let truth = truth_from_scene(&parts, &truth_scene);
    Colonnade {
        store,
        voxels,
        photos,
        truth,
    }
}

#[test]
fn a_prepared_site_is_solved_voxel_by_voxel_with_the_multiresolution_load_and_resumes_mid_iteration(
) {
    let dir = tempfile::tempdir().unwrap();
    let Colonnade {
        store,
        voxels,
        photos,
        truth,
    } = colonnade(dir.path());
    let ids: Vec<String> = photos.iter().map(|p| p.id.clone()).collect();
    let opts = SolveOptions {
        atlas_resolution: 48,
        max_iterations: 2,
        min_iterations: 2,
        spp: vec![32, 64],
        ..SolveOptions::default()
    };

    let fresh = |out: &Path| {
        std::fs::create_dir_all(out).unwrap();
        let start = SolveResult::fresh(prepared_parts(&store).unwrap(), ids.clone(), &opts);
        start.write_geometry(out).unwrap();
        start
    };

    // 1. uninterrupted
    let out_a = dir.path().join("a");
    let start = fresh(&out_a);
    let mut checkpoints = 0;
    let a = igi_reflect::solve(
        start,
        &photos,
        None,
        Some(&truth),
        &opts,
        &NoProgress,
        &mut |r| {
            checkpoints += 1;
            r.write_state(&out_a)
        },
    )
    .unwrap();
    // a checkpoint after every voxel (and the terrain) and after every iteration
    assert_eq!(checkpoints, 2 * (voxels + 1) + 2);
    check_uninterrupted(&a, &store, voxels);

    // 2. killed after three voxels of the second iteration, then resumed from disk
    let out_b = dir.path().join("b");
    let b = killed_and_resumed(fresh(&out_b), &out_b, &photos, &truth, &opts, voxels);
    assert_eq!(b.report.iterations.len(), 2);
    let mut worst = 0.0f32;
    let rho = |r: &SolveResult| {
        r.parts
            .iter()
            .flat_map(|p| p.rho.clone())
            .collect::<Vec<_>>()
    };
    for (x, y) in rho(&a).iter().zip(&rho(&b)) {
        worst = worst.max((*x - *y).abs().max_element());
    }
    assert!(
        worst == 0.0,
        "resumed run differs from the uninterrupted one by {worst}"
    );
    assert_eq!(
        a.report.iterations[1].observations,
        b.report.iterations[1].observations
    );

    // 3. the result re-renders: its scene names the site's full-resolution levels
    let scene_file = igi_reflect::result::load_result_scene(&out_b).unwrap();
    let (scene, _) = igi_render::Scene::load(&scene_file).unwrap();
    assert_eq!(scene.objects.len(), voxels + 1);
}

/// The uninterrupted solve: the albedo error is small and the residual falls; every voxel's
/// scene (the multiresolution load) is far smaller than the whole site at full resolution and
/// holds the voxel itself at full resolution.
fn check_uninterrupted(a: &SolveResult, store: &SiteStore, voxels: usize) {
    assert!(a.report.pending.is_none());
    let its = &a.report.iterations;
    for r in its {
        eprintln!(
            "iteration {}: {:.2} s, obs {}, residual {:.2}%, delta {:.4}, MAE {:?}",
            r.iteration,
            r.wall_s,
            r.observations,
            100.0 * r.residual_rel_rms,
            r.delta_rho,
            r.truth_mae
        );
    }
    let mae = its.last().unwrap().truth_mae.expect("texels seen twice");
    assert!(mae.iter().all(|m| *m < 0.02), "rho_d MAE {mae:?}");
    assert!(its[1].residual_rel_rms < its[0].residual_rel_rms);
    let man = store.manifest();
    let full: u64 = man.triangles_per_level[0] as u64
        + man.terrain.as_ref().map_or(0, |t| t.triangles[0] as u64);
    let mut seen_parts = 0;
    for (p, e) in a.report.parts.iter().zip(man.voxels.iter()) {
        assert_eq!(p.stored.as_ref().unwrap().voxel, e.voxel);
        assert!(
            p.scene_triangles < full,
            "{}: {} of {full}",
            p.name,
            p.scene_triangles
        );
        assert!(p.scene_triangles >= e.triangles[0] as u64);
        seen_parts += (p.seen_texels > 0) as usize;
    }
    assert!(
        seen_parts >= voxels / 2,
        "{seen_parts} of {voxels} voxels seen"
    );
    assert!(a
        .parts
        .iter()
        .flat_map(|p| &p.rho)
        .all(|v| v.is_finite() && v.min_element() >= 0.0 && v.max_element() <= 1.0));
}

/// A solve from `start` killed (its checkpoint fails) after three voxels of the second
/// iteration, then resumed from its result folder `out`.
fn killed_and_resumed(
    start: SolveResult,
    out: &Path,
    photos: &[igi_reflect::Photo],
    truth: &igi_reflect::solver::Truth,
    opts: &SolveOptions,
    voxels: usize,
) -> SolveResult {
    let mut n = 0;
    let killed = igi_reflect::solve(
        start,
        photos,
        None,
        Some(truth),
        opts,
        &NoProgress,
        &mut |r| {
            n += 1;
            if n > voxels + 2 + 3 {
                return Err(ReflectError::Invalid("killed".into()));
            }
            r.write_state(out)
        },
    );
    assert!(killed.is_err());
    let resumed = SolveResult::load(out).unwrap();
    let pending = resumed
        .report
        .pending
        .clone()
        .expect("an iteration in progress");
    assert_eq!((pending.iteration, pending.done.len()), (2, 3));
    assert_eq!(resumed.report.iterations.len(), 1);
    igi_reflect::solve(
        resumed,
        photos,
        None,
        Some(truth),
        opts,
        &NoProgress,
        &mut |r| r.write_state(out),
    )
    .unwrap()
}

/// A Jacobi iteration split into one task per voxel (and the terrain) plus a merge writes the
/// same bytes as `solve` with the Jacobi schedule; a merge with a task missing names it and
/// writes nothing. Also prints the truth error of both schedules per iteration (docs/SOLVER.md).
#[test]
fn jacobi_tasks_and_merge_equal_a_local_jacobi_solve() {
    const ITERS: u32 = 2;
    use igi_reflect::distributed::{groups, initialise};
    use igi_reflect::solver::{Schedule, SolveInputs};
    let dir = tempfile::tempdir().unwrap();
    let Colonnade {
        store,
        voxels,
        photos,
        truth,
    } = colonnade(dir.path());
    let ids: Vec<String> = photos.iter().map(|p| p.id.clone()).collect();
    let opts = SolveOptions {
        atlas_resolution: 48,
        max_iterations: ITERS,
        min_iterations: ITERS,
        spp: vec![16, 32],
        schedule: Schedule::Jacobi,
        ..SolveOptions::default()
    };
    let fresh = |out: &Path| {
        std::fs::create_dir_all(out).unwrap();
        let start = SolveResult::fresh(prepared_parts(&store).unwrap(), ids.clone(), &opts);
        start.write_geometry(out).unwrap();
        start
    };
    let local_dir = dir.path().join("local");
    let local = igi_reflect::solve(
        fresh(&local_dir),
        &photos,
        None,
        Some(&truth),
        &opts,
        &NoProgress,
        &mut |r| r.write_state(&local_dir),
    )
    .unwrap();
    print_gauss_seidel_against(
        &local,
        fresh(&dir.path().join("gauss")),
        &photos,
        &truth,
        &opts,
    );

    let inputs = SolveInputs {
        photos: &photos,
        basis: None,
        truth: Some(&truth),
    };
    let dist = dir.path().join("distributed");
    let work = dir.path().join("work");
    initialise(&dist, fresh(&dist), &inputs, &opts).unwrap();
    let names = groups(&dist, &inputs, &opts).unwrap();
    assert_eq!(names.len(), voxels + 1, "every voxel and the terrain");
    run_tasks_and_merges(&dist, &work, &inputs, &opts, &names, ITERS);
    assert_same_result(&local_dir, &dist, voxels);
}

/// Prints the truth error per iteration of a Gauss-Seidel solve from `start` beside the local
/// Jacobi solve's (docs/SOLVER.md).
fn print_gauss_seidel_against(
    local: &SolveResult,
    start: SolveResult,
    photos: &[igi_reflect::Photo],
    truth: &igi_reflect::solver::Truth,
    opts: &SolveOptions,
) {
    use igi_reflect::solver::Schedule;
    let gauss_opts = SolveOptions {
        schedule: Schedule::GaussSeidel,
        ..opts.clone()
    };
    let gauss =
        igi_reflect::solve_in_memory(start, photos, None, Some(truth), &gauss_opts).unwrap();
    for (g, j) in gauss.report.iterations.iter().zip(&local.report.iterations) {
        eprintln!(
            "iteration {}: rho_d RMS error Gauss-Seidel {:.5} Jacobi {:.5}; MAE {:?} / {:?}",
            g.iteration,
            g.truth_rms.unwrap(),
            j.truth_rms.unwrap(),
            g.truth_mae.unwrap(),
            j.truth_mae.unwrap()
        );
    }
}

/// `iters` distributed iterations: a task per group, then a merge; in the first, one task is
/// lost, and the merge names it and writes nothing until it has run.
fn run_tasks_and_merges(
    dist: &Path,
    work: &Path,
    inputs: &igi_reflect::solver::SolveInputs,
    opts: &SolveOptions,
    names: &[String],
    iters: u32,
) {
    use igi_reflect::distributed::{merge, run_task};
    for it in 0..iters {
        for (n, g) in names.iter().enumerate() {
            if it == 0 && n == 3 {
                continue; // a lost task
            }
            run_task(dist, work, inputs, opts, g, &Default::default()).unwrap();
        }
        if it == 0 {
            let before = std::fs::read(dist.join("report.json")).unwrap();
            let e = merge(dist, work, inputs, opts).unwrap_err().to_string();
            assert!(e.contains(&names[3]) && e.contains("1 task(s)"), "{e}");
            assert_eq!(std::fs::read(dist.join("report.json")).unwrap(), before);
            run_task(dist, work, inputs, opts, &names[3], &Default::default()).unwrap();
        }
        merge(dist, work, inputs, opts).unwrap();
    }
    let e = run_task(dist, work, inputs, opts, "99_99_99", &Default::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("99_99_99"), "{e}");
}

/// The same bytes in the result folders `local` and `dist`: every atlas, the scene, the report
/// but for its wall-clock fields.
fn assert_same_result(local_dir: &Path, dist: &Path, voxels: usize) {
    let mut files = 0;
    let mut differ = Vec::new();
    for entry in std::fs::read_dir(local_dir.join("parts")).unwrap() {
        let name = entry.unwrap().file_name();
        let a = std::fs::read(local_dir.join("parts").join(&name)).unwrap();
        let b = std::fs::read(dist.join("parts").join(&name)).unwrap();
        if a != b {
            differ.push(name);
        }
        files += 1;
    }
    assert!(
        differ.is_empty(),
        "{} of {files} differ: {differ:?}",
        differ.len()
    );
    assert!(files >= 6 * (voxels + 1), "{files} files compared");
    assert_eq!(
        std::fs::read(local_dir.join("scene.toml")).unwrap(),
        std::fs::read(dist.join("scene.toml")).unwrap()
    );
    let report = |d: &Path| {
        let mut r: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(d.join("report.json")).unwrap()).unwrap();
        for it in r["iterations"].as_array_mut().unwrap() {
            it["wall_s"] = 0.into();
            it["cumulative_s"] = 0.into();
        }
        r
    };
    assert_eq!(report(local_dir), report(dist));
}

/// A group whose task cannot finish can be skipped: it keeps its previous albedo, the
/// iteration names it as stale and is not counted as converged, however small the change.
#[test]
fn a_skipped_group_keeps_its_albedo_and_blocks_convergence() {
    use igi_reflect::distributed::{groups, initialise, merge, run_task, write_stale};
    use igi_reflect::solver::{Schedule, SolveInputs};
    let dir = tempfile::tempdir().unwrap();
    let Colonnade { store, photos, .. } = colonnade(dir.path());
    let ids: Vec<String> = photos.iter().map(|p| p.id.clone()).collect();
    let opts = SolveOptions {
        atlas_resolution: 48,
        max_iterations: 1,
        min_iterations: 1,
        tolerance: 10.0,
        spp: vec![8],
        schedule: Schedule::Jacobi,
        ..SolveOptions::default()
    };
    let inputs = SolveInputs {
        photos: &photos,
        basis: None,
        truth: None,
    };
    let out = dir.path().join("r");
    std::fs::create_dir_all(&out).unwrap();
    let start = SolveResult::fresh(prepared_parts(&store).unwrap(), ids, &opts);
    start.write_geometry(&out).unwrap();
    initialise(&out, start, &inputs, &opts).unwrap();
    let work = dir.path().join("work");
    let names = groups(&out, &inputs, &opts).unwrap();
    let skipped = &names[1];
    let before = std::fs::read(out.join(format!("parts/{skipped}_rho_d.exr"))).unwrap();
    for g in &names {
        if g == skipped {
            write_stale(&out, &work, &inputs, &opts, g, &Default::default()).unwrap();
        } else {
            run_task(&out, &work, &inputs, &opts, g, &Default::default()).unwrap();
        }
    }
    let converged = merge(&out, &work, &inputs, &opts).unwrap();
    assert!(!converged, "a run with a stale group never converges");
    let r = SolveResult::load(&out).unwrap();
    assert!(!r.report.converged);
    assert_eq!(r.report.iterations[0].stale, vec![skipped.clone()]);
    let after = std::fs::read(out.join(format!("parts/{skipped}_rho_d.exr"))).unwrap();
    assert_eq!(before, after, "the skipped group keeps its albedo");
    let other = &names[0];
    let i = r.parts.iter().position(|p| p.name() == other).unwrap();
    assert!(
        r.parts[i]
            .rho
            .iter()
            .any(|v| (*v - Vec3::splat(0.5)).abs().max_element() > 0.01),
        "the solved groups changed"
    );
}
