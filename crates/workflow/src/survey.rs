//! The survey folder of FORMATS.md: `survey.toml` naming the site meshes, the photographs with
//! their cameras and lighting files, and optional hand-held BRDF samples. The file is parsed by
//! `igi_formats::survey`; this module resolves and checks what it names.

use crate::WorkflowError;
use igi_camera::Camera;
use igi_formats::{SurveyFile, TomlFile};
use igi_imaging::HdrImage;
use igi_reflect::{Photo, Progress};
use igi_render::Lighting;
use std::path::{Path, PathBuf};

/// How many times brighter than its lighting's plausible brightest a photograph's median may
/// be before igi warns (the bound is already generous: 4 times a uniform sky's white surface).
pub const TOO_BRIGHT: f32 = 10.0;

/// Where a photograph's lighting comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum LightingSource {
    /// A FORMATS.md lighting file.
    File(PathBuf),
    /// A capture of the lighting board to process first (as `igi probe` does): the board
    /// photograph (linear HDR), its camera and the board file.
    Probe {
        image: PathBuf,
        camera: PathBuf,
        board: PathBuf,
    },
    /// No lighting file: the sun of the photo's time at the site and a sky estimated with the
    /// albedo (`crate::lightfit`), starting from the Hosek-Wilkie sky of turbidity
    /// `lightfit::DEFAULT_TURBIDITY`.
    Estimated(crate::lightfit::SkyPhoto),
}

/// One photograph as listed in `survey.toml` (paths resolved against the survey folder).
#[derive(Clone, Debug)]
pub struct PhotoSpec {
    pub id: String,
    pub image: PathBuf,
    pub camera: PathBuf,
    pub lighting: LightingSource,
    /// The camera radiometry file (`igi camera radiometry`) applied to the image on load: the
    /// photo's own `radiometry = ...`, else the survey's `[radiometry] camera = ...`, else none.
    pub radiometry: Option<PathBuf>,
    /// When the photo was taken (`time = ...`, checked to carry its UTC offset).
    pub time: Option<igi_formats::PhotoTime>,
    /// The photo's exposure on the survey's radiometric scale (`exposure = ...`, 1 if absent):
    /// its pixels are divided by it on load.
    pub exposure: f64,
    /// The camera body that took it (`body = ...`; `None`: the survey's unnamed body).
    pub body: Option<String>,
    /// How its stored values become linear (`response = ...`, `transfer = ...`, or the
    /// survey's `[radiometry] response = ...`).
    pub transfer: TransferSpec,
}

/// How a photograph's stored values become linear (docs/IMAGING.md, "Linearising
/// photographs"); response files are checked when the photo is loaded.
#[derive(Clone, Debug, PartialEq)]
pub enum TransferSpec {
    /// The file's own rule (8-bit sRGB, 16-bit and float linear); with the survey's
    /// `[radiometry] response`, 8-bit files through that response instead.
    Default { survey_response: Option<PathBuf> },
    /// `transfer = "srgb"`.
    Srgb,
    /// `transfer = "linear"`.
    Linear,
    /// The photo's own `response = ...` (8-bit files only).
    Response(PathBuf),
}

/// A parsed survey: everything is checked to exist, nothing heavy is loaded yet.
#[derive(Clone, Debug)]
pub struct Survey {
    /// The folder holding `survey.toml`.
    pub root: PathBuf,
    /// The survey file itself.
    pub file: PathBuf,
    pub meshes: Vec<PathBuf>,
    /// A prepared site (`igi prepare` output) in place of meshes: `[site] prepared = "site.igi"`,
    /// or a `mesh` that names such a folder.
    pub prepared: Option<PathBuf>,
    pub photos: Vec<PhotoSpec>,
    pub brdf_samples: Option<PathBuf>,
    /// The site's `[site]` location and north (FORMATS.md, "Site location and photo time"),
    /// checked: latitude and longitude in range, north horizontal.
    pub site: igi_formats::survey::SiteSection,
    /// Surfaces of known diffuse albedo (`[[reference]]`), checked.
    pub references: Vec<igi_formats::survey::ReferenceTarget>,
}

impl Survey {
    /// The BRDF basis fitted to the survey's samples (one Lafortune fit per material), or
    /// `None` without samples.
    pub fn basis(&self) -> Result<Option<igi_brdf::Basis>, WorkflowError> {
        let Some(p) = &self.brdf_samples else {
            return Ok(None);
        };
        let samples = igi_brdf::read_samples(p)?;
        let fits = igi_brdf::fit_materials(&samples, &igi_brdf::FitOptions::default(), &|| {})
            .map_err(|source| WorkflowError::BrdfFile {
                path: p.clone(),
                source,
            })?;
        let mats = fits
            .into_iter()
            .map(|(_, r)| (r.material, r.brdf))
            .collect();
        Ok(Some(igi_brdf::Basis::new(mats)?))
    }

    /// Per photo (the survey's order): the sun and site of a photo whose light is estimated.
    pub fn estimated_photos(&self) -> Vec<Option<crate::lightfit::SkyPhoto>> {
        self.photos
            .iter()
            .map(|p| match &p.lighting {
                LightingSource::Estimated(s) => Some(s.clone()),
                _ => None,
            })
            .collect()
    }

    /// Every photograph loaded (image, camera with radiometry applied, lighting), in the
    /// survey's order; `progress` advances by one per photograph.
    pub fn load_photos(&self, progress: &dyn Progress) -> Result<Vec<Photo>, WorkflowError> {
        progress.begin("photos", self.photos.len() as u64);
        let photos = self
            .photos
            .iter()
            .map(|p| {
                let photo = p.load();
                progress.advance(1);
                photo
            })
            .collect();
        progress.finish();
        photos
    }

    /// Reads `survey.toml` from a survey folder (or the file itself). Every path it names must
    /// exist; photo ids must be unique.
    pub fn load(path: &Path) -> Result<Survey, WorkflowError> {
        let file = if path.is_dir() {
            path.join("survey.toml")
        } else {
            path.to_path_buf()
        };
        let f = SurveyFile::read(&file)?;
        f.check_site_and_references(&file)?;
        let root = file.parent().unwrap_or(Path::new(".")).to_path_buf();
        let paths = SurveyPaths {
            root: &root,
            file: &file,
            site: &f.site,
        };
        let (meshes, prepared) = paths.site(&f.site)?;
        if f.photo.is_empty() {
            return Err(WorkflowError::file(&file, "no [[photo]] entries"));
        }
        let default_radiometry = match f.radiometry.as_ref().and_then(|r| r.camera.as_ref()) {
            Some(c) => Some(radiometry_file(
                paths.existing(c, "camera radiometry file")?,
            )?),
            None => None,
        };
        let survey_response = match f.radiometry.as_ref().and_then(|r| r.response.as_ref()) {
            Some(r) => {
                let r = paths.existing(r, "[radiometry] response file")?;
                // checked before any work; read again when the photos are loaded
                igi_imaging::photo::read_response_csv(&r)?;
                Some(r)
            }
            None => None,
        };
        let mut photos = Vec::new();
        for p in &f.photo {
            if photos.iter().any(|q: &PhotoSpec| q.id == p.id) {
                return Err(WorkflowError::file(
                    &file,
                    format!("photo id `{}` appears twice", p.id),
                ));
            }
            photos.push(paths.photo(p, &default_radiometry, &survey_response)?);
            check_radiometry_size(photos.last().expect("just pushed"))?;
        }
        check_references_seen(&file, &f.reference, &photos)?;
        let brdf_samples = match &f.brdf {
            Some(b) => Some(paths.existing(&b.samples, "BRDF samples")?),
            None => None,
        };
        Ok(Survey {
            root,
            file,
            meshes,
            prepared,
            photos,
            brdf_samples,
            site: f.site.clone(),
            references: f.reference.clone(),
        })
    }
}

/// Resolves the paths a survey file names against its folder, each checked to exist.
struct SurveyPaths<'a> {
    /// The folder holding the survey file.
    root: &'a Path,
    /// The survey file (named in errors).
    file: &'a Path,
    /// `[site]`: its location lights the photos without lighting files.
    site: &'a igi_formats::survey::SiteSection,
}

impl SurveyPaths<'_> {
    /// `p` resolved against the survey folder; an error naming `what` when it does not exist.
    fn existing(&self, p: &Path, what: &str) -> Result<PathBuf, WorkflowError> {
        let full = self.root.join(p);
        if full.exists() {
            Ok(full)
        } else {
            Err(WorkflowError::file(
                self.file,
                format!("{what} {} does not exist", full.display()),
            ))
        }
    }

    /// The `[site]` section: its meshes, or a prepared site (named as `prepared` or as a `mesh`
    /// folder with a `manifest.json`), never both, never neither.
    fn site(
        &self,
        site: &igi_formats::survey::SiteSection,
    ) -> Result<(Vec<PathBuf>, Option<PathBuf>), WorkflowError> {
        let mut meshes = Vec::new();
        let mut prepared = match &site.prepared {
            Some(p) => Some(self.existing(p, "prepared site")?),
            None => None,
        };
        for m in site.mesh.iter().chain(site.meshes.iter()) {
            let full = self.existing(m, "site mesh")?;
            if full.is_dir() && full.join("manifest.json").is_file() {
                prepared = Some(full);
            } else {
                meshes.push(full);
            }
        }
        if let Some(p) = &prepared {
            if !meshes.is_empty() {
                return Err(WorkflowError::file(
                    self.file,
                    "[site] names both a prepared site and meshes; give one or the other",
                ));
            }
            if !p.join("manifest.json").is_file() {
                return Err(WorkflowError::file(
                    self.file,
                    format!(
                        "{} is not a prepared site (no manifest.json; run `igi prepare`)",
                        p.display()
                    ),
                ));
            }
        } else if meshes.is_empty() {
            return Err(WorkflowError::file(
                self.file,
                "[site] names no mesh (use `mesh = ...`, `meshes = [...]` or `prepared = ...`)",
            ));
        }
        Ok((meshes, prepared))
    }

    /// One `[[photo]]` entry with its paths resolved; its radiometry file is its own or else
    /// `default_radiometry`.
    fn photo(
        &self,
        p: &igi_formats::survey::PhotoEntry,
        default_radiometry: &Option<PathBuf>,
        survey_response: &Option<PathBuf>,
    ) -> Result<PhotoSpec, WorkflowError> {
        use igi_formats::survey::PhotoTransfer;
        let transfer = match (&p.response, p.transfer) {
            (Some(_), Some(t)) => {
                return Err(WorkflowError::file(
                    self.file,
                    format!(
                        "photo `{}` has both `response` and `transfer = {t:?}`: give one (a response already says how its codes become linear)",
                        p.id
                    ),
                ))
            }
            (Some(r), None) => {
                let r = self.existing(r, &format!("photo `{}` response file", p.id))?;
                igi_imaging::photo::read_response_csv(&r)?;
                TransferSpec::Response(r)
            }
            (None, Some(PhotoTransfer::Srgb)) => TransferSpec::Srgb,
            (None, Some(PhotoTransfer::Linear)) => TransferSpec::Linear,
            (None, None) => TransferSpec::Default {
                survey_response: survey_response.clone(),
            },
        };
        let lighting = self.lighting(p)?;
        // checked with the survey file; an estimated photo's may come from its EXIF
        let time = match (p.photo_time(), &lighting) {
            (Some(t), _) => t.ok(),
            (None, LightingSource::Estimated(sky)) => Some(sky.time),
            (None, _) => None,
        };
        Ok(PhotoSpec {
            id: p.id.clone(),
            image: self.existing(&p.image, &format!("photo `{}` image", p.id))?,
            camera: self.existing(&p.camera, &format!("photo `{}` camera", p.id))?,
            lighting,
            radiometry: match &p.radiometry {
                Some(r) => Some(radiometry_file(
                    self.existing(r, &format!("photo `{}` radiometry file", p.id))?,
                )?),
                None => default_radiometry.clone(),
            },
            time,
            exposure: p.exposure.unwrap_or(1.0),
            body: p.body.clone(),
            transfer,
        })
    }

    /// A photo's lighting: exactly one of a lighting file and a `[photo.probe]` capture.
    fn lighting(
        &self,
        p: &igi_formats::survey::PhotoEntry,
    ) -> Result<LightingSource, WorkflowError> {
        let id = &p.id;
        match (&p.lighting, &p.probe) {
            (Some(l), None) => Ok(LightingSource::File(
                self.existing(l, &format!("photo `{id}` lighting"))?,
            )),
            (None, Some(b)) => Ok(LightingSource::Probe {
                image: self.existing(&b.image, &format!("photo `{id}` probe image"))?,
                camera: self.existing(&b.camera, &format!("photo `{id}` probe camera"))?,
                board: self.existing(&b.board, &format!("photo `{id}` probe board"))?,
            }),
            (None, None) => self.estimated(p),
            _ => Err(WorkflowError::file(
                self.file,
                format!(
                    "photo `{id}` has both `lighting = ...` and a [photo.probe] capture: give one"
                ),
            )),
        }
    }
}

impl SurveyPaths<'_> {
    /// A photo without lighting file or probe: lit by the sun of its time at the site's
    /// location, with the sky estimated. Needs its `time` and `[site] latitude_deg` /
    /// `longitude_deg`, and the sun above the horizon then.
    fn estimated(
        &self,
        p: &igi_formats::survey::PhotoEntry,
    ) -> Result<LightingSource, WorkflowError> {
        let id = &p.id;
        let time = match p.photo_time() {
            Some(t) => t.ok(),
            None => self.exif_time(p)?,
        };
        let Some(time) = time else {
            return Err(WorkflowError::file(
                self.file,
                format!(
                    "photo `{id}` has no `lighting`, no [photo.probe] and no `time`, and its image carries no EXIF time (DateTimeOriginal with OffsetTimeOriginal, or the GPS date and time): give it a lighting file, a probe capture, or the time it was taken (RFC 3339 with its UTC offset) so that its light can be estimated"
                ),
            ));
        };
        let Some((latitude_deg, longitude_deg)) = self.site.location() else {
            return Err(WorkflowError::file(
                self.file,
                format!(
                    "photo `{id}` has no `lighting`, so its light is estimated from its time and the site's location, but [site] has no `latitude_deg` and `longitude_deg`"
                ),
            ));
        };
        let site = crate::lightfit::SiteLocation {
            latitude_deg,
            longitude_deg,
            north: self.site.north_or_default(),
        };
        match crate::lightfit::SkyPhoto::new(time, site)? {
            Ok(sky) => Ok(LightingSource::Estimated(sky)),
            Err(elevation) => Err(WorkflowError::file(
                self.file,
                format!(
                    "photo `{id}`: at its `time` {} the sun stands {:.2} deg below the horizon at the site; the estimated sky (Hosek-Wilkie) needs the sun up: give this photo a lighting file",
                    p.time.as_deref().unwrap_or(""),
                    -elevation
                ),
            )),
        }
    }
}

impl SurveyPaths<'_> {
    /// A photo's time from its image's EXIF (FORMATS.md, "Site location and photo time"):
    /// `DateTimeOriginal` with `OffsetTimeOriginal`, else the GPS date and time (UTC); `None`
    /// when the image has no EXIF or no time in it. A local time without its offset (the
    /// instant unknown: nothing is guessed) or a malformed one is refused, naming the image.
    fn exif_time(
        &self,
        p: &igi_formats::survey::PhotoEntry,
    ) -> Result<Option<igi_formats::PhotoTime>, WorkflowError> {
        use igi_formats::TimeProblem;
        let image = self.existing(&p.image, &format!("photo `{}` image", p.id))?;
        let exif = match igi_imaging::exif::read_exif(&image) {
            Ok(e) => e,
            Err(igi_imaging::ImagingError::NoExif { .. }) => return Ok(None),
            Err(e) => {
                return Err(WorkflowError::file(
                    &image,
                    format!("its EXIF cannot be read: {e}"),
                ))
            }
        };
        if let Some(note) = igi_formats::PhotoTime::exif_clock_gps_note(&exif) {
            tracing::warn!("photo `{}` ({}): {note}", p.id, image.display());
        }
        match igi_formats::PhotoTime::from_photo_exif(&exif) {
            Ok(t) => Ok(Some(t)),
            Err(TimeProblem::NoExifTime | TimeProblem::Blank) => Ok(None),
            Err(e) => Err(WorkflowError::file(
                &image,
                format!(
                    "photo `{}` has no `time`, and its EXIF time cannot be used: {e}",
                    p.id
                ),
            )),
        }
    }
}

/// Every `[[reference]]` target is in front of some photo's camera, its centre inside the
/// frame (occlusion is not checked here: a target hidden behind the site is found unseen after
/// the first iteration and leaves the scale unfixed, as the report says).
fn check_references_seen(
    file: &Path,
    references: &[igi_formats::survey::ReferenceTarget],
    photos: &[PhotoSpec],
) -> Result<(), WorkflowError> {
    if references.is_empty() {
        return Ok(());
    }
    let cameras = photos
        .iter()
        .map(|p| Camera::load(&p.camera))
        .collect::<Result<Vec<_>, _>>()?;
    for (i, r) in references.iter().enumerate() {
        let c = glam::DVec3::from_array(r.center);
        let seen = cameras
            .iter()
            .any(|cam| cam.project(c).is_some_and(|q| cam.in_frame(q)));
        if !seen {
            return Err(WorkflowError::file(
                file,
                format!(
                    "[[reference]] {} (center {:?}): no photo sees it (its centre is outside every photo's frame); move it, or remove it",
                    i + 1,
                    r.center
                ),
            ));
        }
    }
    Ok(())
}

/// Checks that a camera radiometry file reads (so that a bad one fails before any work).
fn radiometry_file(path: PathBuf) -> Result<PathBuf, WorkflowError> {
    igi_camera::radiometry::CameraRadiometry::load(&path)?;
    Ok(path)
}

/// Checks that a photo's camera has the aspect ratio its radiometry was fitted at (the camera
/// file is small; the image must match the camera, which loading checks).
fn check_radiometry_size(spec: &PhotoSpec) -> Result<(), WorkflowError> {
    let Some(path) = &spec.radiometry else {
        return Ok(());
    };
    let cal = igi_camera::radiometry::CameraRadiometry::load(path)?;
    let cam = Camera::load(&spec.camera)?;
    if cal.fits_size(cam.width as usize, cam.height as usize) {
        return Ok(());
    }
    Err(WorkflowError::file(
        path,
        format!(
            "fitted at {}x{} but photo `{}`'s camera {} is {}x{} (another aspect ratio)",
            cal.width,
            cal.height,
            spec.id,
            spec.camera.display(),
            cam.width,
            cam.height
        ),
    ))
}

impl PhotoSpec {
    /// Loads the image, camera and lighting; the image must match the camera's size and hold
    /// only finite, non-negative radiance (saturated pixels stay marked invalid).
    pub fn load(&self) -> Result<Photo, WorkflowError> {
        let (image, camera) = self.load_image()?;
        let lighting = match &self.lighting {
            LightingSource::File(f) => {
                let l = Lighting::load(f)?;
                self.check_sun_can_light(f, &l)?;
                l
            }
            LightingSource::Probe {
                image,
                camera,
                board,
            } => self.probe_lighting(image, camera, board)?,
            LightingSource::Estimated(sky) => {
                sky.lighting(&crate::lightfit::SkyParams::default())?
            }
        };
        if !matches!(self.lighting, LightingSource::Estimated(_)) {
            self.warn_if_too_bright(&image, &lighting);
        }
        Ok(Photo {
            id: self.id.clone(),
            image,
            camera,
            lighting,
        })
    }

    /// The image on the survey's radiometric scale (made linear, the camera radiometry
    /// applied, divided by its exposure) and its camera, checked as [`PhotoSpec::load`] checks
    /// them; without its lighting.
    pub fn load_image(&self) -> Result<(HdrImage, Camera), WorkflowError> {
        let mut image = self.read_linear()?.image;
        let camera = Camera::load(&self.camera)?;
        self.check_image(&image, &camera)?;
        if let Some(path) = &self.radiometry {
            self.apply_radiometry(path, &mut image)?;
        }
        if self.exposure != 1.0 {
            let scale = (1.0 / self.exposure) as f32;
            image
                .pixels
                .iter_mut()
                .for_each(|p| *p = p.map(|c| c * scale));
        }
        if self.radiometry.is_some() || self.exposure != 1.0 {
            self.check_pixels(&image, " after the radiometry and exposure")?;
        }
        Ok((image, camera))
    }

    /// A photograph whose median luminance is more than [`TOO_BRIGHT`] times the brightest its
    /// lighting can plausibly show ([`Lighting::brightest_plausible`]) is in other units or
    /// exposure than its lighting, or lit by another light: the solve would only report a
    /// residual near 100 %, so it is said first (a warning naming the photo and the light's
    /// source; issue 36). Estimated light is fitted to the photographs and is not checked.
    fn warn_if_too_bright(&self, image: &HdrImage, lighting: &Lighting) {
        let bound = lighting.brightest_plausible();
        let mut lum: Vec<f32> = image
            .pixels
            .iter()
            .map(|p| igi_imaging::color::luminance(*p))
            .collect();
        if lum.is_empty() || bound <= 0.0 {
            return;
        }
        let mid = lum.len() / 2;
        let median = *lum.select_nth_unstable_by(mid, f32::total_cmp).1;
        if median > TOO_BRIGHT * bound {
            let light = match &self.lighting {
                LightingSource::File(f) => f.display().to_string(),
                LightingSource::Probe { image, .. } => format!("the probe {}", image.display()),
                LightingSource::Estimated(_) => "the estimated sky".into(),
            };
            tracing::warn!(
                "photo `{}` ({}): its median luminance {median:.3e} is {:.1e} times the brightest a white surface or the sky under its lighting ({light}) can show ({bound:.3e}): check the photo's exposure and units against the lighting's",
                self.id,
                self.image.display(),
                median / bound
            );
        }
    }

    /// A sun wholly below the horizon (its disk under the ground plane) lights nothing: an
    /// error naming the lighting file when it is the only light, a warning when a sky still
    /// lights the site (docs/RELIABILITY.md, issue 36).
    fn check_sun_can_light(&self, file: &Path, l: &Lighting) -> Result<(), WorkflowError> {
        let Some(sun) = &l.sun else {
            return Ok(());
        };
        let elevation = sun.direction.z.clamp(-1.0, 1.0).asin();
        if elevation >= -sun.angular_diameter / 2.0 {
            return Ok(());
        }
        let what = format!(
            "[sun] direction {:?} stands {:.1} deg below the horizon: the ground hides it, so it \
             lights nothing at the site",
            sun.direction.to_array(),
            -elevation.to_degrees()
        );
        match &l.environment {
            Some(e) if e.is_nonzero() => {
                tracing::warn!(
                    "photo `{}`: {}: {what}; only the sky lights it",
                    self.id,
                    file.display()
                );
                Ok(())
            }
            _ => Err(WorkflowError::File {
                path: file.to_path_buf(),
                msg: format!(
                    "{what}, and it is the only light of photo `{}` (a sun above the horizon has \
                     direction z > 0; or give an [environment] sky)",
                    self.id
                ),
            }),
        }
    }

    /// The photograph's pixels made linear by its transfer (docs/IMAGING.md), before the
    /// radiometry and the exposure; the clipped pixels it lost are reported (a warning when an
    /// 8- or 16-bit file has any; for a float file, its own invalid pixels, at info level).
    pub fn read_linear(&self) -> Result<igi_imaging::photo::LinearPhoto, WorkflowError> {
        use igi_imaging::photo::{read_photo, read_response_csv, Transfer};
        let transfer = match &self.transfer {
            TransferSpec::Default {
                survey_response: None,
            } => Transfer::Default,
            TransferSpec::Default {
                survey_response: Some(r),
            } => Transfer::ResponseFor8Bit(read_response_csv(r)?),
            TransferSpec::Srgb => Transfer::Srgb,
            TransferSpec::Linear => Transfer::Linear,
            TransferSpec::Response(r) => Transfer::Response(read_response_csv(r)?),
        };
        let linear = read_photo(&self.image, &transfer)?;
        let n = linear.image.pixels.len().max(1);
        let msg = format!(
            "photo {}: {}-bit, {}: {} of {} pixels ({:.2}%) clipped, masked out of the solve",
            self.id,
            linear.bits,
            linear.applied,
            linear.clipped,
            linear.image.pixels.len(),
            100.0 * linear.clipped as f64 / n as f64
        );
        // float files carry their own mask (e.g. a merge's saturated pixels): not news
        if linear.clipped > 0 && linear.bits < 32 {
            tracing::warn!("{msg}");
        } else {
            tracing::info!("{msg}");
        }
        Ok(linear)
    }

    /// The image has the camera's size and only finite, non-negative pixels.
    fn check_image(&self, image: &HdrImage, camera: &Camera) -> Result<(), WorkflowError> {
        if image.width != camera.width as usize || image.height != camera.height as usize {
            return Err(WorkflowError::file(
                &self.image,
                format!(
                    "image is {}x{} but its camera {} says {}x{}",
                    image.width,
                    image.height,
                    self.camera.display(),
                    camera.width,
                    camera.height
                ),
            ));
        }
        self.check_pixels(image, "")
    }

    /// Every pixel finite, non-negative and at most the radiance a lighting file may hold
    /// (`igi_formats::lighting::MAX_RADIANCE`, 1e15: larger values overflow the solver's f32
    /// sums into NaN); `after` says what the pixels went through ("" as read).
    fn check_pixels(&self, image: &HdrImage, after: &str) -> Result<(), WorkflowError> {
        let max = igi_formats::lighting::MAX_RADIANCE;
        if let Some(i) = image
            .pixels
            .iter()
            .position(|p| p.iter().any(|c| !(c.is_finite() && *c >= 0.0 && *c <= max)))
        {
            return Err(WorkflowError::file(
                &self.image,
                format!(
                    "photo `{}`: pixel ({}, {}) is {:?}{after}: pixels must be finite, >= 0 and at most {max:e} (as lighting radiance; check the units)",
                    self.id,
                    i % image.width,
                    i / image.width,
                    image.pixels[i],
                ),
            ));
        }
        Ok(())
    }

    /// Applies the camera radiometry file `path` to `image`, which must have the aspect ratio
    /// the radiometry was fitted at.
    fn apply_radiometry(&self, path: &Path, image: &mut HdrImage) -> Result<(), WorkflowError> {
        let cal = igi_camera::radiometry::CameraRadiometry::load(path)?;
        if !cal.fits_size(image.width, image.height) {
            return Err(WorkflowError::file(
                &self.image,
                format!(
                    "image is {}x{} but the radiometry {} was fitted at {}x{} (another aspect ratio)",
                    image.width,
                    image.height,
                    path.display(),
                    cal.width,
                    cal.height
                ),
            ));
        }
        cal.apply(image);
        Ok(())
    }

    /// The lighting recovered from a capture of the lighting board (as `igi probe` does).
    fn probe_lighting(
        &self,
        image: &Path,
        camera: &Path,
        board: &Path,
    ) -> Result<Lighting, WorkflowError> {
        let img = igi_imaging::read_image(image)?;
        let cam = Camera::load(camera)?;
        let spec = igi_probe::BoardSpec::load(board)?;
        let placement = igi_probe::fiducial::place_board(&spec, &img, &cam)?;
        let opt = igi_probe::ProbeOptions {
            refine_centers: placement.refine_by_default(),
            ..igi_probe::ProbeOptions::default()
        };
        let r = igi_probe::process(&img, &cam, &placement.board, &opt).map_err(|source| {
            WorkflowError::ProbeCapture {
                path: image.to_path_buf(),
                photo: self.id.clone(),
                source: Box::new(source),
            }
        })?;
        tracing::info!(
            "photo {}: lighting from its probe capture: {}",
            self.id,
            r.diagnostics.sun_decision
        );
        lighting_from_probe(&r)
    }
}

/// The lighting a probe capture recovered: its sky map and, when the sun was found and its
/// radiance solved, the sun disk.
pub fn lighting_from_probe(r: &igi_probe::ProbeResult) -> Result<Lighting, WorkflowError> {
    let sun = match r
        .diagnostics
        .sun
        .as_ref()
        .and_then(|s| s.radiance.map(|l| (s, l)))
    {
        Some((s, l)) => Some(igi_render::Sun::new(
            glam::DVec3::from_array(s.direction).as_vec3(),
            glam::Vec3::from_array(l),
            s.angular_diameter_deg as f32,
        )?),
        None => None,
    };
    Ok(Lighting {
        environment: Some(igi_render::Environment::from_image(&r.sky, 1.0)?),
        sun,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;
    use igi_camera::radiometry::{CameraRadiometry, Falloff, RadiometryFit};

    /// A survey folder whose files exist (only the camera and radiometry files are read when
    /// the survey is), with `extra` appended to survey.toml and `photo_extra` to the photo.
    fn survey_dir(extra: &str, photo_extra: &str) -> tempfile::TempDir {
        let dir = tempfile::tempdir().unwrap();
        for f in ["site.ply", "photo.exr", "sky.toml"] {
            std::fs::write(dir.path().join(f), "").unwrap();
        }
        Camera::look_at(DVec3::new(5.0, 0.0, 2.0), DVec3::ZERO, 64, 48, 60.0)
            .unwrap()
            .save(&dir.path().join("cam.json"))
            .unwrap();
        let cal = |w, h| CameraRadiometry {
            width: w,
            height: h,
            falloff: Some(Falloff {
                a2: -0.3,
                a4: 0.05,
                a6: 0.0,
            }),
            color_matrix: None,
            fit: RadiometryFit::default(),
        };
        cal(128, 96).save(&dir.path().join("rad.json")).unwrap();
        cal(100, 100).save(&dir.path().join("square.json")).unwrap();
        std::fs::write(dir.path().join("broken.json"), "{\"width\": 3}").unwrap();
        let text = format!(
            "[site]\nmesh = \"site.ply\"\n{extra}\n[[photo]]\nid = \"p\"\nimage = \"photo.exr\"\n\
             camera = \"cam.json\"\nlighting = \"sky.toml\"\n{photo_extra}\n"
        );
        std::fs::write(dir.path().join("survey.toml"), text).unwrap();
        dir
    }

    #[test]
    fn response_and_transfer_keys_are_read_and_checked() {
        let dir = survey_dir("[radiometry]\nresponse = \"resp.csv\"", "");
        igi_imaging::hdr::Response::linear()
            .write_csv(&dir.path().join("resp.csv"))
            .unwrap();
        let s = Survey::load(dir.path()).unwrap();
        assert_eq!(
            s.photos[0].transfer,
            TransferSpec::Default {
                survey_response: Some(dir.path().join("resp.csv"))
            }
        );
        let e = error_of("", "response = \"nope.csv\"");
        assert!(
            e.contains("nope.csv") && e.contains("photo `p` response"),
            "{e}"
        );
        let e = error_of("", "transfer = \"gamma\"");
        assert!(e.contains("gamma") && e.contains("survey.toml"), "{e}");
        let dir = survey_dir("", "transfer = \"linear\"");
        assert_eq!(
            Survey::load(dir.path()).unwrap().photos[0].transfer,
            TransferSpec::Linear
        );
        // both keys: refused; a response that decreases: refused naming its line
        let dir = survey_dir("", "response = \"r.csv\"\ntransfer = \"srgb\"");
        let mut text = String::from("z,g_r,g_g,g_b\n");
        for z in 0..256 {
            let g = if z == 40 {
                -9.0
            } else {
                (z.max(1) as f64 / 128.0).ln()
            };
            text.push_str(&format!("{z},{g},{g},{g}\n"));
        }
        std::fs::write(dir.path().join("r.csv"), &text).unwrap();
        let e = Survey::load(dir.path()).unwrap_err().to_string();
        assert!(e.contains("both `response` and `transfer"), "{e}");
        std::fs::write(
            dir.path().join("survey.toml"),
            std::fs::read_to_string(dir.path().join("survey.toml"))
                .unwrap()
                .replace("transfer = \"srgb\"", ""),
        )
        .unwrap();
        let e = Survey::load(dir.path()).unwrap_err().to_string();
        assert!(
            e.contains("r.csv:42:") && e.contains("must not decrease"),
            "{e}"
        );
    }

    fn error_of(extra: &str, photo_extra: &str) -> String {
        let dir = survey_dir(extra, photo_extra);
        match Survey::load(dir.path()) {
            Ok(_) => panic!("survey with {extra:?} {photo_extra:?} was accepted"),
            Err(e) => format!("{e}"),
        }
    }

    #[test]
    fn radiometry_keys_apply_per_survey_and_per_photo() {
        let dir = survey_dir("[radiometry]\ncamera = \"rad.json\"", "");
        let s = Survey::load(dir.path()).unwrap();
        assert_eq!(s.photos[0].radiometry, Some(dir.path().join("rad.json")));
        let dir = survey_dir("", "");
        assert_eq!(Survey::load(dir.path()).unwrap().photos[0].radiometry, None);
        let dir = survey_dir(
            "[radiometry]\ncamera = \"square.json\"",
            "radiometry = \"rad.json\"",
        );
        let s = Survey::load(dir.path()).unwrap();
        assert_eq!(s.photos[0].radiometry, Some(dir.path().join("rad.json")));
    }

    #[test]
    fn a_photos_exposure_is_read_and_checked() {
        let s = Survey::load(survey_dir("", "exposure = 0.0125").path()).unwrap();
        assert_eq!(s.photos[0].exposure, 0.0125);
        let s = Survey::load(survey_dir("", "").path()).unwrap();
        assert_eq!(s.photos[0].exposure, 1.0);
        for bad in ["0.0", "-2.0", "nan", "inf"] {
            let e = error_of("", &format!("exposure = {bad}"));
            assert!(
                e.contains("survey.toml")
                    && e.contains("`p` exposure")
                    && e.contains("not a positive number"),
                "{bad}: {e}"
            );
        }
    }

    #[test]
    fn bad_radiometry_keys_fail_naming_the_file() {
        let e = error_of("[radiometry]\ncamera = \"missing.json\"", "");
        assert!(e.contains("missing.json"), "{e}");
        let e = error_of("[radiometry]\ncamera = \"broken.json\"", "");
        assert!(
            e.contains("broken.json") && e.contains("not a camera radiometry file"),
            "{e}"
        );
        let e = error_of("[radiometry]\ncamera = \"square.json\"", "");
        assert!(
            e.contains("square.json") && e.contains("64x48") && e.contains("aspect"),
            "{e}"
        );
        let e = error_of("", "radiometry = \"broken.json\"");
        assert!(e.contains("broken.json"), "{e}");
        let e = error_of("[radiometry]\nfile = \"rad.json\"", "");
        assert!(e.contains("survey.toml") && e.contains("file"), "{e}");
    }

    #[test]
    fn the_contract_site_keys_are_read_and_checked() {
        let dir = survey_dir(
            "latitude_deg = 37.9715\nlongitude_deg = 23.7267\nnorth = [1.0, 0.0, 0.0]",
            "time = \"2026-06-21T09:30:00+03:00\"",
        );
        let s = Survey::load(dir.path()).unwrap();
        assert_eq!(s.site.location(), Some((37.9715, 23.7267)));
        assert_eq!(s.site.north_or_default(), [1.0, 0.0, 0.0]);
        let t = s.photos[0].time.expect("the photo's time");
        assert_eq!(t.unix_seconds(), 1_782_023_400);
        let e = error_of("latitude_deg = 95.0\nlongitude_deg = 0.0", "");
        assert!(
            e.contains("survey.toml") && e.contains("latitude_deg"),
            "{e}"
        );
        let e = error_of("", "time = \"2026-06-21T09:30:00\"");
        assert!(e.contains("survey.toml") && e.contains("offset"), "{e}");
    }

    #[test]
    fn a_photo_with_a_time_and_no_lighting_is_lit_by_the_sun_of_its_time() {
        let dir = survey_dir("latitude_deg = 37.9\nlongitude_deg = 23.7", "");
        let text = std::fs::read_to_string(dir.path().join("survey.toml")).unwrap();
        let text = text.replace(
            "lighting = \"sky.toml\"",
            "time = \"2026-06-21T09:30:00+03:00\"",
        );
        std::fs::write(dir.path().join("survey.toml"), text).unwrap();
        let s = Survey::load(dir.path()).unwrap();
        let LightingSource::Estimated(sky) = &s.photos[0].lighting else {
            panic!(
                "the photo's light is not estimated: {:?}",
                s.photos[0].lighting
            );
        };
        // Athens at 06:30 UTC on the solstice: the sun low in the east, where NOAA's solar
        // calculator (its spreadsheet's algorithm, with refraction) puts it at zenith 52.059 and
        // azimuth 88.14 degrees; its direction east-north-up with the default north (+Y)
        let z = sky.position.zenith_deg.to_radians().cos();
        assert!((sky.sun[2] - z).abs() < 1e-6, "{sky:?}");
        assert!((sky.position.zenith_deg - 52.06).abs() < 0.05, "{sky:?}");
        assert!((sky.position.azimuth_deg - 88.14).abs() < 0.05, "{sky:?}");
        assert!(sky.sun[0] > 0.75, "the sun is not in the east: {sky:?}");
    }
}
