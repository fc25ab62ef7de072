//! Inlined trigonometry for the path tracer's hot loop, in place of libm calls (issue 37: the
//! profile showed 13 % of a render in `sincosf`, `atanf` and `acosf`).
//!
//! - [`sincos_turns`]: sine and cosine of `2 pi t` (angles given in turns, as the samplers
//!   draw them): quarter-turn reduction, then Taylor polynomials on `|a| <= pi / 4` (truncation
//!   below 2e-9); measured error at most 2.4e-7 against f64 (`sincos_turns_error_bound`).
//! - [`atan2`]: Cephes' `atanf` polynomial after reduction to `[0, tan(pi / 8)]`; measured
//!   error at most 4e-7 rad against f64 over all four quadrants (`atan2_error_bound`).
//! - [`direction_to_uv`] / [`uv_to_direction`]: the lat-long mapping of
//!   `igi_imaging::latlong` through the two above (`theta = atan2(hypot(x, y), z)`, more
//!   accurate near the poles than `acos(z)`); `uv` within 2e-7 of f64 (`latlong_agrees_with_libm`).
//!
//! Everything is branch-light scalar f32 code that the compiler inlines; no NaN for finite
//! input (`atan2(0, 0) = 0`).

use glam::Vec3;
use std::f32::consts::{FRAC_PI_2, FRAC_PI_4, PI};

/// `(sin(2 pi t), cos(2 pi t))` for `t` in `[-8, 8]` (the samplers pass `[0, 1]`).
#[inline]
pub fn sincos_turns(t: f32) -> (f32, f32) {
    let x = 4.0 * t; // quarter turns (exact)
                     // Nearest integer without a libm call: truncation of a positive number is its floor.
    let q = (x + 32.5) as i32 - 32;
    let a = (x - q as f32) * FRAC_PI_2; // in [-pi/4, pi/4]
    let a2 = a * a;
    let s = a
        * (1.0
            + a2 * (-1.0 / 6.0
                + a2 * (1.0 / 120.0 + a2 * (-1.0 / 5040.0 + a2 * (1.0 / 362_880.0)))));
    let c = 1.0
        + a2 * (-0.5
            + a2 * (1.0 / 24.0
                + a2 * (-1.0 / 720.0 + a2 * (1.0 / 40_320.0 + a2 * (-1.0 / 3_628_800.0)))));
    match q & 3 {
        0 => (s, c),
        1 => (c, -s),
        2 => (-s, -c),
        _ => (-c, s),
    }
}

/// `atan(x)` for `x` in `[0, 1]` (Cephes `atanf`: reduction at `tan(pi / 8)`).
#[inline]
#[allow(clippy::excessive_precision)] // Cephes' coefficients as published
fn atan_unit(x: f32) -> f32 {
    let (base, x) = if x > 0.414_213_57 {
        (FRAC_PI_4, (x - 1.0) / (x + 1.0))
    } else {
        (0.0, x)
    };
    let z = x * x;
    base + (((8.053_744_5e-2 * z - 1.387_768_6e-1) * z + 1.997_771_1e-1) * z - 3.333_294_9e-1)
        * z
        * x
        + x
}

/// Four-quadrant arctangent of `y / x` in `[-pi, pi]`; `atan2(0, 0) = 0`; never NaN for
/// finite input.
#[inline]
pub fn atan2(y: f32, x: f32) -> f32 {
    let (ax, ay) = (x.abs(), y.abs());
    let (mn, mx) = if ax < ay { (ax, ay) } else { (ay, ax) };
    if !(mx > 0.0) {
        return 0.0;
    }
    let mut r = atan_unit(mn / mx);
    if ay > ax {
        r = FRAC_PI_2 - r;
    }
    if x < 0.0 {
        r = PI - r;
    }
    if y < 0.0 {
        -r
    } else {
        r
    }
}

/// Lat-long coordinates of direction `d` (any length): `u = phi / 2 pi` in `[0, 1)`,
/// `v = theta / pi` in `[0, 1]` (`igi_imaging::latlong::direction_to_uv`'s convention);
/// `(0, 0)` for a zero or non-finite `d`.
#[inline]
pub fn direction_to_uv(d: Vec3) -> (f32, f32) {
    let rxy2 = d.x * d.x + d.y * d.y;
    let len2 = rxy2 + d.z * d.z;
    if !(len2 > 0.0) || !len2.is_finite() {
        return (0.0, 0.0);
    }
    let theta = atan2(rxy2.sqrt(), d.z);
    let phi = atan2(d.y, d.x);
    let mut u = phi * (0.5 / PI);
    if u < 0.0 {
        u += 1.0;
    }
    if u >= 1.0 {
        u = 0.0;
    }
    (u, (theta * (1.0 / PI)).clamp(0.0, 1.0))
}

/// The unit direction at lat-long `(u, v)` and its `sin(theta)`
/// (`igi_imaging::latlong::uv_to_direction`'s convention).
#[inline]
pub fn uv_to_direction(u: f32, v: f32) -> (Vec3, f32) {
    let (st, ct) = sincos_turns(0.5 * v);
    let (sp, cp) = sincos_turns(u);
    (Vec3::new(st * cp, st * sp, ct), st)
}

#[cfg(test)]
mod tests {
    use super::*;
    use igi_imaging::latlong;

    #[test]
    fn sincos_turns_error_bound() {
        let mut worst = 0f64;
        let n = 1_000_000;
        for i in 0..=n {
            let t = -1.0 + 3.0 * i as f32 / n as f32;
            let (s, c) = sincos_turns(t);
            let a = std::f64::consts::TAU * t as f64;
            worst = worst
                .max((s as f64 - a.sin()).abs())
                .max((c as f64 - a.cos()).abs());
        }
        assert!(worst < 2.4e-7, "sincos_turns error {worst:e}");
        // Exact at the quarter turns' signs: never a wrong quadrant.
        for (t, s, c) in [
            (0.0, 0.0, 1.0),
            (0.25, 1.0, 0.0),
            (0.5, 0.0, -1.0),
            (0.75, -1.0, 0.0),
        ] {
            let (gs, gc) = sincos_turns(t);
            assert!(
                (gs - s).abs() < 1e-7 && (gc - c).abs() < 1e-7,
                "{t}: {gs} {gc}"
            );
        }
    }

    #[test]
    fn atan2_error_bound() {
        let mut worst = 0f64;
        let n = 2000;
        for i in 0..n {
            let phi = std::f64::consts::TAU * (i as f64 + 0.37) / n as f64;
            for r in [1e-30f64, 1e-3, 1.0, 7.5, 1e20] {
                let (y, x) = ((phi.sin() * r) as f32, (phi.cos() * r) as f32);
                let want = (y as f64).atan2(x as f64);
                worst = worst.max((atan2(y, x) as f64 - want).abs());
            }
        }
        assert!(worst < 4e-7, "atan2 error {worst:e}");
        assert_eq!(atan2(0.0, 0.0), 0.0);
        assert_eq!(atan2(0.0, 1.0), 0.0);
        assert!((atan2(0.0, -1.0) - PI).abs() < 1e-7);
        assert!((atan2(1.0, 0.0) - FRAC_PI_2).abs() < 1e-7);
        assert!((atan2(-1.0, 0.0) + FRAC_PI_2).abs() < 1e-7);
        for v in [f32::MAX, f32::MIN_POSITIVE, 1e-45] {
            assert!(atan2(v, v).is_finite() && atan2(-v, v).is_finite());
        }
    }

    #[test]
    fn latlong_agrees_with_libm() {
        let mut worst = 0f64;
        let mut worst_dir = 0f32;
        for i in 0..400 {
            for j in 0..800 {
                let (u, v) = ((j as f32 + 0.31) / 800.0, (i as f32 + 0.77) / 400.0);
                let d = latlong::uv_to_direction(u, v);
                let (fd, st) = uv_to_direction(u, v);
                worst_dir = worst_dir
                    .max((fd - d).abs().max_element())
                    .max((st - (PI * v).sin()).abs());
                // Against f64 (libm's acos(z) in f32 is itself 6e-6 off near the poles).
                let e = (d * 3.0).as_dvec3();
                let lv = e.x.hypot(e.y).atan2(e.z) / std::f64::consts::PI;
                let lu = e.y.atan2(e.x).rem_euclid(std::f64::consts::TAU) / std::f64::consts::TAU;
                let (gu, gv) = direction_to_uv(d * 3.0);
                // u wraps at 1: compare on the circle.
                let du = (gu as f64 - lu).abs();
                worst = worst.max(du.min(1.0 - du)).max((gv as f64 - lv).abs());
            }
        }
        assert!(worst < 2e-7, "uv error {worst:e}");
        assert!(worst_dir < 5e-7, "direction error {worst_dir:e}");
        // Poles and degenerate input.
        assert_eq!(direction_to_uv(Vec3::Z).1, 0.0);
        assert_eq!(direction_to_uv(-Vec3::Z).1, 1.0);
        assert_eq!(direction_to_uv(Vec3::ZERO), (0.0, 0.0));
        assert_eq!(direction_to_uv(Vec3::new(f32::NAN, 0.0, 1.0)), (0.0, 0.0));
        let (u, _) = direction_to_uv(Vec3::new(1.0, -1e-30, 0.0));
        assert!((0.0..1.0).contains(&u));
    }
}
