//! `igi hull`: bad input is refused with an error naming the file or view, nothing half-written.

use glam::DVec3;
use igi_camera::{Camera, WorldToCamera};
use igi_imaging::{HdrImage, Mask};
use igi_testkit::{assert_failed, s, Cli};
use std::path::{Path, PathBuf};

fn igi() -> Cli {
    Cli::new(env!("CARGO_BIN_EXE_igi"))
}

const W: u32 = 256;
const H: u32 = 192;

fn camera(i: usize, n: usize) -> Camera {
    let a = i as f64 / n as f64 * std::f64::consts::TAU;
    let eye = DVec3::new(2.0 * a.cos(), 2.0 * a.sin(), 0.5);
    let mut c = Camera::pinhole(W, H, 160.0, 160.0, 127.5, 95.5);
    c.pose = WorldToCamera::look_at(eye, DVec3::ZERO, DVec3::Z).unwrap();
    c
}

/// The silhouette of a sphere of radius 0.3 at the origin (pixel centres inside the cone).
fn sphere_mask(c: &Camera) -> Mask {
    let mut m = Mask::new(W as usize, H as usize);
    let centre = c.center_world();
    let half = (0.3 / centre.length()).asin();
    for y in 0..H as usize {
        for x in 0..W as usize {
            let (_, d) = c.pixel_ray(x as f64, y as f64);
            m.set(x, y, d.angle_between(-centre) < half);
        }
    }
    m
}

/// A rig of `n` views around the sphere in `dir`; `edit(i, mask)` may change each mask.
pub(crate) fn make_rig(dir: &Path, n: usize, edit: &dyn Fn(usize, &mut Mask)) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let mut text =
        String::from("[object]\nbbox_min = [-0.4, -0.4, -0.4]\nbbox_max = [0.4, 0.4, 0.4]\n");
    for i in 0..n {
        let c = camera(i, n);
        c.save(&dir.join(format!("c{i}.json"))).unwrap();
        let mut m = sphere_mask(&c);
        edit(i, &mut m);
        m.save_png(&dir.join(format!("m{i}.png"))).unwrap();
        let mut photo = HdrImage::new(W as usize, H as usize);
        for (p, &b) in photo.pixels.iter_mut().zip(&m.data) {
            *p = if b { [0.5, 0.4, 0.3] } else { [0.0; 3] };
        }
        igi_imaging::write_exr(&dir.join(format!("p{i}.exr")), &photo).unwrap();
        text += &format!("\n[[view]]\nid = \"v{i}\"\ncamera = \"c{i}.json\"\nphoto = \"p{i}.exr\"\nmask = \"m{i}.png\"\n");
    }
    let rig = dir.join("rig.toml");
    std::fs::write(&rig, text).unwrap();
    rig
}

fn build_fails(rig: &Path, tmp: &Path, file: &str, problem: &str) {
    let out = tmp.join("hull");
    let o = igi().run(&["hull", "build", s(rig), "-o", s(&out)]);
    assert_failed(
        &o,
        file,
        problem,
        tmp,
        &[rig.parent().unwrap().to_path_buf()],
    );
}

#[test]
fn a_good_rig_builds_and_renders() {
    let t = tempfile::tempdir().unwrap();
    let rig = make_rig(&t.path().join("cap"), 8, &|_, _| {});
    let out = t.path().join("hull");
    let o = igi().ok(&["hull", "build", s(&rig), "-o", s(&out), "--json"]);
    let r: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(r["iou_min"].as_f64().unwrap() > 0.9, "{r}");
    for f in [
        "hull.json",
        "hull.ply",
        "surfels.ply",
        "report.json",
        "volume.png",
        "mattes/v0.exr",
    ] {
        assert!(out.join(f).exists(), "{f}");
    }
    let img = t.path().join("r.exr");
    igi().ok(&[
        "hull",
        "render",
        s(&out),
        "--camera",
        s(&t.path().join("cap/c3.json")),
        "-o",
        s(&img),
    ]);
    let alpha = igi_imaging::read_exr_alpha(&img)
        .unwrap()
        .expect("RGBA output");
    let mask = sphere_mask(&camera(3, 8));
    let rendered = Mask {
        width: W as usize,
        height: H as usize,
        data: alpha.iter().map(|a| *a > 0.5).collect(),
    };
    let iou = rendered.iou(&mask);
    // the splats (at least 0.8 px across) widen the silhouette by about half a pixel: measured
    // 0.9355 at 256 x 192
    assert!(
        iou > 0.92,
        "IoU of the rendered alpha with the true silhouette {iou}"
    );
    // well inside the silhouette the photo's flat colour comes back (alpha 1, premultiplied)
    let colour = igi_imaging::read_image(&img).unwrap();
    let inner = mask.erode(3.0);
    assert!(inner.count() > 1000);
    for (i, _) in inner.data.iter().enumerate().filter(|(_, &m)| m) {
        let (c, a) = (colour.pixels[i], alpha[i]);
        let err = (0..3)
            .map(|k| (c[k] - [0.5, 0.4, 0.3][k]).abs())
            .fold(0.0, f32::max);
        assert!(
            (a - 1.0).abs() < 1e-4 && err < 1e-4,
            "pixel {i}: {c:?} alpha {a}"
        );
    }
}

#[test]
fn fewer_than_two_views() {
    let t = tempfile::tempdir().unwrap();
    let rig = make_rig(&t.path().join("cap"), 1, &|_, _| {});
    build_fails(&rig, t.path(), "rig.toml", "at least 2");
}

/// A carving grid beyond the memory limit is refused before any image is read or the output
/// folder is made: 1024^3 cells at 8 bytes (8.0 GiB) under `IGI_MAX_MEMORY=4G`, and the
/// default 256^3 (128 MiB) under 64M.
#[test]
fn a_carving_grid_beyond_the_memory_limit_is_refused_before_any_work() {
    let t = tempfile::tempdir().unwrap();
    let rig = make_rig(&t.path().join("cap"), 3, &|_, _| {});
    let out = t.path().join("hull");
    for (limit, resolution, bytes) in [
        ("4G", "1024", "8.0 GiB (8589934592 bytes)"),
        ("64M", "256", "0.1 GiB (134217728 bytes)"),
    ] {
        let t0 = std::time::Instant::now();
        let o = igi().with_env("IGI_MAX_MEMORY", limit).run(&[
            "hull",
            "build",
            s(&rig),
            "--resolution",
            resolution,
            "-o",
            s(&out),
        ]);
        let e = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{e}");
        let what = format!("carving grid of {resolution}^3 cells (--resolution {resolution}");
        assert!(e.contains(&what) && e.contains(bytes), "{e}");
        assert!(t0.elapsed().as_secs_f64() < 5.0, "refused at once: {e}");
        assert!(!out.exists(), "nothing written");
    }
}

#[test]
fn image_size_differs_from_its_camera() {
    let t = tempfile::tempdir().unwrap();
    let rig = make_rig(&t.path().join("cap"), 4, &|_, _| {});
    igi_imaging::write_exr(&t.path().join("cap/p2.exr"), &HdrImage::new(10, 10)).unwrap();
    build_fails(
        &rig,
        t.path(),
        "\"v2\"",
        "is 10x10 but the view's camera is 256x192",
    );
}

#[test]
fn empty_and_full_silhouettes() {
    let t = tempfile::tempdir().unwrap();
    let rig = make_rig(&t.path().join("cap"), 4, &|i, m| {
        if i == 1 {
            m.data.fill(false)
        }
    });
    build_fails(&rig, t.path(), "\"v1\"", "silhouette is empty");
    let t = tempfile::tempdir().unwrap();
    let rig = make_rig(&t.path().join("cap"), 4, &|i, m| {
        if i == 2 {
            m.data.fill(true)
        }
    });
    build_fails(&rig, t.path(), "\"v2\"", "silhouette is full");
}

#[test]
fn a_hull_carved_empty_names_the_view() {
    let t = tempfile::tempdir().unwrap();
    let rig = make_rig(&t.path().join("cap"), 4, &|i, m| {
        if i == 2 {
            m.data.fill(false);
            m.set(0, 0, true);
        }
    });
    build_fails(&rig, t.path(), "\"v2\"", "hull is empty after carving");
}

#[test]
fn a_missing_pattern_image() {
    let t = tempfile::tempdir().unwrap();
    let rig = make_rig(&t.path().join("cap"), 3, &|_, _| {});
    let text = std::fs::read_to_string(&rig).unwrap().replace(
        "mask = \"m1.png\"",
        "backdrops = [ { lambda = 27, n = 1, backdrop = \"bg27p.exr\", object = \"p1.exr\" }, { lambda = 27, n = -1, backdrop = \"bg27m.exr\", object = \"p1.exr\" } ]",
    );
    std::fs::write(&rig, text).unwrap();
    build_fails(&rig, t.path(), "bg27p.exr", "v1");
}

/// Light directions on the six axes, and light image i of a view: a flat colour inside the
/// view's silhouette.
const AXES: [[f64; 3]; 6] = [
    [1.0, 0.0, 0.0],
    [-1.0, 0.0, 0.0],
    [0.0, 1.0, 0.0],
    [0.0, -1.0, 0.0],
    [0.0, 0.0, 1.0],
    [0.0, 0.0, -1.0],
];

fn light_colour(i: usize) -> [f32; 3] {
    let k = (i + 1) as f32;
    [0.02 * k, 0.015 * k, 0.01 * k]
}

/// The rig of `make_rig` with six light images a view (see [`light_colour`]).
fn make_lit_rig(dir: &Path, n: usize) -> PathBuf {
    let rig = make_rig(dir, n, &|_, _| {});
    let mut text = std::fs::read_to_string(&rig).unwrap();
    for v in 0..n {
        let mask = sphere_mask(&camera(v, n));
        let mut lights = Vec::new();
        for (i, d) in AXES.iter().enumerate() {
            let mut img = HdrImage::new(W as usize, H as usize);
            for (p, &b) in img.pixels.iter_mut().zip(&mask.data) {
                *p = if b { light_colour(i) } else { [0.0; 3] };
            }
            let name = format!("l{v}_{i}.exr");
            igi_imaging::write_exr(&dir.join(&name), &img).unwrap();
            lights.push(format!(
                "{{ direction = [{}, {}, {}], image = \"{name}\" }}",
                d[0], d[1], d[2]
            ));
        }
        let line = format!("mask = \"m{v}.png\"\n");
        text = text.replace(&line, &format!("{line}lights = [{}]\n", lights.join(", ")));
    }
    std::fs::write(&rig, text).unwrap();
    rig
}

/// A constant sky of radiance `l` (a map and its lighting file) in `dir`.
fn constant_sky(dir: &Path, l: f32) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let mut map = HdrImage::new(16, 8);
    map.pixels.fill([l; 3]);
    igi_imaging::write_exr(&dir.join("sky.exr"), &map).unwrap();
    let toml = dir.join("sky.toml");
    std::fs::write(&toml, "[environment]\nmap = \"sky.exr\"\nscale = 2.0\n").unwrap();
    toml
}

/// Eq. 3 through the command line: flat light images on the six axes under a constant sky of
/// radiance L (0.25 x scale 2) give, inside the silhouette, `L 4 pi / 6` times the sum of the
/// light images (each light's Voronoi cell is a sixth of the sphere).
#[test]
fn a_lit_rig_builds_a_reflectance_field_and_relights_by_eq3() {
    let t = tempfile::tempdir().unwrap();
    let rig = make_lit_rig(&t.path().join("cap"), 4);
    let hull = t.path().join("hull");
    let o = igi().ok(&["hull", "build", s(&rig), "-o", s(&hull), "--json"]);
    let r: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let f = &r["reflectance"];
    assert_eq!(f["light_images"], 24, "{f}");
    // flat images are rank one in every block: one component a block, exact
    assert_eq!(f["max_components"], 1, "{f}");
    assert!(f["relative_rms"].as_f64().unwrap() < 1e-6, "{f}");
    assert!(f["ratio"].as_f64().unwrap() > 10.0, "{f}");
    assert!(hull.join("reflectance/reflectance.json").exists());
    assert!(hull.join("reflectance/v0.bin").exists());
    let sky = constant_sky(&t.path().join("light"), 0.25);
    let img = t.path().join("r.exr");
    let cam = t.path().join("cap/c1.json");
    igi().ok(&[
        "hull",
        "render",
        s(&hull),
        "--camera",
        s(&cam),
        "--lighting",
        s(&sky),
        "-o",
        s(&img),
    ]);
    let out = igi_imaging::read_image(&img).unwrap();
    let sum: Vec<f64> = (0..3)
        .map(|c| (0..6).map(|i| light_colour(i)[c] as f64).sum())
        .collect();
    let inner = sphere_mask(&camera(1, 4)).erode(3.0);
    assert!(inner.count() > 1000);
    let mut worst = 0.0f64;
    for (i, _) in inner.data.iter().enumerate().filter(|(_, &m)| m) {
        for c in 0..3 {
            let expect = 0.5 * 4.0 * std::f64::consts::PI / 6.0 * sum[c];
            worst = worst.max((out.pixels[i][c] as f64 - expect).abs() / expect);
        }
    }
    // measured 5.8e-6 (the Voronoi cells to 1/64 of a sky pixel, f32 storage)
    assert!(worst < 1e-4, "worst relative error {worst:e}");
}

/// `--lighting`: the lighting file is checked before anything else; a hull built without light
/// images cannot be relit, and says so naming the folder; nothing is written.
#[test]
fn relighting_refuses_a_hull_without_a_reflectance_field_and_a_bad_lighting_file() {
    let t = tempfile::tempdir().unwrap();
    let rig = make_rig(&t.path().join("cap"), 4, &|_, _| {});
    let hull = t.path().join("hull");
    igi().ok(&["hull", "build", s(&rig), "-o", s(&hull)]);
    let sky = constant_sky(&t.path().join("light"), 0.25);
    let cam = t.path().join("cap/c0.json");
    let img = t.path().join("r.exr");
    let keep = [t.path().join("cap"), hull.clone(), t.path().join("light")];
    let o = igi().run(&[
        "hull",
        "render",
        s(&hull),
        "--camera",
        s(&cam),
        "--lighting",
        s(&sky),
        "-o",
        s(&img),
    ]);
    assert_failed(
        &o,
        s(&hull),
        "no surface reflectance field",
        t.path(),
        &keep,
    );
    // a lighting file whose map is missing is named even before the hull folder is opened
    let bad = t.path().join("light/bad.toml");
    std::fs::write(&bad, "[environment]\nmap = \"missing.exr\"\n").unwrap();
    let nowhere = t.path().join("no-hull");
    let o = igi().run(&[
        "hull",
        "render",
        s(&nowhere),
        "--camera",
        s(&cam),
        "--lighting",
        s(&bad),
        "-o",
        s(&img),
    ]);
    assert_failed(&o, "bad.toml", "missing.exr", t.path(), &keep);
    // a good lighting file and no hull folder: the missing manifest is named
    let o = igi().run(&[
        "hull",
        "render",
        s(&nowhere),
        "--camera",
        s(&cam),
        "--lighting",
        s(&sky),
        "-o",
        s(&img),
    ]);
    assert_failed(&o, "hull.json", "is not a hull folder", t.path(), &keep);
    // and one that lights nothing
    std::fs::write(&bad, "# nothing\n").unwrap();
    let o = igi().run(&[
        "hull",
        "render",
        s(&hull),
        "--camera",
        s(&cam),
        "--lighting",
        s(&bad),
        "-o",
        s(&img),
    ]);
    assert_failed(
        &o,
        "bad.toml",
        "names neither [environment] nor [sun]",
        t.path(),
        &keep,
    );
}

#[test]
fn a_light_image_of_the_wrong_size() {
    let t = tempfile::tempdir().unwrap();
    let rig = make_lit_rig(&t.path().join("cap"), 3);
    let small = HdrImage::new(10, 10);
    igi_imaging::write_exr(&t.path().join("cap/l0_3.exr"), &small).unwrap();
    build_fails(
        &rig,
        t.path(),
        "l0_3.exr is 10x10 but the view's camera is 256x192",
        "\"v0\"",
    );
    // a missing one is found before any work (in a capture whose other light images are good)
    let t = tempfile::tempdir().unwrap();
    let rig = make_lit_rig(&t.path().join("cap"), 3);
    std::fs::remove_file(t.path().join("cap/l2_5.exr")).unwrap();
    build_fails(&rig, t.path(), "l2_5.exr", "\"v2\"");
}

fn par_set(dir: &Path, line2: Option<&str>) -> PathBuf {
    let src = igi_testkit::shared_data("multiview/dinoSparseRing");
    std::fs::create_dir_all(dir).unwrap();
    for e in std::fs::read_dir(&src).unwrap() {
        let p = e.unwrap().path();
        std::fs::copy(&p, dir.join(p.file_name().unwrap())).unwrap();
    }
    if let Some(l) = line2 {
        let par = dir.join("dinoSR_par.txt");
        let text = std::fs::read_to_string(&par).unwrap();
        let mut lines: Vec<String> = text.lines().map(String::from).collect();
        lines[2] = l.to_string();
        std::fs::write(&par, lines.join("\n")).unwrap();
    }
    dir.to_path_buf()
}

/// Import a copy of the dino set whose third `_par.txt` line is `line`: it must fail naming the
/// file and saying `problem`, and write nothing.
fn import_fails(line: &str, problem: &str) {
    let t = tempfile::tempdir().unwrap();
    let set = par_set(&t.path().join("set"), Some(line));
    let out = t.path().join("rig");
    let o = igi().run(&["hull", "import-middlebury", s(&set), "-o", s(&out)]);
    assert_failed(
        &o,
        "dinoSR_par.txt",
        problem,
        t.path(),
        std::slice::from_ref(&set),
    );
}

#[test]
fn malformed_par_line_and_far_rotation() {
    let k = "dinoSR0002.png 3310.4 0 316.73 0 3325.5 200.55 0 0 1";
    import_fails(
        &format!("{k} 1 0 0 0 1"),
        "line 3: expected an image name and 21 numbers",
    );
    import_fails(
        &format!("{k} 1 0 0 0 1 0 0 0 one 0 0 0.7"),
        "line 3: \"one\" is not a finite number",
    );
    // R with a 0.01 shear, far more than the 1e-3 a measurement error explains
    import_fails(
        &format!("{k} 1 0 0 0 1 0.01 0 0 1 0 0 0.7"),
        "from the nearest rotation",
    );
}

#[test]
fn backdrops_writes_six_patterns() {
    let t = tempfile::tempdir().unwrap();
    let out = t.path().join("bd");
    igi().ok(&[
        "hull",
        "backdrops",
        "--width",
        "32",
        "--height",
        "16",
        "-o",
        s(&out),
    ]);
    let img = igi_imaging::read_image(&out.join("backdrop-l27-p.png")).unwrap();
    assert_eq!((img.width, img.height), (32, 16));
    assert!((img.get(0, 0)[0] * 255.0 - 127.0).abs() < 0.6);
    assert_eq!(std::fs::read_dir(&out).unwrap().count(), 6);
}

/// PSNR (peak 1, the photos' white) of `rendered` against `photo` over the pixels of `mask`.
fn psnr_inside(rendered: &HdrImage, photo: &HdrImage, mask: &Mask) -> f64 {
    rendered.psnr_inside(photo, &mask.data, 1.0).unwrap()
}

/// Per view of the dino: PSNR inside the silhouette, and inside the part of it the rendered
/// alpha covers (> 0.5), which tells the rendering error from the carving error.
struct DinoPsnr {
    view: String,
    silhouette_db: f64,
    covered_db: f64,
    uncovered_pixels: usize,
    silhouette_pixels: usize,
}

/// The Middlebury dino end to end through the command line: import, build at 256 cells per
/// axis (checking the reprojection IoU goals), then render from every input camera and compare
/// with its photo.
fn dino_render_psnr() -> Vec<DinoPsnr> {
    let t = tempfile::tempdir().unwrap();
    let rig_dir = t.path().join("rig");
    let set = igi_testkit::shared_data("multiview/dinoSparseRing");
    igi().ok(&["hull", "import-middlebury", s(&set), "-o", s(&rig_dir)]);
    let out = t.path().join("hull");
    let rig = rig_dir.join("rig.toml");
    let o = igi().ok(&["hull", "build", s(&rig), "-o", s(&out), "--json"]);
    let r: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let views = r["views"].as_array().unwrap();
    assert_eq!(views.len(), 15);
    let (min, mean) = (
        r["iou_min"].as_f64().unwrap(),
        r["iou_mean"].as_f64().unwrap(),
    );
    assert!(min >= 0.97 && mean >= 0.98, "IoU min {min} mean {mean}");
    let mut res = Vec::new();
    for v in views {
        let id = v["view"].as_str().unwrap();
        let img = t.path().join(format!("{id}.exr"));
        let cam = rig_dir.join(format!("cameras/{id}.json"));
        igi().ok(&[
            "hull",
            "render",
            s(&out),
            "--camera",
            s(&cam),
            "-o",
            s(&img),
        ]);
        let rendered = igi_imaging::read_image(&img).unwrap();
        let alpha = igi_imaging::read_exr_alpha(&img).unwrap().unwrap();
        let photo = igi_imaging::read_image(&rig_dir.join(format!("photos/{id}.png"))).unwrap();
        let mask = Mask::load(&rig_dir.join(format!("masks/{id}.png"))).unwrap();
        let mut covered = mask.clone();
        for (m, a) in covered.data.iter_mut().zip(&alpha) {
            *m &= *a > 0.5;
        }
        let p = DinoPsnr {
            view: id.to_string(),
            silhouette_db: psnr_inside(&rendered, &photo, &mask),
            covered_db: psnr_inside(&rendered, &photo, &covered),
            uncovered_pixels: mask.count() - covered.count(),
            silhouette_pixels: mask.count(),
        };
        eprintln!(
            "{id}: PSNR inside the silhouette {:.2} dB, inside its covered part {:.2} dB ({} of {} pixels uncovered)",
            p.silhouette_db, p.covered_db, p.uncovered_pixels, mask.count()
        );
        res.push(p);
    }
    res
}

fn low_mean(x: impl Iterator<Item = f64> + Clone) -> (f64, f64) {
    let n = x.clone().count() as f64;
    (x.clone().fold(f64::INFINITY, f64::min), x.sum::<f64>() / n)
}

/// Measured (docs/OPACITY_HULL.md): inside the silhouette min 31.77 dB (dinoSR0008), mean
/// 36.40 dB; inside the covered part min 34.49 dB, mean 38.14 dB (with the half-way vertices
/// before the sub-cell surface 31.90 / 36.74 and 34.89 / 38.68 dB; without the frame band, with
/// the splat radius and coverage of before:
/// 27.45 dB at dinoSR0010, where the hull missed 0.6 % of the silhouette).
#[test]
fn dino_renders_from_input_cameras() {
    let res = dino_render_psnr();
    let (sil_min, sil_mean) = low_mean(res.iter().map(|p| p.silhouette_db));
    let (cov_min, cov_mean) = low_mean(res.iter().map(|p| p.covered_db));
    eprintln!("PSNR: silhouette min {sil_min:.2} mean {sil_mean:.2} dB; covered part min {cov_min:.2} mean {cov_mean:.2} dB");
    // the goal (30 dB) holds for the blending wherever the hull covers the silhouette
    assert!(cov_min >= 30.0, "covered-part PSNR {cov_min}");
    // the rendered alpha leaves at most 1 % of any silhouette uncovered (measured: 0.56 %)
    for p in &res {
        let f = p.uncovered_pixels as f64 / p.silhouette_pixels as f64;
        assert!(f <= 0.01, "{}: {f:.4} of the silhouette uncovered", p.view);
    }
    // the goal taken per photo: every input view at >= 30 dB inside its whole
    // silhouette (measured 31.77-39.70 dB). Without the frame band (`igi hull build
    // --frame-band 0`) dinoSR0009-0013 reached only 27.45-29.61 dB: dinoSR0002's mask calls
    // the shadowed foot at its top edge background, and the hull lost it.
    for p in &res {
        assert!(
            p.silhouette_db >= 30.0,
            "{}: {:.2} dB",
            p.view,
            p.silhouette_db
        );
    }
}
