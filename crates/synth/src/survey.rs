//! Synthetic surveys with known albedo: the embedded default (`igi demo`) and the solver's
//! tests. A site's parts get a known per-texel albedo (a function of world position, e.g.
//! [`albedo_pattern`] through [`igi_reflect::truth::truth_atlas`]), photos are path-traced from
//! it under given lightings, and everything is written as a FORMATS.md survey folder plus a
//! `truth/scene.toml` holding the true albedo.

use crate::SynthError;
use glam::Vec3;
use igi_camera::Camera;
use igi_formats::lighting::{EnvironmentSection, LightingFile, SunSection};
use igi_formats::scene::{AlbedoEntry, ObjectEntry, SceneFile};
use igi_formats::survey::{PhotoEntry, SiteSection, SurveyFile};
use igi_formats::{f32_decimals, TomlFile};
use igi_geometry::TriMesh;
use igi_imaging::color::SUN_ANGULAR_DIAMETER_DEG;
use igi_imaging::HdrImage;
use igi_reflect::truth::scene_with_albedo;
use igi_reflect::Part;
use igi_render::{render_images, Environment, Lighting, RenderJob, RenderOptions, Scene, Sun};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// A smooth, colourful albedo pattern with per-texel detail, in [0.08, 0.85] per channel.
pub fn albedo_pattern(p: Vec3) -> Vec3 {
    let s = |f: f32, ph: f32| 0.5 + 0.5 * (f + ph).sin();
    let base = Vec3::new(
        0.25 + 0.45 * s(0.9 * p.x + 0.4 * p.z, 0.3),
        0.22 + 0.40 * s(0.7 * p.y - 0.5 * p.z, 1.1),
        0.15 + 0.35 * s(0.5 * (p.x + p.y) + 0.8 * p.z, 2.0),
    );
    // fine stripes (texel-scale variation)
    let stripe =
        if ((p.x * 4.0).floor() as i64 + (p.y * 4.0).floor() as i64 + (p.z * 4.0).floor() as i64)
            % 2
            == 0
        {
            1.0
        } else {
            0.8
        };
    (base * stripe).clamp(Vec3::splat(0.08), Vec3::splat(0.85))
}

/// A lighting condition: a lat-long sky and an optional sun (direction, radiance).
pub struct LightingSpec {
    pub name: String,
    pub sky: HdrImage,
    pub sun: Option<(Vec3, Vec3)>,
}

impl LightingSpec {
    /// The in-memory lighting.
    pub fn lighting(&self) -> Result<Lighting, SynthError> {
        let environment = Some(Environment::from_image(&self.sky, 1.0)?);
        let sun = match self.sun {
            Some((d, l)) => Some(Sun::new(d, l, SUN_ANGULAR_DIAMETER_DEG as f32)?),
            None => None,
        };
        Ok(Lighting { environment, sun })
    }

    /// Writes `NAME.toml` and `NAME_sky.exr` into `dir` (FORMATS.md lighting file).
    pub fn write(&self, dir: &Path) -> Result<PathBuf, SynthError> {
        igi_imaging::write_exr(&dir.join(format!("{}_sky.exr", self.name)), &self.sky)?;
        let file = LightingFile {
            environment: Some(EnvironmentSection {
                map: format!("{}_sky.exr", self.name).into(),
                scale: 1.0,
            }),
            sun: self.sun.map(|(d, l)| SunSection {
                direction: f32_decimals(d.normalize().to_array()),
                radiance: f32_decimals(l.to_array()),
                angular_diameter_deg: SUN_ANGULAR_DIAMETER_DEG,
            }),
        };
        let p = dir.join(format!("{}.toml", self.name));
        file.write(&p, &[])?;
        Ok(p)
    }
}

/// A small test site: an 8 m square ground (a 4 x 4 quad grid at z = 0, facing up) and a
/// 1.2 x 1.2 x 2 m block standing on it at the origin, named `ground` and `block`.
pub fn ground_and_block() -> Vec<(String, TriMesh)> {
    let (size, n) = (8.0f32, 4usize);
    let mut ground = TriMesh {
        positions: vec![],
        normals: Some(vec![]),
        uvs: None,
        colors: None,
        indices: vec![],
    };
    for j in 0..=n {
        for i in 0..=n {
            let f = |k: usize| -size / 2.0 + size * k as f32 / n as f32;
            ground.positions.push([f(i), f(j), 0.0]);
        }
    }
    ground.normals = Some(vec![[0.0, 0.0, 1.0]; ground.positions.len()]);
    for j in 0..n {
        for i in 0..n {
            let a = (j * (n + 1) + i) as u32;
            let (b, c, d) = (a + 1, a + (n + 1) as u32, a + (n + 2) as u32);
            ground.indices.extend([[a, b, d], [a, d, c]]);
        }
    }
    let (c, h) = (Vec3::new(0.0, 0.0, 1.0), Vec3::new(0.6, 0.6, 1.0));
    let mut block = TriMesh {
        positions: vec![],
        normals: Some(vec![]),
        uvs: None,
        colors: None,
        indices: vec![],
    };
    for (nrm, u, v) in [
        (Vec3::X, Vec3::Y, Vec3::Z),
        (-Vec3::X, Vec3::Z, Vec3::Y),
        (Vec3::Y, Vec3::Z, Vec3::X),
        (-Vec3::Y, Vec3::X, Vec3::Z),
        (Vec3::Z, Vec3::X, Vec3::Y),
        (-Vec3::Z, Vec3::Y, Vec3::X),
    ] {
        let base = block.positions.len() as u32;
        for (su, sv) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
            block
                .positions
                .push((c + (nrm + u * su + v * sv) * h).to_array());
            block
                .normals
                .as_mut()
                .expect("normals")
                .push(nrm.to_array());
        }
        block
            .indices
            .extend([[base, base + 1, base + 2], [base, base + 2, base + 3]]);
    }
    vec![("ground".to_string(), ground), ("block".to_string(), block)]
}

/// One photograph of a synthetic survey.
pub struct ShotSpec {
    pub id: String,
    pub camera: Camera,
    /// Index into the lighting list.
    pub lighting: usize,
}

/// Writes a complete survey folder: `geometry/NAME.ply` per part (the atlas meshes; for the parts
/// of a prepared site the survey names the site instead), `truth/` (true albedo atlases and
/// `scene.toml`), `lighting/`, `cameras/`, `photos/` (path-traced with `render`, photograph `i`
/// with its seed plus `7919 i`; stratified and adaptive sampling take noise out,
/// docs/RENDER.md; adaptive photographs share one budget, `render.spp` a pixel on average over
/// all of them, so the noisier ones take more) and `survey.toml`. Photos are rendered under
/// `lightings`; the survey's lighting files are `recorded` (for example what probe captures
/// recovered of the same skies, as in a real survey; pass `lightings` again to record the
/// truth). `progress(i, n)` is called as photo `i` of `n` is finished.
#[allow(clippy::too_many_arguments)]
pub fn write_survey(
    dir: &Path,
    parts: &[Part],
    truth: &[Vec<Vec3>],
    lightings: &[LightingSpec],
    recorded: &[LightingSpec],
    shots: &[ShotSpec],
    render: &RenderOptions,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<(), SynthError> {
    for sub in ["geometry", "truth", "lighting", "cameras", "photos"] {
        let p = dir.join(sub);
        std::fs::create_dir_all(&p).map_err(|e| SynthError::File {
            path: p.clone(),
            msg: format!("cannot create folder: {e}"),
        })?;
    }
    let prepared = parts
        .iter()
        .find_map(|p| p.stored.as_ref().map(|s| s.site.clone()));
    let mut survey = SurveyFile {
        site: match &prepared {
            Some(site) => SiteSection {
                // relative when they share more than the root: they move together
                prepared: Some(igi_files::named_from(site, dir).unwrap_or(site.clone())),
                ..SiteSection::default()
            },
            None => SiteSection::default(),
        },
        brdf: None,
        radiometry: None,
        photo: Vec::new(),
        reference: Vec::new(),
    };
    let meshes = write_truth(dir, parts, truth)?;
    if prepared.is_none() {
        survey.site.meshes = meshes;
    }
    let scene = scene_with_albedo(parts, truth)?;
    let shoot = Shoot {
        dir,
        scene: &scene,
        lit: write_lightings(dir, lightings, recorded)?,
        recorded,
        render,
    };
    for (s, image) in shots.iter().zip(shoot.render(shots, progress)?) {
        survey.photo.push(shoot.photo(s, &image)?);
    }
    survey.write(&dir.join("survey.toml"), &[])?;
    Ok(())
}

/// Writes every part's mesh to `geometry/`, its true albedo atlas to `truth/` and the truth
/// scene `truth/scene.toml`; returns the mesh paths relative to `dir`.
fn write_truth(
    dir: &Path,
    parts: &[Part],
    truth: &[Vec<Vec3>],
) -> Result<Vec<PathBuf>, SynthError> {
    let mut truth_scene = SceneFile::default();
    let mut meshes = Vec::new();
    for (p, a) in parts.iter().zip(truth) {
        igi_geometry::write_ply(
            &dir.join("geometry").join(format!("{}.ply", p.name)),
            &*p.full_mesh()?,
        )?;
        let r = p.resolution();
        let mut img = HdrImage::new(r, r);
        for (px, v) in img.pixels.iter_mut().zip(a) {
            *px = v.to_array();
        }
        igi_imaging::write_exr(
            &dir.join("truth").join(format!("{}_albedo.exr", p.name)),
            &img,
        )?;
        truth_scene.object.push(ObjectEntry {
            mesh: format!("../geometry/{}.ply", p.name).into(),
            albedo: AlbedoEntry::Texture(format!("{}_albedo.exr", p.name).into()),
            lobes: Vec::new(),
            lobe_maps: Vec::new(),
        });
        meshes.push(format!("geometry/{}.ply", p.name).into());
    }
    truth_scene.write(
        &dir.join("truth").join("scene.toml"),
        &["true albedo of the synthetic site (igi solve --truth)"],
    )?;
    Ok(meshes)
}

/// Writes the `recorded` lighting files into `lighting/`; returns the in-memory `lightings` the
/// photos are rendered under (one recorded file per lighting).
fn write_lightings(
    dir: &Path,
    lightings: &[LightingSpec],
    recorded: &[LightingSpec],
) -> Result<Vec<Lighting>, SynthError> {
    if recorded.len() != lightings.len() {
        return Err(SynthError::LightingCount {
            lightings: lightings.len(),
            recorded: recorded.len(),
        });
    }
    let mut lit = Vec::new();
    for (l, r) in lightings.iter().zip(recorded) {
        r.write(&dir.join("lighting"))?;
        lit.push(l.lighting()?);
    }
    Ok(lit)
}

/// What every photograph of [`write_survey`] is rendered and written with.
struct Shoot<'a> {
    dir: &'a Path,
    scene: &'a Scene,
    /// The true lightings, rendered under.
    lit: Vec<Lighting>,
    /// The lightings the survey records.
    recorded: &'a [LightingSpec],
    /// Photograph `i` is rendered with these options, its seed plus `7919 i`.
    render: &'a RenderOptions,
}

impl Shoot<'_> {
    /// Every shot's photograph (one budget of samples for all, [`render_images`]);
    /// `progress(i, n)` as photo `i` of `n` is finished.
    fn render(
        &self,
        shots: &[ShotSpec],
        progress: &(dyn Fn(usize, usize) + Sync),
    ) -> Result<Vec<HdrImage>, SynthError> {
        let mut jobs = Vec::with_capacity(shots.len());
        for (i, s) in shots.iter().enumerate() {
            // rendered under the true lighting; the survey records `recorded[s.lighting]`
            let known = self.recorded.get(s.lighting).and(self.lit.get(s.lighting));
            let lighting = known.ok_or_else(|| SynthError::NoLighting {
                shot: s.id.clone(),
                lighting: s.lighting,
            })?;
            jobs.push(RenderJob {
                camera: &s.camera,
                lighting,
                seed: self.render.seed.wrapping_add(i as u64 * 7919),
            });
        }
        let rows_left: Vec<AtomicU64> = shots
            .iter()
            .map(|s| AtomicU64::new(u64::from(s.camera.height)))
            .collect();
        let row_done = |i: usize, n: u64| {
            if rows_left[i].fetch_sub(n, Ordering::Relaxed) == n {
                progress(i, shots.len());
            }
        };
        let out = render_images(self.scene, &jobs, self.render, &row_done)?;
        Ok(out.into_iter().map(|o| o.mean).collect())
    }

    /// Writes shot `s`'s photograph `image` into `photos/`, saves its camera into `cameras/`;
    /// returns its survey entry.
    fn photo(&self, s: &ShotSpec, image: &HdrImage) -> Result<PhotoEntry, SynthError> {
        let l = &self.recorded[s.lighting];
        let dir = self.dir;
        igi_imaging::write_exr(&dir.join("photos").join(format!("{}.exr", s.id)), image)?;
        s.camera
            .save(&dir.join("cameras").join(format!("{}.json", s.id)))?;
        Ok(PhotoEntry {
            id: s.id.clone(),
            image: format!("photos/{}.exr", s.id).into(),
            camera: format!("cameras/{}.json", s.id).into(),
            lighting: Some(format!("lighting/{}.toml", l.name).into()),
            radiometry: None,
            probe: None,
            time: None,
            exposure: None,
            ..PhotoEntry::default()
        })
    }
}
