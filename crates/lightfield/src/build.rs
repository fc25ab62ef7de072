//! From photographs to a surface light field: grid points from the atlas, data lumispheres,
//! reparameterisation, then one of the fits.

use crate::data::{
    angle_gain, gather_with_hits, observation_median, pixel_hits, reparameterise, GatherReport,
    GridPoint, View,
};
use crate::field::{Coding, SurfaceLightField};
use crate::fit::{fair_pointwise, DataLumisphere, FitOptions};
use crate::lumisphere::{AngleGain, Octahedron};
use crate::pfa::{fit_pfa, PfaOptions};
use crate::quantize::{fit_fq, FqOptions};
use crate::LightFieldError;
use glam::Vec3;
use igi_geometry::atlas::Atlas;
use igi_geometry::texels::TexelCache;
use igi_raycast::RtScene;
use rayon::prelude::*;

/// How the lumispheres are estimated.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Method {
    /// Pointwise fairing.
    Fair,
    /// Function quantization with this many codewords (a power of two).
    Fq { codewords: usize },
    /// Principal function analysis with subspace dimension q (>= 1).
    Pfa { q: usize },
    /// The median texture alone (the diffuse baseline).
    MedianOnly,
}

/// Options of a build.
#[derive(Clone, Copy, Debug)]
pub struct BuildOptions {
    /// Octahedron subdivision level s (3: 258 vertices).
    pub level: u32,
    pub lambda: f32,
    pub mu: f32,
    /// Training-subset size of FQ and PFA.
    pub training: usize,
    pub pfa_iterations: usize,
    pub cg_iterations: usize,
    pub seed: u64,
}

impl Default for BuildOptions {
    fn default() -> Self {
        BuildOptions {
            level: 3,
            lambda: 0.02,
            mu: 1e-4,
            training: 2000,
            pfa_iterations: 6,
            cg_iterations: 120,
            seed: 0,
        }
    }
}

impl BuildOptions {
    /// Checks the options and the method before any work.
    pub fn validate(&self, method: Method) -> Result<(), LightFieldError> {
        if !(self.lambda > 0.0 && self.lambda.is_finite()) {
            return Err(LightFieldError::BadLambda(self.lambda));
        }
        if !(1..=6).contains(&self.level) {
            return Err(LightFieldError::BadLevel(self.level));
        }
        match method {
            Method::Pfa { q } if q < 1 => Err(LightFieldError::BadQ(q)),
            Method::Fq { codewords } if !codewords.is_power_of_two() => {
                Err(LightFieldError::BadCodebookSize(codewords))
            }
            _ => Ok(()),
        }
    }

    fn fit(&self) -> FitOptions {
        FitOptions {
            lambda: self.lambda,
            cg_iterations: self.cg_iterations,
        }
    }
}

/// The grid points of an atlas: its covered texels (index, position, normal).
pub fn grid_points(atlas: &Atlas) -> (Vec<u32>, Vec<GridPoint>) {
    let texels = TexelCache::covered_texels(&atlas.position, &atlas.normal, &atlas.coverage);
    let idx = texels.iter().map(|t| t.index).collect();
    let pts = texels
        .iter()
        .map(|t| GridPoint {
            position: t.position,
            normal: t.normal,
        })
        .collect();
    (idx, pts)
}

/// The reparameterised data lumispheres of every grid point, ready for any fit.
pub struct Prepared {
    pub oct: Octahedron,
    pub resolution: usize,
    pub texels: Vec<u32>,
    pub normals: Vec<Vec3>,
    pub medians: Vec<Vec3>,
    /// The view-angle gain the samples are divided by (the fields multiply it back).
    pub gain: AngleGain,
    pub data: Vec<DataLumisphere>,
    pub report: GatherReport,
}

impl Prepared {
    /// Gathers and reparameterises the data lumispheres of the atlas's grid points.
    pub fn new(atlas: &Atlas, scene: &RtScene, views: &[View], level: u32) -> Self {
        let hits: Vec<Vec<bool>> = views.par_iter().map(|v| pixel_hits(scene, v)).collect();
        Prepared::with_hits(atlas, scene, views, &hits, level)
    }

    /// [`Prepared::new`] with each view's [`pixel_hits`] already cast (one per view, in order).
    pub fn with_hits(
        atlas: &Atlas,
        scene: &RtScene,
        views: &[View],
        hits: &[Vec<bool>],
        level: u32,
    ) -> Self {
        let (texels, points) = grid_points(atlas);
        let (obs, report) = gather_with_hits(scene, &points, views, hits);
        let oct = Octahedron::new(level);
        let medians: Vec<Vec3> = obs.par_iter().map(observation_median).collect();
        let gain = angle_gain(&obs, &points, &medians);
        let data: Vec<DataLumisphere> = obs
            .par_iter()
            .zip(&points)
            .zip(&medians)
            .map(|((o, p), m)| reparameterise(&oct, o, p.normal, *m, &gain))
            .collect();
        let normals = points.iter().map(|p| p.normal).collect();
        Prepared {
            oct,
            resolution: atlas.resolution,
            texels,
            normals,
            medians,
            gain,
            data,
            report,
        }
    }

    /// Total number of samples (for the seconds-per-million-samples figure).
    pub fn samples(&self) -> usize {
        self.data.iter().map(|d| d.samples.len()).sum()
    }

    /// Fits the lumispheres with `method`.
    pub fn fit(
        &self,
        method: Method,
        opts: &BuildOptions,
    ) -> Result<SurfaceLightField, LightFieldError> {
        opts.validate(method)?;
        let fit = opts.fit();
        let coding = match method {
            Method::Fair => Coding::Faired(fair_pointwise(&self.oct, &self.data, &fit)),
            Method::MedianOnly => Coding::MedianOnly,
            Method::Pfa { q } => {
                let po = PfaOptions {
                    q,
                    mu: opts.mu,
                    iterations: opts.pfa_iterations,
                    training: opts.training,
                    seed: opts.seed,
                    fit,
                };
                Coding::Pfa(fit_pfa(&self.oct, &self.data, &po))
            }
            Method::Fq { codewords } => {
                let fo = FqOptions {
                    codewords,
                    training: opts.training,
                    seed: opts.seed,
                    fit,
                    ..FqOptions::default()
                };
                Coding::Quantized(fit_fq(&self.oct, &self.data, &fo))
            }
        };
        let field = SurfaceLightField::new(
            self.oct.clone(),
            self.resolution,
            self.texels.clone(),
            self.medians.clone(),
            self.normals.clone(),
            coding,
        );
        // the median alone has no lumisphere for the gain to scale
        Ok(match method {
            Method::MedianOnly => field,
            _ => field.with_gain(self.gain.clone()),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_options_are_refused_before_any_work() {
        let o = BuildOptions::default();
        assert!(matches!(
            o.validate(Method::Pfa { q: 0 }),
            Err(LightFieldError::BadQ(0))
        ));
        assert!(matches!(
            o.validate(Method::Fq { codewords: 300 }),
            Err(LightFieldError::BadCodebookSize(300))
        ));
        assert!(matches!(
            BuildOptions { level: 0, ..o }.validate(Method::Fair),
            Err(LightFieldError::BadLevel(0))
        ));
        assert!(
            o.validate(Method::Fq { codewords: 256 }).is_ok()
                && o.validate(Method::Pfa { q: 2 }).is_ok()
        );
        for l in [0.0, -1.0, f32::NAN, f32::INFINITY] {
            let bad = BuildOptions { lambda: l, ..o };
            assert!(
                matches!(
                    bad.validate(Method::Fair),
                    Err(LightFieldError::BadLambda(_))
                ),
                "lambda {l}"
            );
        }
    }
}
