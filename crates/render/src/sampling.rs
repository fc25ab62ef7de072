//! Random numbers and sampling distributions for the path tracer.
//!
//! - [`Rng`]: PCG32 (O'Neill), one stream per pixel / query, seeded by [`hash2`]`(seed, index)`
//!   so results do not depend on thread scheduling. No global RNG anywhere.
//! - [`Distribution1D`] / [`Distribution2D`]: piecewise-constant densities on [0, 1) and
//!   [0, 1)^2 (marginal over rows, conditional over columns), as in pbrt-v4.
//! - [`sample_cone`]: uniform directions in a cone, accurate for tiny cones (the sun).
//! - [`power_heuristic`]: MIS weight (beta = 2).
//! - [`shifted_hammersley`] / [`jittered`]: stratified sets in random order, for the first
//!   vertex of the solver's estimates (`PathTracer::lo_estimate_stratified`).

use glam::{Vec2, Vec3};
use igi_brdf::Frame;

/// SplitMix64 finaliser: a strong 64-bit mixing function.
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Hash of (seed, index), used to seed one independent stream per pixel or query.
#[inline]
pub fn hash2(seed: u64, index: u64) -> u64 {
    mix64(mix64(seed) ^ index.wrapping_mul(0xD6E8_FEB8_6659_FD93))
}

/// PCG32 (XSH-RR) generator: `rand_pcg::Pcg32` seeded per stream.
///
/// `Pcg32::new(h, stream)` is the reference `pcg32_srandom_r(h, stream)` (state 0, one step,
/// add `h`, one step), so the stream is exactly the one igi's own PCG32 produced before it
/// was replaced by the crate: same seed, same bytes (`rng_matches_the_reference_pcg32`).
#[derive(Clone, Debug)]
pub struct Rng(rand_pcg::Pcg32);

impl Rng {
    /// A generator for stream `index` of run `seed`.
    pub fn new(seed: u64, index: u64) -> Self {
        let h = hash2(seed, index);
        Rng(rand_pcg::Pcg32::new(h, mix64(h ^ 0xA5A5_A5A5)))
    }

    #[inline]
    pub fn next_u32(&mut self) -> u32 {
        rand::RngCore::next_u32(&mut self.0)
    }

    /// Uniform in [0, 1) (24 random bits, never returns 1.0).
    #[inline]
    pub fn uniform(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 * (1.0 / 16_777_216.0)
    }

    #[inline]
    pub fn uniform2(&mut self) -> Vec2 {
        let a = self.uniform();
        Vec2::new(a, self.uniform())
    }
}

/// `n` points of [0, 1)^2 spread evenly, in random order: the Hammersley set (`x = (i + 1/2) /
/// n`, `y` the base-2 radical inverse of `i`) under one random toroidal shift, shuffled. Each
/// point alone is uniform; together they fill every one of `n` columns once, and every one of
/// `n` rows once when `n` is a power of two.
pub fn shifted_hammersley(n: usize, rng: &mut Rng) -> Vec<Vec2> {
    let shift = rng.uniform2();
    let mut v: Vec<Vec2> = (0..n)
        .map(|i| {
            let p = Vec2::new((i as f32 + 0.5) / n as f32, radical_inverse_2(i as u32));
            Vec2::new(wrap_unit(p.x + shift.x), wrap_unit(p.y + shift.y))
        })
        .collect();
    shuffle(&mut v, rng);
    v
}

/// `n` numbers of [0, 1), one uniform in each of `n` equal strata, in random order.
pub fn jittered(n: usize, rng: &mut Rng) -> Vec<f32> {
    let mut v: Vec<f32> = (0..n)
        .map(|i| ((i as f32 + rng.uniform()) / n as f32).min(ONE_MINUS_EPSILON))
        .collect();
    shuffle(&mut v, rng);
    v
}

/// The largest f32 below 1.
const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;

/// Base-2 radical inverse of `i` (van der Corput), in [0, 1), 24 bits.
#[inline]
fn radical_inverse_2(i: u32) -> f32 {
    (i.reverse_bits() >> 8) as f32 * (1.0 / 16_777_216.0)
}

/// `x` in [0, 2) (a point plus a shift, both in [0, 1)) modulo 1, kept below 1.
#[inline]
fn wrap_unit(x: f32) -> f32 {
    debug_assert!((0.0..2.0).contains(&x), "{x}");
    let f = if x >= 1.0 { x - 1.0 } else { x };
    if f < 1.0 {
        f
    } else {
        0.0
    }
}

/// Fisher-Yates shuffle drawing from `rng`.
fn shuffle<T>(v: &mut [T], rng: &mut Rng) {
    for i in (1..v.len()).rev() {
        let j = ((rng.next_u32() as u64 * (i as u64 + 1)) >> 32) as usize;
        v.swap(i, j);
    }
}

/// Piecewise-constant density on [0, 1) with `n` equal cells.
#[derive(Clone, Debug)]
pub struct Distribution1D {
    func: Vec<f32>,
    /// Normalised density of each cell (func / integral, or 1 when the integral is 0).
    pdf: Vec<f32>,
    /// cdf[0] = 0, cdf[n] = 1 (length n + 1).
    cdf: Vec<f32>,
    /// Walker/Vose alias table: (probability of keeping cell i, alias of cell i).
    alias: Vec<(f32, u32)>,
    /// Guide table of the cdf (Chen and Asau's cutpoints): `guide[k]` is the last cell whose
    /// cdf is at most `k / n`, where [`Self::sample_inverse_cdf`] starts its search.
    guide: Vec<u32>,
    /// Integral of `func` over [0, 1] (= mean of func).
    integral: f64,
}

impl Distribution1D {
    /// `func` must be non-negative and finite (negative or NaN values count as zero).
    /// If it sums to zero the density is uniform.
    pub fn new(func: &[f32]) -> Self {
        let n = func.len().max(1);
        let func: Vec<f32> = if func.is_empty() {
            vec![0.0]
        } else {
            func.iter()
                .map(|&f| if f.is_finite() && f > 0.0 { f } else { 0.0 })
                .collect()
        };
        let mut acc = vec![0f64; n + 1];
        for i in 0..n {
            acc[i + 1] = acc[i] + func[i] as f64 / n as f64;
        }
        let integral = acc[n];
        let cdf: Vec<f32> = if integral > 0.0 {
            acc.iter().map(|&c| (c / integral) as f32).collect()
        } else {
            (0..=n).map(|i| i as f32 / n as f32).collect()
        };
        let mut cdf = cdf;
        cdf[n] = 1.0;
        let pdf = func
            .iter()
            .map(|&f| {
                if integral > 0.0 {
                    (f as f64 / integral) as f32
                } else {
                    1.0
                }
            })
            .collect();
        let alias = build_alias(&func, integral * n as f64);
        let guide = build_guide(&cdf);
        Distribution1D {
            func,
            pdf,
            cdf,
            alias,
            guide,
            integral,
        }
    }

    pub fn len(&self) -> usize {
        self.func.len()
    }

    pub fn is_empty(&self) -> bool {
        self.func.is_empty()
    }

    /// Integral of the unnormalised function over [0, 1].
    pub fn integral(&self) -> f64 {
        self.integral
    }

    /// Density (w.r.t. x in [0,1)) of cell `i`.
    #[inline]
    pub fn pdf_cell(&self, i: usize) -> f32 {
        self.pdf[i]
    }

    /// Samples x in [0, 1); returns (x, pdf(x), cell index). O(1) through the alias table: the
    /// cell is chosen with probability `func[i] / sum(func)`, and x is uniform inside it. Not
    /// monotone in `u` (use [`Self::sample_inverse_cdf`] where that matters).
    #[inline]
    pub fn sample(&self, u: f32) -> (f32, f32, usize) {
        let n = self.func.len();
        let s = u * n as f32;
        let j = (s as usize).min(n - 1);
        let f = (s - j as f32).clamp(0.0, 1.0);
        let (keep, other) = self.alias[j];
        let (i, du) = if f < keep {
            (j, f / keep)
        } else {
            (
                other as usize,
                if keep < 1.0 {
                    (f - keep) / (1.0 - keep)
                } else {
                    0.5
                },
            )
        };
        let x = ((i as f32 + du.clamp(0.0, 1.0)) / n as f32).min(1.0 - f32::EPSILON * 0.5);
        (x, self.pdf[i], i)
    }

    /// Samples x in [0, 1) by inverting the cdf (monotone in `u`; O(1) on average through the
    /// guide table).
    #[inline]
    pub fn sample_inverse_cdf(&self, u: f32) -> (f32, f32, usize) {
        let n = self.func.len();
        // the last cell whose cdf is at most u: at or after the guide's cell for u's bucket
        let mut i = self.guide[((u * n as f32) as usize).min(n - 1)] as usize;
        while i > 0 && self.cdf[i] > u {
            i -= 1; // u * n rounded up to the next bucket
        }
        while i + 1 < n && self.cdf[i + 1] <= u {
            i += 1;
        }
        // Skip zero-probability cells (u landed exactly on a flat stretch of the cdf).
        while i + 1 < n && self.cdf[i + 1] <= self.cdf[i] {
            i += 1;
        }
        while i > 0 && self.cdf[i + 1] <= self.cdf[i] {
            i -= 1;
        }
        let width = self.cdf[i + 1] - self.cdf[i];
        let du = if width > 0.0 {
            ((u - self.cdf[i]) / width).clamp(0.0, 1.0)
        } else {
            0.5
        };
        let x = ((i as f32 + du) / n as f32).min(1.0 - f32::EPSILON * 0.5);
        (x, self.pdf_cell(i), i)
    }
}

/// `guide[k]` = the last cell `i < n` with `cdf[i] <= k / n` (`cdf` has `n + 1` entries).
fn build_guide(cdf: &[f32]) -> Vec<u32> {
    let n = cdf.len() - 1;
    let mut i = 0;
    (0..n)
        .map(|k| {
            let t = k as f32 / n as f32;
            while i + 1 < n && cdf[i + 1] <= t {
                i += 1;
            }
            i as u32
        })
        .collect()
}

/// Vose's alias table for non-negative weights `func` whose sum is `total`.
fn build_alias(func: &[f32], total: f64) -> Vec<(f32, u32)> {
    let n = func.len();
    if !(total > 0.0) {
        return (0..n).map(|i| (1.0, i as u32)).collect();
    }
    let mut scaled: Vec<f64> = func.iter().map(|&f| f as f64 * n as f64 / total).collect();
    let mut table = vec![(1.0f32, 0u32); n];
    let (mut small, mut large): (Vec<usize>, Vec<usize>) = (0..n).partition(|&i| scaled[i] < 1.0);
    while let (Some(&s), Some(&l)) = (small.last(), large.last()) {
        small.pop();
        table[s] = (scaled[s] as f32, l as u32);
        scaled[l] -= 1.0 - scaled[s];
        if scaled[l] < 1.0 {
            large.pop();
            small.push(l);
        }
    }
    for i in large.into_iter().chain(small) {
        table[i] = (1.0, i as u32); // leftovers are 1 up to rounding
    }
    table
}

/// Piecewise-constant density on [0, 1)^2 over a `w x h` grid (row index = v, column = u).
#[derive(Clone, Debug)]
pub struct Distribution2D {
    conditional: Vec<Distribution1D>,
    marginal: Distribution1D,
    w: usize,
    h: usize,
}

impl Distribution2D {
    /// `func[row * w + col]`, row-major.
    pub fn new(func: &[f32], w: usize, h: usize) -> Self {
        assert_eq!(func.len(), w * h, "Distribution2D: func has the wrong size");
        let conditional: Vec<Distribution1D> = (0..h)
            .map(|r| Distribution1D::new(&func[r * w..(r + 1) * w]))
            .collect();
        let row_int: Vec<f32> = conditional.iter().map(|c| c.integral() as f32).collect();
        let marginal = Distribution1D::new(&row_int);
        Distribution2D {
            conditional,
            marginal,
            w,
            h,
        }
    }

    /// Integral of the unnormalised function over the unit square.
    pub fn integral(&self) -> f64 {
        self.marginal.integral()
    }

    /// Samples (u, v); returns ((u, v), pdf w.r.t. du dv).
    #[inline]
    pub fn sample(&self, s: Vec2) -> (Vec2, f32) {
        let (v, pdf_v, row) = self.marginal.sample(s.y);
        let (u, pdf_u, _) = self.conditional[row].sample(s.x);
        (Vec2::new(u, v), pdf_v * pdf_u)
    }

    /// Samples (u, v) by inverting the marginal and conditional cdfs: monotone in each
    /// coordinate of `s`, so stratified `s` stay stratified (O(log n) against the alias
    /// table's O(1)).
    #[inline]
    pub fn sample_inverse_cdf(&self, s: Vec2) -> (Vec2, f32) {
        let (v, pdf_v, row) = self.marginal.sample_inverse_cdf(s.y);
        let (u, pdf_u, _) = self.conditional[row].sample_inverse_cdf(s.x);
        (Vec2::new(u, v), pdf_v * pdf_u)
    }

    /// Density w.r.t. du dv at (u, v).
    #[inline]
    pub fn pdf(&self, uv: Vec2) -> f32 {
        let col = ((uv.x * self.w as f32) as usize).min(self.w - 1);
        let row = ((uv.y * self.h as f32) as usize).min(self.h - 1);
        self.marginal.pdf_cell(row) * self.conditional[row].pdf_cell(col)
    }

    pub fn width(&self) -> usize {
        self.w
    }

    pub fn height(&self) -> usize {
        self.h
    }
}

/// Uniform direction inside the cone around unit `axis` whose solid angle is
/// 2 pi * `one_minus_cos_max`. Works from 1 - cos(theta) directly so that cones a fraction of a
/// degree wide (the sun) keep full precision in f32. The pdf is 1 / (2 pi one_minus_cos_max).
#[inline]
pub fn sample_cone(axis: Vec3, one_minus_cos_max: f32, u: Vec2) -> Vec3 {
    sample_cone_in(&Frame::from_normal(axis), one_minus_cos_max, u)
}

/// [`sample_cone`] around `frame.n` with a precomputed frame.
#[inline]
pub fn sample_cone_in(frame: &Frame, one_minus_cos_max: f32, u: Vec2) -> Vec3 {
    let omc = u.x * one_minus_cos_max; // 1 - cos(theta), uniform
    let sin2 = (omc * (2.0 - omc)).max(0.0);
    let sin_t = sin2.sqrt();
    let cos_t = 1.0 - omc;
    let (sp, cp) = crate::fastmath::sincos_turns(u.y);
    frame
        .to_world(Vec3::new(sin_t * cp, sin_t * sp, cos_t))
        .normalize()
}

/// Power heuristic (beta = 2) weight of strategy `a` against `b`, with one sample each.
#[inline]
pub fn power_heuristic(pdf_a: f32, pdf_b: f32) -> f32 {
    let a = pdf_a * pdf_a;
    let b = pdf_b * pdf_b;
    if a + b > 0.0 && a.is_finite() {
        a / (a + b)
    } else if !a.is_finite() {
        1.0
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The reference PCG32 (O'Neill's `pcg32_srandom_r` and `pcg32_random_r`), which igi's
    /// own generator implemented before `rand_pcg` replaced it.
    fn reference_pcg32(h: u64, stream: u64, n: usize) -> Vec<u32> {
        const MUL: u64 = 6_364_136_223_846_793_005;
        let inc = (stream << 1) | 1;
        let mut state = 0u64;
        let next = |state: &mut u64| {
            let old = *state;
            *state = old.wrapping_mul(MUL).wrapping_add(inc);
            ((((old >> 18) ^ old) >> 27) as u32).rotate_right((old >> 59) as u32)
        };
        next(&mut state);
        state = state.wrapping_add(h);
        next(&mut state);
        (0..n).map(|_| next(&mut state)).collect()
    }

    #[test]
    fn guided_inverse_cdf_finds_the_cell_a_binary_search_finds() {
        let mut rng = Rng::new(11, 0);
        for (len, zeros) in [
            (1usize, false),
            (7, true),
            (64, false),
            (129, true),
            (1000, true),
        ] {
            let func: Vec<f32> = (0..len)
                .map(|i| {
                    let f = rng.uniform() * rng.uniform() * 10.0;
                    if zeros && (i % 5 == 1 || i > len * 2 / 3) {
                        0.0
                    } else {
                        f
                    }
                })
                .collect();
            let d = Distribution1D::new(&func);
            let edges: Vec<f32> = d
                .cdf
                .iter()
                .flat_map(|&c| [c, c.next_down(), c.next_up()])
                .collect();
            let us = (0..5000)
                .map(|_| rng.uniform())
                .chain(edges.into_iter().filter(|u| (0.0..1.0).contains(u)));
            for u in us {
                let n = d.len();
                let expect = d.cdf[..n]
                    .partition_point(|&c| c <= u)
                    .saturating_sub(1)
                    .min(n - 1);
                let (_, _, got) = d.sample_inverse_cdf(u);
                // the search may step off a zero-probability cell it landed on; compare where both
                // land on a cell of positive probability
                if d.pdf_cell(expect) > 0.0 {
                    assert_eq!(got, expect, "len {len}, u {u}");
                } else {
                    assert!(d.pdf_cell(got) > 0.0, "len {len}, u {u}: zero cell {got}");
                }
            }
        }
    }

    #[test]
    fn stratified_sets_fill_every_stratum_once_and_differ_per_stream() {
        for n in [1usize, 16, 64, 100, 128] {
            let mut rng = Rng::new(3, n as u64);
            let pts = shifted_hammersley(n, &mut rng);
            let once = |coord: &dyn Fn(&Vec2) -> f32| {
                let mut count = vec![0u32; n];
                for p in &pts {
                    let c = coord(p);
                    assert!((0.0..1.0).contains(&c), "{c}");
                    count[((c * n as f32) as usize).min(n - 1)] += 1;
                }
                count
            };
            // x: the shift moves the column grid, so each column holds one point, up to a
            // rounding at a stratum's edge for counts that are not powers of two.
            let cols = once(&|p| p.x);
            assert!(cols.iter().all(|&c| c <= 2), "n {n}: {cols:?}");
            assert!(
                cols.iter().filter(|&&c| c == 1).count() + 2 >= n,
                "n {n}: {cols:?}"
            );
            if n.is_power_of_two() {
                let rows = once(&|p| p.y);
                assert!(rows.iter().all(|&c| c <= 2), "n {n}: {rows:?}");
                assert!(
                    rows.iter().filter(|&&c| c == 1).count() + 2 >= n,
                    "n {n}: {rows:?}"
                );
            }
            let j = jittered(n, &mut rng);
            let mut strata: Vec<usize> = j.iter().map(|x| (x * n as f32) as usize).collect();
            strata.sort_unstable();
            assert_eq!(strata, (0..n).collect::<Vec<_>>());
        }
        // another stream: another shift and order
        let a = shifted_hammersley(64, &mut Rng::new(1, 0));
        let b = shifted_hammersley(64, &mut Rng::new(1, 1));
        assert_ne!(a, b);
        // each point alone is uniform: the mean of many sets' first points is 1/2
        let m = (0..4000)
            .map(|i| shifted_hammersley(8, &mut Rng::new(5, i))[0])
            .fold(Vec2::ZERO, |a, p| a + p)
            / 4000.0;
        assert!((m - Vec2::splat(0.5)).abs().max_element() < 0.02, "{m}");
    }

    #[test]
    fn rng_matches_the_reference_pcg32() {
        for (seed, index) in [(0u64, 0u64), (7, 123_456), (u64::MAX, 1 << 40)] {
            let h = hash2(seed, index);
            let want = reference_pcg32(h, mix64(h ^ 0xA5A5_A5A5), 1000);
            let mut r = Rng::new(seed, index);
            let got: Vec<u32> = (0..1000).map(|_| r.next_u32()).collect();
            assert_eq!(got, want, "seed {seed} index {index}");
        }
    }

    #[test]
    fn rng_is_deterministic_and_uniform() {
        let mut a = Rng::new(7, 3);
        let mut b = Rng::new(7, 3);
        let mut c = Rng::new(7, 4);
        let xs: Vec<f32> = (0..10_000).map(|_| a.uniform()).collect();
        let ys: Vec<f32> = (0..10_000).map(|_| b.uniform()).collect();
        let zs: Vec<f32> = (0..10_000).map(|_| c.uniform()).collect();
        assert_eq!(xs, ys);
        assert_ne!(xs, zs);
        let mean = xs.iter().map(|&x| x as f64).sum::<f64>() / 1e4;
        let var = xs.iter().map(|&x| (x as f64 - mean).powi(2)).sum::<f64>() / 1e4;
        assert!((mean - 0.5).abs() < 0.01, "{mean}");
        assert!((var - 1.0 / 12.0).abs() < 0.003, "{var}");
        assert!(xs.iter().all(|&x| (0.0..1.0).contains(&x)));
    }

    #[test]
    fn distribution1d_samples_follow_the_function() {
        let f = [0.0, 1.0, 3.0, 0.0, 4.0];
        let d = Distribution1D::new(&f);
        assert!((d.integral() - 8.0 / 5.0).abs() < 1e-9);
        let mut counts = [0usize; 5];
        let mut rng = Rng::new(1, 0);
        let n = 80_000;
        for _ in 0..n {
            let (x, pdf, i) = d.sample(rng.uniform());
            assert!((0.0..1.0).contains(&x));
            assert_eq!(i, (x * 5.0) as usize);
            assert!((pdf - f[i] / 1.6).abs() < 1e-5);
            counts[i] += 1;
        }
        assert_eq!(counts[0], 0);
        assert_eq!(counts[3], 0);
        for i in [1, 2, 4] {
            let expect = n as f64 * f[i] as f64 / 8.0;
            assert!(
                (counts[i] as f64 - expect).abs() < 4.0 * expect.sqrt(),
                "{i} {counts:?}"
            );
        }
        // Edge values of u land in cells of non-zero probability, inside [0, 1).
        for u in [0.0, 1e-7, 0.4, 0.6, 0.999_999_9] {
            let (x, _, i) = d.sample(u);
            assert!(
                f[i] > 0.0 && (0.0..1.0).contains(&x),
                "u = {u}: cell {i}, x = {x}"
            );
            let (x, _, i) = d.sample_inverse_cdf(u);
            assert!(
                f[i] > 0.0 && (0.0..1.0).contains(&x),
                "u = {u}: cell {i}, x = {x}"
            );
        }
        let (x0, _, i0) = d.sample_inverse_cdf(0.0);
        assert_eq!(i0, 1);
        assert!((x0 - 0.2).abs() < 1e-6);
        // The inverse-cdf sampler follows the function too.
        let mut c2 = [0usize; 5];
        for _ in 0..n {
            c2[d.sample_inverse_cdf(rng.uniform()).2] += 1;
        }
        for i in [1, 2, 4] {
            let expect = n as f64 * f[i] as f64 / 8.0;
            assert!(
                (c2[i] as f64 - expect).abs() < 4.0 * expect.sqrt(),
                "{i} {c2:?}"
            );
        }
        // All-zero function: uniform.
        let z = Distribution1D::new(&[0.0, 0.0]);
        assert_eq!(z.pdf_cell(1), 1.0);
    }

    #[test]
    fn distribution2d_pdf_integrates_to_one() {
        let (w, h) = (7, 5);
        let f: Vec<f32> = (0..w * h).map(|i| ((i * 37) % 11) as f32).collect();
        let d = Distribution2D::new(&f, w, h);
        let mut total = 0.0f64;
        for r in 0..h {
            for c in 0..w {
                let uv = Vec2::new((c as f32 + 0.5) / w as f32, (r as f32 + 0.5) / h as f32);
                let p = d.pdf(uv) as f64;
                total += p / (w * h) as f64;
                let expect = f[r * w + c] as f64 / d.integral();
                assert!(
                    (p - expect).abs() < 1e-4 * expect.max(1.0),
                    "{p} vs {expect}"
                );
            }
        }
        assert!((total - 1.0).abs() < 1e-5, "{total}");
        let mut rng = Rng::new(2, 0);
        for _ in 0..1000 {
            let (uv, pdf) = d.sample(rng.uniform2());
            assert!((pdf - d.pdf(uv)).abs() < 1e-4 * pdf.max(1.0));
            assert!(pdf > 0.0);
        }
    }

    #[test]
    fn cone_samples_are_uniform_inside_a_tiny_cone() {
        let axis = Vec3::new(0.3, -0.5, 0.8).normalize();
        let half = (0.53f64 / 2.0).to_radians();
        let omc = (2.0 * (half / 2.0).sin().powi(2)) as f32;
        let mut rng = Rng::new(3, 0);
        let n = 40_000;
        let mut inner = 0;
        for _ in 0..n {
            let d = sample_cone(axis, omc, rng.uniform2());
            assert!((d.length() - 1.0).abs() < 1e-5);
            let ang = d.cross(axis).length().asin() as f64;
            assert!(ang <= half * 1.0001, "{ang} > {half}");
            // Uniform in solid angle: P(angle < half / sqrt 2) = (1 - cos(h/sqrt2)) / (1 - cos h) ~ 1/2.
            if ang < half / 2f64.sqrt() {
                inner += 1;
            }
        }
        let p = (1.0 - (half / 2f64.sqrt()).cos()) / (1.0 - half.cos());
        let expect = p * n as f64;
        assert!(
            (inner as f64 - expect).abs() < 4.0 * (expect * (1.0 - p)).sqrt(),
            "{inner} vs {expect}"
        );
    }

    #[test]
    fn power_heuristic_limits() {
        assert_eq!(power_heuristic(1.0, 0.0), 1.0);
        assert_eq!(power_heuristic(0.0, 1.0), 0.0);
        assert!((power_heuristic(1.0, 1.0) - 0.5).abs() < 1e-7);
        assert_eq!(power_heuristic(f32::INFINITY, 1.0), 1.0);
        assert_eq!(power_heuristic(0.0, 0.0), 0.0);
    }
}
