//! Time to process one lighting capture: merge three linear brackets of the committed Mitsuba
//! board fixture (256x256) and run the probe pipeline (512x512 hemisphere maps, 256x128 sky,
//! sun detection and solve, diffuse check).
//! Run: `cargo bench --bench probe`

use criterion::{criterion_group, criterion_main, Criterion};
use igi_camera::Camera;
use igi_imaging::hdr::{merge_linear, LinearParams};
use igi_imaging::read_image;
use igi_probe::{process, Board, ProbeOptions};
use std::path::PathBuf;

fn fixture() -> PathBuf {
    PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/datasets/fixtures/board/sunny"
    ))
}

fn bench(c: &mut Criterion) {
    let dir = fixture();
    let brackets: Vec<_> = (0..3)
        .map(|i| read_image(&dir.join(format!("bracket_{i}.png"))).unwrap())
        .collect();
    let times = [0.25, 1.0 / 32.0, 1.0 / 256.0];
    let cam = Camera::load(&dir.join("camera.json")).unwrap();
    let board = Board::load(&dir.join("board.json")).unwrap();
    let opt = ProbeOptions::default();
    let mut g = c.benchmark_group("probe");
    g.sample_size(10);
    g.bench_function("capture_3_brackets_512_maps", |b| {
        b.iter(|| {
            let (img, _) = merge_linear(&brackets, &times, LinearParams::default()).unwrap();
            let r = process(&img, &cam, &board, &opt).unwrap();
            assert!(r.diagnostics.sun_found);
            r
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
