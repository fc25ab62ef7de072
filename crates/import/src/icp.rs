//! Trimmed ICP of the model's sparse points against the scan's mesh: a small similarity
//! (scale included) that refines the control-point alignment (`igi import colmap --icp`).
//!
//! * The mesh's surface is sampled (every triangle on a barycentric grid no coarser than
//!   [`IcpOptions::spacing`] metres, at most [`MAX_SAMPLES`] samples) into a kiddo k-d tree; a
//!   point's closest surface point is the exact closest point on the triangles of its
//!   [`NEIGHBOURS`] nearest samples.
//! * Each iteration pairs every point with its closest surface point, keeps the
//!   [`IcpOptions::keep`] fraction of pairs with the smallest distances (trimmed ICP,
//!   Chetverikov et al. 2002: outliers and points the scan does not cover are left out), and
//!   moves the similarity by the linearised point-to-plane step (Chen and Medioni 1992, with
//!   scale): the small rotation, scale and translation that minimise the kept pairs' squared
//!   distances along their triangles' normals. Point-to-point steps (Umeyama to the closest
//!   points) slide along flat walls and converged linearly: the unit test's misalignment took
//!   all 100 iterations (0.0109 deg left); point-to-plane takes 16 (0.0086 deg). It stops when
//!   no kept point moves by 1e-9 of the mesh's size, or after [`IcpOptions::max_iterations`].
//! * The refinement is a correction of an alignment that is already close: it is refused when
//!   it would turn the points by more than [`MAX_TURN_DEG`] degrees, scale them by more than
//!   [`MAX_SCALE_CHANGE`], or move their centroid by more than [`MAX_SHIFT`] of their spread
//!   (the control points and the mesh then disagree; ICP's nearest points would not mean
//!   correspondences), and when the kept pairs' RMS distance does not fall.

use glam::DVec3;
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use serde::Serialize;
use std::num::NonZeroUsize;

use crate::align::Similarity;
pub use crate::error::IcpError;

/// Samples of the mesh looked at per closest-point query.
pub const NEIGHBOURS: usize = 16;
/// The most surface samples (the spacing grows to keep below this).
pub const MAX_SAMPLES: usize = 2_000_000;
/// The largest accepted rotation of the refinement, degrees.
pub const MAX_TURN_DEG: f64 = 5.0;
/// The largest accepted relative change of scale.
pub const MAX_SCALE_CHANGE: f64 = 0.1;
/// The largest accepted shift of the points' centroid, as a fraction of their spread.
pub const MAX_SHIFT: f64 = 0.2;
/// The fewest points ICP runs on.
pub const MIN_POINTS: usize = crate::error::ICP_MIN_POINTS;

/// How the refinement runs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IcpOptions {
    /// The fraction of point pairs kept each iteration (the closest ones), in (0, 1].
    pub keep: f64,
    pub max_iterations: usize,
    /// Metres between surface samples (`None`: 1/200 of the mesh's bounding-box diagonal).
    pub spacing: Option<f64>,
}

impl Default for IcpOptions {
    fn default() -> Self {
        IcpOptions {
            keep: 0.8,
            max_iterations: 100,
            spacing: None,
        }
    }
}

/// The refinement found: `correction` moves scan-frame points (already aligned) onto the mesh.
#[derive(Clone, Copy, Debug)]
pub struct Icp {
    pub correction: Similarity,
    pub iterations: usize,
    /// Points given, and kept in the last iteration.
    pub points: usize,
    pub kept: usize,
    /// Metres: RMS distance to the mesh of the kept points, before and after.
    pub rms_before_m: f64,
    pub rms_after_m: f64,
    /// Degrees, relative change, metres: how far the correction moves the points.
    pub turn_deg: f64,
    pub scale_change: f64,
    pub shift_m: f64,
}

/// The numbers of [`Icp`] as alignment.json and the report give them.
#[derive(Clone, Debug, Serialize)]
pub struct IcpReport {
    pub iterations: usize,
    pub points: usize,
    pub kept: usize,
    pub rms_before_m: f64,
    pub rms_after_m: f64,
    pub turn_deg: f64,
    pub scale_change: f64,
    pub shift_m: f64,
}

impl From<&Icp> for IcpReport {
    fn from(i: &Icp) -> Self {
        IcpReport {
            iterations: i.iterations,
            points: i.points,
            kept: i.kept,
            rms_before_m: i.rms_before_m,
            rms_after_m: i.rms_after_m,
            turn_deg: i.turn_deg,
            scale_change: i.scale_change,
            shift_m: i.shift_m,
        }
    }
}

/// A triangle mesh's surface for closest-point queries.
pub struct Surface {
    tris: Vec<[DVec3; 3]>,
    /// The triangle of each sample.
    owner: Vec<u32>,
    tree: ImmutableKdTree<f64, 3>,
    /// Metres: the bounding box's diagonal.
    pub size: f64,
}

impl Surface {
    /// The surface of `positions` and `indices` (module docs); triangles of zero area and
    /// indices out of range are left out.
    pub fn new(
        positions: &[[f32; 3]],
        indices: &[[u32; 3]],
        spacing: Option<f64>,
    ) -> Result<Surface, IcpError> {
        let tris: Vec<[DVec3; 3]> = indices
            .iter()
            .filter(|t| t.iter().all(|&i| (i as usize) < positions.len()))
            .map(|t| t.map(|i| DVec3::from_array(positions[i as usize].map(f64::from))))
            .filter(|t| (t[1] - t[0]).cross(t[2] - t[0]).length() > 0.0)
            .filter(|t| t.iter().all(|v| v.is_finite()))
            .collect();
        if tris.is_empty() {
            return Err(IcpError::EmptyMesh);
        }
        let (lo, hi) = tris.iter().flatten().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), v| (lo.min(*v), hi.max(*v)),
        );
        let size = (hi - lo).length().max(1e-9);
        let mut h = spacing.filter(|s| *s > 0.0).unwrap_or(size / 200.0);
        let steps = |h: f64| -> Vec<usize> {
            tris.iter()
                .map(|t| {
                    let e = (t[1] - t[0])
                        .length()
                        .max((t[2] - t[1]).length())
                        .max((t[0] - t[2]).length());
                    ((e / h).ceil() as usize).max(1)
                })
                .collect()
        };
        let count = |n: &[usize]| n.iter().map(|n| (n + 1) * (n + 2) / 2).sum::<usize>();
        let mut n = steps(h);
        while count(&n) > MAX_SAMPLES {
            h *= 1.5;
            n = steps(h);
        }
        let mut samples: Vec<[f64; 3]> = Vec::with_capacity(count(&n));
        let mut owner = Vec::with_capacity(samples.capacity());
        for (k, (t, &n)) in tris.iter().zip(&n).enumerate() {
            for i in 0..=n {
                for j in 0..=(n - i) {
                    let (a, b) = (i as f64 / n as f64, j as f64 / n as f64);
                    let p = t[0] + a * (t[1] - t[0]) + b * (t[2] - t[0]);
                    samples.push(p.to_array());
                    owner.push(k as u32);
                }
            }
        }
        let tree = ImmutableKdTree::new_from_slice(&samples);
        Ok(Surface {
            tris,
            owner,
            tree,
            size,
        })
    }

    /// The closest point of the surface to `p` (module docs), its distance and the unit
    /// normal of the triangle it lies on.
    pub fn closest(&self, p: DVec3) -> (DVec3, f64, DVec3) {
        let k = NonZeroUsize::new(NEIGHBOURS).unwrap_or(NonZeroUsize::MIN);
        let mut best = (p, f64::INFINITY, DVec3::Z);
        let mut seen: Vec<u32> = Vec::with_capacity(NEIGHBOURS);
        for nn in self.tree.nearest_n::<SquaredEuclidean>(&p.to_array(), k) {
            let t = self.owner[nn.item as usize];
            if seen.contains(&t) {
                continue;
            }
            seen.push(t);
            let tri = &self.tris[t as usize];
            let q = closest_on_triangle(p, tri);
            let d = q.distance(p);
            if d < best.1 {
                best = (q, d, (tri[1] - tri[0]).cross(tri[2] - tri[0]).normalize());
            }
        }
        best
    }
}

/// The closest point of triangle `t` to `p` (Ericson, Real-Time Collision Detection, 5.1.5).
pub fn closest_on_triangle(p: DVec3, t: &[DVec3; 3]) -> DVec3 {
    let [a, b, c] = *t;
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = 1.0 / (va + vb + vc);
    a + ab * (vb * denom) + ac * (vc * denom)
}

/// The kept pairs (indices of the `keep` fraction closest) and their RMS distance.
fn trimmed(points: &[DVec3], s: &Similarity, surface: &Surface, keep: usize) -> (Vec<Pair>, f64) {
    let mut pairs: Vec<(Pair, f64)> = points
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let (q, d, n) = surface.closest(s.apply(*p));
            (Pair { i, q, n }, d)
        })
        .collect();
    pairs.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.0.i.cmp(&b.0.i)));
    pairs.truncate(keep);
    let rms = (pairs.iter().map(|p| p.1 * p.1).sum::<f64>() / keep as f64).sqrt();
    (pairs.into_iter().map(|(p, _)| p).collect(), rms)
}

/// A point (its index) paired with its closest surface point and that point's normal.
struct Pair {
    i: usize,
    q: DVec3,
    n: DVec3,
}

/// One point-to-plane step (Chen and Medioni 1992, with scale): the small similarity about the
/// moved points' centroid (rotation `w`, relative scale `sigma`, translation `t`) that
/// minimises the kept pairs' squared distances along their normals, linearised, applied to
/// `s`. Directions the pairs' normals leave free (a plane's own slide) keep `s`'s.
fn plane_step(points: &[DVec3], s: &Similarity, pairs: &[Pair]) -> Option<Similarity> {
    let moved: Vec<DVec3> = pairs.iter().map(|p| s.apply(points[p.i])).collect();
    let c = moved.iter().copied().sum::<DVec3>() / moved.len() as f64;
    let spread = (moved.iter().map(|p| p.distance_squared(c)).sum::<f64>() / moved.len() as f64)
        .sqrt()
        .max(1e-12);
    // unknowns scaled by the spread so that the seven columns are alike
    let mut ata = nalgebra::SMatrix::<f64, 7, 7>::zeros();
    let mut atb = nalgebra::SVector::<f64, 7>::zeros();
    for (p, pair) in moved.iter().zip(pairs) {
        let r = (*p - c) / spread;
        let (n, rxn) = (pair.n, r.cross(pair.n));
        let a = nalgebra::SVector::<f64, 7>::from([rxn.x, rxn.y, rxn.z, n.x, n.y, n.z, r.dot(n)]);
        let b = (pair.q - *p).dot(n) / spread;
        ata += a * a.transpose();
        atb += a * b;
    }
    // a tiny ridge: unconstrained directions stay where they are
    let ridge = 1e-9 * ata.trace().max(1e-300);
    ata += nalgebra::SMatrix::<f64, 7, 7>::identity() * ridge;
    let x = ata.cholesky()?.solve(&atb);
    let w = DVec3::new(x[0], x[1], x[2]);
    let (t, sigma) = (DVec3::new(x[3], x[4], x[5]) * spread, x[6]);
    let rot = glam::DMat3::from_quat(glam::DQuat::from_scaled_axis(w));
    let k = 1.0 + sigma;
    let next = Similarity {
        scale: k * s.scale,
        rotation: rot * s.rotation,
        translation: k * (rot * (s.translation - c)) + c + t,
    };
    (next.scale.is_finite() && next.scale > 0.0 && next.translation.is_finite()).then_some(next)
}

/// Refines: the similarity that best moves `points` (scan frame, already aligned) onto
/// `surface` by trimmed ICP (module docs).
pub fn icp(points: &[DVec3], surface: &Surface, opts: &IcpOptions) -> Result<Icp, IcpError> {
    if !(opts.keep > 0.0 && opts.keep <= 1.0) {
        return Err(IcpError::BadKeep(opts.keep));
    }
    if points.len() < MIN_POINTS {
        return Err(IcpError::TooFewPoints(points.len()));
    }
    if points.iter().any(|p| !p.is_finite()) {
        return Err(IcpError::NotFinite);
    }
    let keep = ((points.len() as f64 * opts.keep).round() as usize)
        .clamp(MIN_POINTS.min(points.len()), points.len());
    let mut s = Similarity::identity();
    let (mut pairs, rms_before) = trimmed(points, &s, surface, keep);
    let mut rms = rms_before;
    let mut iterations = 0;
    for _ in 0..opts.max_iterations {
        iterations += 1;
        let next_s = plane_step(points, &s, &pairs).ok_or(IcpError::Degenerate)?;
        let motion = pairs
            .iter()
            .map(|p| next_s.apply(points[p.i]).distance(s.apply(points[p.i])))
            .fold(0.0, f64::max);
        s = next_s;
        let (next, next_rms) = trimmed(points, &s, surface, keep);
        pairs = next;
        rms = next_rms;
        if motion < 1e-9 * surface.size {
            break;
        }
    }
    let n = points.len() as f64;
    let centroid = points.iter().copied().sum::<DVec3>() / n;
    let spread = (points
        .iter()
        .map(|p| p.distance_squared(centroid))
        .sum::<f64>()
        / n)
        .sqrt();
    let turn_deg = glam::DQuat::from_mat3(&s.rotation)
        .angle_between(glam::DQuat::IDENTITY)
        .to_degrees();
    let scale_change = s.scale - 1.0;
    let shift_m = s.apply(centroid).distance(centroid);
    let too_far = if turn_deg > MAX_TURN_DEG {
        Some(format!(
            "turn the points by {turn_deg:.2} degrees (at most {MAX_TURN_DEG})"
        ))
    } else if scale_change.abs() > MAX_SCALE_CHANGE {
        Some(format!(
            "scale the points by {:.4} (at most 1 +- {MAX_SCALE_CHANGE})",
            s.scale
        ))
    } else if shift_m > MAX_SHIFT * spread {
        Some(format!(
            "move the points by {shift_m:.3} m (at most {MAX_SHIFT} of their spread, {:.3} m)",
            MAX_SHIFT * spread
        ))
    } else {
        None
    };
    if let Some(why) = too_far {
        return Err(IcpError::TooFar(why));
    }
    if !(rms <= rms_before) {
        return Err(IcpError::NoGain {
            before: rms_before,
            after: rms,
        });
    }
    Ok(Icp {
        correction: s,
        iterations,
        points: points.len(),
        kept: keep,
        rms_before_m: rms_before,
        rms_after_m: rms,
        turn_deg,
        scale_change,
        shift_m,
    })
}

/// `a` after `b`: `x -> a(b(x))`.
pub fn compose(a: &Similarity, b: &Similarity) -> Similarity {
    Similarity {
        scale: a.scale * b.scale,
        rotation: a.rotation * b.rotation,
        translation: a.scale * (a.rotation * b.translation) + a.translation,
    }
}
