//! Issue 32, item 1, on a capture igi did not make: a turntable capture rendered by Mitsuba 3
//! (`datasets/mitsuba/hull_straws.py`): the Stanford bunny, a glossy blue ball and ten straws
//! 0.6 mm thick (under half a pixel) running out of the top of every frame; two cameras (12 and
//! 38 degrees up) x 12 turntable positions at 320 x 240; the six Eq. 1 backdrop pairs per view
//! on a monitor behind the object (which lights it, and which the ball reflects); truth at 4 new
//! views between the turntable positions. The capture (141 MB of EXR) is not committed: the test
//! renders it into the target folder with the script (1 min 40 s on two cores)
//! and reuses it while the script is unchanged; without Python's `mitsuba` the test fails and
//! says so.
//!
//! The hull is built from the rig file as `igi hull build` builds it, and rendered at each new
//! view as `igi hull render` renders it. Against the truth (the object inside the rig's box,
//! where a hull can be):
//! - IoU of the silhouettes (alpha > 0.05, the carving's background threshold);
//! - alpha mean absolute error over the pixels where either alpha exceeds 0.02;
//! - colour relative RMSE (sqrt of the summed squared error over the summed squared truth, RGB)
//!   over the pixels the truth covers fully (alpha >= 0.999) and the render covers too.

use igi_camera::{Camera, Rig};
use igi_imaging::{read_image, HdrImage};
use igi_opacity_hull::build::{build, load_model, BuildOptions, BuildReport};
use igi_opacity_hull::render::{render, RenderOptions};
use igi_opacity_hull::views::MatteOptions;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

const SCRIPT: &str = "datasets/mitsuba/hull_straws.py";
const NEW_VIEWS: usize = 4;

fn capture() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| igi_testkit::mitsuba_capture(SCRIPT, "hull_straws", "IGI_HULL_STRAWS_DIR"))
}

/// A new view: its camera, the true premultiplied colour and alpha.
struct Truth {
    camera: Camera,
    colour: HdrImage,
    alpha: Vec<f32>,
}

fn truths() -> Vec<Truth> {
    let dir = capture().join("heldout");
    (0..NEW_VIEWS)
        .map(|k| Truth {
            camera: Camera::load(&dir.join(format!("h{k}.json"))).unwrap(),
            colour: read_image(&dir.join(format!("h{k}.exr"))).unwrap(),
            alpha: read_image(&dir.join(format!("h{k}_alpha.exr")))
                .unwrap()
                .pixels
                .iter()
                .map(|p| p[0])
                .collect(),
        })
        .collect()
}

/// One new view's scores: silhouette IoU, alpha MAE, colour relative RMSE.
#[derive(Debug, Clone, Copy)]
struct Scores {
    iou: f64,
    alpha_mae: f64,
    colour: f64,
}

fn scores(colour: &HdrImage, alpha: &[f32], truth: &Truth) -> Scores {
    let (mut inter, mut union) = (0usize, 0usize);
    let (mut ae, mut an) = (0.0f64, 0usize);
    let (mut se, mut st) = (0.0f64, 0.0f64);
    for (i, (&a, &t)) in alpha.iter().zip(&truth.alpha).enumerate() {
        let (sa, st_) = (a > 0.05, t > 0.05);
        inter += (sa && st_) as usize;
        union += (sa || st_) as usize;
        if a > 0.02 || t > 0.02 {
            ae += (a - t).abs() as f64;
            an += 1;
        }
        if t >= 0.999 && a >= 0.999 {
            for c in 0..3 {
                let (p, q) = (colour.pixels[i][c] as f64, truth.colour.pixels[i][c] as f64);
                se += (p - q) * (p - q);
                st += q * q;
            }
        }
    }
    Scores {
        iou: inter as f64 / union.max(1) as f64,
        alpha_mae: ae / an.max(1) as f64,
        colour: (se / st.max(1e-30)).sqrt(),
    }
}

/// The hull built with `frame_band` (the rest default), and its scores at the new views.
fn evaluate(frame_band: usize) -> (BuildReport, Vec<Scores>) {
    let rig = Rig::load(&capture().join("rig.toml")).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("hull");
    let opts = BuildOptions {
        matte: MatteOptions {
            frame_band,
            ..MatteOptions::default()
        },
        ..BuildOptions::default()
    };
    let report = build(&rig, &out, opts, &mut |_| {}).unwrap();
    let model = load_model(&out).unwrap();
    let s = truths()
        .iter()
        .map(|t| {
            let (img, alpha) = render(&model, &t.camera, RenderOptions::default());
            scores(&img, &alpha, t)
        })
        .collect();
    (report, s)
}

fn show(name: &str, report: &BuildReport, s: &[Scores]) {
    let f = |g: &dyn Fn(&Scores) -> f64| {
        s.iter()
            .map(|x| format!("{:.3}", g(x)))
            .collect::<Vec<_>>()
            .join(" ")
    };
    eprintln!(
        "{name}: hull {:.1} cm3, {} triangles; input views' IoU min {:.3} mean {:.3}; new views' IoU {}, alpha MAE {}, colour {}",
        report.volume_m3 * 1e6,
        report.triangles,
        report.iou_min,
        report.iou_mean,
        f(&|x| x.iou),
        f(&|x| x.alpha_mae),
        f(&|x| x.colour)
    );
}

/// The colour goal, met (2026-11-29): 0.087 0.089 0.087 0.090 with the defaults.
#[test]
fn mitsuba_straws_new_views_colour_within_0_15() {
    let (report, s) = evaluate(MatteOptions::default().frame_band);
    show("defaults", &report, &s);
    for (k, x) in s.iter().enumerate() {
        assert!(
            x.colour <= 0.15,
            "new view {k}: colour relative RMSE {:.3} > 0.15",
            x.colour
        );
    }
}

/// Not met (2026-11-29), with the defaults: IoU 0.943 0.851 0.916 0.935, alpha MAE 0.091 0.103
/// 0.099 0.076. Before the sub-cell surface: 0.936 0.849 0.900 0.924 and 0.094 0.105 0.106
/// 0.081; with the splat radius of one cell and no partial coverage, before that: IoU
/// 0.77-0.84, alpha MAE 0.16-0.19.
/// The render covers pixels that the truth does not (and misses almost none): see
/// docs/OPACITY_HULL.md, "The capture, rendered by Mitsuba 3".
#[test]
#[ignore = "goal not met: new views' IoU 0.85-0.94, alpha MAE 0.08-0.10 (docs/OPACITY_HULL.md)"]
fn mitsuba_straws_new_views_iou_0_95_and_alpha_within_0_05() {
    let (report, s) = evaluate(MatteOptions::default().frame_band);
    show("defaults", &report, &s);
    let (report0, s0) = evaluate(0);
    show("--frame-band 0", &report0, &s0);
    for (k, x) in s.iter().enumerate() {
        assert!(x.iou >= 0.95, "new view {k}: IoU {:.3} < 0.95", x.iou);
        assert!(
            x.alpha_mae <= 0.05,
            "new view {k}: alpha MAE {:.3} > 0.05",
            x.alpha_mae
        );
    }
}
