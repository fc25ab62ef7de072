//! Issue 32, item 2: a glossy bunny under a small bright light, rendered by Mitsuba 3
//! (`datasets/mitsuba/slf_gloss.py`: rough plastic, GGX alpha 0.12 over a warm diffuse, a dim sky
//! with a 4-degree spot 30 times brighter; 96 views of 256 x 256 at 64 spp; the true mesh; 6 new
//! views at 1024 spp). The capture (20 MB) is not committed: the test renders it into the target
//! folder with the script (about 7 minutes on two shared cores) and reuses it while the script
//! is unchanged; without Python's `mitsuba` the test fails and says so.

use igi_camera::{Camera, Rig};
use igi_imaging::{read_image, HdrImage};
use igi_lightfield::{
    prepare_rig, BuildOptions, GridOptions, Method, RenderSlfOptions, RigPrepared,
};
use std::path::PathBuf;
use std::sync::OnceLock;

const SCRIPT: &str = "datasets/mitsuba/slf_gloss.py";

/// The capture folder: `$IGI_SLF_GLOSS_DIR` when set (a capture the script wrote), else the
/// target folder's, rendered by the script when missing or made by another version of it.
fn capture() -> PathBuf {
    igi_testkit::mitsuba_capture(SCRIPT, "slf_gloss", "IGI_SLF_GLOSS_DIR")
}

struct Gloss {
    prep: RigPrepared,
    held_out: Vec<(Camera, HdrImage)>,
}

fn gloss() -> &'static Gloss {
    static G: OnceLock<Gloss> = OnceLock::new();
    G.get_or_init(|| {
        let dir = capture();
        let rig = Rig::load(&dir.join("rig.toml")).unwrap();
        let mesh = igi_geometry::read_mesh(&dir.join("mesh.ply")).unwrap();
        let prep = prepare_rig(&rig, &mesh, GridOptions::default(), 3, &|_| {}).unwrap();
        let held_out = (0..6)
            .map(|k| {
                let h = dir.join("heldout");
                (
                    Camera::load(&h.join(format!("h{k}.json"))).unwrap(),
                    read_image(&h.join(format!("h{k}.exr"))).unwrap(),
                )
            })
            .collect();
        Gloss { prep, held_out }
    })
}

/// Colour relative RMSE (sqrt of the summed squared error over the summed squared truth, RGB)
/// and PSNR (peak: the truth's maximum there) over the pixels the field covers whose 8
/// neighbours it covers too (the truth's silhouette pixels mix the object with the background).
fn errors(img: &HdrImage, alpha: &[f32], truth: &HdrImage) -> (f64, f64) {
    let (w, h) = (img.width as i64, img.height as i64);
    let (mut se, mut st, mut n, mut peak) = (0.0f64, 0.0f64, 0usize, 0.0f64);
    for i in 0..alpha.len() {
        let (x, y) = (i as i64 % w, i as i64 / w);
        let inner = (-1..=1).all(|dy| {
            (-1..=1).all(|dx| {
                let (a, b) = (x + dx, y + dy);
                a >= 0 && b >= 0 && a < w && b < h && alpha[(b * w + a) as usize] > 0.5
            })
        });
        if !inner {
            continue;
        }
        for c in 0..3 {
            let (p, t) = (img.pixels[i][c] as f64, truth.pixels[i][c] as f64);
            se += (p - t) * (p - t);
            st += t * t;
            peak = peak.max(t);
        }
        n += 1;
    }
    let mse = se / (3 * n.max(1)) as f64;
    (
        (se / st.max(1e-30)).sqrt(),
        10.0 * (peak * peak / mse).log10(),
    )
}

fn evaluate(method: Method, opts: &BuildOptions) -> Vec<(f64, f64)> {
    let g = gloss();
    let field = g.prep.prepared.fit(method, opts).unwrap();
    let r = field.renderer(&g.prep.atlas.mesh).unwrap();
    g.held_out
        .iter()
        .map(|(cam, truth)| {
            let (img, alpha) = r.render(cam, &RenderSlfOptions::default());
            errors(&img, &alpha, truth)
        })
        .collect()
}

fn show(name: &str, e: &[(f64, f64)]) {
    let rel: Vec<String> = e.iter().map(|(r, _)| format!("{r:.3}")).collect();
    let db: Vec<String> = e.iter().map(|(_, p)| format!("{p:.2}")).collect();
    eprintln!(
        "{name}: relative RMSE {} / PSNR {} dB",
        rel.join(" "),
        db.join(" ")
    );
}

fn mean_db(e: &[(f64, f64)]) -> f64 {
    e.iter().map(|(_, p)| p).sum::<f64>() / e.len() as f64
}

/// Per new view: (colour relative RMSE, PSNR in dB).
type Errors = Vec<(f64, f64)>;

/// The errors of the median alone, pointwise fairing and PFA q = 2.
fn report() -> (Errors, Errors, Errors) {
    let g = gloss();
    eprintln!(
        "gather: {:?}, atlas texel {:.4}",
        g.prep.prepared.report, g.prep.atlas.texel_size
    );
    let opts = BuildOptions::default();
    let median = evaluate(Method::MedianOnly, &opts);
    show("median alone", &median);
    let fair = evaluate(Method::Fair, &opts);
    show("pointwise fairing", &fair);
    let pfa = evaluate(Method::Pfa { q: 2 }, &opts);
    show("PFA q = 2", &pfa);
    (median, fair, pfa)
}

/// Met (2026-11-29, with the view-angle gain): fairing 30.50 29.51 30.34 31.57 28.66 33.67 dB
/// against the median alone's 26.65 27.13 26.93 26.57 23.42 29.58 dB, 4.00 dB better on average
/// (3.05 dB without the gain).
#[test]
fn glossy_bunny_under_a_small_bright_light_fairing_beats_the_median() {
    let (median, fair, _) = report();
    let gain = mean_db(&fair) - mean_db(&median);
    assert!(
        gain >= 3.0,
        "fairing {:.2} dB against the median alone {:.2} dB: {gain:.2} dB better, not 3",
        mean_db(&fair),
        mean_db(&median)
    );
    for (k, (f, m)) in fair.iter().zip(&median).enumerate() {
        assert!(
            f.0 < m.0,
            "new view {k}: fairing {:.3} not below the median's {:.3}",
            f.0,
            m.0
        );
    }
}

/// Not met (2026-11-29, with the view-angle gain): PFA q = 2 reaches 0.063 0.084 0.086 0.095
/// 0.101 0.157 (fairing 0.053 0.067 0.070 0.068 0.080 0.147); see docs/LIGHTFIELD.md, "Gloss
/// under a small bright light".
#[test]
#[ignore = "goal not met: PFA q = 2 at 0.063-0.157, docs/LIGHTFIELD.md"]
fn glossy_bunny_under_a_small_bright_light_pfa_within_0_07() {
    let (_, _, pfa) = report();
    for (k, (r, _)) in pfa.iter().enumerate() {
        assert!(
            *r <= 0.07,
            "new view {k}: PFA q = 2 colour relative RMSE {r:.3} > 0.07"
        );
    }
}
