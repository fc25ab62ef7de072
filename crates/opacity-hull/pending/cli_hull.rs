//! `igi hull`: bad input is refused with an error naming the file or view, nothing half-written.

use glam::DVec3;
use igi_imaging::{Camera, HdrImage, Mask, WorldToCamera};
use igi_testkit::{assert_failed, s, Cli};
use std::path::{Path, PathBuf};

fn igi() -> Cli {
    Cli::new(env!("CARGO_BIN_EXE_igi"))
}

const W: u32 = 128;
const H: u32 = 96;

fn camera(i: usize, n: usize) -> Camera {
    let a = i as f64 / n as f64 * std::f64::consts::TAU;
    let eye = DVec3::new(2.0 * a.cos(), 2.0 * a.sin(), 0.5);
    let mut c = Camera::pinhole(W, H, 80.0, 80.0, 63.5, 47.5);
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
fn make_rig(dir: &Path, n: usize, edit: &dyn Fn(usize, &mut Mask)) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let mut text = String::from("[object]\nbbox_min = [-0.4, -0.4, -0.4]\nbbox_max = [0.4, 0.4, 0.4]\n");
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
    assert_failed(&o, file, problem, tmp, &[rig.parent().unwrap().to_path_buf()]);
}

#[test]
fn a_good_rig_builds_and_renders() {
    let t = tempfile::tempdir().unwrap();
    let rig = make_rig(&t.path().join("cap"), 8, &|_, _| {});
    let out = t.path().join("hull");
    let o = igi().ok(&["hull", "build", s(&rig), "-o", s(&out), "--json"]);
    let r: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(r["iou_min"].as_f64().unwrap() > 0.9, "{r}");
    for f in ["hull.json", "hull.ply", "surfels.ply", "report.json", "volume.png", "mattes/v0.exr"] {
        assert!(out.join(f).exists(), "{f}");
    }
    let img = t.path().join("r.exr");
    igi().ok(&["hull", "render", s(&out), "--camera", s(&t.path().join("cap/c3.json")), "-o", s(&img)]);
    let alpha = igi_imaging::read_exr_alpha(&img).unwrap().expect("RGBA output");
    let mask = sphere_mask(&camera(3, 8));
    let rendered = Mask { width: W as usize, height: H as usize, data: alpha.iter().map(|a| *a > 0.5).collect() };
    let iou = rendered.iou(&mask);
    assert!(iou > 0.85, "IoU of the rendered alpha with the true silhouette {iou}");
}

#[test]
fn fewer_than_two_views() {
    let t = tempfile::tempdir().unwrap();
    let rig = make_rig(&t.path().join("cap"), 1, &|_, _| {});
    build_fails(&rig, t.path(), "rig.toml", "at least 2");
}

#[test]
fn image_size_differs_from_its_camera() {
    let t = tempfile::tempdir().unwrap();
    let rig = make_rig(&t.path().join("cap"), 4, &|_, _| {});
    igi_imaging::write_exr(&t.path().join("cap/p2.exr"), &HdrImage::new(10, 10)).unwrap();
    build_fails(&rig, t.path(), "\"v2\"", "is 10x10 but the view's camera is 128x96");
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

#[test]
fn malformed_par_line_and_far_rotation() {
    let t = tempfile::tempdir().unwrap();
    let set = par_set(&t.path().join("set"), Some("dinoSR0002.png 3310.4 0 316.73 0 3325.5 200.55 0 0 1 1 0 0 0 1"));
    let out = t.path().join("rig");
    let o = igi().run(&["hull", "import-middlebury", s(&set), "-o", s(&out)]);
    assert_failed(&o, "dinoSR_par.txt", "line 3", t.path(), &[set.clone()]);
    let t = tempfile::tempdir().unwrap();
    let set = par_set(&t.path().join("set"), Some("dinoSR0002.png 3310.4 0 316.73 0 3325.5 200.55 0 0 1 1 0 0 0 1 0.01 0 0 1 0 0 0.7"));
    let out = t.path().join("rig");
    let o = igi().run(&["hull", "import-middlebury", s(&set), "-o", s(&out)]);
    assert_failed(&o, "dinoSR_par.txt", "from the nearest rotation", t.path(), &[set.clone()]);
}

#[test]
fn backdrops_writes_six_patterns() {
    let t = tempfile::tempdir().unwrap();
    let out = t.path().join("bd");
    igi().ok(&["hull", "backdrops", "--width", "32", "--height", "16", "-o", s(&out)]);
    let img = igi_imaging::read_image(&out.join("backdrop-l27-p.png")).unwrap();
    assert_eq!((img.width, img.height), (32, 16));
    assert!((img.get(0, 0)[0] * 255.0 - 127.0).abs() < 0.6);
    assert_eq!(std::fs::read_dir(&out).unwrap().count(), 6);
}
