//! `igi view` (issue 35, item 2) in a real browser: Debian's `chromium`, headless, WebGL through
//! SwiftShader (`--use-gl=angle --use-angle=swiftshader --enable-unsafe-swiftshader`). A missing
//! chromium fails the test with the reason (`bash scripts/deps.sh test` installs it).
//!
//! * The first line of standard output is `http://127.0.0.1:PORT/`; the page loads the result
//!   as glTF through three.js's GLTFLoader and its title becomes `igi: ready` once the first
//!   frame is drawn; a screenshot at 1024 x 768 shows the site (its pixels differ from the
//!   empty page's sky colour).
//! * Bad input: a folder that is not a result; a port in use; a path outside the folder.

use crate::cli_gltf::quick_result;
use std::io::{BufRead, BufReader, Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};

fn igi() -> Command {
    igi_testkit::Cli::new(env!("CARGO_BIN_EXE_igi")).command()
}

/// A running `igi view`, its URL and the lines of its standard error; killed when dropped.
struct Served(Child, String, std::sync::mpsc::Receiver<String>);

impl Drop for Served {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn serve(dir: &Path, port: &str, lightings: &[PathBuf]) -> Served {
    let mut child = igi()
        .arg("view")
        .arg(dir)
        .args(["--port", port])
        .args(lightings.iter().flat_map(|l| [Path::new("--lighting"), l]))
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
    Served(child, url, rx)
}

/// The page's messages (`page: ...` lines of igi's standard error) until `until` holds for one,
/// or the time is up.
fn page_says(served: &Served, until: impl Fn(&str) -> bool, secs: u64) -> Vec<String> {
    let end = std::time::Instant::now() + std::time::Duration::from_secs(secs);
    let mut said = vec![];
    while let Some(left) = end.checked_duration_since(std::time::Instant::now()) {
        match served.2.recv_timeout(left) {
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

fn chromium_command(url: &str, extra: &[&str]) -> Command {
    let mut c = Command::new(chromium());
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
    let mut browser = chromium_command(&fixed, &unlimited).spawn().unwrap();
    let frames = std::cell::Cell::new(0);
    let said = page_says(
        &served,
        |l| {
            frames.set(frames.get() + l.starts_with("page: frame_ms=") as usize);
            frames.get() == 4
        },
        180,
    );
    let _ = browser.kill();
    let _ = browser.wait();
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
    let shot = tmp.path().join("shot.png");
    let arg = format!("--screenshot={}", shot.display());
    let status = chromium_command(&served.1, &[&arg, "--virtual-time-budget=200000"])
        .status()
        .unwrap();
    assert!(shot.exists(), "no screenshot ({status})");
    let img = image::open(&shot).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (1024, 768));
    let sky = [0x87i32, 0xa9, 0xc9];
    let site = img
        .pixels()
        .filter(|p| p.0.iter().zip(sky).any(|(&a, b)| (a as i32 - b).abs() > 24));
    let fraction = site.count() as f64 / (1024.0 * 768.0);
    assert!(fraction > 0.2, "the site covers {fraction:.3} of the frame");
    if let Some(to) = std::env::var_os("IGI_VIEW_SCREENSHOT") {
        std::fs::copy(&shot, to).unwrap();
    }
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
}

#[test]
fn bad_folders_and_busy_ports_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let out = igi().arg("view").arg(tmp.path()).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("not a result folder"),
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
