//! BRDF inference from a Lambertian colour (Debevec et al. 2004, 3.2.3).
//!
//! The measured materials' diffuse colours are reduced by PCA to their first principal direction
//! `e` (uncentred: the eigenvector of `sum rho rho^T` with the largest eigenvalue, signed so that its
//! components sum positive; the paper found (0.688, 0.573, 0.445) at the Parthenon). Each material
//! gets the coordinate `t = rho_d . e`. A new colour `rho_d` is projected to `t` and
//! `rho_d' = t e`; the two materials whose coordinates bracket `t` (or the two nearest, clamped at
//! the ends) have their lobe parameters `Cxy, Cz, N` and lobe colours interpolated linearly in `t`;
//! the retroreflective lobe colour (Cxy > 0, Cz > 0) is then scaled per channel by `rho_d / rho_d'`.
//! Lobes are matched by index (the fitter always writes [retroreflective, specular]).

use glam::Vec3;

use crate::{BrdfError, Lafortune, Lobe};

/// A set of measured materials used to infer lobes for a new diffuse colour.
#[derive(Clone, Debug)]
pub struct Basis {
    /// (name, BRDF, coordinate on the axis), sorted by coordinate.
    pub materials: Vec<(String, Lafortune, f32)>,
    /// Unit first principal direction of the materials' diffuse colours.
    pub axis: Vec3,
}

impl Basis {
    pub fn new(materials: Vec<(String, Lafortune)>) -> Result<Self, BrdfError> {
        if materials.is_empty() {
            return Err(BrdfError::EmptyBasis);
        }
        let mut m = nalgebra::Matrix3::<f64>::zeros();
        for (_, b) in &materials {
            let r = nalgebra::Vector3::new(b.rho_d.x as f64, b.rho_d.y as f64, b.rho_d.z as f64);
            m += r * r.transpose();
        }
        let eig = m.symmetric_eigen();
        let k = eig.eigenvalues.imax();
        let v = eig.eigenvectors.column(k);
        let mut axis = Vec3::new(v[0] as f32, v[1] as f32, v[2] as f32);
        if axis.x + axis.y + axis.z < 0.0 {
            axis = -axis;
        }
        if !axis.is_finite() || axis.length() < 0.5 || eig.eigenvalues[k] <= 0.0 {
            // all colours black: fall back to grey
            axis = Vec3::ONE.normalize();
        }
        let axis = axis.normalize();
        let mut materials: Vec<(String, Lafortune, f32)> = materials
            .into_iter()
            .map(|(n, b)| {
                let t = b.rho_d.dot(axis);
                (n, b, t)
            })
            .collect();
        materials.sort_by(|a, b| a.2.total_cmp(&b.2));
        Ok(Basis { materials, axis })
    }

    /// Coordinate of a colour along the axis.
    pub fn project(&self, rho_d: Vec3) -> f32 {
        rho_d.dot(self.axis)
    }

    /// A full Lafortune BRDF for the diffuse colour `rho_d`.
    pub fn infer(&self, rho_d: Vec3) -> Lafortune {
        let t = self.project(rho_d);
        let ms = &self.materials;
        // bracketing pair and weight of the upper one
        let (a, b, w) = if ms.len() == 1 {
            (0, 0, 0.0)
        } else {
            let hi = ms
                .iter()
                .position(|m| m.2 >= t)
                .unwrap_or(ms.len() - 1)
                .max(1);
            let lo = hi - 1;
            let span = ms[hi].2 - ms[lo].2;
            let w = if span > 0.0 {
                ((t - ms[lo].2) / span).clamp(0.0, 1.0)
            } else {
                0.5
            };
            (lo, hi, w)
        };
        let (la, lb) = (&ms[a].1.lobes, &ms[b].1.lobes);
        let lerp = |x: f32, y: f32| x + (y - x) * w;
        let proj = self.axis * t;
        let scale = Vec3::new(
            ratio(rho_d.x, proj.x),
            ratio(rho_d.y, proj.y),
            ratio(rho_d.z, proj.z),
        );
        let lobes = la
            .iter()
            .zip(lb.iter())
            .map(|(p, q)| {
                let mut l = Lobe {
                    rho: p.rho + (q.rho - p.rho) * w,
                    cxy: lerp(p.cxy, q.cxy),
                    cz: lerp(p.cz, q.cz),
                    n: lerp(p.n, q.n),
                };
                if l.cxy > 0.0 && l.cz > 0.0 {
                    l.rho *= scale;
                }
                l
            })
            .collect();
        Lafortune { rho_d, lobes }
    }
}

/// rho_d / rho_d' per channel, 1 where the projection is (near) zero.
fn ratio(x: f32, p: f32) -> f32 {
    if p > 1e-6 {
        (x / p).max(0.0)
    } else {
        1.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mat(rho_d: Vec3, retro_n: f32, spec_n: f32, spec_cxy: f32) -> Lafortune {
        Lafortune {
            rho_d,
            lobes: vec![
                Lobe {
                    rho: rho_d * 0.2,
                    cxy: 0.7,
                    cz: 1.0,
                    n: retro_n,
                },
                Lobe {
                    rho: Vec3::splat(1.5),
                    cxy: spec_cxy,
                    cz: 1.0,
                    n: spec_n,
                },
            ],
        }
    }

    fn on_axis_basis() -> (Basis, Vec3) {
        let e = Vec3::new(0.688, 0.573, 0.445).normalize();
        let b = Basis::new(vec![
            ("dark".into(), mat(e * 0.2, 2.0, 20.0, -1.0)),
            ("mid".into(), mat(e * 0.5, 4.0, 60.0, -0.9)),
            ("light".into(), mat(e * 0.9, 8.0, 200.0, -0.8)),
        ])
        .unwrap();
        (b, e)
    }

    #[test]
    fn axis_is_the_dominant_colour_direction() {
        let (b, e) = on_axis_basis();
        assert!((b.axis - e).length() < 1e-5, "{:?}", b.axis);
        let names: Vec<_> = b.materials.iter().map(|m| m.0.as_str()).collect();
        assert_eq!(names, ["dark", "mid", "light"]);
    }

    #[test]
    fn samples_on_the_axis_reproduce_exactly() {
        let (b, _) = on_axis_basis();
        for (_, m, _) in b.materials.clone() {
            let got = b.infer(m.rho_d);
            assert_eq!(got.rho_d, m.rho_d);
            for (g, w) in got.lobes.iter().zip(&m.lobes) {
                assert!((g.rho - w.rho).abs().max_element() < 1e-5, "{g:?} vs {w:?}");
                assert!(
                    (g.cxy - w.cxy).abs() < 1e-5
                        && (g.cz - w.cz).abs() < 1e-5
                        && (g.n - w.n).abs() < 1e-3,
                    "{g:?} vs {w:?}"
                );
            }
        }
    }

    #[test]
    fn between_two_samples_the_lobes_interpolate() {
        let (b, e) = on_axis_basis();
        // a quarter of the way from "mid" (t=0.5) to "light" (t=0.9)
        let got = b.infer(e * 0.6);
        let s = got.lobes[1];
        assert!((s.n - (60.0 + 0.25 * 140.0)).abs() < 1e-2, "{s:?}");
        assert!((s.cxy - (-0.9 + 0.25 * 0.1)).abs() < 1e-5, "{s:?}");
        let r = got.lobes[0];
        assert!((r.n - 5.0).abs() < 1e-4, "{r:?}");
        // on the axis the retro colour is the interpolated one (scale 1)
        assert!((r.rho - e * 0.2 * 0.6).abs().max_element() < 1e-5, "{r:?}");
        // beyond the ends: clamped to the end material
        assert!((b.infer(e * 2.0).lobes[1].n - 200.0).abs() < 1e-3);
        assert!((b.infer(e * 0.01).lobes[1].n - 20.0).abs() < 1e-3);
    }

    #[test]
    fn off_axis_colour_scales_the_retro_lobe_per_channel() {
        let (b, e) = on_axis_basis();
        let rho = Vec3::new(0.5, 0.3, 0.2);
        let t = rho.dot(e);
        let proj = e * t;
        let got = b.infer(rho);
        // interpolated retro colour on the axis is 0.2 * proj (rho = 0.2 rho_d in every basis
        // material, which is linear in t); scaled by rho / proj it becomes 0.2 * rho
        assert!(
            (got.lobes[0].rho - rho * 0.2).abs().max_element() < 1e-4,
            "{:?} vs {:?}",
            got.lobes[0].rho,
            proj
        );
        // the specular colour is not scaled
        assert!((got.lobes[1].rho - Vec3::splat(1.5)).abs().max_element() < 1e-5);
    }

    #[test]
    fn single_material_and_empty_basis() {
        let b = Basis::new(vec![("one".into(), mat(Vec3::splat(0.4), 3.0, 30.0, -1.0))]).unwrap();
        assert_eq!(b.infer(Vec3::splat(0.1)).lobes[1].n, 30.0);
        assert!(Basis::new(vec![]).is_err());
    }
}
