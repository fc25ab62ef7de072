//! `igi demo`: the embedded default, end to end on a procedural site (no downloaded data).
use crate::report::{Bar, Ctx};
use igi_workflow::demo::{run_demo, DemoOptions};
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct DemoArgs {
    /// Output folder (survey, result, pictures, demo.json).
    #[arg(short, long, default_value = "out/demo")]
    pub output: PathBuf,
    /// Smaller and faster (for tests): 60x40 photos, 32-texel atlases, fewer samples.
    #[arg(long)]
    pub quick: bool,
    /// Solve on atlases sized from the photographs (as `igi solve --atlas auto`, at most 512
    /// texels per part, large meshes cut into parts) instead of the true textures' 128-texel
    /// atlases: ten times slower, and over the surface no more accurate than the truth's own
    /// atlases (docs/SOLVER.md, "Two errors").
    #[arg(long)]
    pub atlas_auto: bool,
    /// No probes (issue 34): the photographs carry their time and the survey the site's
    /// location (Paris, 21 June 2026) and no lighting file; the solve estimates each photo's
    /// light (SPA sun, Hosek-Wilkie and CIE overcast skies fitted with the albedo,
    /// docs/SKY.md), and the report compares it with the true skies. Each estimated photo's
    /// lighting file and picture (photograph, re-rendering, fitted sky) are in
    /// result/lighting/. Up to 10 iterations (each with a lighting round) instead of 3: the
    /// solve goes on while the fitted light still moves.
    #[arg(long)]
    pub no_probes: bool,
    /// Print demo.json on stdout.
    #[arg(long)]
    pub json: bool,
}

pub fn run(a: DemoArgs, ctx: &Ctx) -> anyhow::Result<()> {
    let mut opts = if a.quick {
        DemoOptions {
            atlas: 32,
            atlas_auto_max: None,
            photo_width: 60,
            photo_height: 40,
            photo_spp: 32,
            solve_spp: vec![8, 16],
            iterations: 2,
            relight_spp: 16,
            ..DemoOptions::default()
        }
    } else {
        DemoOptions::default()
    };
    if a.atlas_auto {
        opts.atlas_auto_max = Some(512);
    }
    opts.estimate_light = a.no_probes;
    if a.no_probes && !a.quick {
        opts.iterations = igi_workflow::demo::NO_PROBES_ITERATIONS;
    }
    let bar = Bar(ctx.progress(1, "demo"));
    let quiet = ctx.quiet;
    let report = run_demo(&a.output, &opts, &bar, &|s| {
        if !quiet {
            eprintln!("igi demo: {s}");
        }
    })?;
    bar.0.finish_and_clear();
    if a.json {
        crate::report::print_json(&report)?;
    } else {
        println!(
            "procedural site: {} parts, {} triangles; {} photographs in {:.1} s",
            report.parts, report.triangles, report.photos, report.photo_seconds
        );
        for p in &report.probes {
            match (p.sun_direction_error_deg, p.sun_radiance_error) {
                (Some(d), Some(e)) => println!(
                    "probe {}: sun within {:.3} deg, radiance error {:+.2}% {:+.2}% {:+.2}%, check {:.2}% RMS",
                    p.name,
                    d,
                    100.0 * e[0],
                    100.0 * e[1],
                    100.0 * e[2],
                    p.check_rms_percent.unwrap_or(f64::NAN)
                ),
                _ => println!("probe {}: no sun (found: {}), check {:.2}% RMS", p.name, p.sun_found, p.check_rms_percent.unwrap_or(f64::NAN)),
            }
        }
        if let Some(l) = &report.estimated_light {
            println!(
                "no probes: each photo's light estimated with the albedo ({} rounds; {})",
                l.rounds,
                if l.absolute_scale {
                    "scale from a reference target".to_string()
                } else {
                    format!(
                        "no reference target: scale from a mean sun scale of 1, last gauge {:.4}",
                        l.gauge
                    )
                }
            );
            for p in &l.photos {
                let f = &p.fitted;
                let t = &p.truth;
                let sun = match p.sun_direction_error_deg {
                    Some(d) => format!("sun within {d:.4} deg, "),
                    None => String::new(),
                };
                let clear = if f.sun_scale > 0.0 || f.sky_scale > 0.0 {
                    format!(
                        "turbidity {:.1} (true {:.1}), sun {:.3} (true {:.3}), sky {:.3} (true {:.3}), ",
                        f.turbidity, t.turbidity, f.sun_scale, t.sun_scale, f.sky_scale, t.sky_scale
                    )
                } else {
                    "no sun, no clear sky, ".to_string()
                };
                println!(
                    "  {}: {sun}{clear}overcast zenith {:.3} (true {:.3}), residual {:.1}% RMS",
                    p.photo,
                    f.overcast_scale,
                    t.overcast_zenith,
                    100.0 * p.relative_rms
                );
            }
        }
        if let Some(m) = report.albedo_mae {
            println!("solve: {} iterations in {:.1} s; albedo MAE vs truth {:.4} {:.4} {:.4} (texels seen twice)", report.iterations, report.solve_seconds, m[0], m[1], m[2]);
        }
        if let Some(m) = report.albedo_surface_mae {
            println!("       albedo MAE over the surface {:.4} {:.4} {:.4} (area-uniform points whose texel was seen twice)", m[0], m[1], m[2]);
        }
        let c = &report.relight;
        println!(
            "re-lit held-out view: relative mean {:+.2}%, RMSE {:.4} vs {:.4} explained by noise",
            100.0 * c.relative_mean_difference,
            c.rmse,
            c.noise_rmse.unwrap_or(f64::NAN)
        );
        println!(
            "wrote {} (pictures/, result/, survey/, demo.json) in {:.1} s",
            a.output.display(),
            report.total_seconds
        );
    }
    Ok(())
}
