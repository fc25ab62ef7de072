//! Fresnel reflectance of the calibration spheres and a Levenberg-Marquardt fit of a complex
//! index of refraction from reflectance-versus-angle samples.

pub use crate::error::ReflectanceProblem;
use crate::{IorFitProblem, ProbeError};
use igi_imaging::csv::Table;
use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt};
use nalgebra::{Complex, DVector, Dyn, OMatrix, Owned, Vector2, U2};
use std::path::Path;

/// Default complex index (n, k) of the steel mirror sphere, per channel (about 52 % at normal).
pub const MIRROR_IOR: [(f64, f64); 3] = [(2.40, 2.98), (2.40, 3.02), (2.40, 3.02)];

/// Unpolarised Fresnel reflectance at incidence cosine `cos_i` of a medium with complex index
/// `n + i k` seen from air (exact complex formula; `k = 0` gives a dielectric).
pub fn conductor(cos_i: f64, n: f64, k: f64) -> f64 {
    let ci = cos_i.clamp(0.0, 1.0);
    let eta = Complex::new(n, k);
    let s2 = Complex::new(1.0 - ci * ci, 0.0);
    let ct = (Complex::new(1.0, 0.0) - s2 / (eta * eta)).sqrt();
    let ci_c = Complex::new(ci, 0.0);
    let rs = (ci_c - eta * ct) / (ci_c + eta * ct);
    let rp = (eta * ci_c - ct) / (eta * ci_c + ct);
    let r = 0.5 * (rs.norm_sqr() + rp.norm_sqr());
    if r.is_finite() {
        r.clamp(0.0, 1.0)
    } else {
        1.0
    }
}

/// Unpolarised Fresnel reflectance of a dielectric of index `eta` seen from air.
pub fn dielectric(cos_i: f64, eta: f64) -> f64 {
    conductor(cos_i, eta, 0.0)
}

/// Result of [`fit_complex_ior`].
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct IorFit {
    pub n: f64,
    pub k: f64,
    /// RMS of reflectance residuals.
    pub rms: f64,
    pub evaluations: usize,
}

struct IorProblem<'a> {
    samples: &'a [(f64, f64)],
    p: Vector2<f64>,
}

impl IorProblem<'_> {
    fn res_at(&self, p: &Vector2<f64>) -> DVector<f64> {
        DVector::from_iterator(
            self.samples.len(),
            self.samples
                .iter()
                .map(|&(theta, r)| conductor(theta.cos(), p[0], p[1]) - r),
        )
    }
}

impl LeastSquaresProblem<f64, Dyn, U2> for IorProblem<'_> {
    type ResidualStorage = Owned<f64, Dyn>;
    type JacobianStorage = Owned<f64, Dyn, U2>;
    type ParameterStorage = Owned<f64, U2>;

    fn set_params(&mut self, x: &Vector2<f64>) {
        self.p = *x;
    }
    fn params(&self) -> Vector2<f64> {
        self.p
    }
    fn residuals(&self) -> Option<DVector<f64>> {
        let r = self.res_at(&self.p);
        r.iter().all(|v| v.is_finite()).then_some(r)
    }
    fn jacobian(&self) -> Option<OMatrix<f64, Dyn, U2>> {
        let mut j = OMatrix::<f64, Dyn, U2>::zeros(self.samples.len());
        for c in 0..2 {
            let h = 1e-6 * self.p[c].abs().max(1.0);
            let mut a = self.p;
            let mut b = self.p;
            a[c] += h;
            b[c] -= h;
            let d = (self.res_at(&a) - self.res_at(&b)) / (2.0 * h);
            j.set_column(c, &d);
        }
        j.iter().all(|v| v.is_finite()).then_some(j)
    }
}

/// Fit `n + i k` to samples `(incidence angle in radians, measured reflectance)` by
/// Levenberg-Marquardt, starting from `init`. Needs at least 3 samples; angles spread toward
/// grazing make `n` and `k` separable (normal incidence alone fixes only one combination).
pub fn fit_complex_ior(samples: &[(f64, f64)], init: (f64, f64)) -> Result<IorFit, ProbeError> {
    if samples.len() < 3 {
        return Err(ProbeError::Fit(IorFitProblem::TooFewSamples(samples.len())));
    }
    if let Some(s) = samples.iter().find(|(t, r)| {
        !(t.is_finite()
            && r.is_finite()
            && *t >= 0.0
            && *t < std::f64::consts::FRAC_PI_2
            && (0.0..=1.0).contains(r))
    }) {
        return Err(ProbeError::Fit(IorFitProblem::BadSample {
            angle: s.0,
            reflectance: s.1,
        }));
    }
    let problem = IorProblem {
        samples,
        p: Vector2::new(init.0, init.1),
    };
    let (problem, report) = LevenbergMarquardt::new().minimize(problem);
    if !report.termination.was_successful() {
        return Err(ProbeError::Fit(IorFitProblem::Stopped(format!(
            "{:?}",
            report.termination
        ))));
    }
    let p = problem.p;
    let rms = (problem.res_at(&p).norm_squared() / samples.len() as f64).sqrt();
    Ok(IorFit {
        n: p[0],
        k: p[1].abs(),
        rms,
        evaluations: report.number_of_evaluations,
    })
}

/// Reflectance-versus-angle samples of one sphere: incidence angle in degrees and the measured
/// reflectance per channel (a CSV file with the header `angle_deg,r,g,b`, columns in any order).
#[derive(Clone, Debug, PartialEq)]
pub struct ReflectanceSamples {
    pub angle_deg: Vec<f64>,
    pub rgb: Vec<[f64; 3]>,
}

impl ReflectanceSamples {
    pub fn load(path: &Path) -> Result<Self, ProbeError> {
        let text = std::fs::read_to_string(path).map_err(|e| ProbeError::Io {
            path: path.to_path_buf(),
            source: e,
        })?;
        Self::parse(&text, path)
    }

    /// Parses the CSV text read from `path` (named in errors) through `igi_imaging::csv`:
    /// blank lines and lines starting with `#` are skipped, columns are found by name.
    pub fn parse(text: &str, path: &Path) -> Result<Self, ProbeError> {
        let table = Table::parse(text, path)?;
        let cols = table.columns(&["angle_deg", "r", "g", "b"])?;
        let problem = |line, problem| ProbeError::Samples {
            path: path.to_path_buf(),
            line,
            problem,
        };
        let mut out = ReflectanceSamples {
            angle_deg: Vec::new(),
            rgb: Vec::new(),
        };
        for row in table.rows() {
            let v: Vec<f64> = ["angle_deg", "r", "g", "b"]
                .iter()
                .zip(&cols)
                .map(|(name, &c)| table.number(row, c, name))
                .collect::<Result<_, _>>()?;
            let (a, rgb) = (v[0], [v[1], v[2], v[3]]);
            if !(0.0..90.0).contains(&a) {
                return Err(problem(Some(row.line), ReflectanceProblem::Angle(a)));
            }
            if rgb.iter().any(|x| !(0.0..=1.0).contains(x)) {
                return Err(problem(
                    Some(row.line),
                    ReflectanceProblem::Reflectance(rgb),
                ));
            }
            out.angle_deg.push(a);
            out.rgb.push(rgb);
        }
        if out.angle_deg.len() < 3 {
            return Err(problem(
                None,
                ReflectanceProblem::TooFew(out.angle_deg.len()),
            ));
        }
        Ok(out)
    }
}

/// Fit the mirror sphere's complex index per channel ([`fit_complex_ior`], started from the
/// default steel index [`MIRROR_IOR`]).
pub fn fit_mirror_ior(samples: &ReflectanceSamples) -> Result<[IorFit; 3], ProbeError> {
    let mut fits = Vec::with_capacity(3);
    for c in 0..3 {
        let s: Vec<(f64, f64)> = samples
            .angle_deg
            .iter()
            .zip(&samples.rgb)
            .map(|(a, v)| (a.to_radians(), v[c]))
            .collect();
        fits.push(fit_complex_ior(&s, MIRROR_IOR[c])?);
    }
    Ok([fits[0], fits[1], fits[2]])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normal_incidence_matches_closed_form() {
        // ((n-1)^2 + k^2) / ((n+1)^2 + k^2)
        for &(n, k) in &[(2.4, 2.98), (2.4, 3.02), (1.5, 0.0), (0.2, 3.5)] {
            let want = ((n - 1.0) * (n - 1.0) + k * k) / ((n + 1.0) * (n + 1.0) + k * k);
            assert!((conductor(1.0, n, k) - want).abs() < 1e-12, "{n} {k}");
        }
        // the steel sphere: about 52-53 % at normal incidence
        let r = conductor(1.0, 2.40, 2.98);
        assert!((r - 0.5303).abs() < 1e-3, "{r}");
        assert!((dielectric(1.0, 1.5) - 0.04).abs() < 1e-12);
    }

    #[test]
    fn grazing_and_brewster() {
        // everything reflects at grazing incidence
        assert!(conductor(1e-9, 2.4, 3.0) > 0.999);
        assert!(dielectric(0.0, 1.5) > 0.999);
        // dielectric at Brewster's angle: Rp = 0, so R = Rs / 2
        let tb = 1.5f64.atan();
        let (ci, st) = (tb.cos(), tb.sin() / 1.5);
        let ct = (1.0 - st * st).sqrt();
        let rs = ((ci - 1.5 * ct) / (ci + 1.5 * ct)).powi(2);
        assert!((dielectric(ci, 1.5) - 0.5 * rs).abs() < 1e-12);
        // conductor is brighter toward grazing than at normal incidence (after the dip)
        assert!(conductor(0.1, 2.4, 2.98) > conductor(1.0, 2.4, 2.98));
    }

    #[test]
    fn lm_recovers_index_from_noisy_samples() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
        for &(n, k) in &[(2.40, 2.98), (2.40, 3.02), (1.2, 4.5)] {
            let samples: Vec<(f64, f64)> = (0..40)
                .map(|i| {
                    let t = (i as f64 / 40.0) * 1.45;
                    (t, conductor(t.cos(), n, k) + rng.gen_range(-1e-4..1e-4))
                })
                .collect();
            let fit = fit_complex_ior(&samples, (1.5, 2.0)).unwrap();
            assert!(
                (fit.n - n).abs() < 0.03 && (fit.k - k).abs() < 0.03,
                "{fit:?} vs {n} {k}"
            );
            assert!(fit.rms < 2e-4);
        }
    }

    #[test]
    fn lm_rejects_bad_samples() {
        assert!(fit_complex_ior(&[(0.1, 0.5), (0.2, 0.5)], (2.0, 3.0)).is_err());
        assert!(fit_complex_ior(&[(0.1, 0.5), (0.2, f64::NAN), (0.3, 0.5)], (2.0, 3.0)).is_err());
        assert!(fit_complex_ior(&[(0.1, 0.5), (0.2, 1.5), (0.3, 0.5)], (2.0, 3.0)).is_err());
    }

    #[test]
    fn reflectance_csv_parses_and_fits_per_channel() {
        let truth = [(2.1, 3.3), (2.4, 3.02), (2.9, 2.6)];
        let mut csv = String::from("# steel sphere\nr,angle_deg,g,b\n");
        for i in 0..30 {
            let a = 2.5 * i as f64;
            let r = truth.map(|(n, k)| conductor(a.to_radians().cos(), n, k));
            csv.push_str(&format!("{},{a},{},{}\n", r[0], r[1], r[2]));
        }
        let s = ReflectanceSamples::parse(&csv, Path::new("s.csv")).unwrap();
        assert_eq!(s.angle_deg.len(), 30);
        let fits = fit_mirror_ior(&s).unwrap();
        for c in 0..3 {
            assert!(
                (fits[c].n - truth[c].0).abs() < 1e-4 && (fits[c].k - truth[c].1).abs() < 1e-4,
                "{c}: {:?}",
                fits[c]
            );
        }
        for (bad, want) in [
            ("angle,r,g,b\n1,0.5,0.5,0.5\n", "lacks column `angle_deg`"),
            ("angle_deg,r,g,b\n1,0.5,0.5\n", "s.csv:2"),
            ("angle_deg,r,g,b\n95,0.5,0.5,0.5\n", "not in [0, 90)"),
            ("angle_deg,r,g,b\n5,0.5,1.5,0.5\n", "not in [0, 1]"),
            ("angle_deg,r,g,b\n5,0.5,0.5,0.5\n", "at least 3"),
        ] {
            let e = ReflectanceSamples::parse(bad, Path::new("s.csv"))
                .unwrap_err()
                .to_string();
            assert!(e.contains(want), "{e}");
        }
    }
}
