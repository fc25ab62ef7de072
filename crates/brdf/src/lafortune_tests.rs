//! Tests of the Lafortune model: chi-square goodness of fit of the sampler (pbrt-v4 style),
//! pdf normalisation, eval/pdf consistency, reciprocity, energy, and no NaN for random input.

use glam::{Vec2, Vec3};
use rand::{Rng, SeedableRng};

use crate::{Frame, Lafortune, Lobe};

const PI: f32 = std::f32::consts::PI;

/// A specular lobe (Cxy = -1, Cz = 1) normalised so that its albedo at normal incidence is `k`.
fn spec(k: Vec3, n: f32) -> Lobe {
    Lobe {
        rho: k * (n + 2.0) / (2.0 * PI),
        cxy: -1.0,
        cz: 1.0,
        n,
    }
}
/// A retroreflective lobe (Cxy = Cz = 1, axis = wo), albedo about `k` at normal incidence.
fn retro(k: Vec3, n: f32) -> Lobe {
    Lobe {
        rho: k * (n + 2.0) / (2.0 * PI),
        cxy: 1.0,
        cz: 1.0,
        n,
    }
}

fn materials() -> Vec<(&'static str, Lafortune)> {
    let s = Vec3::splat;
    vec![
        ("diffuse", Lafortune::lambertian(Vec3::new(0.5, 0.6, 0.7))),
        (
            "specular n=30",
            Lafortune {
                rho_d: s(0.2),
                lobes: vec![spec(Vec3::new(0.5, 0.4, 0.3), 30.0)],
            },
        ),
        (
            "off-specular cxy=-0.8",
            Lafortune {
                rho_d: s(0.1),
                lobes: vec![Lobe {
                    rho: s(0.5) * 22.0 / (2.0 * PI),
                    cxy: -0.8,
                    cz: 1.0,
                    n: 20.0,
                }],
            },
        ),
        (
            "retroreflective n=10",
            Lafortune {
                rho_d: s(0.3),
                lobes: vec![retro(s(0.4), 10.0)],
            },
        ),
        (
            "mix diffuse+spec+retro",
            Lafortune {
                rho_d: Vec3::new(0.3, 0.25, 0.2),
                lobes: vec![spec(s(0.3), 50.0), retro(s(0.2), 8.0)],
            },
        ),
        (
            "stiff specular n=1000",
            Lafortune {
                rho_d: s(0.1),
                lobes: vec![spec(s(0.8), 1000.0)],
            },
        ),
        (
            "stiff specular n=1e4",
            Lafortune {
                rho_d: s(0.05),
                lobes: vec![spec(s(0.9), 1.0e4)],
            },
        ),
        (
            "pure lobe n=1e4, no diffuse",
            Lafortune {
                rho_d: Vec3::ZERO,
                lobes: vec![spec(s(0.9), 1.0e4)],
            },
        ),
        (
            "stiff retro n=1000 + spec",
            Lafortune {
                rho_d: s(0.05),
                lobes: vec![retro(s(0.3), 1000.0), spec(s(0.5), 200.0)],
            },
        ),
    ]
}

fn view_dirs() -> Vec<Vec3> {
    let mut v = Vec::new();
    for cos in [1.0f32, 0.866, 0.5, 0.2, 0.05] {
        let sin = (1.0 - cos * cos).max(0.0).sqrt();
        let phi = 0.7f32;
        v.push(Vec3::new(sin * phi.cos(), sin * phi.sin(), cos));
    }
    v
}

/// Regularised upper incomplete gamma Q(a, x) (Numerical Recipes: series / continued fraction).
fn gamma_q(a: f64, x: f64) -> f64 {
    fn ln_gamma(x: f64) -> f64 {
        // Lanczos approximation (g = 7, n = 9).
        let c = [
            0.999_999_999_999_809_9,
            676.520_368_121_885_1,
            -1_259.139_216_722_402_8,
            771.323_428_777_653_1,
            -176.615_029_162_140_6,
            12.507_343_278_686_905,
            -0.138_571_095_265_720_12,
            9.984_369_578_019_572e-6,
            1.505_632_735_149_311_6e-7,
        ];
        let x = x - 1.0;
        let mut s = c[0];
        for (i, ci) in c.iter().enumerate().skip(1) {
            s += ci / (x + i as f64);
        }
        let t = x + 7.5;
        0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + s.ln()
    }
    if x <= 0.0 {
        return 1.0;
    }
    let gln = ln_gamma(a);
    if x < a + 1.0 {
        let mut ap = a;
        let mut sum = 1.0 / a;
        let mut del = sum;
        for _ in 0..10_000 {
            ap += 1.0;
            del *= x / ap;
            sum += del;
            if del.abs() < sum.abs() * 1e-15 {
                break;
            }
        }
        1.0 - sum * (-x + a * x.ln() - gln).exp()
    } else {
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / 1e-300;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..10_000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < 1e-300 {
                d = 1e-300;
            }
            c = b + an / c;
            if c.abs() < 1e-300 {
                c = 1e-300;
            }
            d = 1.0 / d;
            let del = d * c;
            h *= del;
            if (del - 1.0).abs() < 1e-15 {
                break;
            }
        }
        (-x + a * x.ln() - gln).exp() * h
    }
}

#[test]
fn gamma_q_matches_known_values() {
    // Q(1, x) = exp(-x); chi^2 with 2 dof at 5.991 has p = 0.05; 10 dof at 23.209 has p = 0.01.
    assert!((gamma_q(1.0, 2.0) - (-2.0f64).exp()).abs() < 1e-12);
    assert!((gamma_q(1.0, 5.991 / 2.0) - 0.05).abs() < 1e-4);
    assert!((gamma_q(5.0, 23.209 / 2.0) - 0.01).abs() < 1e-4);
    assert!((gamma_q(50.0, 50.0) - 0.4811).abs() < 1e-3);
}

/// Bins on the sphere around `axis`: edges in c = cos(angle to axis) (equal-mass edges of a
/// cos^m lobe, merged with uniform edges, plus the back hemisphere) times uniform azimuth bins.
struct Binning {
    frame: Frame,
    c_edges: Vec<f64>,
    n_phi: usize,
}

impl Binning {
    fn new(axis: Vec3, m: f64) -> Self {
        let mut e: Vec<f64> = Vec::new();
        let k = 12;
        for i in 0..=k {
            // P(c > e) = 1 - e^(m+1) for a cos^m lobe: equal mass per bin
            e.push((i as f64 / k as f64).powf(1.0 / (m + 1.0)));
        }
        for i in 0..=10 {
            e.push(-1.0 + 2.0 * i as f64 / 10.0);
        }
        e.sort_by(|a, b| a.partial_cmp(b).unwrap());
        e.dedup_by(|a, b| (*a - *b).abs() < 1e-9);
        Binning {
            frame: Frame::from_normal(axis),
            c_edges: e,
            n_phi: 16,
        }
    }
    fn n_bins(&self) -> usize {
        (self.c_edges.len() - 1) * self.n_phi
    }
    fn dir(&self, c: f64, phi: f64) -> Vec3 {
        let s = (1.0 - c * c).max(0.0).sqrt();
        self.frame
            .to_world(Vec3::new(
                (s * phi.cos()) as f32,
                (s * phi.sin()) as f32,
                c as f32,
            ))
            .normalize()
    }
    fn bin_of(&self, w: Vec3) -> usize {
        let l = self.frame.to_local(w);
        let c = (l.z as f64).clamp(-1.0, 1.0);
        let mut phi = (l.y as f64).atan2(l.x as f64);
        if phi < 0.0 {
            phi += 2.0 * std::f64::consts::PI;
        }
        let ic = match self.c_edges.iter().position(|&e| e > c) {
            Some(0) => 0,
            Some(i) => i - 1,
            None => self.c_edges.len() - 2,
        };
        let ip =
            ((phi / (2.0 * std::f64::consts::PI) * self.n_phi as f64) as usize).min(self.n_phi - 1);
        ic * self.n_phi + ip
    }
    /// Integrate `g` over every bin: midpoint rule on sub-cells whose c edges are the union of
    /// uniform-in-c and uniform-in-c^(m+1) edges (so both broad and sharp lobes are resolved).
    fn integrate(&self, m: f64, mut g: impl FnMut(Vec3) -> f64) -> Vec<f64> {
        let mut out = vec![0.0; self.n_bins()];
        let sub_phi = 12;
        let sub_c = 24;
        for ic in 0..self.c_edges.len() - 1 {
            let (a, b) = (self.c_edges[ic], self.c_edges[ic + 1]);
            let mut sub: Vec<f64> = (0..=sub_c)
                .map(|i| a + (b - a) * i as f64 / sub_c as f64)
                .collect();
            if a >= 0.0 {
                let (wa, wb) = (a.powf(m + 1.0), b.powf(m + 1.0));
                for i in 1..sub_c {
                    let w = wa + (wb - wa) * i as f64 / sub_c as f64;
                    sub.push(w.powf(1.0 / (m + 1.0)).clamp(a, b)); // underflow of w must not leave [a, b]
                }
                // geometric edges in w resolve the exponential tail of the lobe below the bin's top
                for k in 1..120 {
                    let w = wb * 2f64.powf(-k as f64 / 3.0);
                    if w <= wa {
                        break;
                    }
                    sub.push(w.powf(1.0 / (m + 1.0)).clamp(a, b));
                }
            }
            // edges uniform in angle resolve other lobes near either pole of the binning axis
            let (ta, tb) = (a.acos(), b.acos());
            for i in 1..48 {
                sub.push((ta + (tb - ta) * i as f64 / 48.0).cos().clamp(a, b));
            }
            sub.sort_by(|x, y| x.partial_cmp(y).unwrap());
            sub.dedup_by(|x, y| (*x - *y).abs() < 1e-13);
            for ip in 0..self.n_phi {
                let dphi = 2.0 * std::f64::consts::PI / self.n_phi as f64;
                let mut acc = 0.0;
                for w in sub.windows(2) {
                    let dc = w[1] - w[0];
                    let cm = 0.5 * (w[0] + w[1]);
                    for jp in 0..sub_phi {
                        let phi = dphi * (ip as f64 + (jp as f64 + 0.5) / sub_phi as f64);
                        acc += g(self.dir(cm, phi)) * dc * dphi / sub_phi as f64;
                    }
                }
                out[ic * self.n_phi + ip] = acc;
            }
        }
        out
    }
}

/// The binning axis and exponent for a material at `wo`: the sharpest lobe's axis, else the normal.
fn binning_for(m: &Lafortune, wo: Vec3) -> (Vec3, f64) {
    let mut best = (Vec3::Z, 1.0f64);
    for l in &m.lobes {
        if (l.n as f64) > best.1 {
            let c = Vec3::new(l.cxy * wo.x, l.cxy * wo.y, l.cz * wo.z);
            if c.length() > 0.0 {
                best = (c.normalize(), l.n as f64);
            }
        }
    }
    best
}

/// One chi-square test; returns (p-value, integral of the pdf over the hemisphere, quadrature albedo).
fn chi2_test(m: &Lafortune, wo: Vec3, n_samples: usize, seed: u64) -> (f64, f64, Vec3) {
    let r = m.as_ref();
    let (axis, expo) = binning_for(m, wo);
    let bins = Binning::new(axis, expo);
    let mut observed = vec![0.0f64; bins.n_bins()];
    let mut none = 0.0f64;
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    for _ in 0..n_samples {
        let us: f32 = rng.gen();
        let u = Vec2::new(rng.gen(), rng.gen());
        match r.sample(wo, us, u) {
            Some(s) => {
                assert!(s.wi.z > 0.0 && s.pdf > 0.0 && s.pdf.is_finite() && s.value.is_finite());
                assert!((s.wi.length() - 1.0).abs() < 1e-4);
                observed[bins.bin_of(s.wi)] += 1.0;
            }
            None => none += 1.0,
        }
    }
    let pdf_int = bins.integrate(expo, |w| r.pdf(w, wo) as f64);
    let total: f64 = pdf_int.iter().sum();
    let mut alb = [0.0f64; 3];
    for c in 0..3 {
        alb[c] = bins
            .integrate(expo, |w| (r.eval(w, wo)[c] * w.z.max(0.0)) as f64)
            .iter()
            .sum();
    }
    let mut expected: Vec<f64> = pdf_int.iter().map(|p| p * n_samples as f64).collect();
    expected.push((1.0 - total).max(0.0) * n_samples as f64);
    observed.push(none);
    // merge low-expectation bins into one pooled bin, chi^2 over the rest
    let (mut pool_e, mut pool_o) = (0.0, 0.0);
    let mut chi2 = 0.0;
    let mut dof = 0usize;
    for (bi, (e, o)) in expected.iter().zip(&observed).enumerate() {
        if *e < 5.0 {
            pool_e += e;
            pool_o += o;
        } else {
            if std::env::var("CHI_DEBUG").is_ok() && (o - e) * (o - e) / e > 20.0 {
                eprintln!(
                    "bin {bi} ic {} ip {} e={e} o={o} edges {:?}",
                    bi / bins.n_phi,
                    bi % bins.n_phi,
                    bins.c_edges
                );
            }
            chi2 += (o - e) * (o - e) / e;
            dof += 1;
        }
    }
    if pool_e > 0.0 || pool_o > 0.0 {
        if pool_e < 5.0 && pool_o > 2.0 * pool_e + 25.0 {
            return (
                0.0,
                total,
                Vec3::new(alb[0] as f32, alb[1] as f32, alb[2] as f32),
            );
        }
        if pool_e > 0.0 {
            chi2 += (pool_o - pool_e) * (pool_o - pool_e) / pool_e;
            dof += 1;
        }
    }
    let p = gamma_q((dof as f64 - 1.0) / 2.0, chi2 / 2.0);
    (
        p,
        total,
        Vec3::new(alb[0] as f32, alb[1] as f32, alb[2] as f32),
    )
}

#[test]
fn sampler_passes_chi_square_for_every_material_and_view() {
    let mut seed = 1u64;
    for (name, m) in materials() {
        for wo in view_dirs() {
            seed += 1;
            let (p, total, quad_albedo) = chi2_test(&m, wo, 200_000, seed);
            assert!(p > 1e-4, "{name}, wo = {wo:?}: chi-square p-value {p:.3e}");
            assert!(
                total <= 1.0 + 2e-3 && total > 0.3,
                "{name}, wo = {wo:?}: pdf integrates to {total}"
            );
            // eval/pdf consistency: the estimator E[f cos / pdf] equals the quadrature albedo
            let mc = m.as_ref().albedo(wo, 200_000, seed + 1000);
            for c in 0..3 {
                let (a, b) = (mc[c], quad_albedo[c]);
                assert!(
                    (a - b).abs() <= 0.02 * b.max(0.02),
                    "{name}, wo = {wo:?}: MC albedo {mc:?} vs quadrature {quad_albedo:?}"
                );
            }
            assert!(
                quad_albedo.max_element() <= 1.0,
                "{name}: albedo {quad_albedo:?} > 1"
            );
        }
    }
}

#[test]
fn lambertian_albedo_is_exact_and_pdf_is_cosine() {
    let m = Lafortune::lambertian(Vec3::new(0.2, 0.5, 0.9));
    for wo in view_dirs() {
        let a = m.as_ref().albedo(wo, 1000, 3);
        assert!((a - m.rho_d).abs().max_element() < 1e-5, "{a:?}");
        let wi = Vec3::new(0.6, 0.0, 0.8);
        assert!((m.as_ref().pdf(wi, wo) - 0.8 / PI).abs() < 1e-6);
        assert!((m.as_ref().eval(wi, wo) - m.rho_d / PI).abs().max_element() < 1e-7);
    }
}

#[test]
fn normalised_specular_albedo_at_normal_incidence_matches_analytic() {
    // (n+2)/(2pi) * integral cos^(n+1) = 1 at wo = z, for n from 1 to 1e4.
    for n in [1.0f32, 30.0, 1000.0, 1.0e4] {
        let m = Lafortune {
            rho_d: Vec3::ZERO,
            lobes: vec![spec(Vec3::new(0.9, 0.5, 0.1), n)],
        };
        let a = m.as_ref().albedo(Vec3::Z, 100_000, 11);
        assert!(
            (a - Vec3::new(0.9, 0.5, 0.1)).abs().max_element() < 0.01,
            "n = {n}: {a:?}"
        );
    }
}

#[test]
fn reciprocity_holds_exactly() {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
    for (name, m) in materials() {
        for _ in 0..2000 {
            let a = random_upper(&mut rng);
            let b = random_upper(&mut rng);
            let fab = m.as_ref().eval(a, b);
            let fba = m.as_ref().eval(b, a);
            assert_eq!(fab, fba, "{name}: f(a,b) != f(b,a) for {a:?} {b:?}");
        }
    }
}

fn random_upper(rng: &mut impl Rng) -> Vec3 {
    loop {
        let v = Vec3::new(
            rng.gen_range(-1.0..1.0),
            rng.gen_range(-1.0..1.0),
            rng.gen_range(0.0..1.0),
        );
        let l = v.length();
        if l > 0.1 && l <= 1.0 && v.z > 0.0 {
            return v / l;
        }
    }
}

#[test]
fn test_materials_conserve_energy_and_check_detects_violation() {
    for (name, m) in materials() {
        let a = m.max_albedo();
        assert!(a.max_element() <= 1.0, "{name}: max albedo {a:?}");
        assert!(m.is_energy_conserving(), "{name}");
    }
    // |C| > 1: |c(wo)|^N grows as 1.2^100 ~ 8e7 -> far above 1.
    let bad = Lafortune {
        rho_d: Vec3::splat(0.1),
        lobes: vec![Lobe {
            rho: Vec3::splat(1.0),
            cxy: -1.2,
            cz: 1.2,
            n: 100.0,
        }],
    };
    assert!(bad.max_albedo().max_element() > 10.0);
    assert!(!bad.is_energy_conserving());
    // A too-bright lambertian is also flagged.
    assert!(!Lafortune::lambertian(Vec3::new(0.5, 1.2, 0.5)).is_energy_conserving());
}

#[test]
fn below_horizon_and_degenerate_inputs_give_zero() {
    let m = &materials()[4].1;
    let r = m.as_ref();
    let up = Vec3::new(0.0, 0.6, 0.8);
    let down = Vec3::new(0.0, 0.6, -0.8);
    assert_eq!(r.eval(down, up), Vec3::ZERO);
    assert_eq!(r.eval(up, down), Vec3::ZERO);
    assert_eq!(r.pdf(up, down), 0.0);
    assert!(r.sample(down, 0.5, Vec2::splat(0.5)).is_none());
    assert!(r.sample(Vec3::X, 0.5, Vec2::splat(0.5)).is_none()); // wo.z = 0
                                                                 // zero albedo: finite zeros, samples still valid
    let z = Lafortune {
        rho_d: Vec3::ZERO,
        lobes: vec![Lobe {
            rho: Vec3::ZERO,
            cxy: -1.0,
            cz: 1.0,
            n: 1e4,
        }],
    };
    let s = z.as_ref().sample(up, 0.3, Vec2::new(0.2, 0.9)).unwrap();
    assert_eq!(s.value, Vec3::ZERO);
    assert!(s.pdf > 0.0 && s.pdf.is_finite());
    assert_eq!(z.as_ref().albedo(up, 100, 1), Vec3::ZERO);
    // eval_pdf agrees with eval and pdf
    let wi = Vec3::new(0.1, -0.5, 0.86).normalize();
    assert_eq!(r.eval_pdf(wi, up), (r.eval(wi, up), r.pdf(wi, up)));
}

mod prop {
    use super::*;
    use proptest::prelude::*;

    fn dir() -> impl Strategy<Value = Vec3> {
        (-1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0)
            .prop_filter("nonzero", |(x, y, z)| x * x + y * y + z * z > 1e-6)
            .prop_map(|(x, y, z)| Vec3::new(x, y, z).normalize())
    }
    fn lobe() -> impl Strategy<Value = Lobe> {
        (
            0.0f32..10.0,
            0.0f32..10.0,
            0.0f32..10.0,
            -2.0f32..2.0,
            -2.0f32..2.0,
            prop_oneof![0.0f32..10.0, 0.0f32..1.0e4],
        )
            .prop_map(|(r, g, b, cxy, cz, n)| Lobe {
                rho: Vec3::new(r, g, b),
                cxy,
                cz,
                n,
            })
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 2000, .. ProptestConfig::default() })]
        #[test]
        fn never_nan_or_inf(rd in (0.0f32..1.0, 0.0f32..1.0, 0.0f32..1.0), lobes in proptest::collection::vec(lobe(), 0..3),
                            wi in dir(), wo in dir(), us in 0.0f32..1.0, u1 in 0.0f32..1.0, u2 in 0.0f32..1.0) {
            let m = Lafortune { rho_d: Vec3::new(rd.0, rd.1, rd.2), lobes };
            let r = m.as_ref();
            let f = r.eval(wi, wo);
            prop_assert!(f.is_finite() && f.min_element() >= 0.0, "{:?}", f);
            let p = r.pdf(wi, wo);
            prop_assert!(p.is_finite() && p >= 0.0);
            if let Some(s) = r.sample(wo, us, Vec2::new(u1, u2)) {
                prop_assert!(s.value.is_finite() && s.pdf.is_finite() && s.pdf > 0.0 && s.wi.is_finite() && s.wi.z > 0.0);
            }
            let a = r.albedo(wo, 16, 5);
            prop_assert!(a.is_finite());
        }
    }
}
