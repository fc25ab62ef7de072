//! The path tracer: next-event estimation toward the sun and the environment with MIS (power
//! heuristic) against BSDF sampling, `K` indirect bounces after direct lighting, optional
//! Russian roulette, rayon over rows / query points, one PCG stream per pixel (per group of
//! pixels that share packets, when a pixel has fewer samples than a packet) or query.
//!
//! Path length convention (Mitsuba's `max_depth = K + 2`): the camera ray hits vertex x1; each
//! of x1 .. x_{K+1} gets direct light (a sun sample, an environment sample, and the BSDF-sampled
//! ray that escapes to the sky); the path continues by BSDF sampling from x1 .. x_K.

use crate::adaptive::{self, ImagePilot, PilotPixel};
use crate::lighting::{Environment, LightSample, Lighting, Sun};
use crate::sampling::{hash2, jittered, power_heuristic, shifted_hammersley, Rng};
use crate::scene::{Scene, SurfacePoint};
use crate::RenderError;
use glam::{DVec3, Vec2, Vec3};
use igi_brdf::{BsdfSample, Frame, LafortuneRef};
use igi_camera::{Camera, PixelRays};
use igi_imaging::HdrImage;
use igi_raycast::{offset_origin, RaySegment, PACKET};
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};

/// Options of a render or a query batch.
#[derive(Clone, Copy, Debug)]
pub struct RenderOptions {
    /// Samples per pixel (or per query point).
    pub spp: u32,
    pub seed: u64,
    /// Indirect bounces after direct lighting (K; Mitsuba max_depth = K + 2).
    pub indirect: u32,
    /// Russian roulette from the third vertex on (unbiased; shortens long paths).
    pub russian_roulette: bool,
    /// Stratify each pixel's (or query's) samples: the pixel position and the first vertex's
    /// light and BSDF numbers are spread evenly over the samples instead of drawn independently
    /// (unbiased, far less noise for the same samples, docs/RENDER.md). The standard error is
    /// then an upper bound, so validation against a reference's noise keeps it off.
    pub stratified: bool,
    /// Deal a render's samples by each pixel's noise ([`render_image`] only; queries take
    /// `spp` each): `spp` is then the mean over the image, a pilot of an eighth of it (on its
    /// own stream, discarded) measures every pixel's relative noise and cost, and the rest goes
    /// where it lowers the image's summed relative variance most, between `spp / 4` and
    /// `4 spp` a pixel ([`crate::adaptive`]). Unbiased; needs `spp >= 16`.
    pub adaptive: bool,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            spp: 16,
            seed: 0,
            indirect: 2,
            russian_roulette: false,
            stratified: false,
            adaptive: false,
        }
    }
}

/// A Monte-Carlo estimate: the mean and its standard error (per channel).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Estimate {
    pub mean: Vec3,
    pub stderr: Vec3,
}

/// Running mean and variance in f64, from sums of the samples' offsets from the first one
/// (the shifted-data algorithm: as stable as Welford's for these magnitudes, without a
/// division per sample).
#[derive(Clone, Copy, Debug, Default)]
pub struct Accumulator {
    n: u64,
    shift: DVec3,
    sum: DVec3,
    sum2: DVec3,
}

impl Accumulator {
    #[inline]
    pub fn add(&mut self, x: Vec3) {
        let x = x.as_dvec3();
        if self.n == 0 {
            self.shift = x;
        }
        let d = x - self.shift;
        self.n += 1;
        self.sum += d;
        self.sum2 += d * d;
    }

    pub fn estimate(&self) -> Estimate {
        if self.n == 0 {
            return Estimate::default();
        }
        let n = self.n as f64;
        let var = if self.n > 1 {
            ((self.sum2 - self.sum * self.sum / n) / (n - 1.0)).max(DVec3::ZERO)
        } else {
            DVec3::ZERO
        };
        Estimate {
            mean: (self.shift + self.sum / n).as_vec3(),
            stderr: (var / n).map(f64::sqrt).as_vec3(),
        }
    }
}

/// Counters gathered during a render.
#[derive(Debug, Default)]
pub struct Stats {
    /// Rays traced (closest-hit and shadow rays).
    pub rays: AtomicU64,
    /// Samples that came out NaN or infinite and were dropped (should stay 0).
    pub bad_samples: AtomicU64,
    /// Camera samples traced (an adaptive render's pilot included).
    pub samples: AtomicU64,
}

/// A thread's own counts, added to [`Stats`] once a row (atomics per pixel cost a shared
/// cache line per pixel).
#[derive(Clone, Copy, Debug, Default)]
struct Counts {
    rays: u64,
    bad: u64,
    samples: u64,
}

impl Counts {
    fn flush(&self, stats: &Stats) {
        stats.rays.fetch_add(self.rays, Ordering::Relaxed);
        stats.bad_samples.fetch_add(self.bad, Ordering::Relaxed);
        stats.samples.fetch_add(self.samples, Ordering::Relaxed);
    }
}

/// Result of [`render_image`].
pub struct RenderOutput {
    pub mean: HdrImage,
    pub stderr: HdrImage,
    pub rays: u64,
    pub bad_samples: u64,
    /// Camera samples traced: `spp` a pixel, or for an adaptive render its pilot's and its
    /// counts' sum.
    pub samples: u64,
}

/// The random numbers one sample spends at the first path vertex: the sun, the environment,
/// the BSDF's lobe choice and direction.
#[derive(Clone, Copy, Debug)]
struct FirstVertex {
    sun: Vec2,
    env: Vec2,
    select: f32,
    bsdf: Vec2,
}

/// Stratified first-vertex numbers for `n` samples: each 2-D pair is its own
/// [`shifted_hammersley`] set and the lobe choice one [`jittered`] set, each dealt to the samples
/// in its own random order, so the pairs are independent of each other (pbrt's padding). An
/// unbiased estimator (each number is uniform on its own) whose variance, for a smooth
/// integrand, falls faster than `1 / n`.
struct FirstVertexSamples {
    sun: Vec<Vec2>,
    env: Vec<Vec2>,
    select: Vec<f32>,
    bsdf: Vec<Vec2>,
}

impl FirstVertexSamples {
    fn new(n: usize, rng: &mut Rng) -> Self {
        FirstVertexSamples {
            sun: shifted_hammersley(n, rng),
            env: shifted_hammersley(n, rng),
            select: jittered(n, rng),
            bsdf: shifted_hammersley(n, rng),
        }
    }

    fn get(&self, j: usize) -> FirstVertex {
        FirstVertex {
            sun: self.sun[j],
            env: self.env[j],
            select: self.select[j],
            bsdf: self.bsdf[j],
        }
    }
}

/// The BRDF at a vertex, with a fast path for purely Lambertian materials (no lobes): the
/// general Lafortune mixture pdf costs a log and an exp per call, the Lambertian one a multiply.
#[derive(Clone, Copy)]
struct Shading<'b> {
    brdf: LafortuneRef<'b>,
}

const INV_PI: f32 = std::f32::consts::FRAC_1_PI;

impl<'b> Shading<'b> {
    #[inline]
    fn eval_pdf(&self, wi: Vec3, wo: Vec3) -> (Vec3, f32) {
        if self.brdf.lobes.is_empty() {
            if wi.z > 0.0 && wo.z > 0.0 {
                (self.brdf.rho_d * INV_PI, wi.z * INV_PI)
            } else {
                (Vec3::ZERO, 0.0)
            }
        } else {
            self.brdf.eval_pdf(wi, wo)
        }
    }

    #[inline]
    fn sample(&self, wo: Vec3, u_select: f32, u: Vec2) -> Option<BsdfSample> {
        if self.brdf.lobes.is_empty() {
            if !(wo.z > 0.0) {
                return None;
            }
            // Cosine-weighted hemisphere (Malley): pdf = cos / pi.
            let r = u.x.sqrt();
            let (s, c) = crate::fastmath::sincos_turns(u.y);
            let wi = Vec3::new(r * c, r * s, (1.0 - u.x).max(0.0).sqrt());
            if !(wi.z > 0.0) {
                return None;
            }
            Some(BsdfSample {
                wi,
                value: self.brdf.rho_d * INV_PI,
                pdf: wi.z * INV_PI,
            })
        } else {
            self.brdf.sample(wo, u_select, u)
        }
    }
}

/// The path tracer bound to a scene and a lighting.
pub struct PathTracer<'a> {
    pub scene: &'a Scene,
    pub lighting: &'a Lighting,
    /// Number of vertices that receive direct light: K + 1.
    max_vertices: u32,
    rr: bool,
    stratified: bool,
}

impl<'a> PathTracer<'a> {
    pub fn new(scene: &'a Scene, lighting: &'a Lighting, opts: &RenderOptions) -> Self {
        PathTracer {
            scene,
            lighting,
            max_vertices: opts.indirect.saturating_add(1),
            rr: opts.russian_roulette,
            stratified: opts.stratified,
        }
    }

    /// Mean and standard error of `spp` samples of [`lo`](Self::lo) (a non-finite sample counts
    /// as zero), drawn from `rng`. With [`RenderOptions::stratified`] the first vertex's numbers
    /// are stratified across the samples (`FirstVertexSamples`): the direct light and the
    /// first bounce, most of the variance of a surface lit by the sky, converge faster than
    /// `1 / sqrt(spp)`; deeper vertices draw from `rng`. The standard error is still the
    /// samples' spread over `sqrt(spp)`, which stratification makes an upper bound.
    pub fn lo_estimate(
        &self,
        sp: &SurfacePoint,
        wo: Vec3,
        first_brdf: Option<LafortuneRef<'_>>,
        spp: u32,
        rng: &mut Rng,
    ) -> Estimate {
        let mut acc = Accumulator::default();
        let mut rays = 0;
        if self.stratified {
            let first = FirstVertexSamples::new(spp as usize, rng);
            let v = self.vertex(sp, wo, first_brdf);
            for j0 in (0..spp as usize).step_by(PACKET) {
                let n = (spp as usize - j0).min(PACKET);
                let mut l = [Vec3::ZERO; PACKET];
                self.first_vertex_packet(&v, &first, j0..j0 + n, rng, &mut rays, &mut l);
                for v in &l[..n] {
                    acc.add(if v.is_finite() { *v } else { Vec3::ZERO });
                }
            }
        } else {
            for _ in 0..spp {
                let v = self.lo_from(sp, wo, first_brdf, None, rng, &mut rays);
                acc.add(if v.is_finite() { v } else { Vec3::ZERO });
            }
        }
        acc.estimate()
    }

    /// The samples `js` of [`Self::lo_estimate`] from their shared first vertex `v`, whose
    /// numbers are all given: its sun, environment and BSDF rays go to Embree as packets (the
    /// sun's coherent: one origin, one disk), the paths then go on one by one, in sample order
    /// (so `rng` is drawn as [`Self::lo_from`] draws it). `out[i]` for sample `js.start + i`.
    fn first_vertex_packet(
        &self,
        v: &Vertex<'_>,
        first: &FirstVertexSamples,
        js: std::ops::Range<usize>,
        rng: &mut Rng,
        rays: &mut u64,
        out: &mut [Vec3],
    ) {
        let (sun, env) = self.lights();
        let samples = || js.clone().enumerate().map(|(i, j)| (i, first.get(j)));
        if let Some(sun) = sun {
            let mut shadow = ShadowRays::new();
            for (i, f) in samples() {
                shadow.push(i, v, Vec3::ONE, &sun.sample(f.sun));
            }
            shadow.trace(self.scene, true, out, rays);
        }
        if let Some(env) = env {
            let mut shadow = ShadowRays::new();
            for (i, f) in samples() {
                if let Some(ls) = env.sample_monotone(f.env) {
                    if ls.radiance != Vec3::ZERO {
                        shadow.push(i, v, Vec3::ONE, &ls);
                    }
                }
            }
            shadow.trace(self.scene, false, out, rays);
        }
        let mut next = [NO_RAY; PACKET];
        let mut path = [(0usize, Vec3::ZERO, 0f32); PACKET];
        let mut m = 0;
        for (i, f) in samples() {
            let Some(bs) = v.brdf.sample(v.wo_l, f.select, f.bsdf) else {
                continue;
            };
            let wi = v.frame.to_world(bs.wi);
            if !(bs.pdf > 0.0) || wi.dot(v.ng) <= 0.0 || !wi.is_finite() {
                continue;
            }
            let beta = bs.value * (bs.wi.z / bs.pdf);
            if !beta.is_finite() || beta == Vec3::ZERO {
                continue;
            }
            next[m] = ray_from(v.origin, wi);
            path[m] = (i, beta, bs.pdf);
            m += 1;
        }
        let mut hits = [None; PACKET];
        self.scene
            .rt()
            .intersect_packet(&next[..m], false, &mut hits);
        *rays += m as u64;
        for ((ray, &(i, beta, pdf)), hit) in next.iter().zip(&path).zip(&hits).take(m) {
            match hit {
                None => out[i] += beta * escaped_mis(sun, env, ray.dir, pdf),
                Some(h) if self.max_vertices > 1 => {
                    let sp = self.scene.surface_point(h);
                    out[i] += self.lo_path(&sp, -ray.dir, beta, 2, None, None, rng, rays);
                }
                Some(_) => {}
            }
        }
    }

    /// Radiance arriving at `origin` along `-dir` (a camera ray). Rays that leave the scene
    /// see the environment and the sun disk.
    #[inline]
    pub fn li(&self, origin: Vec3, dir: Vec3, rng: &mut Rng, rays: &mut u64) -> Vec3 {
        self.li_from(origin, dir, None, rng, rays)
    }

    /// [`Self::li`] with the first vertex's random numbers given (`first`) instead of drawn.
    #[inline]
    fn li_from(
        &self,
        origin: Vec3,
        dir: Vec3,
        first: Option<FirstVertex>,
        rng: &mut Rng,
        rays: &mut u64,
    ) -> Vec3 {
        *rays += 1;
        match self.scene.intersect(origin, dir) {
            None => self.lighting.escaped(dir),
            Some(h) => {
                let sp = self.scene.surface_point(&h);
                self.lo_from(&sp, -dir, None, first, rng, rays)
            }
        }
    }

    /// Radiance leaving surface point `sp` in direction `wo` (unit, world). Surfaces emit
    /// nothing. `first_brdf` overrides the material at `sp` only (used by [`irradiance`]).
    pub fn lo(
        &self,
        sp: &SurfacePoint,
        wo: Vec3,
        first_brdf: Option<LafortuneRef<'_>>,
        rng: &mut Rng,
        rays: &mut u64,
    ) -> Vec3 {
        self.lo_from(sp, wo, first_brdf, None, rng, rays)
    }

    /// [`Self::lo`] with the first vertex's random numbers given (`first`) instead of drawn.
    fn lo_from(
        &self,
        sp: &SurfacePoint,
        wo: Vec3,
        first_brdf: Option<LafortuneRef<'_>>,
        first: Option<FirstVertex>,
        rng: &mut Rng,
        rays: &mut u64,
    ) -> Vec3 {
        self.lo_path(sp, wo, Vec3::ONE, 1, first_brdf, first, rng, rays)
    }

    /// The radiance a path carries back from its vertex number `vertex` at `sp` (outgoing
    /// direction `wo`, throughput `beta` so far): [`Self::lo_from`] from any vertex on.
    /// `first_brdf` and `first` apply at vertex 1 only.
    #[allow(clippy::too_many_arguments)]
    fn lo_path(
        &self,
        sp: &SurfacePoint,
        wo: Vec3,
        beta: Vec3,
        vertex: u32,
        first_brdf: Option<LafortuneRef<'_>>,
        first: Option<FirstVertex>,
        rng: &mut Rng,
        rays: &mut u64,
    ) -> Vec3 {
        let mut l = Vec3::ZERO;
        let mut beta = beta;
        let mut sp = *sp;
        let mut wo = wo;
        let mut vertex = vertex;
        let (sun, env) = self.lights();
        loop {
            let brdf_override = if vertex == 1 { first_brdf } else { None };
            let v = self.vertex(&sp, wo, brdf_override);
            let given = first.filter(|_| vertex == 1);

            // Next-event estimation: one sample of the sun and one of the environment.
            if let Some(sun) = sun {
                let ls = sun.sample(given.map_or_else(|| rng.uniform2(), |f| f.sun));
                if let Some(c) = self.light_sample(&v, beta, &ls, rays) {
                    l += c;
                }
            }
            if let Some(env) = env {
                let ls = match given {
                    Some(f) => env.sample_monotone(f.env),
                    None => env.sample(rng.uniform2()),
                };
                if let Some(ls) = ls {
                    if ls.radiance != Vec3::ZERO {
                        if let Some(c) = self.light_sample(&v, beta, &ls, rays) {
                            l += c;
                        }
                    }
                }
            }

            // BSDF sampling: the MIS partner of the light samples and the path continuation.
            let (u_sel, u) = match given {
                Some(f) => (f.select, f.bsdf),
                None => (rng.uniform(), rng.uniform2()),
            };
            let Some(bs) = v.brdf.sample(v.wo_l, u_sel, u) else {
                break;
            };
            let wi = v.frame.to_world(bs.wi);
            if !(bs.pdf > 0.0) || wi.dot(v.ng) <= 0.0 || !wi.is_finite() {
                break;
            }
            beta *= bs.value * (bs.wi.z / bs.pdf);
            if !beta.is_finite() || beta == Vec3::ZERO {
                break;
            }
            *rays += 1;
            let Some(h) = self.scene.intersect(v.origin, wi) else {
                l += beta * escaped_mis(sun, env, wi, bs.pdf);
                break;
            };
            if vertex >= self.max_vertices || !self.survives_roulette(vertex, &mut beta, rng) {
                break;
            }
            sp = self.scene.surface_point(&h);
            wo = -wi;
            vertex += 1;
        }
        l
    }

    /// [`Self::li_from`] for up to [`PACKET`] camera rays at once (`out[i]` for `cam[i]`),
    /// their paths traced in lockstep so that every ray query goes to Embree as one packet:
    /// the camera rays and the sun's shadow rays as coherent packets, the environment's shadow
    /// rays and the BSDF rays as incoherent ones. Same estimator, same random numbers per
    /// vertex as [`Self::li_from`], drawn path after path at each vertex.
    fn li_packet(
        &self,
        cam: &[RaySegment],
        first: &[Option<FirstVertex>],
        rng: &mut Rng,
        rays: &mut u64,
        out: &mut [Vec3],
    ) {
        let rt = self.scene.rt();
        let (sun, env) = self.lights();
        let mut hits = [None; PACKET];
        rt.intersect_packet(cam, true, &mut hits);
        *rays += cam.len() as u64;
        let mut paths = [PathState {
            sample: 0,
            sp: SurfacePoint {
                position: Vec3::ZERO,
                ng: Vec3::Z,
                ns: Vec3::Z,
                uv: Vec2::ZERO,
                object: 0,
                prim: 0,
            },
            wo: Vec3::Z,
            beta: Vec3::ONE,
        }; PACKET];
        let mut n = 0;
        for (i, (r, h)) in cam.iter().zip(&hits).enumerate() {
            match h {
                None => out[i] = self.lighting.escaped(r.dir),
                Some(h) => {
                    out[i] = Vec3::ZERO;
                    paths[n].sample = i;
                    paths[n].sp = self.scene.surface_point(h);
                    paths[n].wo = -r.dir;
                    n += 1;
                }
            }
        }
        let mut vertex = 1u32;
        while n > 0 {
            let verts: [Option<Vertex<'_>>; PACKET] = std::array::from_fn(|k| {
                (k < n).then(|| self.vertex(&paths[k].sp, paths[k].wo, None))
            });
            let given = |sample: usize| first[sample].filter(|_| vertex == 1);
            // Next-event estimation: the sun's shadow rays as one packet, the environment's.
            if let Some(sun) = sun {
                let mut shadow = ShadowRays::new();
                for (k, v) in verts
                    .iter()
                    .enumerate()
                    .take(n)
                    .filter_map(|(k, v)| Some((k, v.as_ref()?)))
                {
                    let ls = sun
                        .sample(given(paths[k].sample).map_or_else(|| rng.uniform2(), |f| f.sun));
                    shadow.push(paths[k].sample, v, paths[k].beta, &ls);
                }
                shadow.trace(self.scene, true, out, rays);
            }
            if let Some(env) = env {
                let mut shadow = ShadowRays::new();
                for (k, v) in verts
                    .iter()
                    .enumerate()
                    .take(n)
                    .filter_map(|(k, v)| Some((k, v.as_ref()?)))
                {
                    let ls = match given(paths[k].sample) {
                        Some(f) => env.sample_monotone(f.env),
                        None => env.sample(rng.uniform2()),
                    };
                    if let Some(ls) = ls.filter(|ls| ls.radiance != Vec3::ZERO) {
                        shadow.push(paths[k].sample, v, paths[k].beta, &ls);
                    }
                }
                shadow.trace(self.scene, false, out, rays);
            }
            // BSDF sampling: the MIS partner of the light samples and the path continuation.
            let mut next = [NO_RAY; PACKET];
            let mut pdfs = [0f32; PACKET];
            let mut m = 0;
            for (k, v) in verts
                .iter()
                .enumerate()
                .take(n)
                .filter_map(|(k, v)| Some((k, v.as_ref()?)))
            {
                let (u_sel, u) = match given(paths[k].sample) {
                    Some(f) => (f.select, f.bsdf),
                    None => (rng.uniform(), rng.uniform2()),
                };
                let Some(bs) = v.brdf.sample(v.wo_l, u_sel, u) else {
                    continue;
                };
                let wi = v.frame.to_world(bs.wi);
                if !(bs.pdf > 0.0) || wi.dot(v.ng) <= 0.0 || !wi.is_finite() {
                    continue;
                }
                let beta = paths[k].beta * bs.value * (bs.wi.z / bs.pdf);
                if !beta.is_finite() || beta == Vec3::ZERO {
                    continue;
                }
                next[m] = ray_from(v.origin, wi);
                pdfs[m] = bs.pdf;
                paths[m] = PathState { beta, ..paths[k] };
                m += 1;
            }
            rt.intersect_packet(&next[..m], false, &mut hits);
            *rays += m as u64;
            n = 0;
            for k in 0..m {
                let wi = next[k].dir;
                let Some(h) = hits[k] else {
                    out[paths[k].sample] += paths[k].beta * escaped_mis(sun, env, wi, pdfs[k]);
                    continue;
                };
                let mut beta = paths[k].beta;
                if vertex >= self.max_vertices || !self.survives_roulette(vertex, &mut beta, rng) {
                    continue;
                }
                paths[n] = PathState {
                    sample: paths[k].sample,
                    sp: self.scene.surface_point(&h),
                    wo: -wi,
                    beta,
                };
                n += 1;
            }
            vertex += 1;
        }
    }

    /// The sun and the environment, the latter only when it is not black.
    #[inline]
    fn lights(&self) -> (Option<&Sun>, Option<&Environment>) {
        let env = self
            .lighting
            .environment
            .as_ref()
            .filter(|e| e.is_nonzero());
        (self.lighting.sun.as_ref(), env)
    }

    /// The shading context of a path vertex: two-sided surfaces have their normals oriented
    /// toward the outgoing direction; `brdf_override` replaces the material's BRDF.
    #[inline]
    fn vertex<'s>(
        &'s self,
        sp: &SurfacePoint,
        wo: Vec3,
        brdf_override: Option<LafortuneRef<'s>>,
    ) -> Vertex<'s> {
        let ng = if sp.ng.dot(wo) < 0.0 { -sp.ng } else { sp.ng };
        let ns = if sp.ns.dot(ng) < 0.0 { -sp.ns } else { sp.ns };
        let frame = Frame::from_normal(ns);
        let brdf = Shading {
            brdf: brdf_override.unwrap_or_else(|| {
                self.scene.objects[sp.object as usize]
                    .material
                    .brdf_at(sp.uv)
            }),
        };
        Vertex {
            ng,
            frame,
            wo_l: frame.to_local(wo),
            brdf,
            origin: offset_origin(sp.position, ng),
        }
    }

    /// The MIS-weighted contribution (times the path throughput `beta`) of one light sample at
    /// vertex `v`, or `None` when the light is below the surface, the BRDF is zero there, or the
    /// shadow ray is blocked. Counts the shadow ray in `rays`.
    #[inline]
    fn light_sample(
        &self,
        v: &Vertex<'_>,
        beta: Vec3,
        ls: &LightSample,
        rays: &mut u64,
    ) -> Option<Vec3> {
        let c = light_unoccluded(v, beta, ls)?;
        *rays += 1;
        (!self.scene.occluded(v.origin, ls.wi, f32::INFINITY)).then_some(c)
    }

    /// Russian roulette from the second bounce on (when enabled): whether the path goes on;
    /// a surviving path's throughput is divided by its survival probability.
    #[inline]
    fn survives_roulette(&self, vertex: u32, beta: &mut Vec3, rng: &mut Rng) -> bool {
        if self.rr && vertex >= 2 {
            let q = beta.max_element().min(0.95);
            if rng.uniform() >= q {
                return false;
            }
            *beta /= q;
        }
        true
    }
}

/// A path vertex ready for shading (see [`PathTracer::vertex`]).
struct Vertex<'b> {
    /// Geometric normal on the side of the outgoing direction.
    ng: Vec3,
    /// Shading frame around the (oriented) shading normal.
    frame: Frame,
    /// Outgoing direction in `frame`.
    wo_l: Vec3,
    brdf: Shading<'b>,
    /// Ray origin offset off the surface along `ng`.
    origin: Vec3,
}

/// [`PathTracer::light_sample`]'s contribution if the shadow ray is not blocked (`None` when
/// it need not be traced: the light is below the surface or the BRDF is zero there).
#[inline]
fn light_unoccluded(v: &Vertex<'_>, beta: Vec3, ls: &LightSample) -> Option<Vec3> {
    if !(ls.wi.dot(v.ng) > 0.0) {
        return None;
    }
    let wi_l = v.frame.to_local(ls.wi);
    let (f, pdf_b) = v.brdf.eval_pdf(wi_l, v.wo_l);
    if f == Vec3::ZERO {
        return None;
    }
    let w = power_heuristic(ls.pdf, pdf_b);
    Some(beta * f * ls.radiance * (wi_l.z * w / ls.pdf))
}

/// Shadow rays gathered over a packet's paths: the ray, the path it belongs to, and what it
/// adds there when unblocked.
struct ShadowRays {
    rays: [RaySegment; PACKET],
    lane: [usize; PACKET],
    add: [Vec3; PACKET],
    n: usize,
}

impl ShadowRays {
    fn new() -> Self {
        ShadowRays {
            rays: [NO_RAY; PACKET],
            lane: [0; PACKET],
            add: [Vec3::ZERO; PACKET],
            n: 0,
        }
    }

    #[inline]
    fn push(&mut self, lane: usize, v: &Vertex<'_>, beta: Vec3, ls: &LightSample) {
        if let Some(c) = light_unoccluded(v, beta, ls) {
            self.rays[self.n] = ray_from(v.origin, ls.wi);
            self.lane[self.n] = lane;
            self.add[self.n] = c;
            self.n += 1;
        }
    }

    /// Traces the rays as one packet; adds each unblocked one's light to `l` of its path.
    fn trace(&self, scene: &Scene, coherent: bool, l: &mut [Vec3], rays: &mut u64) {
        let mut blocked = [false; PACKET];
        scene
            .rt()
            .occluded_packet(&self.rays[..self.n], coherent, &mut blocked);
        *rays += self.n as u64;
        for i in 0..self.n {
            if !blocked[i] {
                l[self.lane[i]] += self.add[i];
            }
        }
    }
}

/// A path of a packet between two vertices: where it stands and what it carries.
#[derive(Clone, Copy)]
struct PathState {
    /// Index of the path's sample in the packet.
    sample: usize,
    sp: SurfacePoint,
    wo: Vec3,
    beta: Vec3,
}

const NO_RAY: RaySegment = RaySegment {
    origin: Vec3::ZERO,
    dir: Vec3::Z,
    tnear: 0.0,
    tfar: f32::INFINITY,
};

#[inline]
fn ray_from(origin: Vec3, dir: Vec3) -> RaySegment {
    RaySegment {
        origin,
        dir,
        tnear: 0.0,
        tfar: f32::INFINITY,
    }
}

/// Radiance of the sun and the environment seen along an escaping BSDF-sampled direction `wi`,
/// each MIS-weighted against the BSDF pdf `pdf_bsdf`.
#[inline]
fn escaped_mis(sun: Option<&Sun>, env: Option<&Environment>, wi: Vec3, pdf_bsdf: f32) -> Vec3 {
    let mut le = Vec3::ZERO;
    if let Some(sun) = sun {
        if sun.contains(wi) {
            le += sun.radiance * power_heuristic(pdf_bsdf, sun.pdf(wi));
        }
    }
    if let Some(env) = env {
        let (l_env, pdf_env) = env.eval_pdf(wi);
        le += l_env * power_heuristic(pdf_bsdf, pdf_env);
    }
    le
}

/// Pixel (x, y)'s estimate from `spp` camera samples on the pixel's own stream of
/// `opts.seed`, and the rays they traced (also added to `counts`).
fn render_pixel(
    pt: &PathTracer,
    camera: &PixelRays,
    opts: &RenderOptions,
    spp: u32,
    x: usize,
    y: usize,
    counts: &mut Counts,
) -> (Estimate, u64) {
    let rays_before = counts.rays;
    let e = render_pixels(pt, camera, opts, y, &[(x, spp)], counts)[0];
    (e, counts.rays - rays_before)
}

/// The estimates of neighbouring pixels `(x, spp)` of row `y`, their samples traced together
/// in full packets of [`PACKET`] (a 4-spp pixel alone fills half of one), on the stream of the
/// first pixel: each pixel's strata are drawn in pixel order, then its jitters and paths
/// packet by packet. One pixel alone is [`render_pixel`]. Rays and samples go to `counts`.
fn render_pixels(
    pt: &PathTracer,
    camera: &PixelRays,
    opts: &RenderOptions,
    y: usize,
    pixels: &[(usize, u32)],
    counts: &mut Counts,
) -> Vec<Estimate> {
    let mut rng = Rng::new(
        opts.seed,
        (y * camera.width() as usize + pixels[0].0) as u64,
    );
    let strata: Vec<_> = pixels
        .iter()
        .map(|&(_, spp)| {
            opts.stratified.then(|| {
                let jitter = shifted_hammersley(spp as usize, &mut rng);
                (jitter, FirstVertexSamples::new(spp as usize, &mut rng))
            })
        })
        .collect();
    let mut accs = vec![Accumulator::default(); pixels.len()];
    let mut samples = pixels
        .iter()
        .enumerate()
        .flat_map(|(k, &(_, spp))| (0..spp as usize).map(move |j| (k, j)))
        .peekable();
    while samples.peek().is_some() {
        let mut cam = [NO_RAY; PACKET];
        let mut first = [None; PACKET];
        // each sample of the packet: its pixel, and its lane when its camera ray is valid
        let mut slots = [(0usize, None::<usize>); PACKET];
        let (mut n, mut len) = (0, 0);
        for (k, j) in samples.by_ref().take(PACKET) {
            let (jitter, f) = match &strata[k] {
                Some((jitter, first)) => (jitter[j], Some(first.get(j))),
                None => (rng.uniform2(), None),
            };
            let x = pixels[k].0 as f32;
            let (o, d) = camera.ray(x - 0.5 + jitter.x, y as f32 - 0.5 + jitter.y);
            slots[len] = (k, None);
            if o.is_finite() && d.is_finite() && d != Vec3::ZERO {
                cam[n] = ray_from(o, d);
                first[n] = f;
                slots[len].1 = Some(n);
                n += 1;
            }
            len += 1;
        }
        let mut li = [Vec3::ZERO; PACKET];
        pt.li_packet(&cam[..n], &first[..n], &mut rng, &mut counts.rays, &mut li);
        for &(k, lane) in &slots[..len] {
            let mut v = lane.map_or(Vec3::ZERO, |i| li[i]);
            if !v.is_finite() {
                counts.bad += 1;
                v = Vec3::ZERO;
            }
            accs[k].add(v);
        }
    }
    counts.samples += pixels.iter().map(|&(_, spp)| spp as u64).sum::<u64>();
    accs.iter().map(Accumulator::estimate).collect()
}

/// What an adaptive render's pilot ([`crate::adaptive`]) measures, on the stream
/// `hash2(opts.seed, PILOT_STREAM)`, its rays and samples counted in `stats`, its samples
/// discarded.
fn pilot(pt: &PathTracer, camera: &Camera, opts: &RenderOptions, stats: &Stats) -> ImagePilot {
    let (w, h) = (camera.width as usize, camera.height as usize);
    let pilot_spp = adaptive::pilot_spp(opts.spp);
    let pilot_opts = RenderOptions {
        seed: hash2(opts.seed, PILOT_STREAM),
        ..*opts
    };
    let rays = PixelRays::new(camera);
    let rows: Vec<Vec<PilotPixel>> = (0..h)
        .into_par_iter()
        .map(|y| {
            let mut counts = Counts::default();
            let row: Vec<PilotPixel> = (0..w)
                .map(|x| {
                    let (e, r) = render_pixel(pt, &rays, &pilot_opts, pilot_spp, x, y, &mut counts);
                    PilotPixel {
                        mean: e.mean.element_sum() / 3.0,
                        sd: e.stderr.element_sum() / 3.0 * (pilot_spp as f32).sqrt(),
                        cost: r as f32 / pilot_spp as f32,
                    }
                })
                .collect();
            counts.flush(stats);
            row
        })
        .collect();
    let pixels = rows.into_iter().flatten().collect();
    ImagePilot {
        width: w,
        height: h,
        pixels,
    }
}

/// The stream number (under the render's seed) of an adaptive render's pilot.
const PILOT_STREAM: u64 = 0x0070_696c_6f74;

/// One image of [`render_images`]: its camera, the lighting it is rendered under and its seed
/// (in place of `RenderOptions::seed`).
#[derive(Clone, Copy)]
pub struct RenderJob<'a> {
    pub camera: &'a Camera,
    pub lighting: &'a Lighting,
    pub seed: u64,
}

/// Renders an image through `camera` (OpenCV model with distortion, via `Camera::pixel_ray`).
/// Pixel (x, y) averages `spp` rays (with [`RenderOptions::adaptive`], its own number of them)
/// through points uniform in [x - 0.5, x + 0.5] x [y - 0.5, y + 0.5] (box filter). Returns the
/// mean and the per-pixel standard error.
/// `progress(n)` is called with the number of pixel rows finished since the last call.
pub fn render_image(
    scene: &Scene,
    lighting: &Lighting,
    camera: &Camera,
    opts: &RenderOptions,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<RenderOutput, RenderError> {
    let job = RenderJob {
        camera,
        lighting,
        seed: opts.seed,
    };
    let mut out = render_images(scene, &[job], opts, &|_, n| progress(n))?;
    Ok(out.remove(0))
}

/// Renders several images of one scene as [`render_image`] renders one, each with its job's
/// seed. With [`RenderOptions::adaptive`] they share one budget, `spp` a pixel on average over
/// all of them: every image's pilot runs first, then the samples are dealt over all their
/// pixels at once ([`adaptive::sample_counts_over`]), so a noisier image takes more of them
/// (for a single image, exactly [`render_image`]'s counts). `progress(job, n)` is called with
/// the number of that image's pixel rows finished since the last call.
pub fn render_images(
    scene: &Scene,
    jobs: &[RenderJob],
    opts: &RenderOptions,
    progress: &(dyn Fn(usize, u64) + Sync),
) -> Result<Vec<RenderOutput>, RenderError> {
    if opts.spp == 0 {
        return Err(RenderError::ZeroSpp);
    }
    if opts.adaptive && opts.spp < adaptive::MIN_SPP {
        return Err(RenderError::AdaptiveSpp(opts.spp, adaptive::MIN_SPP));
    }
    if let Some(j) = jobs
        .iter()
        .find(|j| j.camera.width == 0 || j.camera.height == 0)
    {
        return Err(RenderError::EmptyImage(
            j.camera.width as usize,
            j.camera.height as usize,
        ));
    }
    let job_opts: Vec<RenderOptions> = jobs
        .iter()
        .map(|j| RenderOptions {
            seed: j.seed,
            ..*opts
        })
        .collect();
    let tracers: Vec<PathTracer> = jobs
        .iter()
        .zip(&job_opts)
        .map(|(j, o)| PathTracer::new(scene, j.lighting, o))
        .collect();
    let stats: Vec<Stats> = jobs.iter().map(|_| Stats::default()).collect();
    let counts: Option<Vec<Vec<u32>>> = opts.adaptive.then(|| {
        let pilots: Vec<ImagePilot> = (0..jobs.len())
            .map(|k| pilot(&tracers[k], jobs[k].camera, &job_opts[k], &stats[k]))
            .collect();
        adaptive::sample_counts_over(&pilots, opts.spp)
    });
    Ok((0..jobs.len())
        .map(|k| {
            let c = counts.as_ref().map(|c| c[k].as_slice());
            let row_done = |n| progress(k, n);
            trace_image(
                &tracers[k],
                jobs[k].camera,
                &job_opts[k],
                c,
                &stats[k],
                &row_done,
            )
        })
        .collect())
}

/// Every pixel of one image (its own number of samples from `counts`, else `opts.spp`).
fn trace_image(
    pt: &PathTracer,
    camera: &Camera,
    opts: &RenderOptions,
    counts: Option<&[u32]>,
    stats: &Stats,
    progress: &(dyn Fn(u64) + Sync),
) -> RenderOutput {
    let (w, h) = (camera.width as usize, camera.height as usize);
    let rays = PixelRays::new(camera);
    let rows: Vec<(Vec<[f32; 3]>, Vec<[f32; 3]>)> = (0..h)
        .into_par_iter()
        .map(|y| {
            let mut mean_row = Vec::with_capacity(w);
            let mut se_row = Vec::with_capacity(w);
            let mut row_counts = Counts::default();
            // pixels of fewer samples than a packet share packets
            let group = (PACKET / opts.spp.max(1) as usize).max(1);
            let pixels: Vec<(usize, u32)> = (0..w)
                .map(|x| (x, counts.map_or(opts.spp, |c| c[y * w + x])))
                .collect();
            for g in pixels.chunks(group) {
                for e in render_pixels(pt, &rays, opts, y, g, &mut row_counts) {
                    mean_row.push(e.mean.to_array());
                    se_row.push(e.stderr.to_array());
                }
            }
            row_counts.flush(stats);
            progress(1);
            (mean_row, se_row)
        })
        .collect();
    let mut mean = HdrImage::new(w, h);
    let mut stderr = HdrImage::new(w, h);
    for (y, (m, s)) in rows.into_iter().enumerate() {
        mean.pixels[y * w..(y + 1) * w].copy_from_slice(&m);
        stderr.pixels[y * w..(y + 1) * w].copy_from_slice(&s);
    }
    RenderOutput {
        mean,
        stderr,
        rays: stats.rays.load(Ordering::Relaxed),
        bad_samples: stats.bad_samples.load(Ordering::Relaxed),
        samples: stats.samples.load(Ordering::Relaxed),
    }
}

/// Radiance leaving each surface point toward a world position (`targets[i]`, e.g. a camera
/// centre), under `lighting`. Points are independent (rayon); point i uses stream
/// `hash(seed, i)`.
pub fn radiance_toward(
    scene: &Scene,
    lighting: &Lighting,
    points: &[SurfacePoint],
    targets: &[Vec3],
    opts: &RenderOptions,
) -> Result<Vec<Estimate>, RenderError> {
    check_query(points.len(), "targets", targets.len(), opts)?;
    let pt = PathTracer::new(scene, lighting, opts);
    Ok(points
        .par_iter()
        .zip(targets.par_iter())
        .enumerate()
        .map(|(i, (sp, target))| {
            let wo = (*target - sp.position).normalize_or_zero();
            if wo == Vec3::ZERO {
                return Estimate::default();
            }
            pt.lo_estimate(sp, wo, None, opts.spp, &mut Rng::new(opts.seed, i as u64))
        })
        .collect())
}

/// Irradiance (W/m^2-like units: radiance times sr) arriving at each point on the side of
/// `normals[i]`, including interreflections up to the same path length as a render (the
/// point acts as a white Lambertian receiver: E = pi * L_out).
pub fn irradiance(
    scene: &Scene,
    lighting: &Lighting,
    points: &[Vec3],
    normals: &[Vec3],
    opts: &RenderOptions,
) -> Result<Vec<Estimate>, RenderError> {
    check_query(points.len(), "normals", normals.len(), opts)?;
    let pt = PathTracer::new(scene, lighting, opts);
    let white = LafortuneRef {
        rho_d: Vec3::ONE,
        lobes: &[],
    };
    let pi = std::f32::consts::PI;
    Ok(points
        .par_iter()
        .zip(normals.par_iter())
        .enumerate()
        .map(|(i, (p, n))| {
            let n = n.normalize_or_zero();
            if n == Vec3::ZERO || !p.is_finite() {
                return Estimate::default();
            }
            // object/prim/uv are unused at the first vertex (its BRDF is overridden).
            let sp = SurfacePoint {
                position: *p,
                ng: n,
                ns: n,
                uv: Vec2::ZERO,
                object: 0,
                prim: 0,
            };
            let e = pt.lo_estimate(
                &sp,
                n,
                Some(white),
                opts.spp,
                &mut Rng::new(opts.seed, i as u64),
            );
            Estimate {
                mean: e.mean * pi,
                stderr: e.stderr * pi,
            }
        })
        .collect())
}

/// A query batch needs one `other` per point and at least one sample each.
fn check_query(
    points: usize,
    other: &'static str,
    other_len: usize,
    opts: &RenderOptions,
) -> Result<(), RenderError> {
    if points != other_len {
        return Err(RenderError::Unpaired {
            what: "points",
            len: points,
            other,
            other_len,
        });
    }
    if opts.spp == 0 {
        return Err(RenderError::ZeroSpp);
    }
    Ok(())
}
