//! `igi export --format gltf` (issue 35, item 1) on a quick solve of the Mitsuba survey fixture
//! (`datasets/fixtures/survey`):
//!
//! * the base colour read back from `scene.glb` (the embedded PNG decoded, sRGB to linear,
//!   bilinear at the glTF UV) at points found through the root node's Y-up rotation equals
//!   `igi sample`'s albedo there within 8-bit quantisation (this checks the axes, the V flip and
//!   the sRGB transfer);
//! * the GLB passes the Khronos glTF-Validator (npm `gltf-validator`, run with node) with 0
//!   errors; a missing node or validator fails the test with the reason
//!   (`bash scripts/deps.sh test` installs it);
//! * a part with a known Lafortune lobe gets a fitted material whose error is printed and kept
//!   in `extras` with the exact lobe; a part without lobes is pure diffuse (roughness 1,
//!   specular 0);
//! * the output folder's rules: never the result folder or inside it, never a folder with
//!   other files; an earlier export is replaced whole.

use glam::Vec3;
use igi_testkit::run_ok;
use std::path::{Path, PathBuf};
use std::process::Command;

fn igi() -> Command {
    igi_testkit::Cli::new(env!("CARGO_BIN_EXE_igi")).command()
}

fn fixture() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("datasets/fixtures/survey")
}

/// A quick result of the fixture (one iteration, 32 x 32 atlases); `igi view`'s tests use it too.
pub(crate) fn quick_result(tmp: &Path) -> PathBuf {
    let res = tmp.join("res");
    run_ok(igi().arg("solve").arg(fixture()).arg("-o").arg(&res).args([
        "--atlas",
        "32",
        "--iterations",
        "1",
        "--spp",
        "4",
        "--quiet",
    ]));
    res
}

fn export(res: &Path, format: &str, out: &Path) -> std::process::Output {
    igi()
        .arg("export")
        .arg(res)
        .args(["--format", format, "-o"])
        .arg(out)
        .output()
        .unwrap()
}

/// The folder of the npm package `gltf-validator`: `IGI_GLTF_VALIDATOR`, or where
/// `scripts/deps.sh test` installs it.
fn validator() -> PathBuf {
    let dir = std::env::var_os("IGI_GLTF_VALIDATOR")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("/opt/igi-node/node_modules/gltf-validator"));
    assert!(
        dir.join("package.json").is_file(),
        "the Khronos glTF-Validator is not installed at {} (run `bash scripts/deps.sh test`, or set IGI_GLTF_VALIDATOR to the gltf-validator package folder)",
        dir.display()
    );
    dir
}

/// Runs the Khronos glTF-Validator on `glb`: its report (JSON).
fn validate(glb: &Path) -> serde_json::Value {
    let dir = tempfile::tempdir().unwrap();
    let script = dir.path().join("validate.js");
    std::fs::write(
        &script,
        "const v = require(process.argv[2]);\n\
         const bytes = new Uint8Array(require('fs').readFileSync(process.argv[3]));\n\
         v.validateBytes(bytes, {maxIssues: 100}).then(r => console.log(JSON.stringify(r)))\n\
           .catch(e => { console.error('validator failed: ' + e); process.exit(2); });\n",
    )
    .unwrap();
    let out = Command::new("node")
        .arg(&script)
        .arg(validator())
        .arg(glb)
        .output()
        .unwrap_or_else(|e| panic!("node (needed to run the glTF-Validator) cannot run: {e}"));
    assert!(
        out.status.success(),
        "glTF-Validator: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("validator report")
}

/// sRGB to linear.
fn srgb_to_linear(x: f32) -> f32 {
    if x <= 0.040_45 {
        x / 12.92
    } else {
        ((x + 0.055) / 1.055).powf(2.4)
    }
}

/// One part read back from the GLB.
struct GlbPart {
    name: String,
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    uvs: Vec<[f32; 2]>,
    indices: Vec<u32>,
    /// The base colour texture: width, height, 8-bit sRGB RGB rows from the top.
    png: image::RgbImage,
    roughness: f32,
    specular: f32,
    extras: serde_json::Value,
}

/// The root node's rotation and the parts of `scene.glb`.
fn read_glb(path: &Path) -> (glam::Quat, Vec<GlbPart>) {
    let bytes = std::fs::read(path).unwrap();
    let g = gltf::Gltf::from_slice(&bytes).expect("the gltf crate reads the GLB");
    let blob = g.blob.clone().expect("a BIN chunk");
    let scene = g.default_scene().expect("a default scene");
    let roots: Vec<_> = scene.nodes().collect();
    assert_eq!(roots.len(), 1, "one root node");
    let (_, rot, scale) = roots[0].transform().decomposed();
    assert_eq!(scale, [1.0; 3]);
    let mut parts = Vec::new();
    for node in roots[0].children() {
        let mesh = node.mesh().expect("a part node holds its mesh");
        let prim = mesh.primitives().next().unwrap();
        let r = prim.reader(|_| Some(&blob[..]));
        let material = prim.material();
        let pbr = material.pbr_metallic_roughness();
        let tex = pbr.base_color_texture().expect("a base colour texture");
        let gltf::image::Source::View { view, mime_type } = tex.texture().source().source() else {
            panic!("the texture is embedded")
        };
        assert_eq!(mime_type, "image/png");
        let png = &blob[view.offset()..view.offset() + view.length()];
        let png = image::load_from_memory_with_format(png, image::ImageFormat::Png)
            .unwrap()
            .to_rgb8();
        let extras: serde_json::Value =
            serde_json::from_str(material.extras().as_ref().unwrap().get()).unwrap();
        parts.push(GlbPart {
            name: node.name().unwrap().to_string(),
            positions: r.read_positions().unwrap().map(Vec3::from).collect(),
            normals: r.read_normals().unwrap().map(Vec3::from).collect(),
            uvs: r.read_tex_coords(0).unwrap().into_f32().collect(),
            indices: r.read_indices().unwrap().into_u32().collect(),
            png,
            roughness: pbr.roughness_factor(),
            specular: material
                .specular()
                .map(|s| s.specular_factor())
                .unwrap_or(1.0),
            extras: extras["igi"].clone(),
        });
    }
    (glam::Quat::from_array(rot), parts)
}

/// The base colour at glTF `uv` (top-left origin): bilinear in linear RGB over the texel
/// centres, clamped at the edges (the sampler's CLAMP_TO_EDGE), and its 8-bit quantisation
/// bound (half a step of each texel's sRGB value, in linear, weighted as the lookup).
fn base_colour(png: &image::RgbImage, uv: [f32; 2]) -> (Vec3, Vec3) {
    let (w, h) = (png.width() as i64, png.height() as i64);
    let x = uv[0] * w as f32 - 0.5;
    let y = uv[1] * h as f32 - 0.5;
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let mut c = Vec3::ZERO;
    let mut bound = Vec3::ZERO;
    for (dx, dy, wgt) in [
        (0, 0, (1.0 - fx) * (1.0 - fy)),
        (1, 0, fx * (1.0 - fy)),
        (0, 1, (1.0 - fx) * fy),
        (1, 1, fx * fy),
    ] {
        let px = (x0 as i64 + dx).clamp(0, w - 1) as u32;
        let py = (y0 as i64 + dy).clamp(0, h - 1) as u32;
        let p = png.get_pixel(px, py).0;
        for k in 0..3 {
            let s = p[k] as f32 / 255.0;
            c[k] += wgt * srgb_to_linear(s);
            let hi = srgb_to_linear((s + 0.5 / 255.0).min(1.0)) - srgb_to_linear(s);
            let lo = srgb_to_linear(s) - srgb_to_linear((s - 0.5 / 255.0).max(0.0));
            bound[k] += wgt * hi.max(lo);
        }
    }
    (c, bound)
}

/// Points on every part's triangles (every `step`th, at six barycentric positions) in glTF's
/// scene (the root rotation applied), their glTF UVs and normals, per part.
fn surface_points(rot: glam::Quat, p: &GlbPart, step: usize) -> Vec<(Vec3, Vec3, [f32; 2])> {
    let mut out = Vec::new();
    for t in p.indices.chunks(3).step_by(step) {
        let [a, b, c] = [t[0], t[1], t[2]].map(|i| i as usize);
        for w in [
            [1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0],
            [0.6, 0.3, 0.1],
            [0.1, 0.6, 0.3],
            [0.2, 0.15, 0.65],
            [0.45, 0.45, 0.1],
            [0.05, 0.25, 0.7],
        ] {
            let pos = p.positions[a] * w[0] + p.positions[b] * w[1] + p.positions[c] * w[2];
            let e1 = p.positions[b] - p.positions[a];
            let e2 = p.positions[c] - p.positions[a];
            let n = e1.cross(e2);
            if n.length() < 1e-10 {
                continue;
            }
            let nv = p.normals[a] + p.normals[b] + p.normals[c];
            let n = if n.dot(nv) < 0.0 { -n } else { n };
            let uv = [0, 1].map(|k| p.uvs[a][k] * w[0] + p.uvs[b][k] * w[1] + p.uvs[c][k] * w[2]);
            out.push((rot * pos, rot * n.normalize(), uv));
        }
    }
    out
}

/// glTF's Y-up scene point as igi's world point (Z up): igi (x, y, z) is glTF (x, z, -y).
fn to_igi(q: Vec3) -> Vec3 {
    Vec3::new(q.x, -q.z, q.y)
}

#[test]
fn gltf_export_matches_igi_sample_passes_the_validator_and_keeps_the_result_safe() {
    let tmp = tempfile::tempdir().unwrap();
    let tmp = tmp.path();
    let res = quick_result(tmp);
    let out = tmp.join("gltf");
    let o = export(&res, "gltf", &out);
    let stdout = String::from_utf8_lossy(&o.stdout).to_string();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let glb = out.join("scene.glb");
    // the fixture's result has no lobes: every part is pure diffuse, and says so
    assert!(
        stdout.contains("part wall: no lobes: pure diffuse (roughness 1, specular 0, exact)"),
        "{stdout}"
    );
    for f in ["wall_albedo.exr", "wall_albedo.png", "export.json"] {
        assert!(out.join(f).is_file(), "{f}");
    }
    let (rot, parts) = read_glb(&glb);
    let want = glam::Quat::from_rotation_x(-std::f32::consts::FRAC_PI_2);
    assert!(rot.dot(want).abs() > 1.0 - 1e-6, "root rotation {rot}");
    assert_eq!(parts.len(), 3);
    for p in &parts {
        assert_eq!((p.roughness, p.specular), (1.0, 0.0), "{}", p.name);
        assert!(
            p.extras["fit"]["model"]
                .as_str()
                .unwrap()
                .starts_with("pure diffuse"),
            "{}",
            p.extras
        );
    }
    check_base_colour(tmp, &res, rot, &parts);
    check_validator(&glb);
    check_fitted_lobes(tmp, &res);
    check_output_folders(tmp, &res, &out);
}

/// The base colour at points of every part equals `igi sample` there within 8-bit
/// quantisation.
fn check_base_colour(tmp: &Path, res: &Path, rot: glam::Quat, parts: &[GlbPart]) {
    let mut points = Vec::new();
    for p in parts {
        for (q, n, uv) in surface_points(rot, p, 1) {
            // an underside (a block's bottom face) lies on the ground: `igi sample` may find
            // either surface there
            if to_igi(n).z < -0.5 {
                continue;
            }
            points.push((
                p.name.clone(),
                to_igi(q),
                to_igi(n),
                uv,
                base_colour(&p.png, uv),
            ));
        }
    }
    assert!(points.len() > 50, "{} points", points.len());
    let mut csv = String::from("x,y,z,nx,ny,nz\n");
    for (_, q, n, _, _) in &points {
        csv.push_str(&format!(
            "{},{},{},{},{},{}\n",
            q.x, q.y, q.z, n.x, n.y, n.z
        ));
    }
    let pts = tmp.join("glb_points.csv");
    std::fs::write(&pts, csv).unwrap();
    let vals = tmp.join("glb_values.csv");
    run_ok(
        igi()
            .arg("sample")
            .arg(res)
            .arg("--points")
            .arg(&pts)
            .arg("-o")
            .arg(&vals),
    );
    let text = std::fs::read_to_string(&vals).unwrap();
    let (mut checked, mut worst) = (0, 0.0f32);
    for (line, (name, q, _, uv, (c, bound))) in text.lines().skip(1).zip(&points) {
        let v: Vec<f32> = line
            .split(',')
            .take(9)
            .map(|s| s.parse().unwrap())
            .collect();
        let rho = Vec3::new(v[6], v[7], v[8]);
        if rho.max_element() > 1.0 {
            continue; // the PNG clips above 1
        }
        checked += 1;
        for k in 0..3 {
            let err = (c[k] - rho[k]).abs();
            worst = worst.max(err / (bound[k] + 1e-6));
            assert!(
                err <= bound[k] + 1e-5,
                "{name} at {q} (glTF uv {uv:?}): base colour {c} vs igi sample {rho} (channel {k}: {err:.2e} > 8-bit bound {:.2e})",
                bound[k]
            );
        }
    }
    eprintln!(
        "base colour vs igi sample: {checked} of {} points checked, worst error {worst:.2} of the 8-bit bound",
        points.len()
    );
    assert!(
        checked * 10 >= points.len() * 9,
        "{checked} of {}",
        points.len()
    );
}

fn check_validator(glb: &Path) {
    let r = validate(glb);
    let issues = &r["issues"];
    eprintln!(
        "glTF-Validator {}: {} errors, {} warnings, {} infos, {} hints",
        r["validatorVersion"],
        issues["numErrors"],
        issues["numWarnings"],
        issues["numInfos"],
        issues["numHints"]
    );
    assert_eq!(
        issues["numErrors"], 0,
        "glTF-Validator: {}",
        issues["messages"]
    );
    assert_eq!(r["info"]["version"], "2.0");
}

/// A copy of the result whose wall has a known glossy lobe (and the ground a retroreflective
/// one besides): the fit's error is printed, small for the glossy lobe, and kept in extras with
/// the exact lobes.
fn check_fitted_lobes(tmp: &Path, res: &Path) {
    let glossy = tmp.join("res-glossy");
    std::fs::create_dir_all(glossy.join("parts")).unwrap();
    for e in std::fs::read_dir(res).unwrap() {
        let e = e.unwrap();
        if e.file_type().unwrap().is_file() {
            std::fs::copy(e.path(), glossy.join(e.file_name())).unwrap();
        }
    }
    for e in std::fs::read_dir(res.join("parts")).unwrap() {
        let e = e.unwrap();
        std::fs::copy(e.path(), glossy.join("parts").join(e.file_name())).unwrap();
    }
    std::fs::write(
        glossy.join("parts/wall_lobes.json"),
        r#"[{"rho": [0.1, 0.1, 0.1], "cxy": -1.0, "cz": 1.0, "n": 30.0}]"#,
    )
    .unwrap();
    std::fs::write(
        glossy.join("parts/ground_lobes.json"),
        r#"[{"rho": [0.1, 0.1, 0.1], "cxy": -1.0, "cz": 1.0, "n": 30.0}, {"rho": [0.05, 0.05, 0.05], "cxy": 0.9, "cz": 0.9, "n": 10.0}]"#,
    )
    .unwrap();
    let out = tmp.join("gltf-glossy");
    let o = export(&glossy, "gltf", &out);
    let stdout = String::from_utf8_lossy(&o.stdout).to_string();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    eprintln!("{stdout}");
    let error_of = |part: &str| -> f32 {
        let line = stdout
            .lines()
            .find(|l| l.starts_with(&format!("part {part}:")))
            .unwrap_or_else(|| panic!("{stdout}"));
        let pc = line
            .split("fit error ")
            .nth(1)
            .unwrap()
            .split('%')
            .next()
            .unwrap();
        pc.parse::<f32>().unwrap() / 100.0
    };
    let (wall, ground) = (error_of("wall"), error_of("ground"));
    assert!(wall > 0.0 && wall < 0.25, "wall fit error {wall}");
    assert!(
        stdout.contains("1 retroreflective lobe(s) folded in"),
        "{stdout}"
    );
    let (_, parts) = read_glb(&out.join("scene.glb"));
    let wall_p = parts.iter().find(|p| p.name == "wall").unwrap();
    assert!(wall_p.specular > 0.0 && wall_p.roughness < 1.0);
    let fit = &wall_p.extras["fit"];
    assert!(
        (fit["rel_rms"].as_f64().unwrap() as f32 - wall).abs() < 6e-4,
        "{fit}"
    );
    let lobe = &wall_p.extras["lobes"][0];
    assert_eq!(lobe["n"], 30.0);
    assert_eq!(lobe["cxy"], -1.0);
    let ground_p = parts.iter().find(|p| p.name == "ground").unwrap();
    assert_eq!(ground_p.extras["lobes"][1]["kind"], "retroreflective");
    assert!(
        ground_p.extras["fit"]["retroreflective"]
            .as_str()
            .unwrap()
            .contains("folded"),
        "{}",
        ground_p.extras
    );
    // the retroreflective lobe cannot be expressed: the ground fits worse than the wall
    assert!(ground > wall, "ground {ground} vs wall {wall}");
    // the block kept no lobes: pure diffuse
    let block = parts.iter().find(|p| p.name == "block").unwrap();
    assert_eq!((block.roughness, block.specular), (1.0, 0.0));
    check_validator(&out.join("scene.glb"));
}

/// Every file under `dir` with its bytes.
fn snapshot(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    let mut v = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                v.push((p.clone(), std::fs::read(&p).unwrap()));
            }
        }
    }
    v.sort();
    v
}

fn refused(o: &std::process::Output, needle: &str) {
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "accepted; stderr: {err}");
    assert!(err.contains(needle), "expected `{needle}` in: {err}");
}

/// The output folder's rules, checked before the first byte.
fn check_output_folders(tmp: &Path, res: &Path, earlier: &Path) {
    let before = snapshot(res);
    // the result folder itself, and a folder inside it
    for (out, needle) in [
        (res.to_path_buf(), "is the result folder"),
        (res.join("export"), "lies inside the result folder"),
        (res.join("parts/../x"), "lies inside the result folder"),
    ] {
        for fmt in ["gltf", "ply"] {
            refused(&export(res, fmt, &out), needle);
        }
    }
    assert!(snapshot(res) == before, "the result folder changed");
    // a folder holding other files
    let busy = tmp.join("busy");
    std::fs::create_dir_all(&busy).unwrap();
    std::fs::write(busy.join("notes.txt"), "mine").unwrap();
    refused(&export(res, "gltf", &busy), "holds no earlier igi export");
    assert_eq!(
        snapshot(&busy).len(),
        1,
        "nothing written into the refused folder"
    );
    // an earlier export with a file of someone else's
    std::fs::write(earlier.join("notes.txt"), "mine").unwrap();
    let had = snapshot(earlier);
    refused(&export(res, "ply", earlier), "notes.txt");
    assert!(snapshot(earlier) == had, "the refused folder changed");
    std::fs::remove_file(earlier.join("notes.txt")).unwrap();
    // an earlier export alone is replaced whole: a PLY export leaves no GLB behind
    let o = export(res, "ply", earlier);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(!earlier.join("scene.glb").exists(), "two exports mixed");
    assert!(earlier.join("wall.ply").is_file());
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(earlier.join("export.json")).unwrap())
            .unwrap();
    assert_eq!(m["format"], "ply");
    let listed: Vec<&str> = m["files"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f.as_str().unwrap())
        .collect();
    let mut present: Vec<String> = std::fs::read_dir(earlier)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n != "export.json")
        .collect();
    present.sort();
    assert_eq!(
        present, listed,
        "export.json lists exactly the folder's files"
    );
    // and no staging folder is left beside it
    let leftovers: Vec<_> = std::fs::read_dir(tmp)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains("partial"))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
    // an empty folder is fine, and a staging folder a killed export to it left is removed
    let empty = tmp.join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    let host = std::fs::read_to_string("/proc/sys/kernel/hostname").unwrap();
    let host: String = host
        .trim()
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' {
                c
            } else {
                'x'
            }
        })
        .collect();
    let max_pid: u32 = std::fs::read_to_string("/proc/sys/kernel/pid_max")
        .unwrap()
        .trim()
        .parse()
        .unwrap();
    // a process id above the largest the kernel hands out: never a running process
    let stale = tmp.join(format!(".empty.igi-export-{host}-{}.partial", max_pid + 1));
    std::fs::create_dir_all(&stale).unwrap();
    std::fs::write(stale.join("scene.glb"), "half").unwrap();
    let o = export(res, "gltf", &empty);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        !stale.exists(),
        "the killed export's staging folder is left"
    );
}

/// The JSON and BIN chunks of a GLB, through the `gltf` crate.
fn glb_doc(path: &Path) -> (gltf::Gltf, Vec<u8>) {
    let bytes = std::fs::read(path).unwrap();
    let g = gltf::Gltf::from_slice(&bytes).expect("the gltf crate reads the GLB");
    let blob = g.blob.clone().expect("a BIN chunk");
    (g, blob)
}

/// An opacity hull of 8 views around a sphere of radius 0.3 whose photographs are the colour
/// (0.5, 0.4, 0.3) inside its silhouette (`cli_hull`'s rig), built by `igi hull build`.
pub(crate) fn sphere_hull(tmp: &Path) -> PathBuf {
    let rig = crate::cli_hull::make_rig(&tmp.join("cap"), 8, &|_, _| {});
    let hull = tmp.join("hull");
    run_ok(igi().args(["hull", "build"]).arg(&rig).arg("-o").arg(&hull));
    hull
}

/// A surface light field on a sphere of radius 0.5 (a 32 x 32 atlas) whose median radiance is
/// a known function of each grid point's position, saved through `igi_lightfield::store`;
/// returns the folder and each grid point's texel and median.
pub(crate) fn sphere_light_field(tmp: &Path) -> (PathBuf, Vec<(u32, Vec3)>) {
    use igi_geometry::atlas::{build_atlas, AtlasOptions};
    let mesh = igi_geometry::procedural::uv_sphere(8, 16, 0.5);
    let atlas = build_atlas(
        &mesh,
        AtlasOptions {
            resolution: 32,
            gutter: 1,
        },
    )
    .unwrap();
    let mut points = Vec::new();
    for (t, c) in atlas.coverage.pixels.iter().enumerate() {
        if c[0] == 1.0 {
            let p = Vec3::from(atlas.position.pixels[t]);
            points.push((t as u32, Vec3::new(2.0 + 2.0 * p.x, 1.0 + p.y, 1.5 - p.z)));
        }
    }
    let field = igi_lightfield::SurfaceLightField::new(
        igi_lightfield::Octahedron::new(2),
        32,
        points.iter().map(|p| p.0).collect(),
        points.iter().map(|p| p.1).collect(),
        vec![Vec3::Z; points.len()],
        igi_lightfield::field::Coding::MedianOnly,
    );
    let dir = tmp.join("slf");
    igi_lightfield::store::save(&dir, &field, &atlas.mesh, serde_json::json!({})).unwrap();
    (dir, points)
}

/// Hull and light-field folders export as glTF (issue 35 item 1, "hulls and the light
/// field's median texture export too"): the hull's surfels as points with the photographs'
/// colour (the opaque surfels' median and 95th-percentile error printed and bounded) and its
/// surface as a mesh, the light field's mesh with its median as the texture;
/// both pass the validator; a folder that is none of result, hull and light field, and a hull
/// asked for as PLY, are refused.
#[test]
fn hull_and_light_field_folders_export_as_gltf() {
    let tmp = tempfile::tempdir().unwrap();

    // the hull: every surfel seen by some view has the photographs' colour
    let hull = sphere_hull(tmp.path());
    let out = tmp.path().join("hull_gltf");
    let o = export(&hull, "gltf", &out);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    check_validator(&out.join("scene.glb"));
    let (g, blob) = glb_doc(&out.join("scene.glb"));
    let surfels = igi_geometry::read_points_ply(&hull.join("surfels.ply")).unwrap();
    let hull_mesh = igi_geometry::read_mesh(&hull.join("hull.ply")).unwrap();
    let mut seen = 0;
    let mut errs: Vec<f32> = Vec::new();
    let mut found_mesh = false;
    for mesh in g.meshes() {
        let prim = mesh.primitives().next().unwrap();
        let r = prim.reader(|_| Some(&blob[..]));
        let pos: Vec<Vec3> = r.read_positions().unwrap().map(Vec3::from).collect();
        match mesh.name() {
            Some("surfels") => {
                assert_eq!(prim.mode(), gltf::mesh::Mode::Points);
                assert_eq!(pos.len(), surfels.positions.len());
                let colours: Vec<[f32; 4]> = r.read_colors(0).unwrap().into_rgba_f32().collect();
                for (p, c) in pos.iter().zip(&colours) {
                    // on the hull of a sphere of radius 0.3 carved from 8 views
                    assert!((p.length() - 0.3).abs() < 0.08, "surfel at {p}");
                    if c[3] > 0.5 {
                        seen += 1;
                        let err = (Vec3::new(c[0], c[1], c[2]) - Vec3::new(0.5, 0.4, 0.3)).abs();
                        errs.push(err.max_element());
                    }
                }
            }
            Some("hull") => {
                found_mesh = true;
                assert_eq!(prim.mode(), gltf::mesh::Mode::Triangles);
                assert_eq!(pos.len(), hull_mesh.positions.len());
                let idx = r.read_indices().unwrap().into_u32().count();
                assert_eq!(idx, 3 * hull_mesh.indices.len());
            }
            other => panic!("unexpected mesh {other:?}"),
        }
    }
    assert!(found_mesh, "no hull surface in the GLB");
    assert!(seen * 2 > surfels.positions.len(), "{seen} opaque surfels");
    errs.sort_by(f32::total_cmp);
    let (median, p95) = (errs[errs.len() / 2], errs[errs.len() * 95 / 100]);
    eprintln!(
        "hull: {} surfels, {seen} opaque; their colour off the photographs' by {median:.4} (median), {p95:.4} (95th percentile), {:.4} (worst)",
        surfels.positions.len(),
        errs[errs.len() - 1]
    );
    // surfels at a view's silhouette take that view's border pixels, part background: the
    // bulk is the photographs' colour, the tail is the silhouette's
    assert!(median < 0.03 && p95 < 0.2, "{median} {p95}");

    // the light field: its median is the texture at each grid point's texel
    let (slf, points) = sphere_light_field(tmp.path());
    let out = tmp.path().join("slf_gltf");
    let o = export(&slf, "gltf", &out);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    check_validator(&out.join("scene.glb"));
    let (g, blob) = glb_doc(&out.join("scene.glb"));
    let material = g.materials().next().unwrap();
    let extras: serde_json::Value =
        serde_json::from_str(material.extras().as_ref().unwrap().get()).unwrap();
    let scale = extras["igi"]["median_scale"].as_f64().unwrap() as f32;
    let tex = material
        .pbr_metallic_roughness()
        .base_color_texture()
        .unwrap();
    let gltf::image::Source::View { view, .. } = tex.texture().source().source() else {
        panic!("embedded")
    };
    let png = image::load_from_memory(&blob[view.offset()..view.offset() + view.length()])
        .unwrap()
        .to_rgb8();
    assert_eq!(png.dimensions(), (32, 32));
    // the texture at each grid point's texel is the median the folder stores (8 bits of its
    // own, median.bin) x median_scale, within half an 8-bit sRGB step; the median given
    // before the store's quantisation is printed beside it
    let (stored, _) = igi_lightfield::store::load(&slf).unwrap();
    assert_eq!(stored.texels.len(), points.len());
    let half_steps = |t: u32, m: Vec3| {
        let px = png.get_pixel(t % 32, t / 32).0;
        (0..3)
            .map(|c| {
                let want = (m[c] * scale).clamp(0.0, 1.0);
                let got = srgb_to_linear(px[c] as f32 / 255.0);
                let step = if want >= got {
                    srgb_to_linear((px[c] as f32 + 0.5) / 255.0) - got
                } else {
                    got - srgb_to_linear((px[c] as f32 - 0.5) / 255.0)
                };
                (got - want).abs() / step.max(1e-9)
            })
            .fold(0.0f32, f32::max)
    };
    let worst_stored = stored
        .texels
        .iter()
        .zip(&stored.median)
        .map(|(&t, &m)| half_steps(t, m))
        .fold(0.0f32, f32::max);
    let worst_given = points
        .iter()
        .map(|&(t, m)| half_steps(t, m))
        .fold(0.0f32, f32::max);
    eprintln!(
        "light field: {} grid points' texture off the stored median by at most {worst_stored:.3} half 8-bit steps ({worst_given:.2} off the median before the store's quantisation)",
        points.len()
    );
    assert!(
        worst_stored <= 1.0 + 1e-3,
        "the texture is {worst_stored} half-steps off the stored median"
    );
    // the mesh's UVs flipped to glTF's top-left origin
    let mesh = igi_geometry::read_mesh(&slf.join("mesh.ply")).unwrap();
    let prim = g.meshes().next().unwrap().primitives().next().unwrap();
    let uv: Vec<[f32; 2]> = prim
        .reader(|_| Some(&blob[..]))
        .read_tex_coords(0)
        .unwrap()
        .into_f32()
        .collect();
    for (a, b) in uv.iter().zip(mesh.uvs.as_ref().unwrap()) {
        assert!((a[0] - b[0]).abs() < 1e-6 && (a[1] - (1.0 - b[1])).abs() < 1e-6);
    }

    // refused: a folder of something else; a hull as PLY
    let other = tmp.path().join("other");
    std::fs::create_dir_all(&other).unwrap();
    std::fs::write(other.join("notes.txt"), "x").unwrap();
    let o = export(&other, "gltf", &tmp.path().join("o1"));
    refused(
        &o,
        "not a result folder of `igi solve` (report.json and parts/), an opacity-hull folder",
    );
    assert!(!tmp.path().join("o1").exists());
    let o = export(&hull, "ply", &tmp.path().join("o2"));
    refused(&o, "a hull folder exports only as glTF");
    assert!(!tmp.path().join("o2").exists());
}

/// A prepared site: the procedural colonnade's stylobate (`igi_geometry::procedural`, as `igi
/// demo` builds it) and its terrain, `igi prepare --atlas 32` (16 voxels of 4.3 m and the
/// terrain, 3 levels), solved with the survey fixture's photographs (one iteration, 4 samples
/// per pixel; most voxels unseen and filled); returns the result folder and the site's
/// manifest.
pub(crate) fn prepared_result(tmp: &Path) -> (PathBuf, serde_json::Value) {
    let site_meshes = igi_geometry::procedural::colonnade_site(1, 1);
    let mesh = |name: &str| {
        let path = tmp.join(format!("{name}.ply"));
        let m = &site_meshes.iter().find(|m| m.0 == name).unwrap().1;
        igi_geometry::write_ply(&path, m).unwrap();
        path
    };
    let site = tmp.join("site.igi");
    run_ok(
        igi()
            .arg("-q")
            .arg("prepare")
            .arg(mesh("stylobate"))
            .arg("--terrain")
            .arg(mesh("terrain"))
            .args(["--atlas", "32", "-o"])
            .arg(&site),
    );
    // the fixture's photographs, by absolute path
    let text = std::fs::read_to_string(fixture().join("survey.toml")).unwrap();
    let mut photos = text[text.find("[[photo]]").unwrap()..].to_string();
    for folder in ["photos/", "cameras/", "lighting/"] {
        let abs = format!("\"{}/{folder}", fixture().display());
        photos = photos.replace(&format!("\"{folder}"), &abs);
    }
    let prepared = tmp.join("prepared.toml");
    let site_name = site.display().to_string();
    std::fs::write(
        &prepared,
        format!("[site]\nprepared = {site_name:?}\n\n{photos}"),
    )
    .unwrap();
    let res = tmp.join("prepared-result");
    run_ok(igi().arg("solve").arg(&prepared).arg("-o").arg(&res).args([
        "--spp",
        "4",
        "--iterations",
        "1",
        "--quiet",
    ]));
    let man = serde_json::from_str(&std::fs::read_to_string(site.join("manifest.json")).unwrap())
        .unwrap();
    (res, man)
}

/// Runs the Khronos glTF-Validator on every file of `glbs` in one node process: per file its
/// number of errors and warnings.
fn validate_all(glbs: &[PathBuf]) -> Vec<(u64, u64)> {
    let dir = tempfile::tempdir().unwrap();
    let script = dir.path().join("validate_all.js");
    std::fs::write(
        &script,
        "const v = require(process.argv[2]);\n\
         const fs = require('fs');\n\
         (async () => { for (const f of process.argv.slice(3)) {\n\
           const r = await v.validateBytes(new Uint8Array(fs.readFileSync(f)), {maxIssues: 100});\n\
           if (r.issues.numErrors > 0) console.error(f + ': ' + JSON.stringify(r.issues.messages));\n\
           console.log(r.issues.numErrors + ' ' + r.issues.numWarnings);\n\
         } })().catch(e => { console.error('validator failed: ' + e); process.exit(2); });\n",
    )
    .unwrap();
    let out = Command::new("node")
        .arg(&script)
        .arg(validator())
        .args(glbs)
        .output()
        .unwrap_or_else(|e| panic!("node (needed to run the glTF-Validator) cannot run: {e}"));
    assert!(
        out.status.success(),
        "glTF-Validator: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let counts: Vec<(u64, u64)> = String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| {
            let (e, w) = l.split_once(' ').unwrap();
            (e.parse().unwrap(), w.parse().unwrap())
        })
        .collect();
    assert_eq!(
        counts.len(),
        glbs.len(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    counts
}

/// A column-major 4 x 4 matrix from a tileset's `transform`.
fn mat4(v: &serde_json::Value) -> glam::DMat4 {
    let a: Vec<f64> = v
        .as_array()
        .expect("a transform array")
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    assert_eq!(a.len(), 16, "a transform has 16 numbers");
    glam::DMat4::from_cols_slice(&a)
}

/// One tile of a tileset, flattened: its part and level (from the GLB's name), bounding box
/// (centre, half axes), geometric error, content and depth in its part's chain.
struct Tile {
    part_level: Option<(String, usize)>,
    centre: glam::DVec3,
    half: [glam::DVec3; 3],
    error: f64,
    uri: Option<String>,
    leaf: bool,
}

/// Checks the 3D Tiles 1.1 schema's required fields of `t` and its children, that each
/// child's geometric error is at most its parent's, and flattens the tree into `out`.
fn walk_tiles(t: &serde_json::Value, parent_error: f64, out: &mut Vec<Tile>) {
    let b: Vec<f64> = t["boundingVolume"]["box"]
        .as_array()
        .expect("boundingVolume.box")
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    assert_eq!(b.len(), 12, "a box has 12 numbers");
    assert!(b.iter().all(|x| x.is_finite()));
    let error = t["geometricError"].as_f64().expect("geometricError");
    assert!(
        error >= 0.0 && error <= parent_error,
        "geometricError {error} above its parent's {parent_error}"
    );
    if let Some(r) = t.get("refine") {
        assert!(r == "REPLACE" || r == "ADD", "refine {r}");
    }
    let uri = t.get("content").map(|c| {
        c["uri"]
            .as_str()
            .expect("content.uri is required")
            .to_string()
    });
    let kids = t.get("children").map_or(&[][..], |c| {
        let c = c.as_array().expect("children is an array");
        assert!(!c.is_empty(), "children has at least one tile");
        c.as_slice()
    });
    let part_level = uri.as_ref().map(|u| {
        let stem = u.strip_suffix(".glb").expect("a GLB");
        let (name, level) = stem.rsplit_once("_level").expect("NAME_levelL.glb");
        (name.to_string(), level.parse().unwrap())
    });
    out.push(Tile {
        part_level,
        centre: glam::DVec3::new(b[0], b[1], b[2]),
        half: [
            glam::DVec3::new(b[3], b[4], b[5]),
            glam::DVec3::new(b[6], b[7], b[8]),
            glam::DVec3::new(b[9], b[10], b[11]),
        ],
        error,
        uri,
        leaf: kids.is_empty(),
    });
    for k in kids {
        walk_tiles(k, error, out);
    }
}

/// A prepared site exports as 3D Tiles 1.1 (issue 35 item 1): a GLB per part and level, each
/// passing the glTF-Validator; `tileset.json` has the schema's required fields, its bounding
/// boxes hold every vertex of their GLB (through the GLB's root rotation, 3D Tiles' Y up to Z
/// up and the root transform), its geometric errors fall to 0 at the leaves, and every part
/// of the result is there once, at every level of the prepared site.
#[test]
fn a_prepared_site_exports_as_3d_tiles() {
    let tmp = tempfile::tempdir().unwrap();
    let (res, man) = prepared_result(tmp.path());
    let out = tmp.path().join("tiles");
    let o = export(&res, "gltf", &out);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        !out.join("scene.glb").exists(),
        "a prepared site has no single GLB"
    );
    let set: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("tileset.json")).unwrap()).unwrap();
    // required: asset.version, geometricError, root (boundingVolume, geometricError, refine)
    assert_eq!(set["asset"]["version"], "1.1");
    let top = set["geometricError"].as_f64().expect("geometricError");
    let root = &set["root"];
    assert!(root["refine"] == "REPLACE", "the root's refine is required");
    let transform = mat4(&root["transform"]);
    let mut tiles = Vec::new();
    walk_tiles(root, top, &mut tiles);

    // every part of the result once, at every level of the prepared site
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(res.join("report.json")).unwrap()).unwrap();
    let mut names: Vec<String> = report["parts"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["name"].as_str().unwrap().to_string())
        .collect();
    names.sort();
    let levels = man["levels"].as_array().unwrap().len();
    assert_eq!(levels, 3);
    assert_eq!(names.len(), man["voxels"].as_array().unwrap().len() + 1);
    let mut leaves: Vec<String> = tiles
        .iter()
        .filter(|t| t.leaf)
        .map(|t| {
            let (n, l) = t.part_level.clone().expect("a leaf has content");
            assert_eq!(l, 0, "a leaf is level 0");
            assert_eq!(t.error, 0.0, "a leaf's geometric error is 0");
            n
        })
        .collect();
    leaves.sort();
    assert_eq!(leaves, names, "each part once, as a leaf");
    let with_content: Vec<&Tile> = tiles.iter().filter(|t| t.uri.is_some()).collect();
    assert_eq!(with_content.len(), names.len() * levels);
    // the chain of a part: coarser levels above, geometric errors not increasing downward
    // (walk_tiles), and the coarsest one positive where the site simplified the part
    let coarse_errors: Vec<f64> = tiles
        .iter()
        .filter(|t| t.part_level.as_ref().is_some_and(|p| p.1 == levels - 1))
        .map(|t| t.error)
        .collect();
    assert!(coarse_errors.iter().all(|e| *e > 0.0), "{coarse_errors:?}");

    // every GLB validates; every vertex lies in its tile's box
    let glbs: Vec<PathBuf> = with_content
        .iter()
        .map(|t| out.join(t.uri.as_ref().unwrap()))
        .collect();
    let counts = validate_all(&glbs);
    let errors: u64 = counts.iter().map(|c| c.0).sum();
    let warnings: u64 = counts.iter().map(|c| c.1).sum();
    eprintln!(
        "3D Tiles: {} parts x {levels} levels = {} GLBs, glTF-Validator {errors} errors, {warnings} warnings",
        names.len(),
        glbs.len()
    );
    assert_eq!(errors, 0);
    let y_up_to_z_up = glam::DMat4::from_cols_array(&[
        1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0,
    ]);
    let (mut vertices, mut worst) = (0usize, f64::NEG_INFINITY);
    for (t, glb) in with_content.iter().zip(&glbs) {
        let (rot, parts) = read_glb(glb);
        assert_eq!(parts.len(), 1, "{}: one part", glb.display());
        let (name, level) = t.part_level.clone().unwrap();
        assert_eq!(parts[0].name, name);
        // level 0 is the prepared site's full mesh
        if level == 0 {
            let entry = man["voxels"]
                .as_array()
                .unwrap()
                .iter()
                .find(|e| {
                    let v = &e["voxel"];
                    format!("{}_{}_{}", v[0], v[1], v[2]) == name
                })
                .unwrap_or(&man["terrain"]);
            assert_eq!(
                parts[0].indices.len(),
                3 * entry["triangles"][0].as_u64().unwrap() as usize,
                "{name}"
            );
        }
        let rot = glam::DQuat::from_xyzw(rot.x as f64, rot.y as f64, rot.z as f64, rot.w as f64);
        for p in &parts[0].positions {
            let gltf_world = rot * p.as_dvec3();
            let q = transform.transform_point3(y_up_to_z_up.transform_point3(gltf_world));
            // the igi point itself (to the f32 rotation's rounding): the tileset's frame is
            // igi's, so the boxes are checked on p
            assert!((q - p.as_dvec3()).length() < 1e-5, "{q} against {p}");
            // inside the box: |(p - c) . a_k| <= |a_k|^2 for each half axis a_k
            for a in &t.half {
                let over = (p.as_dvec3() - t.centre).dot(*a).abs() / a.length_squared() - 1.0;
                worst = worst.max(over);
            }
            vertices += 1;
        }
    }
    eprintln!("3D Tiles: {vertices} vertices, the largest (|(q - c) . a| / |a|^2 - 1) {worst:.3e} (<= 0 inside)");
    assert!(worst <= 1e-9, "a vertex outside its tile's box by {worst}");
}

/// A result whose report lists no parts, a part twice or a part named with a path separator
/// (whose files would lie outside `parts/`) is refused naming the report, nothing written; the
/// same folder with its own report exports.
#[test]
fn a_result_report_whose_parts_cannot_be_read_is_refused_naming_it() {
    let tmp = tempfile::tempdir().unwrap();
    let res = quick_result(tmp.path());
    let rp = res.join("report.json");
    let good = std::fs::read_to_string(&rp).unwrap();
    let report: serde_json::Value = serde_json::from_str(&good).unwrap();
    type Edit = fn(&mut serde_json::Value);
    let edits: [(&str, Edit); 3] = [
        ("the result holds no parts", |r| {
            r["parts"] = serde_json::json!([])
        }),
        ("two parts of the result are both named `ground`", |r| {
            r["parts"][1] = r["parts"][0].clone()
        }),
        ("`../../ground` cannot name a part", |r| {
            r["parts"][0]["name"] = "../../ground".into()
        }),
    ];
    for (k, (says, edit)) in edits.iter().enumerate() {
        let mut r = report.clone();
        edit(&mut r);
        std::fs::write(&rp, r.to_string()).unwrap();
        let out = tmp.path().join(format!("out{k}"));
        let o = export(&res, "gltf", &out);
        refused(&o, &format!("report.json: invalid input: {says}"));
        assert!(!out.exists());
    }
    std::fs::write(&rp, good).unwrap();
    let o = export(&res, "gltf", &tmp.path().join("ok"));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}
