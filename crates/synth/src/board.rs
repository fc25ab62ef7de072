//! A small reference renderer of lighting-board photographs (`igi_probe::Board`) from a known
//! lat-long sky (and sun), for round-trip tests, benchmarks and the demo's probe captures.
//! Independent of the unwarping code: it traces camera rays forward (pixel -> sphere ->
//! reflected direction), with `ss` x `ss` supersampling.

use glam::DVec3;
use igi_camera::{Camera, WorldToCamera};
use igi_capture::sphere::SphereView;
use igi_capture::spot::pixel_response;
use igi_imaging::HdrImage;
use igi_probe::envmap::{disk_cosine_solid_angle, latlong_lookup, Integrator};
use igi_probe::{Board, SphereKind};
use rayon::prelude::*;

/// A sun for [`render_board`]: direction (unit, toward the sun), radiance, angular diameter.
#[derive(Clone, Copy, Debug)]
pub struct SynthSun {
    pub direction: DVec3,
    pub radiance: [f32; 3],
    pub diameter_deg: f64,
}

/// Render the board's spheres (and the sky behind them) as the camera sees them. Mirror and
/// black spheres reflect the sky (and the sun disk where reflected rays hit it) times their
/// Fresnel reflectance; the diffuse sphere shows reflectance * irradiance / pi (irradiance
/// from the integrated sky plus the sun disk, evaluated at each sub-sample's normal; a pixel
/// inside its image at incidence cosine >= 0.5, off the sun's terminator, takes one sample at
/// its centre, which is its mean to about 1e-5 relative there).
/// `sky` must be fully valid.
pub fn render_board(
    camera: &Camera,
    board: &Board,
    sky: &HdrImage,
    sun: Option<SynthSun>,
    ss: usize,
) -> HdrImage {
    render_board_with_panel(camera, board, sky, sun, ss, None)
}

/// The flat board behind the spheres, printed with fiducials, for [`render_board_with_panel`]:
/// a rectangle of the board plane `z = 0` (board frame) of constant radiance `white`, with
/// markers of radiance `black` where their images are 0 (and `white` where 255).
#[derive(Clone, Debug)]
pub struct SynthPanel {
    /// Board to camera: `x_cam = r x_board + t`.
    pub board_to_camera: WorldToCamera,
    /// `[x0, y0, x1, y1]` in the board plane.
    pub extent: [f64; 4],
    pub white: f32,
    pub black: f32,
    /// Each marker: its corners in the board frame (the image's top-left, top-right,
    /// bottom-right, bottom-left; in the plane z = 0), and its `side` x `side` image (bytes).
    pub markers: Vec<([DVec3; 4], usize, Vec<u8>)>,
}

impl SynthPanel {
    /// Radiance of board-frame point `q` (in the plane) if it is on the panel.
    fn radiance(&self, q: DVec3) -> Option<f32> {
        let [x0, y0, x1, y1] = self.extent;
        if !(q.x >= x0 && q.x <= x1 && q.y >= y0 && q.y <= y1) {
            return None;
        }
        for (c, side, bits) in &self.markers {
            let (a, b) = (c[1] - c[0], c[3] - c[0]);
            let (s, t) = (
                (q - c[0]).dot(a) / a.length_squared(),
                (q - c[0]).dot(b) / b.length_squared(),
            );
            if (0.0..1.0).contains(&s) && (0.0..1.0).contains(&t) {
                let (col, row) = ((s * *side as f64) as usize, (t * *side as f64) as usize);
                let v = bits[row.min(side - 1) * side + col.min(side - 1)] as f32 / 255.0;
                return Some(self.black + (self.white - self.black) * v);
            }
        }
        Some(self.white)
    }

    /// Nearest hit (distance along the unit world ray, radiance) of the panel.
    fn hit(&self, camera: &Camera, o: DVec3, d: DVec3) -> Option<(f64, f32)> {
        let c2w = camera.pose.inverse();
        let to_world = |p: DVec3| c2w.apply(self.board_to_camera.apply(p));
        let origin = to_world(DVec3::ZERO);
        let (ex, ey) = (to_world(DVec3::X) - origin, to_world(DVec3::Y) - origin);
        let n = ex.cross(ey);
        let den = d.dot(n);
        if den.abs() < 1e-12 {
            return None;
        }
        let t = (origin - o).dot(n) / den;
        if t <= 0.0 || !t.is_finite() {
            return None;
        }
        let q = o + t * d - origin;
        self.radiance(DVec3::new(q.dot(ex), q.dot(ey), 0.0))
            .map(|v| (t, v))
    }
}

/// [`render_board`] with the board itself behind the spheres (an optional textured panel
/// with fiducials, see [`SynthPanel`]); rays that miss spheres and panel show the sky. The
/// mirror and black spheres reflect the panel where their reflected rays meet it (their rims);
/// the diffuse sphere's irradiance is the sky's alone.
pub fn render_board_with_panel(
    camera: &Camera,
    board: &Board,
    sky: &HdrImage,
    sun: Option<SynthSun>,
    ss: usize,
    panel: Option<&SynthPanel>,
) -> HdrImage {
    let scene = Scene::new(camera, board, sky, sun, panel, true);
    render_pixels(&scene, ss.max(1), &|x, y| !scene.smooth_diffuse_pixel(x, y))
}

/// How the synthetic camera of [`render_board_sensor`] forms a pixel: the scene blurred by a
/// Gaussian lens (standard deviation `blur_sigma` pixels), then integrated over the pixel's area.
#[derive(Clone, Copy, Debug)]
pub struct Sensor {
    /// Sub-samples per pixel side for everything but the sun (box filter of the pixel area).
    pub ss: usize,
    /// The lens's Gaussian blur in pixels (0: none).
    pub blur_sigma: f64,
}

/// Sub-samples per side of the square around a sun spot in [`render_board_sensor`] (the disk's
/// reflection is about 0.8 of that square across, so some 20,000 samples land in it).
const SUN_GRID: usize = 192;

/// A board photograph as a camera with a Gaussian lens and square pixels takes it: each pixel
/// is the integral over its area of the lens-blurred scene. The sky, the spheres' outlines and
/// the diffuse sphere are rendered with `ss` x `ss` box samples (only inside the spheres' pixel
/// boxes and not inside the diffuse sphere away from its rim; elsewhere one sample) and blurred
/// by [`gaussian_blur`] (exact for the smooth parts).
/// The sun's tiny reflections in the mirror and black spheres are rendered separately and
/// exactly: the spot is sampled densely (192 x 192 rays over its square, whatever the
/// sphere's size) and each sample is spread over the pixels by the box-times-Gaussian pixel
/// response ([`pixel_response`]), so the spot's sub-pixel position survives in the pixels as it
/// does in a photograph. The sun seen directly in the background is not drawn.
pub fn render_board_sensor(
    camera: &Camera,
    board: &Board,
    sky: &HdrImage,
    sun: Option<SynthSun>,
    sensor: Sensor,
) -> HdrImage {
    let scene = Scene::new(camera, board, sky, sun, None, false);
    let boxes: Vec<(usize, usize, usize, usize)> =
        scene.views.iter().map(|v| v.pixel_bbox()).collect();
    let margin = 2 + (4.0 * sensor.blur_sigma).ceil() as usize;
    let near = |x: usize, y: usize| {
        boxes.iter().any(|b| {
            x + margin >= b.0 && x <= b.2 + margin && y + margin >= b.1 && y <= b.3 + margin
        })
    };
    let dense = |x: usize, y: usize| near(x, y) && !scene.smooth_diffuse_pixel(x, y);
    let mut img = gaussian_blur(
        &render_pixels(&scene, sensor.ss.max(1), &dense),
        sensor.blur_sigma,
    );
    if let Some(s) = sun {
        for i in 0..scene.views.len() {
            if scene.views[i].kind != SphereKind::Diffuse {
                add_sun_spot(&mut img, &scene, i, s, sensor.blur_sigma);
            }
        }
    }
    img
}

/// Add the sun's reflection in sphere `vi` to `img` (see [`render_board_sensor`]).
fn add_sun_spot(img: &mut HdrImage, scene: &Scene, vi: usize, sun: SynthSun, sigma: f64) {
    let view = &scene.views[vi];
    let Some(centre) = view.reflection_point(sun.direction) else {
        return;
    };
    let alpha = (sun.diameter_deg * 0.5).to_radians();
    let (e1, e2) = sun.direction.any_orthonormal_pair();
    let extent = (0..32)
        .filter_map(|k| {
            let t = k as f64 * std::f64::consts::TAU / 32.0;
            let w = alpha.cos() * sun.direction + alpha.sin() * (t.cos() * e1 + t.sin() * e2);
            view.reflection_point(w)
        })
        .map(|q| q.pixel.distance(centre.pixel))
        .fold(0.0, f64::max);
    let half = 1.25 * extent + 1e-3;
    let step = 2.0 * half / SUN_GRID as f64;
    let reach = 0.5 + if sigma > 0.0 { 5.0 * sigma } else { 0.0 };
    let (x0, y0) = (
        (centre.pixel.x - half - reach).floor().max(0.0) as usize,
        (centre.pixel.y - half - reach).floor().max(0.0) as usize,
    );
    let x1 = ((centre.pixel.x + half + reach).ceil() as usize).min(img.width - 1);
    let y1 = ((centre.pixel.y + half + reach).ceil() as usize).min(img.height - 1);
    let cos_a = alpha.cos();
    for j in 0..SUN_GRID {
        for i in 0..SUN_GRID {
            let u = centre.pixel.x - half + (i as f64 + 0.5) * step;
            let v = centre.pixel.y - half + (j as f64 + 0.5) * step;
            let (o, d) = scene.camera.pixel_ray(u, v);
            let Some((hit, p)) = scene.nearest_sphere(o, d) else {
                continue;
            };
            if hit != vi {
                continue;
            }
            let n = (p - view.center) / view.radius;
            if d.reflect(n).dot(sun.direction) < cos_a {
                continue;
            }
            let r = scene.reflectance(view.kind, n.dot(-d).max(0.0));
            let wx: Vec<f64> = (x0..=x1)
                .map(|x| pixel_response(x as f64 - u, sigma))
                .collect();
            for y in y0..=y1 {
                let wy = pixel_response(y as f64 - v, sigma) * step * step;
                if wy == 0.0 {
                    continue;
                }
                for (x, w) in (x0..=x1).zip(&wx) {
                    let k = y * img.width + x;
                    for c in 0..3 {
                        img.pixels[k][c] += (w * wy * r[c] * sun.radiance[c] as f64) as f32;
                    }
                }
            }
        }
    }
}

/// Incidence cosine above which a diffuse-sphere pixel takes one sample
/// ([`Scene::smooth_diffuse_pixel`]).
const SMOOTH_DIFFUSE_COS: f64 = 0.5;

/// What the synthetic camera sees: the spheres, the optional panel, the sky and sun.
struct Scene<'a> {
    camera: &'a Camera,
    board: &'a Board,
    views: Vec<SphereView<'a>>,
    sky: &'a HdrImage,
    integ: Option<Integrator>,
    /// The diffuse sphere's pixel box `(x0, y0, x1, y1)`, if the board has one.
    diffuse_box: Option<(usize, usize, usize, usize)>,
    sun: Option<SynthSun>,
    panel: Option<&'a SynthPanel>,
    /// Whether the sun disk is seen in the mirror and black spheres' reflections (else only
    /// in the background and in the diffuse sphere's irradiance).
    sun_in_reflections: bool,
}

impl<'a> Scene<'a> {
    fn new(
        camera: &'a Camera,
        board: &'a Board,
        sky: &'a HdrImage,
        sun: Option<SynthSun>,
        panel: Option<&'a SynthPanel>,
        sun_in_reflections: bool,
    ) -> Self {
        let views: Vec<SphereView> =
            std::iter::once(SphereView::new(camera, SphereKind::Mirror, &board.mirror))
                .chain(
                    board
                        .black
                        .iter()
                        .map(|b| SphereView::new(camera, SphereKind::Black, b)),
                )
                .chain(
                    board
                        .diffuse
                        .iter()
                        .map(|b| SphereView::new(camera, SphereKind::Diffuse, b)),
                )
                .collect();
        let integ = board.diffuse.as_ref().map(|_| Integrator::new(sky));
        let diffuse_box = views
            .iter()
            .find(|v| v.kind == SphereKind::Diffuse)
            .map(|v| v.pixel_bbox());
        Scene {
            camera,
            board,
            views,
            sky,
            integ,
            diffuse_box,
            sun,
            panel,
            sun_in_reflections,
        }
    }

    /// Sky radiance in direction `d`, with the sun disk when `with_sun`.
    fn env(&self, d: DVec3, with_sun: bool) -> [f64; 3] {
        let mut v = latlong_lookup(self.sky, d.as_vec3())
            .unwrap_or([0.0; 3])
            .map(|c| c as f64);
        if let (Some(s), true) = (self.sun, with_sun) {
            if d.dot(s.direction) >= (s.diameter_deg * 0.5).to_radians().cos() {
                for k in 0..3 {
                    v[k] += s.radiance[k] as f64;
                }
            }
        }
        v
    }

    /// Whether pixel (x, y) lies inside the diffuse sphere's image, away from its rim and off
    /// the sun's terminator: the rays through its four corners all meet the diffuse sphere
    /// first at incidence cosine >= [`SMOOTH_DIFFUSE_COS`], at normals all facing the sun or
    /// all facing away. There the shading is so smooth over the pixel that its centre sample
    /// is its mean (the box rule's error, `pixel^2 / 24` times the curvature of the shading,
    /// for a normal that turns at most `2 / r` radians a pixel on a sphere of `r` pixels: about
    /// 1e-5 relative, 1e-4 beside the terminator; test
    /// `one_sample_inside_the_diffuse_sphere_is_its_pixels_mean`) and sub-samples, each a sum
    /// over every sky texel, would cost without changing it.
    fn smooth_diffuse_pixel(&self, x: usize, y: usize) -> bool {
        let inside = |(x0, y0, x1, y1)| (x0..=x1).contains(&x) && (y0..=y1).contains(&y);
        if !self.diffuse_box.is_some_and(inside) {
            return false;
        }
        let corners = [(-0.5, -0.5), (0.5, -0.5), (-0.5, 0.5), (0.5, 0.5)].map(|(dx, dy)| {
            let (o, d) = self.camera.pixel_ray(x as f64 + dx, y as f64 + dy);
            self.nearest_sphere(o, d).and_then(|(i, p)| {
                let view = &self.views[i];
                let n = (p - view.center) / view.radius;
                (view.kind == SphereKind::Diffuse && n.dot(-d) >= SMOOTH_DIFFUSE_COS).then_some(n)
            })
        });
        if !corners.iter().all(Option::is_some) {
            return false;
        }
        self.sun.is_none_or(|s| {
            let lit = corners
                .iter()
                .flatten()
                .filter(|n| n.dot(s.direction) > 0.0);
            matches!(lit.count(), 0 | 4)
        })
    }

    /// Index of the nearest sphere the ray hits, and the hit point.
    fn nearest_sphere(&self, o: DVec3, d: DVec3) -> Option<(usize, DVec3)> {
        let mut best: Option<(f64, usize, DVec3)> = None;
        for (i, view) in self.views.iter().enumerate() {
            if let Some(p) = view.intersect(o, d) {
                let t = (p - o).length();
                if best.is_none_or(|b| t < b.0) {
                    best = Some((t, i, p));
                }
            }
        }
        best.map(|b| (b.1, b.2))
    }

    /// Fresnel reflectance of the mirror or black sphere at incidence cosine `cos_i`.
    fn reflectance(&self, kind: SphereKind, cos_i: f64) -> [f64; 3] {
        if kind == SphereKind::Mirror {
            self.board.mirror_reflectance(cos_i)
        } else {
            self.board.black_reflectance(cos_i)
        }
    }

    /// Radiance along the camera ray `o + t d`.
    fn radiance(&self, o: DVec3, d: DVec3) -> [f64; 3] {
        let best = self.nearest_sphere(o, d);
        if let Some((t, v)) = self.panel.and_then(|p| p.hit(self.camera, o, d)) {
            if best.is_none_or(|b| t < (b.1 - o).length()) {
                return [v as f64; 3];
            }
        }
        let Some((i, p)) = best else {
            return self.env(d, true);
        };
        let view = &self.views[i];
        let n = (p - view.center) / view.radius;
        if view.kind == SphereKind::Diffuse {
            return self.diffuse(n);
        }
        let r = self.reflectance(view.kind, n.dot(-d).max(0.0));
        let w = d.reflect(n);
        // what the sphere reflects: the panel behind it where the reflected ray meets it (the
        // rims, at grazing incidence), else the sky
        let l = match self
            .panel
            .and_then(|pl| pl.hit(self.camera, p + 1e-9 * n, w))
        {
            Some((_, v)) => [v as f64; 3],
            None => self.env(w, self.sun_in_reflections),
        };
        [0, 1, 2].map(|c| r[c] * l[c])
    }

    /// The diffuse sphere at normal `n`: reflectance * irradiance (sky and sun disk) / pi.
    fn diffuse(&self, n: DVec3) -> [f64; 3] {
        let mut e = self
            .integ
            .as_ref()
            .map(|i| i.irradiance(n.as_vec3()))
            .unwrap_or([0.0; 3])
            .map(|v| v as f64);
        if let Some(s) = self.sun {
            let k = disk_cosine_solid_angle(s.diameter_deg) * n.dot(s.direction).max(0.0);
            for c in 0..3 {
                e[c] += k * s.radiance[c] as f64;
            }
        }
        let rho = self.board.diffuse_reflectance;
        [0, 1, 2].map(|c| rho[c] * e[c] / std::f64::consts::PI)
    }
}

/// Every pixel of the scene as the mean of `ss` x `ss` samples over its area where `dense(x,
/// y)`, else one sample at its centre.
fn render_pixels(
    scene: &Scene,
    ss: usize,
    dense: &(dyn Fn(usize, usize) -> bool + Sync),
) -> HdrImage {
    let (w, h) = (scene.camera.width as usize, scene.camera.height as usize);
    let rows: Vec<Vec<[f32; 3]>> = (0..h)
        .into_par_iter()
        .map(|y| {
            (0..w)
                .map(|x| {
                    let n = if dense(x, y) { ss } else { 1 };
                    let mut acc = [0.0f64; 3];
                    for sy in 0..n {
                        for sx in 0..n {
                            let u = x as f64 - 0.5 + (sx as f64 + 0.5) / n as f64;
                            let v = y as f64 - 0.5 + (sy as f64 + 0.5) / n as f64;
                            let (o, d) = scene.camera.pixel_ray(u, v);
                            let val = scene.radiance(o, d);
                            for c in 0..3 {
                                acc[c] += val[c];
                            }
                        }
                    }
                    acc.map(|v| (v / (n * n) as f64) as f32)
                })
                .collect()
        })
        .collect();
    let mut img = HdrImage::new(w, h);
    for (y, row) in rows.into_iter().enumerate() {
        for (x, p) in row.into_iter().enumerate() {
            img.set(x, y, p);
        }
    }
    img
}

/// Unit vector from elevation and azimuth in degrees (azimuth from +X toward +Y, Z up).
pub fn direction_from_angles(elevation_deg: f64, azimuth_deg: f64) -> DVec3 {
    let (e, a) = (elevation_deg.to_radians(), azimuth_deg.to_radians());
    DVec3::new(e.cos() * a.cos(), e.cos() * a.sin(), e.sin())
}

/// A lens's blur for [`render_board`] output: separable Gaussian of standard deviation `sigma`
/// pixels (truncated at 4 sigma, renormalised at the image border), like Mitsuba's default
/// reconstruction filter (sigma 0.5 px). Sub-pixel suns spread over a few pixels, so their
/// centroids carry sub-pixel information, as in a real photograph.
pub fn gaussian_blur(img: &HdrImage, sigma: f64) -> HdrImage {
    if sigma <= 0.0 {
        return img.clone();
    }
    let r = (4.0 * sigma).ceil() as i64;
    let k: Vec<f64> = (-r..=r)
        .map(|d| (-(d * d) as f64 / (2.0 * sigma * sigma)).exp())
        .collect();
    let (w, h) = (img.width as i64, img.height as i64);
    let pass = |src: &HdrImage, dx: i64, dy: i64| -> HdrImage {
        let rows: Vec<Vec<[f32; 3]>> = (0..h)
            .into_par_iter()
            .map(|y| {
                (0..w)
                    .map(|x| {
                        let (mut acc, mut ws) = ([0.0f64; 3], 0.0);
                        for (i, kv) in k.iter().enumerate() {
                            let o = i as i64 - r;
                            let (sx, sy) = (x + o * dx, y + o * dy);
                            if sx < 0 || sy < 0 || sx >= w || sy >= h {
                                continue;
                            }
                            let p = src.get(sx as usize, sy as usize);
                            for c in 0..3 {
                                acc[c] += kv * p[c] as f64;
                            }
                            ws += kv;
                        }
                        acc.map(|v| (v / ws) as f32)
                    })
                    .collect()
            })
            .collect();
        let mut out = HdrImage::new(w as usize, h as usize);
        for (y, row) in rows.into_iter().enumerate() {
            for (x, p) in row.into_iter().enumerate() {
                out.set(x, y, p);
            }
        }
        out
    };
    pass(&pass(img, 1, 0), 0, 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The board fixture's camera and board, and a graded sky with a blue cast (128 x 64).
    fn setting() -> (Camera, Board, HdrImage) {
        let d = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../datasets/fixtures/board/sunny");
        let sky = igi_imaging::latlong::map_from_fn(128, 64, |d| {
            let up = d.z.max(0.0);
            [0.5 + 0.4 * up + 0.3 * d.x, 0.6 + 0.3 * up, 0.9 - 0.5 * up]
        });
        (
            Camera::load(&d.join("camera.json")).unwrap(),
            Board::load(&d.join("board.json")).unwrap(),
            sky,
        )
    }

    /// The diffuse sphere's interior pixels take one sample instead of `ss^2`: against dense
    /// sampling everywhere, under a sky and a low sun, they differ by 1.3e-5 relative on
    /// average and 1.3e-4 at most (beside the terminator, where the shading is small), and
    /// every other pixel is the same bytes.
    #[test]
    fn one_sample_inside_the_diffuse_sphere_is_its_pixels_mean() {
        let (cam, board, sky) = setting();
        let sun = SynthSun {
            direction: direction_from_angles(20.0, 120.0),
            radiance: [3.0e4, 2.5e4, 2.0e4],
            diameter_deg: 0.53,
        };
        let fast = render_board(&cam, &board, &sky, Some(sun), 4);
        let scene = Scene::new(&cam, &board, &sky, Some(sun), None, true);
        let dense = render_pixels(&scene, 4, &|_, _| true);
        let (mut smooth, mut worst, mut sum) = (0, 0.0f64, 0.0f64);
        for y in 0..fast.height {
            for x in 0..fast.width {
                let (a, b) = (fast.get(x, y), dense.get(x, y));
                if scene.smooth_diffuse_pixel(x, y) {
                    smooth += 1;
                    for c in 0..3 {
                        let e = ((a[c] - b[c]) / b[c]).abs() as f64;
                        worst = worst.max(e);
                        sum += e / 3.0;
                    }
                } else {
                    assert_eq!(a, b, "pixel ({x}, {y}) outside the diffuse interior");
                }
            }
        }
        let diffuse = scene.views.iter().find(|v| v.kind == SphereKind::Diffuse);
        let r = diffuse.unwrap().check_in_image().unwrap();
        assert!(
            smooth as f64 > 0.5 * std::f64::consts::PI * r * r,
            "{smooth} smooth pixels on a sphere of radius {r:.1} px"
        );
        let mean = sum / smooth as f64;
        assert!(
            worst < 2e-4 && mean < 2e-5,
            "largest relative difference {worst:.2e}, mean {mean:.2e}"
        );
    }
}
