//! Real data: lat-long light probes (round trip through a rendered mirror ball) and a real
//! chrome ball photographed in three brackets.

use glam::{DMat3, DVec3};
use igi_camera::{Camera, WorldToCamera};
use igi_imaging::hdr::{merge_linear, LinearParams};
use igi_imaging::io::srgb_to_linear;
use igi_imaging::{latlong, read_image, HdrImage};
use igi_probe::{process, Board, ProbeOptions};
use igi_synth::board::render_board;
use std::path::PathBuf;

fn data(rel: &str) -> PathBuf {
    igi_testkit::shared_data(rel)
}

/// Camera at the world origin looking along +X (x right = world -Y, y down = world -Z).
fn camera(w: u32, h: u32, f: f64) -> Camera {
    let mut c = Camera::pinhole(w, h, f, f, (w as f64 - 1.0) / 2.0, (h as f64 - 1.0) / 2.0);
    c.pose = WorldToCamera {
        r: DMat3::from_cols_array_2d(&[[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])
            .transpose(),
        t: DVec3::ZERO,
    };
    c
}

/// Box-average a lat-long map by `f` (solid-angle weighted).
fn downsample(m: &HdrImage, f: usize) -> HdrImage {
    igi_probe::envmap::downsample_latlong(m, f)
}

/// Reference: the area average over each texel of a `w` x `w/2` map of the continuous
/// environment the renderer shows (the probe's bilinear interpolant), by 16 x 16 sub-samples
/// weighted by sin(theta).
fn area_average(probe: &HdrImage, w: usize) -> HdrImage {
    let h = w / 2;
    let mut out = HdrImage::new(w, h);
    let n = 16;
    for i in 0..h {
        for j in 0..w {
            let (mut acc, mut wsum) = ([0.0f64; 3], 0.0f64);
            for sy in 0..n {
                for sx in 0..n {
                    let u = (j as f32 + (sx as f32 + 0.5) / n as f32) / w as f32;
                    let v = (i as f32 + (sy as f32 + 0.5) / n as f32) / h as f32;
                    let wt = (std::f64::consts::PI * v as f64).sin();
                    let p =
                        igi_probe::envmap::latlong_lookup(probe, latlong::uv_to_direction(u, v))
                            .unwrap();
                    for c in 0..3 {
                        acc[c] += wt * p[c] as f64;
                    }
                    wsum += wt;
                }
            }
            out.set(j, i, acc.map(|v| (v / wsum) as f32));
        }
    }
    out
}

/// Pixels of the ball image per probe texel at the probe's brightest texel, along azimuth and
/// along the polar angle (the sampling rate of the ball image relative to the probe's own).
fn pixels_per_probe_texel(probe: &HdrImage, view: &igi_capture::sphere::SphereView) -> (f64, f64) {
    let lum = |p: [f32; 3]| p[0] + p[1] + p[2];
    let k = (0..probe.pixels.len())
        .max_by(|a, b| lum(probe.pixels[*a]).total_cmp(&lum(probe.pixels[*b])))
        .unwrap();
    let (i, j, w, h) = (k / probe.width, k % probe.width, probe.width, probe.height);
    let at = |i: usize, j: usize| {
        view.reflection_point(latlong::pixel_center_direction(i, j % w, w, h).as_dvec3())
            .unwrap()
            .pixel
    };
    let c = at(i, j);
    (
        c.distance(at(i, j + 1)),
        c.distance(at((i + 1).min(h - 1), j)),
    )
}

#[test]
fn latlong_probe_round_trip_through_a_mirror_ball() {
    // The ball image must sample the probe's small bright sources at least at the probe's own
    // rate (Nyquist: one pixel per probe texel or more; printed for the brightest texel). Grace's lamps (up to 5000x the mean) are
    // single texels 12 degrees from the zenith, 0.29 degrees wide in azimuth: a ball of 300 px
    // radius gives only 0.72 px per texel there and the pixel footprint moves lamp light into the
    // neighbouring comparison texels (8 % relative RMS); 600 px gives 1.44 px per texel.
    // docs/PROBE.md, "Resolution", has the error against the ball radius.
    for name in ["pisa", "uffizi", "wells", "ennis", "grace"] {
        let probe = read_image(&data(&format!(
            "light_probes/probulator_latlong_256x128/{name}.hdr"
        )))
        .unwrap();
        assert_eq!((probe.width, probe.height), (256, 128));
        let cam = camera(1232, 1232, 6000.0);
        // ball of radius 0.1 m at 1.0 m: 603 px in radius
        let board = Board::mirror_only(DVec3::new(0.0, 0.0, 1.0), 0.1);
        let view = igi_capture::sphere::SphereView::new(
            &cam,
            igi_probe::SphereKind::Mirror,
            &board.mirror,
        );
        let (pu, pv) = pixels_per_probe_texel(&probe, &view);
        let img = render_board(&cam, &board, &probe, None, 2);
        let opt = ProbeOptions {
            map_width: 512,
            conv_width: 128,
            hemi_size: 64,
            ..ProbeOptions::default()
        };
        let r = process(&img, &cam, &board, &opt).unwrap();
        assert!(!r.diagnostics.sun_found || r.diagnostics.sun.as_ref().unwrap().radiance.is_none());
        // compare at 64x32 (5.6 degree texels): the recovered 512x256 map box-averaged, the
        // probe's interpolant area-averaged; only coarse texels whose every fine texel is valid (outside the blind
        // spot and the camera cone)
        let (cw, ch) = (64, 32);
        let rec = downsample(&r.sky_measured, 512 / cw);
        let reference = area_average(&probe, cw);
        let (mut se, mut st, mut n) = (0.0f64, 0.0f64, 0usize);
        for i in 0..ch {
            let sa = latlong::pixel_solid_angle(i, cw, ch) as f64;
            for j in 0..cw {
                let k = i * cw + j;
                if !rec.valid[k] {
                    continue;
                }
                for c in 0..3 {
                    se += sa * (rec.pixels[k][c] - reference.pixels[k][c]).powi(2) as f64;
                    st += sa * (reference.pixels[k][c] as f64).powi(2);
                }
                n += 1;
            }
        }
        let rel = (se / st).sqrt();
        eprintln!(
            "{name}: round trip relative RMS {rel:.4} over {n} of {} texels ({pu:.2} x {pv:.2} px per probe texel at its brightest)",
            cw * ch
        );
        assert!(n > cw * ch * 3 / 4, "{name}: only {n} valid texels");
        assert!(rel < 0.03, "{name}: round trip relative RMS {rel}");
        assert!(r.sky.pixels.iter().flatten().all(|v| v.is_finite()));
    }
}

/// Merges sRGB brackets of a chrome ball that fills a `side x side` crop (centre at the crop's
/// centre, radius `radius` px; a long lens, so nearly orthographic), unwarps it and checks the
/// map is finite and that its brightest 0.5 % of directions are the lamps: many times the
/// median, and clipped in the longest exposure where the ball shows them.
fn check_chrome_ball(name: &str, imgs: &[HdrImage], times: &[f64], radius: f64) {
    let (w, h) = (imgs[0].width, imgs[0].height);
    let sat = srgb_to_linear(0.98);
    let (merged, _) = merge_linear(
        imgs,
        times,
        LinearParams {
            noise_floor: 0.002,
            saturation: sat,
        },
    )
    .unwrap();
    let f = 10000.0;
    let cam = camera(w as u32, h as u32, f);
    let board = Board::mirror_only(DVec3::new(0.0, 0.0, f / radius), 1.0);
    let r = process(&merged, &cam, &board, &ProbeOptions::default()).unwrap();
    let m = &r.sky_measured;
    assert!(
        r.sky
            .pixels
            .iter()
            .flatten()
            .all(|v| v.is_finite() && *v >= 0.0),
        "{name}"
    );
    assert!(
        m.valid_fraction() > 0.5,
        "{name}: valid fraction {}",
        m.valid_fraction()
    );
    let mut idx: Vec<usize> = (0..m.pixels.len()).filter(|&k| m.valid[k]).collect();
    let lum = |p: [f32; 3]| 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2];
    idx.sort_by(|a, b| lum(m.pixels[*b]).total_cmp(&lum(m.pixels[*a])));
    let top = &idx[..idx.len() / 200];
    let median = lum(m.pixels[idx[idx.len() / 2]]);
    let mirror =
        igi_capture::sphere::SphereView::new(&cam, igi_probe::SphereKind::Mirror, &board.mirror);
    // where the ball shows them, the longest exposure is clipped (checked where it reaches 255
    // at all: the iPhone set's longest bracket peaks at 0.97, its lamps are not clipped)
    let long_max = imgs[0]
        .pixels
        .iter()
        .flatten()
        .fold(0.0f32, |a, b| a.max(*b));
    let (mut up, mut clipped) = (0, 0);
    for &k in top {
        let d = latlong::pixel_center_direction(k / m.width, k % m.width, m.width, m.height);
        if d.z > 0.0 {
            up += 1;
        }
        let rp = mirror.reflection_point(d.as_dvec3()).unwrap();
        let (x, y) = (rp.pixel.x.round() as usize, rp.pixel.y.round() as usize);
        // the longest exposure near where the ball shows the direction (2 px: the mapping's
        // and the registration's slack)
        let near = (y.saturating_sub(2)..(y + 3).min(h))
            .flat_map(|yy| (x.saturating_sub(2)..(x + 3).min(w)).map(move |xx| (xx, yy)))
            .map(|(xx, yy)| imgs[0].get(xx, yy).into_iter().fold(0.0f32, f32::max))
            .fold(0.0f32, f32::max);
        if near >= sat {
            clipped += 1;
        }
    }
    let weakest = lum(m.pixels[*top.last().unwrap()]);
    eprintln!(
        "{name}: {} brightest directions, {up} above the horizon, {clipped} clipped in the long exposure \
         (max {long_max}); weakest of them {weakest}, median {median}",
        top.len()
    );
    assert!(
        weakest > 10.0 * median,
        "{name}: the lamps are only {} x the median",
        weakest / median
    );
    if long_max >= 0.999 {
        assert!(
            clipped as f64 > 0.8 * top.len() as f64,
            "{name}: {clipped} of {} clipped",
            top.len()
        );
    }
    assert!(
        up as f64 > 0.8 * top.len() as f64,
        "{name}: {up} of {} above the horizon (ceiling lamps)",
        top.len()
    );
}

fn srgb_image(rel: &str) -> HdrImage {
    let mut im = read_image(&data(rel)).unwrap();
    im.pixels
        .iter_mut()
        .for_each(|p| *p = p.map(srgb_to_linear));
    im
}

#[test]
fn real_chrome_ball_brackets_merge_and_unwarp() {
    // 147x147 crops of the same ball at 0.1, 0.025, 0.00625 s (sRGB JPEGs); the ball fills the
    // crop: centre (73, 73), radius about 71.5 px.
    let imgs: Vec<HdrImage> = ["rec1.jpg", "rec2.jpg", "rec3.jpg"]
        .iter()
        .map(|n| srgb_image(&format!("mirror_ball_ldr/olapietka_sony_a6400/{n}")))
        .collect();
    check_chrome_ball("olapietka", &imgs, &[0.1, 0.025, 0.00625], 71.5);
}

#[test]
fn second_real_chrome_ball_hand_cropped_brackets_are_registered_merged_and_unwarped() {
    // Hand crops of one ball at 0.1, 0.025, 0.00625 s that differ in size (480x472, 484x468,
    // 490x480): the ball fills each crop, so each is resampled about its centre to a common
    // 480x480 frame in which the ball has radius 234 px (each crop's inscribed radius less 2%),
    // i.e. the ball's centre and radius are given rather than found.
    let side = 480usize;
    let target_r = 234.0f32;
    let imgs: Vec<HdrImage> = ["ball_10.JPG", "ball_40.JPG", "ball_160.JPG"]
        .iter()
        .map(|n| {
            let src = srgb_image(&format!("mirror_ball_ldr/uiuc_cs445_kagrawal_iphone7/{n}"));
            let (cx, cy) = (
                (src.width as f32 - 1.0) / 2.0,
                (src.height as f32 - 1.0) / 2.0,
            );
            let src_r = 0.98 * src.width.min(src.height) as f32 / 2.0;
            let c = (side as f32 - 1.0) / 2.0;
            let mut out = HdrImage::new(side, side);
            for y in 0..side {
                for x in 0..side {
                    let s = src_r / target_r;
                    let i = y * side + x;
                    match src.bilinear(cx + (x as f32 - c) * s, cy + (y as f32 - c) * s) {
                        Some(p) => out.pixels[i] = p,
                        None => out.valid[i] = false,
                    }
                }
            }
            out
        })
        .collect();
    check_chrome_ball("uiuc", &imgs, &[0.1, 0.025, 0.00625], target_r as f64);
}
