//! `igi view` (issue 35, item 2) in a real browser: Debian's `chromium`, headless, WebGL through
//! SwiftShader (`--use-gl=angle --use-angle=swiftshader --enable-unsafe-swiftshader`). A missing
//! chromium fails the test with the reason (`bash scripts/deps.sh test` installs it).
//!
//! * The first line of standard output is `http://127.0.0.1:PORT/`; the page loads the result
//!   as glTF through three.js's GLTFLoader and its title becomes `igi: ready` once the first
//!   frame is drawn; a screenshot at 1024 x 768 shows the site (its pixels differ from the
//!   empty page's sky colour).
//! * Bad input: a folder that is not a result; a port in use; a path outside the folder.

use crate::cli_gltf::{prepared_result, quick_result, sphere_hull, sphere_light_field};
use igi_testkit::run_ok;
use std::io::{BufRead, BufReader, Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};

fn igi() -> Command {
    igi_testkit::Cli::new(env!("CARGO_BIN_EXE_igi")).command()
}

/// A running `igi view`, its URL and the lines of its standard error; killed when dropped.
/// Lines that are not the page's (`RUST_LOG=igi_view=debug`: the requests) are kept apart.
struct Served(
    Child,
    String,
    std::sync::mpsc::Receiver<String>,
    std::cell::RefCell<Vec<String>>,
);

impl Drop for Served {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn serve(dir: &Path, port: &str, lightings: &[PathBuf]) -> Served {
    serve_with(dir, port, lightings, &[])
}

fn serve_with(dir: &Path, port: &str, lightings: &[PathBuf], extra: &[&str]) -> Served {
    let mut child = igi()
        .env("RUST_LOG", "igi_view=debug")
        .arg("view")
        .arg(dir)
        .args(["--port", port])
        .args(lightings.iter().flat_map(|l| [Path::new("--lighting"), l]))
        .args(extra)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    let url = line.trim().to_string();
    assert!(
        url.starts_with("http://127.0.0.1:") && url.ends_with('/'),
        "first line {url:?}"
    );
    let (tx, rx) = std::sync::mpsc::channel();
    let stderr = BufReader::new(child.stderr.take().unwrap());
    std::thread::spawn(move || {
        for line in stderr.lines().map_while(Result::ok) {
            let _ = tx.send(line);
        }
    });
    Served(child, url, rx, Default::default())
}

/// The page's messages (`page: ...` lines of igi's standard error) until `until` holds for one,
/// or the time is up.
fn page_says(served: &Served, until: impl Fn(&str) -> bool, secs: u64) -> Vec<String> {
    let end = std::time::Instant::now() + std::time::Duration::from_secs(secs);
    let mut said = vec![];
    while let Some(left) = end.checked_duration_since(std::time::Instant::now()) {
        match served.2.recv_timeout(left) {
            Ok(line) if !line.starts_with("page: ") => served.3.borrow_mut().push(line),
            Ok(line) => {
                let done = until(&line);
                said.push(line);
                if done {
                    break;
                }
            }
            Err(_) => break,
        }
    }
    said
}

/// The raw HTTP answer to `request` sent to the server at `url`.
fn http(url: &str, request: &str) -> String {
    let addr = url.trim_start_matches("http://").trim_end_matches('/');
    let mut s = std::net::TcpStream::connect(addr).unwrap();
    s.write_all(request.as_bytes()).unwrap();
    let mut out = Vec::new();
    s.read_to_end(&mut out).unwrap();
    String::from_utf8_lossy(&out).into_owned()
}

/// The status code of a raw HTTP answer.
fn status(answer: &str) -> u16 {
    let line = answer.lines().next().unwrap_or("");
    line.split(' ')
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or(0)
}

fn chromium() -> PathBuf {
    let path = PathBuf::from("/usr/bin/chromium");
    assert!(
        path.exists(),
        "chromium is missing: the browser test needs Debian's chromium (`bash scripts/deps.sh test` installs it)"
    );
    path
}

/// Headless chromium on `url` with `extra` flags and its own profile in `profile` (so that
/// browsers of tests running side by side never share one; the caller's temporary folder,
/// removed after the browser has gone).
fn chromium_command(url: &str, extra: &[&str], profile: &Path) -> Command {
    let mut c = Command::new(chromium());
    c.arg(format!("--user-data-dir={}", profile.display()));
    c.args([
        "--headless=new",
        "--no-sandbox",
        "--use-gl=angle",
        "--use-angle=swiftshader",
        "--enable-unsafe-swiftshader",
        "--window-size=1024,768",
    ])
    .args(extra)
    .arg(url)
    .stdout(Stdio::null())
    .stderr(Stdio::null());
    c
}

/// Opens `url` of `served` in headless chromium (with `extra` flags) and returns the page's
/// messages until `until` holds for one or `secs` pass. A launch from which not one message
/// arrives is killed, the end of its verbose log and what the server logged printed, and the
/// browser launched again (three launches at most; docs/VIEW.md); a page that reports and
/// then stops has what chromium and the server logged printed, and is not retried.
fn open_page(
    served: &Served,
    url: &str,
    extra: &[&str],
    until: impl Fn(&str) -> bool,
    secs: u64,
) -> Vec<String> {
    let mut said = Vec::new();
    for attempt in 0..3 {
        let log = std::env::temp_dir().join(format!(
            "igi-chromium-{}-{attempt}-{}.log",
            std::process::id(),
            served
                .1
                .rsplit(':')
                .next()
                .unwrap_or("")
                .trim_end_matches('/')
        ));
        let profile = tempfile::tempdir().unwrap();
        let mut browser = chromium_command(url, extra, profile.path())
            .args(["--enable-logging=stderr", "--v=1"])
            .stderr(std::fs::File::create(&log).unwrap())
            .spawn()
            .unwrap();
        said = page_says(served, &until, secs);
        let exited = browser.try_wait().ok().flatten();
        let _ = browser.kill();
        let _ = browser.wait();
        let text = std::fs::read_to_string(&log).unwrap_or_default();
        let _ = std::fs::remove_file(&log);
        if !said.is_empty() {
            if !said.iter().any(|l| until(l)) {
                // what the browser logged of the page that never got there
                let notes: Vec<&str> = text
                    .lines()
                    .filter(|l| {
                        ["ERROR", "CONSOLE", "GPU", "crash", "lost"]
                            .iter()
                            .any(|k| l.contains(k))
                    })
                    .collect();
                let from = notes.len().saturating_sub(40);
                println!(
                    "{url}: the page stopped after {said:?}; chromium logged:\n{}",
                    notes[from..].join("\n")
                );
                let other = served.3.borrow();
                let from = other.len().saturating_sub(60);
                println!("the server logged:\n{}", other[from..].join("\n"));
            }
            break;
        }
        let tail: Vec<&str> = text.lines().rev().take(25).collect();
        let other = served.3.borrow();
        let from = other.len().saturating_sub(60);
        println!(
            "launch {} of chromium never reached {url} in {secs} s (exited by itself: {exited:?}); the end of its log:\n{}\nthe server logged:\n{}",
            attempt + 1,
            tail.into_iter().rev().collect::<Vec<_>>().join("\n"),
            other[from..].join("\n")
        );
    }
    said
}

/// Opens `url` of `served` until the page's title settles (`igi: ...`), asserts that it is
/// `igi: ready` (naming `label`), and returns what the page said.
fn open_until_ready(served: &Served, url: &str, label: &str) -> Vec<String> {
    open_until_told(served, url, label, &[])
}

/// [`open_until_ready`], waiting also for a message starting with each of `also`: the page
/// sends each message in a request of its own, so they may reach the server in any order (a
/// measurement made in the first frame can arrive after the title that frame set).
fn open_until_told(served: &Served, url: &str, label: &str, also: &[&str]) -> Vec<String> {
    let seen = std::cell::RefCell::new(vec![false; also.len() + 1]);
    let said = open_page(
        served,
        url,
        &[],
        |l| {
            let mut seen = seen.borrow_mut();
            if l.starts_with("page: title=igi: error") {
                return true;
            }
            seen[0] |= l == "page: title=igi: ready";
            for (k, prefix) in also.iter().enumerate() {
                seen[k + 1] |= l.starts_with(&format!("page: {prefix}"));
            }
            seen.iter().all(|s| *s)
        },
        180,
    );
    assert!(
        said.iter().any(|l| l == "page: title=igi: ready"),
        "{label}: the page never became ready: {said:?}"
    );
    said
}

#[test]
fn a_result_opens_in_a_real_browser() {
    let tmp = tempfile::tempdir().unwrap();
    let res = quick_result(tmp.path());
    let fixture = Path::new(env!("CARGO_MANIFEST_DIR")).join("datasets/fixtures/survey/lighting");
    let lightings = ["sunny", "lowsun"].map(|n| fixture.join(format!("{n}.toml")));
    let served = serve(&res, "0", &lightings);
    // The page tells the server its title as it changes and, each second, its frame time.
    let fixed = format!("{}?width=1024&height=768&lighting=1", served.1);
    let unlimited = ["--disable-gpu-vsync", "--disable-frame-rate-limit"];
    let frames = std::cell::Cell::new(0);
    let said = open_page(
        &served,
        &fixed,
        &unlimited,
        |l| {
            frames.set(frames.get() + l.starts_with("page: frame_ms=") as usize);
            frames.get() == 4
        },
        180,
    );
    assert!(
        said.iter().any(|l| l == "page: title=igi: ready"),
        "the page never became ready: {said:?}"
    );
    assert!(!said.iter().any(|l| l.contains("igi: error")), "{said:?}");
    assert!(
        said.iter().any(|l| l == "page: lighting=lowsun"),
        "{said:?}"
    );
    let frames: Vec<&String> = said
        .iter()
        .filter(|l| l.starts_with("page: frame_ms="))
        .collect();
    assert!(!frames.is_empty(), "no frame time: {said:?}");
    for f in &frames {
        assert!(f.ends_with("&width=1024&height=768"), "{f}");
        println!("{f}");
    }

    // A screenshot at 1024 x 768 shows the site over the page's sky colour (0x87a9c9).
    let fraction = covered_fraction(&served, &tmp.path().join("shot.png"), "IGI_VIEW_SCREENSHOT");
    assert!(fraction > 0.2, "the site covers {fraction:.3} of the frame");
}

#[test]
fn the_server_answers_only_get_and_head_under_its_folder() {
    let tmp = tempfile::tempdir().unwrap();
    let res = quick_result(tmp.path());
    std::fs::write(tmp.path().join("secret.txt"), "secret").unwrap();
    let served = serve(&res, "0", &[]);
    let url = &served.1;
    let get = |p: &str| http(url, &format!("GET {p} HTTP/1.0\r\n\r\n"));
    assert_eq!(status(&get("/")), 200, "{}", get("/"));
    assert_eq!(status(&get("/files/report.json")), 200);
    assert_eq!(status(&get("/files/../secret.txt")), 403);
    assert_eq!(status(&get("/files/%2e%2e/secret.txt")), 403);
    let head = http(url, "HEAD /igi/scene.glb HTTP/1.0\r\n\r\n");
    assert_eq!(status(&head), 200, "{head}");
    assert!(!head.contains("glTF"), "HEAD sent a body");
    let post = http(url, "POST / HTTP/1.0\r\nContent-Length: 0\r\n\r\n");
    assert_eq!(status(&post), 405, "{post}");
    // each part's standard-error picture is the export's NAME_stderr.png, pixel for pixel
    let out = tmp.path().join("gltf");
    run_ok(
        igi()
            .arg("export")
            .arg(&res)
            .args(["--format", "gltf", "-o"])
            .arg(&out),
    );
    let scene: serde_json::Value =
        serde_json::from_slice(&http_body(&get("/igi/scene.json"))).unwrap();
    let parts = scene["parts"].as_array().unwrap();
    assert!(!parts.is_empty(), "{scene}");
    for p in parts {
        let answer = http_bytes(
            url,
            &format!("GET {} HTTP/1.0\r\n\r\n", p["stderr"].as_str().unwrap()),
        );
        let served = image::load_from_memory(&answer).unwrap().to_rgb8();
        let name = p["name"].as_str().unwrap();
        let written = image::open(out.join(format!("{name}_stderr.png")))
            .unwrap()
            .to_rgb8();
        assert_eq!(served.dimensions(), written.dimensions(), "{name}");
        assert!(
            served.pixels().eq(written.pixels()),
            "{name}: pixels differ"
        );
    }
    // no site given: no sky
    assert_eq!(status(&get("/igi/sky?time=2026-06-21T12:00:00Z")), 404);
}

/// The body of a raw HTTP answer (after the blank line).
fn http_body(answer: &str) -> Vec<u8> {
    answer
        .split_once("\r\n\r\n")
        .map_or(Vec::new(), |(_, b)| b.as_bytes().to_vec())
}

/// The body of the answer to `request`, as bytes.
fn http_bytes(url: &str, request: &str) -> Vec<u8> {
    let addr = url.trim_start_matches("http://").trim_end_matches('/');
    let mut s = std::net::TcpStream::connect(addr).unwrap();
    s.write_all(request.as_bytes()).unwrap();
    let mut out = Vec::new();
    s.read_to_end(&mut out).unwrap();
    let at = out.windows(4).position(|w| w == b"\r\n\r\n").unwrap() + 4;
    out[at..].to_vec()
}

#[test]
fn bad_folders_and_busy_ports_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let out = igi().arg("view").arg(tmp.path()).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success()
            && err.contains("not a result folder")
            && err.contains("an opacity-hull folder")
            && err.contains("a surface-light-field folder")
            && err.contains("nor a 3D Tiles export"),
        "{err}"
    );
    assert!(
        out.stdout.is_empty(),
        "a URL was printed for a refused folder"
    );

    let res = quick_result(tmp.path());
    let nope = tmp.path().join("nope.toml");
    let out = igi()
        .arg("view")
        .arg(&res)
        .arg("--lighting")
        .arg(&nope)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("nope.toml"), "{err}");
    assert!(
        out.stdout.is_empty(),
        "a URL was printed for a refused lighting"
    );
    // a survey whose photo's camera is broken, and a camera file that is not one
    let survey = tmp.path().join("survey");
    std::fs::create_dir_all(survey.join("cameras")).unwrap();
    let fixture = Path::new(env!("CARGO_MANIFEST_DIR")).join("datasets/fixtures/survey");
    std::fs::write(
        survey.join("survey.toml"),
        format!(
            "[site]\nmesh = {:?}\n\n[[photo]]\nid = \"a\"\nimage = {:?}\ncamera = \"cameras/a.json\"\nlighting = {:?}\n",
            fixture.join("geometry/ground.ply"),
            fixture.join("photos/v00-sunny.exr"),
            fixture.join("lighting/sunny.toml"),
        ),
    )
    .unwrap();
    std::fs::write(survey.join("cameras/a.json"), "{\"width\": 160}").unwrap();
    for (flag, path) in [
        ("--survey", survey.clone()),
        ("--camera", survey.join("cameras/a.json")),
    ] {
        let out = igi()
            .arg("view")
            .arg(&res)
            .arg(flag)
            .arg(&path)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && err.contains("a.json"),
            "{flag}: {err}"
        );
        assert!(out.stdout.is_empty(), "{flag}: a URL was printed");
    }
    let busy = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let port = busy.local_addr().unwrap().port().to_string();
    let out = igi()
        .arg("view")
        .arg(&res)
        .args(["--port", &port])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains(&format!("cannot listen on 127.0.0.1:{port}")),
        "{err}"
    );
}

/// The `key=value` pairs of a page message (`page: measure=...&a=...`).
fn fields(line: &str) -> std::collections::HashMap<String, String> {
    line.trim_start_matches("page: ")
        .split('&')
        .filter_map(|kv| kv.split_once('='))
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect()
}

fn vec3(s: &str) -> glam::Vec3 {
    let v: Vec<f32> = s.split(',').map(|x| x.parse().unwrap()).collect();
    glam::Vec3::new(v[0], v[1], v[2])
}

/// Display modes, distance measurement and the sky of a date and time, in the browser:
/// * the page's materials carry the export's fitted roughness and specular per part;
/// * two points picked on the canvas lie on the result's surface (`igi sample` finds them)
///   and the distance shown is theirs;
/// * the sun and sky the page gets for a date and time at the site are `igi sky`'s.
#[test]
fn lobes_measurement_and_the_sky_of_a_date_in_a_real_browser() {
    let tmp = tempfile::tempdir().unwrap();
    let res = quick_result(tmp.path());
    let served = serve_with(&res, "0", &[], &["--site", "48.85,2.35"]);
    let time = "2026-06-21T12:00:00Z";
    let url = format!(
        "{}?width=1024&height=768&mode=lobes&measure=412,600,612,560&time={time}",
        served.1
    );
    let said = open_until_told(
        &served,
        &url,
        "page",
        &["mode=", "lobes=", "measure=", "sky="],
    );
    assert!(said.iter().any(|l| l == "page: mode=lobes"), "{said:?}");

    // the lobes: as the export fitted them
    let out = tmp.path().join("gltf");
    run_ok(
        igi()
            .arg("export")
            .arg(&res)
            .args(["--format", "gltf", "-o"])
            .arg(&out),
    );
    let bytes = std::fs::read(out.join("scene.glb")).unwrap();
    let g = gltf::Gltf::from_slice(&bytes).unwrap();
    let lobes = said
        .iter()
        .find_map(|l| l.strip_prefix("page: lobes="))
        .expect("the page told its lobes");
    let mut checked = 0;
    for m in g.materials() {
        let name = m.name().unwrap();
        let (r, sp) = lobes
            .split(';')
            .find_map(|p| p.strip_prefix(&format!("{name}:")))
            .and_then(|rs| rs.split_once(':'))
            .unwrap_or_else(|| panic!("no part {name} in {lobes}"));
        let rough = m.pbr_metallic_roughness().roughness_factor();
        let spec = m.specular().map_or(1.0, |s| s.specular_factor());
        assert!(
            (r.parse::<f32>().unwrap() - rough).abs() < 1e-4,
            "{name}: {r} vs {rough}"
        );
        assert!(
            (sp.parse::<f32>().unwrap() - spec).abs() < 1e-4,
            "{name}: {sp} vs {spec}"
        );
        checked += 1;
    }
    println!("lobes as the page has them: {lobes} ({checked} parts)");

    // the measurement: two surface points, their distance
    let m = said
        .iter()
        .find(|l| l.starts_with("page: measure="))
        .expect("the page measured");
    let f = fields(m);
    let (a, b) = (vec3(&f["a"]), vec3(&f["b"]));
    let d: f32 = f["measure"].parse().unwrap();
    assert!(
        d > 0.0 && ((a - b).length() - d).abs() < 1e-5 * d.max(1.0),
        "{m}"
    );
    let pts = tmp.path().join("picked.csv");
    let (na, nb) = (vec3(&f["na"]), vec3(&f["nb"]));
    std::fs::write(
        &pts,
        format!(
            "x,y,z,nx,ny,nz\n{},{},{},{},{},{}\n{},{},{},{},{},{}\n",
            a.x, a.y, a.z, na.x, na.y, na.z, b.x, b.y, b.z, nb.x, nb.y, nb.z
        ),
    )
    .unwrap();
    // igi sample refuses a point farther than its tolerance from every surface of the result
    run_ok(
        igi()
            .arg("sample")
            .arg(&res)
            .arg("--points")
            .arg(&pts)
            .arg("-o")
            .arg(tmp.path().join("picked_values.csv")),
    );
    println!("measured {d} m between {a} and {b}");

    // the sky: igi sky's sun and sky at the same time and site
    let sky = said
        .iter()
        .find_map(|l| l.strip_prefix("page: sky="))
        .expect("the page got a sky");
    let sky: serde_json::Value = serde_json::from_str(sky).unwrap();
    let o = run_ok(
        igi()
            .args([
                "sky",
                "--site",
                "48.85,2.35",
                "--time",
                time,
                "--width",
                "64",
                "--json",
                "-o",
            ])
            .arg(tmp.path().join("sky.toml")),
    );
    let want: serde_json::Value = serde_json::from_str(&o).unwrap();
    let num = |v: &serde_json::Value| v.as_f64().unwrap();
    assert!((num(&sky["sun_elevation_deg"]) - num(&want["sun_elevation_deg"])).abs() < 1e-9);
    assert!((num(&sky["sun_azimuth_deg"]) - num(&want["sun_azimuth_deg"])).abs() < 1e-9);
    for c in 0..3 {
        let (got, w) = (
            num(&sky["sun_direction"][c]),
            num(&want["sun_direction"][c]),
        );
        assert!((got - w).abs() < 1e-6, "{sky} {want}");
        let (got, w) = (
            num(&sky["sky_up"][c]),
            num(&want["sky_horizontal_irradiance"][c]),
        );
        assert!((got / w - 1.0).abs() < 1e-4, "sky up {got} vs {w}");
    }
    // Paris at 12:00 UTC on the solstice (14:00 CEST): the sun 55 to 66 degrees up
    let el = num(&sky["sun_elevation_deg"]);
    assert!(el > 55.0 && el < 66.0, "{el}");
    println!(
        "sky at {time}: sun elevation {el:.3} deg, sky irradiance up {}",
        sky["sky_up"]
    );
}

/// A hull (surfels as splats, its surface) and a light field (its median texture) open in
/// the browser; the screenshot shows them over the page's background.
#[test]
fn a_hull_and_a_light_field_open_in_a_real_browser() {
    let tmp = tempfile::tempdir().unwrap();
    let hull = sphere_hull(tmp.path());
    let (slf, _) = sphere_light_field(tmp.path());
    for (dir, kind, keep) in [
        (&hull, "hull", "IGI_VIEW_SCREENSHOT_HULL"),
        (&slf, "light field", "IGI_VIEW_SCREENSHOT_SLF"),
    ] {
        let served = serve(dir, "0", &[]);
        let scene = http(&served.1, "GET /igi/scene.json HTTP/1.0\r\n\r\n");
        assert!(scene.contains(&format!("\"kind\": \"{kind}\"")), "{scene}");
        let fixed = format!("{}?width=1024&height=768", served.1);
        open_until_ready(&served, &fixed, kind);
        let shot = tmp.path().join(format!("{}.png", kind.replace(' ', "_")));
        let covered = covered_fraction(&served, &shot, keep);
        println!("{kind}: covers {covered:.3} of the frame");
        assert!(covered > 0.1, "{kind} covers {covered:.3} of the frame");
    }
}

/// The viewer's frame time at 1024 x 768 on the demo's result (`igi demo`: three parts of
/// 128 x 128 texels), as the page reports it over its first one-second windows, in headless
/// chromium on SwiftShader (software WebGL, no frame-rate limit). Printed for docs/VIEW.md; the
/// test asserts that the page draws and that every window's mean is a finite positive time.
#[test]
fn the_demo_result_frame_time_at_1024x768() {
    let tmp = tempfile::tempdir().unwrap();
    let demo = tmp.path().join("demo");
    run_ok(igi().arg("demo").arg("-o").arg(&demo));
    let served = serve(&demo.join("result"), "0", &[]);
    let fixed = format!("{}?width=1024&height=768", served.1);
    let unlimited = ["--disable-gpu-vsync", "--disable-frame-rate-limit"];
    let frames = std::cell::Cell::new(0);
    let said = open_page(
        &served,
        &fixed,
        &unlimited,
        |l| {
            frames.set(frames.get() + l.starts_with("page: frame_ms=") as usize);
            frames.get() == 5
        },
        180,
    );
    assert!(
        said.iter().any(|l| l == "page: title=igi: ready"),
        "the page never became ready: {said:?}"
    );
    let ms: Vec<f64> = said
        .iter()
        .filter_map(|l| l.strip_prefix("page: frame_ms="))
        .map(|f| {
            assert!(f.ends_with("&width=1024&height=768"), "{f}");
            f.split('&').next().unwrap().parse().unwrap()
        })
        .collect();
    assert_eq!(ms.len(), 5, "{said:?}");
    assert!(ms.iter().all(|m| m.is_finite() && *m > 0.0), "{ms:?}");
    let mut sorted = ms.clone();
    sorted.sort_by(f64::total_cmp);
    println!(
        "demo result at 1024 x 768: frame time per one-second window {ms:?} ms, median {:.2} ms",
        sorted[2]
    );
}

/// Headless chromium's screenshot of `served` at 1024 x 768 (kept at `$keep` when set): the
/// fraction of the frame that is not the page's sky colour.
fn covered_fraction(served: &Served, shot: &Path, keep: &str) -> f64 {
    let img = screenshot(&served.1, shot, keep);
    assert_eq!(img.dimensions(), (1024, 768));
    let sky = [0x87i32, 0xa9, 0xc9];
    img.pixels()
        .filter(|p| p.0.iter().zip(sky).any(|(&a, b)| (a as i32 - b).abs() > 24))
        .count() as f64
        / (img.width() * img.height()) as f64
}

/// Headless chromium's screenshot of `url` (its window 1024 x 768) into `shot`, copied to
/// `$keep` when that is set. On a loaded machine chromium sometimes takes the shot before the
/// page has drawn anything (one colour, the page's background, every pixel: seen in 1 launch
/// of 4 beside four busy loops); such a launch is repeated, three launches at most, and what
/// the page then draws is measured by the caller as before.
fn screenshot(url: &str, shot: &Path, keep: &str) -> image::RgbImage {
    let arg = format!("--screenshot={}", shot.display());
    for launch in 1..=3 {
        let profile = tempfile::tempdir().unwrap();
        let _ = std::fs::remove_file(shot);
        let status = chromium_command(url, &[&arg, "--virtual-time-budget=200000"], profile.path())
            .status()
            .unwrap();
        assert!(shot.exists(), "no screenshot of {url} ({status})");
        if let Some(to) = std::env::var_os(keep) {
            std::fs::copy(shot, to).unwrap();
        }
        let img = image::open(shot).unwrap().to_rgb8();
        let first = *img.get_pixel(0, 0);
        if img.pixels().any(|p| *p != first) {
            return img;
        }
        println!("screenshot {launch} of {url}: one colour {first:?}, the page had not drawn");
    }
    panic!("three screenshots of {url} showed nothing drawn");
}

/// A prepared site opens as 3D Tiles (issue 35, "a prepared site (with its tileset) opens in
/// the viewer"): its result folder (the tiles made in memory, served under `/igi/tiles/`) and
/// its `igi export --format gltf` folder (`tileset.json` and the GLBs, served under
/// `/files/`): each page loads one leaf per part, becomes `igi: ready`, and the site covers
/// the frame.
#[test]
fn a_prepared_site_and_its_3d_tiles_open_in_a_real_browser() {
    let tmp = tempfile::tempdir().unwrap();
    let (res, man) = prepared_result(tmp.path());
    let parts = man["voxels"].as_array().unwrap().len() + 1;
    let out = tmp.path().join("tiles");
    run_ok(
        igi()
            .arg("export")
            .arg(&res)
            .args(["--format", "gltf", "-o"])
            .arg(&out),
    );
    for (label, dir, tileset, keep) in [
        (
            "prepared result",
            &res,
            "/igi/tiles/tileset.json",
            "IGI_VIEW_SCREENSHOT_TILES",
        ),
        (
            "3D Tiles export",
            &out,
            "/files/tileset.json",
            "IGI_VIEW_SCREENSHOT_TILES_EXPORT",
        ),
    ] {
        let served = serve(dir, "0", &[]);
        let scene = http(&served.1, "GET /igi/scene.json HTTP/1.0\r\n\r\n");
        assert!(scene.contains("\"kind\": \"tiles\""), "{label}: {scene}");
        assert!(
            scene.contains(&format!("\"tileset\": \"{tileset}\"")),
            "{label}: {scene}"
        );
        let set = http(&served.1, &format!("GET {tileset} HTTP/1.0\r\n\r\n"));
        assert_eq!(status(&set), 200, "{label}: {set}");
        assert!(set.contains("\"version\": \"1.1\""), "{label}: {set}");
        let set: serde_json::Value = serde_json::from_slice(&http_bytes(
            &served.1,
            &format!("GET {tileset} HTTP/1.0\r\n\r\n"),
        ))
        .unwrap();
        // never refined; 16 px (the default) refines the terrain; 0.008 px some voxels (their
        // coarsest levels err by hundredths of a pixel here); 0 every part to level 0
        for max_sse in [1e9, 16.0, 0.008, 0.0] {
            let fixed = format!("{}?width=1024&height=768&sse={max_sse}", served.1);
            let said = open_until_told(&served, &fixed, label, &["tiles="]);
            let told = said
                .iter()
                .find(|l| l.starts_with("page: tiles="))
                .unwrap_or_else(|| panic!("{label}: no tiles shown: {said:?}"));
            let f = fields(told);
            assert_eq!(f["tiles"], parts.to_string(), "{label}: one tile per part");
            let shown = chosen_levels(&set, &f, max_sse);
            println!("{label}, at most {max_sse} px: levels shown {shown:?}");
        }
        let shot = tmp.path().join(format!("{}.png", label.replace(' ', "_")));
        let covered = covered_fraction(&served, &shot, keep);
        println!("{label}: {parts} parts, covers {covered:.3} of the frame");
        assert!(covered > 0.1, "{label} covers {covered:.3} of the frame");
    }
}

/// The levels the page shows (`levels=K:SSE;...`, one per part in the tileset's order) are
/// the coarsest whose screen-space error is at most `max_sse` pixels, else level 0, as the
/// test computes it from the tileset (each level's box and geometricError) and the camera the
/// page reports (`camera=X,Y,Z` in igi's frame, `per_unit`: pixels per unit at distance 1);
/// returns the levels' numbers, 0 the finest.
fn chosen_levels(
    set: &serde_json::Value,
    told: &std::collections::HashMap<String, String>,
    max_sse: f64,
) -> Vec<usize> {
    let cam: Vec<f64> = told["camera"]
        .split(',')
        .map(|v| v.parse().unwrap())
        .collect();
    let per_unit: f64 = told["per_unit"].parse().unwrap();
    let shown: Vec<(usize, f64)> = told["levels"]
        .split(';')
        .map(|l| {
            let (k, sse) = l.split_once(':').unwrap();
            (k.parse().unwrap(), sse.parse().unwrap())
        })
        .collect();
    let chains = set["root"]["children"].as_array().unwrap();
    assert_eq!(shown.len(), chains.len());
    let mut numbers = Vec::new();
    for (chain, (k, page_sse)) in chains.iter().zip(&shown) {
        let mut sse = Vec::new();
        let mut t = Some(chain);
        while let Some(tile) = t {
            let b: Vec<f64> = tile["boundingVolume"]["box"]
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_f64().unwrap())
                .collect();
            let r = [3, 6, 9]
                .map(|i| b[i] * b[i] + b[i + 1] * b[i + 1] + b[i + 2] * b[i + 2])
                .iter()
                .sum::<f64>()
                .sqrt();
            let d = ((0..3).map(|i| (cam[i] - b[i]).powi(2)).sum::<f64>().sqrt() - r).max(1e-9);
            sse.push(tile["geometricError"].as_f64().unwrap() * per_unit / d);
            t = tile["children"].as_array().and_then(|c| c.first());
        }
        let want = sse
            .iter()
            .position(|&s| s <= max_sse)
            .unwrap_or(sse.len() - 1);
        assert_eq!(*k, want, "levels' errors {sse:?} px, at most {max_sse}");
        assert!(
            (page_sse - sse[want]).abs() <= 1e-4 * sse[want].max(1.0),
            "{page_sse} against {}",
            sse[want]
        );
        numbers.push(sse.len() - 1 - want);
    }
    numbers
}

/// The survey's photographs from their capture cameras (`igi view --survey`): looking through
/// the fixture's photo 1, two canvas points picked on the site are surface points that the
/// photo's camera file projects back onto those very pixels (the page's camera is the capture
/// camera: pose, K, principal point), and with the overlay opaque the screenshot is the
/// photograph's picture in place (nearer it than shifted by one pixel any way).
#[test]
fn the_photographs_overlay_from_their_capture_cameras_in_a_real_browser() {
    let tmp = tempfile::tempdir().unwrap();
    let res = quick_result(tmp.path());
    let survey = Path::new(env!("CARGO_MANIFEST_DIR")).join("datasets/fixtures/survey");
    let served = serve_with(&res, "0", &[], &["--survey", survey.to_str().unwrap()]);
    let (x1, y1, x2, y2) = (100.0, 420.0, 500.0, 330.0);
    let url = format!(
        "{}?width=640&height=480&photo=1&mode=albedo&measure={x1},{y1},{x2},{y2}",
        served.1
    );
    let said = open_until_told(&served, &url, "photo page", &["photo=", "measure="]);
    let shown = said
        .iter()
        .find(|l| l.starts_with("page: photo="))
        .unwrap_or_else(|| panic!("the page showed no photo: {said:?}"));
    let f = fields(shown);
    assert_eq!(
        (
            f["photo"].as_str(),
            f["width"].as_str(),
            f["height"].as_str()
        ),
        ("v01-lowsun", "640", "480"),
        "{shown}"
    );
    let scale: f64 = f["scale"].parse().unwrap();
    assert_eq!(scale, 4.0);
    let m = said
        .iter()
        .find(|l| l.starts_with("page: measure="))
        .unwrap_or_else(|| panic!("the page measured nothing: {said:?}"));
    let f = fields(m);
    let cam = igi_camera::Camera::load(&survey.join("cameras/v01-lowsun.json")).unwrap();
    for (key, x, y) in [("a", x1, y1), ("b", x2, y2)] {
        let p: Vec<f64> = f[key].split(',').map(|v| v.parse().unwrap()).collect();
        let uv = cam
            .project(glam::DVec3::new(p[0], p[1], p[2]))
            .unwrap_or_else(|| panic!("{key} = {p:?} is behind the camera"));
        let want = glam::DVec2::new(x / scale - 0.5, y / scale - 0.5);
        let err = (uv - want).length();
        println!(
            "canvas ({x}, {y}): {key} = {p:?} projects to {uv} (clicked {want}): {err:.2e} px"
        );
        assert!(err < 0.01, "{key}: {uv} against {want}");
    }

    // with the overlay opaque, the canvas shows the photo's picture (the 640 x 480 canvas
    // averaged back to 160 x 120), in place to a fraction of a pixel
    let shot_url = format!(
        "{}?width=640&height=480&photo=1&overlay=1&panel=0",
        served.1
    );
    let shot = screenshot(
        &shot_url,
        &tmp.path().join("photo.png"),
        "IGI_VIEW_SCREENSHOT_PHOTO",
    );
    let png = http_bytes(&served.1, "GET /igi/photo/1.png HTTP/1.0\r\n\r\n");
    let photo = image::load_from_memory(&png).unwrap().to_rgb8();
    assert_eq!(photo.dimensions(), (cam.width, cam.height));
    let shown = |x: u32, y: u32, c: usize| {
        let mut s = 0.0;
        for dy in 0..4 {
            for dx in 0..4 {
                s += shot.get_pixel(4 * x + dx, 4 * y + dy).0[c] as f64;
            }
        }
        s / 16.0
    };
    let mad = |sx: i32, sy: i32| {
        let (mut sum, mut n) = (0.0, 0);
        for y in 2..cam.height - 2 {
            for x in 2..cam.width - 2 {
                let q = photo.get_pixel((x as i32 + sx) as u32, (y as i32 + sy) as u32);
                for c in 0..3 {
                    sum += (shown(x, y, c) - q.0[c] as f64).abs();
                    n += 1;
                }
            }
        }
        sum / n as f64
    };
    let here = mad(0, 0);
    let shifted = [(1, 0), (-1, 0), (0, 1), (0, -1)].map(|(sx, sy)| mad(sx, sy));
    println!("overlay against the photo: mean abs difference {here:.2} (of 255); shifted one pixel {shifted:.2?}");
    assert!(here < 4.0, "{here}");
    for s in shifted {
        assert!(here < 0.5 * s, "{here} against {s} shifted");
    }
}

/// A light field whose colour depends on the view (PFA with two prototypes: a highlight about
/// the reflected +Z and a flat grey, weighted by each point's height) on the sphere of
/// `sphere_light_field`, saved through `igi_lightfield::store`.
fn glossy_sphere_light_field(tmp: &Path) -> PathBuf {
    use igi_geometry::atlas::{build_atlas, AtlasOptions};
    use igi_lightfield::{field::Coding, Octahedron, Pfa, SurfaceLightField};
    let mesh = igi_geometry::procedural::uv_sphere(16, 32, 0.5);
    let atlas = build_atlas(
        &mesh,
        AtlasOptions {
            resolution: 64,
            gutter: 1,
        },
    )
    .unwrap();
    let (mut texels, mut median, mut coefficients) = (vec![], vec![], vec![]);
    for (t, c) in atlas.coverage.pixels.iter().enumerate() {
        if c[0] == 1.0 {
            let p = glam::Vec3::from(atlas.position.pixels[t]);
            texels.push(t as u32);
            median.push(glam::Vec3::new(
                0.2 + 0.3 * (p.x + 0.5),
                0.3,
                0.25 + 0.2 * p.y,
            ));
            let a = (p.z + 0.5).clamp(0.0, 1.0);
            coefficients.push(vec![a, 1.0 - a]);
        }
    }
    let oct = Octahedron::new(3);
    let highlight = (0..oct.len())
        .map(|v| glam::Vec3::new(1.0, 0.9, 0.7) * oct.direction(v).z.max(0.0).powi(4))
        .collect();
    let grey = vec![glam::Vec3::splat(-0.05); oct.len()];
    let n = texels.len();
    let field = SurfaceLightField::new(
        oct,
        64,
        texels,
        median,
        vec![glam::Vec3::Z; n],
        Coding::Pfa(Pfa {
            prototypes: vec![highlight, grey],
            coefficients,
            energy_history: vec![],
        }),
    );
    let dir = tmp.join("glossy_slf");
    igi_lightfield::store::save(&dir, &field, &atlas.mesh, serde_json::json!({})).unwrap();
    dir
}

/// A light field's view-dependent colour in the page: looking through a camera
/// (`igi view SLF --camera CAM.json`, `?photo=0`), the page's pixels are `igi slf render`'s
/// through that camera (times the page's scale, as 8-bit sRGB) over the sphere's inside
/// pixels, and far nearer them than the median texture alone (`?mode=albedo`).
#[test]
fn a_light_field_shows_its_view_dependent_colour_in_a_real_browser() {
    let tmp = tempfile::tempdir().unwrap();
    let slf = glossy_sphere_light_field(tmp.path());
    let cam = igi_camera::Camera::look_at(
        glam::DVec3::new(0.6, -1.5, 0.9),
        glam::DVec3::ZERO,
        640,
        480,
        40.0,
    )
    .unwrap();
    let cam_file = tmp.path().join("cam.json");
    cam.save(&cam_file).unwrap();
    let truth = tmp.path().join("truth.exr");
    run_ok(
        igi()
            .args(["slf", "render"])
            .arg(&slf)
            .arg("--camera")
            .arg(&cam_file)
            .arg("-o")
            .arg(&truth),
    );
    let truth_rgb = igi_imaging::read_image(&truth).unwrap();
    let alpha = igi_imaging::io::read_exr_alpha(&truth).unwrap().unwrap();
    let served = serve_with(&slf, "0", &[], &["--camera", cam_file.to_str().unwrap()]);
    let scene: serde_json::Value = serde_json::from_slice(&http_bytes(
        &served.1,
        "GET /igi/scene.json HTTP/1.0\r\n\r\n",
    ))
    .unwrap();
    let scale = scene["slf"]["scale"].as_f64().unwrap() as f32;
    assert_eq!(scene["slf"]["coding"], "pfa");
    let shot = |mode: &str, keep: &str| {
        let url = format!(
            "{}?width=640&height=480&photo=0&panel=0&mode={mode}",
            served.1
        );
        screenshot(&url, &tmp.path().join(format!("{mode}.png")), keep)
    };
    let (w, h) = (640usize, 480usize);
    let inside = |x: usize, y: usize| {
        x > 0
            && y > 0
            && x + 1 < w
            && y + 1 < h
            && (0..9).all(|k| alpha[(y + k / 3 - 1) * w + x + k % 3 - 1] == 1.0)
    };
    let error = |img: &image::RgbImage| {
        let (mut sum, mut n) = (0.0f64, 0usize);
        for y in 0..h {
            for x in 0..w {
                if !inside(x, y) {
                    continue;
                }
                let t = truth_rgb.pixels[y * w + x];
                let p = img.get_pixel(x as u32, y as u32).0;
                for c in 0..3 {
                    let want = igi_imaging::io::linear_to_srgb(t[c] * scale) * 255.0;
                    sum += ((p[c] as f64) - want as f64).powi(2);
                    n += 1;
                }
            }
        }
        assert!(n > 3 * 20_000, "{n} values inside the sphere");
        10.0 * (255.0f64 * 255.0 / (sum / n as f64)).log10()
    };
    let psnr = error(&shot("shaded", "IGI_VIEW_SCREENSHOT_SLF_VD"));
    let median = error(&shot("albedo", "IGI_VIEW_SCREENSHOT_SLF_MEDIAN"));
    println!("the page against igi slf render: {psnr:.1} dB view-dependent, {median:.1} dB the median texture alone");
    assert!(psnr > 35.0, "{psnr} dB");
    assert!(psnr > median + 6.0, "{psnr} dB against {median} dB");
}

/// The page's render of a flat textured part under a sun against igi's own direct-light render
/// (issue 35, "numeric checks"): the fixture's result seen from above its ground (no other
/// part in view, the sun at the zenith so nothing shades it), lit by a lighting file of a sun
/// alone (`--lighting`, `?lighting=0`) and looked through the same camera (`--camera`,
/// `?photo=0`). The page scales its light so that a white surface facing up reads 0.8, so
/// igi's radiance L = albedo E / pi is expected there as L pi 0.8 / luminance(E), E the sun's
/// irradiance (its radiance times its disk's solid angle), as 8-bit sRGB. The axes, the
/// texture's V flip, sRGB and the light's scale all have to be right.
#[test]
fn a_flat_part_under_a_sun_matches_igi_render_in_a_real_browser() {
    let tmp = tempfile::tempdir().unwrap();
    let res = quick_result(tmp.path());
    let radiance = [20000.0f64, 19000.0, 17000.0];
    let light = tmp.path().join("sun.toml");
    std::fs::write(
        &light,
        format!(
            "[sun]\ndirection = [0.0, 0.0, 1.0]\nradiance = {radiance:?}\nangular_diameter_deg = 0.53\n"
        ),
    )
    .unwrap();
    let cam = igi_camera::Camera::look_at(
        glam::DVec3::new(0.0, -4.3, 6.0),
        glam::DVec3::new(0.0, -4.0, 0.0),
        640,
        480,
        40.0,
    )
    .unwrap();
    let cam_file = tmp.path().join("down.json");
    cam.save(&cam_file).unwrap();
    let truth = tmp.path().join("direct.exr");
    run_ok(
        igi()
            .arg("render")
            .arg(&res)
            .arg("--lighting")
            .arg(&light)
            .arg("--camera")
            .arg(&cam_file)
            .args(["--spp", "16", "--indirect", "0", "--stratified", "-q", "-o"])
            .arg(&truth),
    );
    let truth = igi_imaging::read_image(&truth).unwrap();
    let half = (0.53f64 / 2.0).to_radians();
    let solid_angle = 2.0 * std::f64::consts::PI * (1.0 - half.cos());
    let e = radiance.map(|r| r * solid_angle);
    let k = std::f64::consts::PI * 0.8 / (0.2126 * e[0] + 0.7152 * e[1] + 0.0722 * e[2]);

    let served = serve_with(
        &res,
        "0",
        std::slice::from_ref(&light),
        &["--camera", cam_file.to_str().unwrap()],
    );
    let url = format!(
        "{}?width=640&height=480&photo=0&panel=0&lighting=0",
        served.1
    );
    let page = screenshot(
        &url,
        &tmp.path().join("page.png"),
        "IGI_VIEW_SCREENSHOT_SUN",
    );
    // PSNR of the page against igi's render, that render read upside down when `flip`
    let psnr = |flip: bool| {
        let (mut sum, mut n) = (0.0f64, 0usize);
        for y in 0..480usize {
            for x in 0..640usize {
                let t = truth.pixels[if flip { 479 - y } else { y } * 640 + x];
                let p = page.get_pixel(x as u32, y as u32).0;
                for c in 0..3 {
                    let want = igi_imaging::io::linear_to_srgb((t[c] as f64 * k) as f32) * 255.0;
                    sum += (p[c] as f64 - want as f64).powi(2);
                    n += 1;
                }
            }
        }
        10.0 * (255.0f64 * 255.0 / (sum / n as f64)).log10()
    };
    let (here, flipped) = (psnr(false), psnr(true));
    println!(
        "the page against igi render (direct light, x {k:.4e}): {here:.1} dB (against it upside down: {flipped:.1} dB)"
    );
    assert!(here > 35.0, "{here} dB");
    assert!(here > flipped + 10.0, "{here} dB, upside down {flipped} dB");
}

/// Flying (`?nav=fly`, three.js's FlyControls): W held for 2 s (`?fly=KeyW:2`, in steps of
/// 0.1 s) moves the camera straight ahead by its speed times 2 s, and S back.
#[test]
fn the_page_flies_in_a_real_browser() {
    let tmp = tempfile::tempdir().unwrap();
    let res = quick_result(tmp.path());
    let served = serve(&res, "0", &[]);
    for (key, ahead) in [("KeyW", 1.0), ("KeyS", -1.0)] {
        let url = format!("{}?width=640&height=480&nav=fly&fly={key}:2", served.1);
        let said = open_until_told(&served, &url, key, &["fly="]);
        let told = said
            .iter()
            .find(|l| l.starts_with("page: fly="))
            .unwrap_or_else(|| panic!("{key}: the page did not fly: {said:?}"));
        let f = fields(told);
        let num = |k: &str| f[k].parse::<f64>().unwrap();
        let (moved, forward, speed) = (num("moved"), num("forward"), num("speed"));
        println!("{key} for 2 s: moved {moved} (speed {speed} a second), along the view {forward}");
        assert!(
            speed > 0.0 && ((moved / (2.0 * speed)) - 1.0).abs() < 1e-5,
            "{told}"
        );
        assert!((forward - ahead).abs() < 1e-6, "{told}");
    }
}
