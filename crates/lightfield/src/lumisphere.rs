//! The lumisphere domain: the s-times 4-to-1 subdivided octahedron `|x| + |y| + |z| = 1`
//! (s = 3: 4 * 8^2 + 2 = 258 vertices), the map h from unit directions onto it (Eq. 3), the
//! barycentric weights of a direction in its triangle, the umbrella Laplacian over its vertices,
//! the reparameterisation of Eqs. 9-10 (median removal, reflection about the normal) and the
//! view-angle gain that takes out what the reflected parameterisation cannot express.
//!
//! Vertices are the integer points (X, Y, Z) with |X| + |Y| + |Z| = n = 2^s; the octahedron
//! point of a vertex is (X, Y, Z) / n. A lumisphere is one RGB value per vertex, linear inside
//! each triangle of the subdivided octahedron (piecewise linear in the h domain).

use glam::Vec3;

/// The subdivided octahedron.
#[derive(Clone, Debug)]
pub struct Octahedron {
    /// Subdivision level s.
    pub level: u32,
    /// Segments per octahedron edge, n = 2^s.
    pub n: i32,
    /// Octahedron-domain position of every vertex (on |x| + |y| + |z| = 1).
    pub points: Vec<Vec3>,
    /// Neighbouring vertices of every vertex (4 at the six octahedron corners, 6 elsewhere).
    pub neighbours: Vec<Vec<u32>>,
    /// Vertex index by (X + n, Y + n, Z >= 0 ? 0 : 1).
    index: Vec<u32>,
}

/// A direction in its triangle: three vertices and their barycentric weights (sum 1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bary {
    pub vertices: [u32; 3],
    pub weights: [f32; 3],
}

/// Eq. 3: h(w) = (asin wx, asin wy, asin wz) / (|asin wx| + |asin wy| + |asin wz|). `w` need
/// not be exactly unit (components are clamped); the zero vector maps to +Z.
pub fn h_map(w: Vec3) -> Vec3 {
    let a = Vec3::new(
        w.x.clamp(-1.0, 1.0).asin(),
        w.y.clamp(-1.0, 1.0).asin(),
        w.z.clamp(-1.0, 1.0).asin(),
    );
    let s = a.x.abs() + a.y.abs() + a.z.abs();
    if !(s > 1e-12) {
        return Vec3::Z;
    }
    a / s
}

/// The inverse of h: the unit direction whose image is the octahedron point `p`
/// (asin w_i = t p_i with t chosen so that |w| = 1, by bisection).
pub fn h_inverse(p: Vec3) -> Vec3 {
    let m = p.abs().max_element();
    if !(m > 0.0) {
        return Vec3::Z;
    }
    let norm2 =
        |t: f32| (t * p.x).sin().powi(2) + (t * p.y).sin().powi(2) + (t * p.z).sin().powi(2);
    let (mut lo, mut hi) = (0.0f32, std::f32::consts::FRAC_PI_2 / m);
    for _ in 0..40 {
        let mid = 0.5 * (lo + hi);
        if norm2(mid) < 1.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let t = 0.5 * (lo + hi);
    Vec3::new((t * p.x).sin(), (t * p.y).sin(), (t * p.z).sin()).normalize_or(Vec3::Z)
}

/// Eq. 10: the direction reflected about the normal, 2 (n . w) n - w: the mirror of `w` across
/// the line of `n`, both pointing away from the surface (glam's `reflect` is the other
/// convention, an incident ray bounced: w - 2 (n . w) n).
pub fn reflect_about_normal(w: Vec3, n: Vec3) -> Vec3 {
    2.0 * n.dot(w) * n - w
}

/// The per-channel median of colours (Eq. 9 removes it from every sample of a point); zero for
/// no colours. For an even count, the mean of the two middle values.
pub fn median_rgb(colours: &[Vec3]) -> Vec3 {
    if colours.is_empty() {
        return Vec3::ZERO;
    }
    let mut out = [0.0f32; 3];
    let mut ch: Vec<f32> = Vec::with_capacity(colours.len());
    for (c, o) in out.iter_mut().enumerate() {
        ch.clear();
        ch.extend(colours.iter().map(|v| v[c]));
        ch.sort_by(|a, b| a.total_cmp(b));
        let k = ch.len();
        *o = if k % 2 == 1 {
            ch[k / 2]
        } else {
            0.5 * (ch[k / 2 - 1] + ch[k / 2])
        };
    }
    Vec3::from_array(out)
}

/// Knots of an estimated [`AngleGain`], at n . w = 0, 0.1, ..., 1.
pub const GAIN_KNOTS: usize = 11;

/// The view-angle gain h(n . w): how much larger a surface's view-dependent colour (its samples
/// with the median removed) is at a given angle between the normal and the view. Fresnel
/// reflection grows toward grazing views, and so does the (1 - F) loss of the diffuse part, so
/// a point's lumisphere carries a factor of n . w = n . r that depends on its own normal: two
/// points of one material seeing the same sky in the same reflected direction r differ by it.
/// No subspace of functions of r alone holds that (PFA's prototypes, FQ's codewords; pointwise
/// fairing suffers less, but its thin-plate extrapolation does too). The samples are divided by
/// h before a fit and the lumisphere is multiplied by it when rendering (docs/LIGHTFIELD.md,
/// "Gloss under a small bright light"). Piecewise linear in n . w over its knots (evenly spaced
/// on [0, 1]); no knots: 1 everywhere (folders of earlier builds).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct AngleGain {
    pub knots: Vec<f32>,
}

impl AngleGain {
    /// h at n . w = `c` (clamped to [0, 1]).
    pub fn at(&self, c: f32) -> f32 {
        let k = &self.knots;
        if k.len() < 2 {
            return k.first().copied().unwrap_or(1.0);
        }
        let x = c.clamp(0.0, 1.0) * (k.len() - 1) as f32;
        let i = (x as usize).min(k.len() - 2);
        let f = x - i as f32;
        k[i] * (1.0 - f) + k[i + 1] * f
    }

    /// The gain of a capture from its samples, each (n . w, squared length of the colour minus
    /// the point's median): at each of [`GAIN_KNOTS`] knots the RMS of the samples weighted by
    /// their linear-interpolation weight to it, the whole scaled to RMS 1 over the samples.
    /// A knot with under [`GAIN_MIN_SAMPLES`] samples' weight takes its nearest such knot's
    /// value, no knot's value falls below 1 % of the largest, and samples with nothing
    /// view-dependent (all zero) give no gain (1 everywhere).
    pub fn estimate(samples: impl Iterator<Item = (f32, f32)>) -> AngleGain {
        let k = GAIN_KNOTS;
        let (mut sum, mut weight) = (vec![0.0f64; k], vec![0.0f64; k]);
        for (c, r2) in samples.filter(|(c, r2)| c.is_finite() && r2.is_finite()) {
            let x = c.clamp(0.0, 1.0) * (k - 1) as f32;
            let i = (x as usize).min(k - 2);
            let f = (x - i as f32) as f64;
            for (j, w) in [(i, 1.0 - f), (i + 1, f)] {
                sum[j] += w * r2 as f64;
                weight[j] += w;
            }
        }
        let total: f64 = sum.iter().sum::<f64>() / weight.iter().sum::<f64>().max(1e-300);
        let populated: Vec<usize> = (0..k).filter(|&j| weight[j] >= GAIN_MIN_SAMPLES).collect();
        if !(total > 0.0) || populated.is_empty() {
            return AngleGain::default();
        }
        let rms = |j: usize| (sum[j] / weight[j] / total).sqrt() as f32;
        let knots: Vec<f32> = (0..k)
            .map(|j| rms(*populated.iter().min_by_key(|&&p| p.abs_diff(j)).unwrap()))
            .collect();
        let floor = 0.01 * knots.iter().fold(0.0f32, |a, b| a.max(*b));
        AngleGain {
            knots: knots.into_iter().map(|v| v.max(floor)).collect(),
        }
    }
}

/// The samples' weight a knot of [`AngleGain::estimate`] needs to stand on its own.
pub const GAIN_MIN_SAMPLES: f64 = 100.0;

impl Octahedron {
    /// The s-times subdivided octahedron (s <= 6).
    pub fn new(level: u32) -> Self {
        let n = 1i32 << level.min(6);
        let side = (2 * n + 1) as usize;
        let mut index = vec![u32::MAX; side * side * 2];
        let mut keys = Vec::new();
        for x in -n..=n {
            for y in -(n - x.abs())..=(n - x.abs()) {
                let z = n - x.abs() - y.abs();
                for zs in if z == 0 { vec![0] } else { vec![z, -z] } {
                    index[Self::key(n, x, y, zs)] = keys.len() as u32;
                    keys.push((x, y, zs));
                }
            }
        }
        let points = keys
            .iter()
            .map(|&(x, y, z)| Vec3::new(x as f32, y as f32, z as f32) / n as f32)
            .collect();
        let mut oct = Octahedron {
            level,
            n,
            points,
            neighbours: Vec::new(),
            index,
        };
        oct.neighbours = keys
            .iter()
            .map(|&(x, y, z)| oct.neighbours_of(x, y, z))
            .collect();
        oct
    }

    fn key(n: i32, x: i32, y: i32, z: i32) -> usize {
        let side = (2 * n + 1) as usize;
        ((x + n) as usize * side + (y + n) as usize) * 2 + usize::from(z < 0)
    }

    /// Index of the lattice vertex (x, y, z), |x| + |y| + |z| = n.
    fn vertex(&self, x: i32, y: i32, z: i32) -> u32 {
        self.index[Self::key(self.n, x, y, z)]
    }

    /// The lattice neighbours: the points at L1 distance 2 on the surface that share a triangle
    /// edge (one coordinate +1 step, another -1 step in magnitude, within one octant or across).
    fn neighbours_of(&self, x: i32, y: i32, z: i32) -> Vec<u32> {
        let p = [x, y, z];
        let mut out = Vec::new();
        for a in 0..3 {
            for b in 0..3 {
                if a == b {
                    continue;
                }
                for sa in [-1, 1] {
                    for sb in [-1, 1] {
                        let mut q = p;
                        q[a] += sa;
                        q[b] += sb;
                        if q.iter().map(|v| v.abs()).sum::<i32>() != self.n {
                            continue;
                        }
                        // an edge of the triangulation: the step stays in one closed octant
                        let same_octant = (0..3).all(|c| p[c] * q[c] >= 0);
                        if same_octant && (q[a].abs() - p[a].abs()) * (q[b].abs() - p[b].abs()) < 0
                        {
                            let v = self.vertex(q[0], q[1], q[2]);
                            if !out.contains(&v) {
                                out.push(v);
                            }
                        }
                    }
                }
            }
        }
        out
    }

    /// Number of vertices N_s.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// The unit direction of vertex `v` (h^-1 of its octahedron point).
    pub fn direction(&self, v: usize) -> Vec3 {
        h_inverse(self.points[v])
    }

    /// The triangle of direction `w` and its barycentric weights in the h domain.
    pub fn locate(&self, w: Vec3) -> Bary {
        let p = h_map(w);
        let nf = self.n as f32;
        let (sx, sy, sz) = (sign(p.x), sign(p.y), sign(p.z));
        let (a, b) = (p.x.abs() * nf, p.y.abs() * nf);
        let n = self.n;
        let i = (a.floor() as i32).clamp(0, n);
        let j = (b.floor() as i32).clamp(0, n - i);
        let (fa, fb) = (a - i as f32, b - j as f32);
        let v = |i: i32, j: i32| self.vertex(sx * i, sy * j, sz * (n - i - j));
        if i + j >= n {
            return Bary {
                vertices: [v(i, n - i); 3],
                weights: [1.0, 0.0, 0.0],
            };
        }
        if fa + fb <= 1.0 || i + j + 2 > n {
            let ws = [1.0 - fa - fb, fa, fb];
            Bary {
                vertices: [v(i, j), v(i + 1, j), v(i, j + 1)],
                weights: clean(ws),
            }
        } else {
            let ws = [fa + fb - 1.0, 1.0 - fb, 1.0 - fa];
            Bary {
                vertices: [v(i + 1, j + 1), v(i + 1, j), v(i, j + 1)],
                weights: clean(ws),
            }
        }
    }

    /// The value of lumisphere `f` (one RGB per vertex) in direction `w`.
    pub fn eval(&self, f: &[Vec3], w: Vec3) -> Vec3 {
        eval_bary(f, &self.locate(w))
    }

    /// The umbrella Laplacian of `f` at every vertex: mean of the neighbours minus the vertex.
    pub fn laplacian(&self, f: &[Vec3], out: &mut [Vec3]) {
        for (v, nb) in self.neighbours.iter().enumerate() {
            let s: Vec3 = nb.iter().map(|&u| f[u as usize]).sum();
            out[v] = s / nb.len() as f32 - f[v];
        }
    }

    /// The transpose of the umbrella Laplacian applied to `g` (for the normal equations).
    pub fn laplacian_transpose(&self, g: &[Vec3], out: &mut [Vec3]) {
        out.iter_mut().zip(g).for_each(|(o, x)| *o = -*x);
        for (v, nb) in self.neighbours.iter().enumerate() {
            let share = g[v] / nb.len() as f32;
            for &u in nb {
                out[u as usize] += share;
            }
        }
    }
}

/// Barycentric interpolation of vertex values.
#[inline]
pub fn eval_bary(f: &[Vec3], b: &Bary) -> Vec3 {
    f[b.vertices[0] as usize] * b.weights[0]
        + f[b.vertices[1] as usize] * b.weights[1]
        + f[b.vertices[2] as usize] * b.weights[2]
}

fn sign(x: f32) -> i32 {
    if x < 0.0 {
        -1
    } else {
        1
    }
}

fn clean(w: [f32; 3]) -> [f32; 3] {
    let w = w.map(|x| x.max(0.0));
    let s = w[0] + w[1] + w[2];
    if s > 0.0 {
        w.map(|x| x / s)
    } else {
        [1.0, 0.0, 0.0]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dirs() -> Vec<Vec3> {
        // a deterministic spread of directions (Fibonacci sphere) plus the axes and edges
        let mut d: Vec<Vec3> = (0..500)
            .map(|i| {
                let z = 1.0 - 2.0 * (i as f32 + 0.5) / 500.0;
                let phi = i as f32 * 2.399_963;
                let r = (1.0 - z * z).sqrt();
                Vec3::new(r * phi.cos(), r * phi.sin(), z)
            })
            .collect();
        d.extend([
            Vec3::X,
            -Vec3::X,
            Vec3::Y,
            -Vec3::Y,
            Vec3::Z,
            -Vec3::Z,
            Vec3::new(1.0, 1.0, 0.0).normalize(),
        ]);
        d
    }

    #[test]
    fn level_three_has_258_vertices_and_the_euler_characteristic_of_a_sphere() {
        for s in 0..5 {
            let o = Octahedron::new(s);
            let n = 1usize << s;
            assert_eq!(o.len(), 4 * n * n + 2);
            let edges: usize = o.neighbours.iter().map(|v| v.len()).sum::<usize>() / 2;
            let faces = 8 * n * n;
            assert_eq!(
                o.len() as i64 - edges as i64 + faces as i64,
                2,
                "V - E + F at s = {s}"
            );
        }
        assert_eq!(Octahedron::new(3).len(), 258);
        let o = Octahedron::new(3);
        let corners = o.neighbours.iter().filter(|v| v.len() == 4).count();
        assert_eq!(corners, 6);
        assert!(o.neighbours.iter().all(|v| v.len() == 4 || v.len() == 6));
    }

    #[test]
    fn h_maps_onto_the_octahedron_and_inverts() {
        for w in dirs() {
            let p = h_map(w);
            assert!((p.x.abs() + p.y.abs() + p.z.abs() - 1.0).abs() < 1e-5);
            assert!(
                (h_inverse(p) - w).length() < 1e-4,
                "{w} -> {p} -> {}",
                h_inverse(p)
            );
        }
        // the analytic value at an octant centre: all asin equal
        let w = Vec3::ONE.normalize();
        assert!((h_map(w) - Vec3::splat(1.0 / 3.0)).length() < 1e-6);
        assert_eq!(h_map(Vec3::ZERO), Vec3::Z);
    }

    #[test]
    fn barycentric_evaluation_reproduces_vertex_values_and_linear_functions_of_the_domain() {
        let o = Octahedron::new(3);
        // at vertex directions the vertex value comes back exactly
        let f: Vec<Vec3> = (0..o.len()).map(|v| Vec3::splat(v as f32)).collect();
        for v in 0..o.len() {
            let e = o.eval(&f, o.direction(v));
            assert!((e.x - v as f32).abs() < 1e-2, "vertex {v}: {e}");
        }
        // a function linear in the h domain within every octant (|px| + 2|py|) is reproduced
        let g: Vec<Vec3> = o
            .points
            .iter()
            .map(|p| Vec3::splat(p.x.abs() + 2.0 * p.y.abs()))
            .collect();
        for w in dirs() {
            let p = h_map(w);
            let b = o.locate(w);
            assert!(
                (b.weights.iter().sum::<f32>() - 1.0).abs() < 1e-5
                    && b.weights.iter().all(|x| *x >= 0.0)
            );
            assert!((o.eval(&g, w).x - (p.x.abs() + 2.0 * p.y.abs())).abs() < 1e-4);
        }
    }

    #[test]
    fn umbrella_laplacian_is_zero_on_constants_and_its_transpose_is_adjoint() {
        let o = Octahedron::new(3);
        let c = vec![Vec3::new(0.3, 1.0, -2.0); o.len()];
        let mut l = vec![Vec3::ZERO; o.len()];
        o.laplacian(&c, &mut l);
        assert!(l.iter().all(|v| v.length() < 1e-6));
        // <L f, g> = <f, L^T g>
        let f: Vec<Vec3> = (0..o.len())
            .map(|v| Vec3::new((v as f32).sin(), (v * v % 7) as f32, 1.0))
            .collect();
        let g: Vec<Vec3> = (0..o.len())
            .map(|v| Vec3::new((v as f32 * 0.3).cos(), (v % 5) as f32, -1.0))
            .collect();
        let (mut lf, mut ltg) = (vec![Vec3::ZERO; o.len()], vec![Vec3::ZERO; o.len()]);
        o.laplacian(&f, &mut lf);
        o.laplacian_transpose(&g, &mut ltg);
        let a: f32 = lf.iter().zip(&g).map(|(x, y)| x.dot(*y)).sum();
        let b: f32 = f.iter().zip(&ltg).map(|(x, y)| x.dot(*y)).sum();
        assert!((a - b).abs() < 1e-3 * a.abs().max(1.0));
        // the umbrella at the +Z pole of a "height" function p.z: mean of the 4 neighbours - 1
        let hz: Vec<Vec3> = o.points.iter().map(|p| Vec3::splat(p.z)).collect();
        o.laplacian(&hz, &mut lf);
        let pole = o.points.iter().position(|p| *p == Vec3::Z).unwrap();
        assert!((lf[pole].x - (-1.0 / 8.0)).abs() < 1e-6);
    }

    #[test]
    fn reflection_about_the_normal_and_the_median() {
        let n = Vec3::Z;
        let w = Vec3::new(0.6, 0.0, 0.8);
        assert!((reflect_about_normal(w, n) - Vec3::new(-0.6, 0.0, 0.8)).length() < 1e-6);
        assert!(
            (reflect_about_normal(n, n) - n).length() < 1e-6,
            "the normal reflects to itself"
        );
        let m = median_rgb(&[
            Vec3::new(1.0, 5.0, 0.0),
            Vec3::new(3.0, 1.0, 0.0),
            Vec3::new(2.0, 9.0, 7.0),
        ]);
        assert_eq!(m, Vec3::new(2.0, 5.0, 0.0));
        assert_eq!(median_rgb(&[Vec3::ONE, Vec3::splat(3.0)]), Vec3::splat(2.0));
        assert_eq!(median_rgb(&[]), Vec3::ZERO);
    }

    #[test]
    fn the_angle_gain_recovers_a_known_falloff() {
        // samples whose view-dependent part is h(c) = 1 + 4 (1 - c)^3 times a fixed pattern
        let h = |c: f32| 1.0 + 4.0 * (1.0 - c).powi(3);
        let samples: Vec<(f32, f32)> = (0..20_000)
            .map(|i| {
                let c = (i % 1000) as f32 / 999.0;
                let pattern = [0.5f32, 1.0, 1.5][i % 3];
                (c, (h(c) * pattern).powi(2))
            })
            .collect();
        let g = AngleGain::estimate(samples.iter().copied());
        assert_eq!(g.knots.len(), GAIN_KNOTS);
        // up to one overall scale, the knots follow h: within 2 % inside; the tent of the
        // end knot c = 0 has only one side, where h falls steeply (5 at 0, 3.9 at 0.1), so its
        // RMS is 7 % low there
        let scale = g.at(1.0) / h(1.0);
        for j in 0..GAIN_KNOTS {
            let c = j as f32 / (GAIN_KNOTS - 1) as f32;
            let want = h(c) * scale;
            let tol = if j == 0 { 0.1 } else { 0.02 };
            assert!(
                (g.at(c) - want).abs() < tol * want,
                "c {c}: {} against {want}",
                g.at(c)
            );
        }
        // RMS 1 over the samples
        let rms2: f32 =
            samples.iter().map(|(c, _)| g.at(*c).powi(2)).sum::<f32>() / samples.len() as f32;
        assert!((rms2 - 1.0).abs() < 0.05, "{rms2}");
        // interpolation between knots, and clamping outside [0, 1]
        let mid = 0.5 * (g.knots[3] + g.knots[4]);
        assert!((g.at(0.35) - mid).abs() < 1e-5);
        assert_eq!(g.at(-1.0), g.knots[0]);
        assert_eq!(g.at(2.0), g.knots[GAIN_KNOTS - 1]);
    }

    #[test]
    fn the_angle_gain_without_view_dependence_is_one_and_sparse_knots_borrow() {
        let flat = AngleGain::estimate((0..500).map(|i| (i as f32 / 499.0, 0.0)));
        assert_eq!(flat, AngleGain::default());
        assert_eq!(flat.at(0.3), 1.0);
        assert_eq!(AngleGain::estimate(std::iter::empty()).at(0.7), 1.0);
        // samples only near c = 1 (a frontal capture): the knots below borrow the nearest
        // populated knot's value, and NaN samples are ignored
        let frontal = AngleGain::estimate(
            (0..1000)
                .map(|i| (0.95 + 0.05 * (i as f32 / 999.0), 0.04))
                .chain([(f32::NAN, 1.0), (0.5, f32::NAN)]),
        );
        assert!(
            frontal.knots.iter().all(|k| (k - 1.0).abs() < 1e-4),
            "{:?}",
            frontal.knots
        );
    }
}
