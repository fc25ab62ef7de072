//! The result of a solve, in memory and as a folder: writing it, resuming from it, re-lighting
//! it (export and sampling read it in `igi-export`). In memory a [`SolveResult`] holds one
//! [`PartResult`] per part (its geometry, albedo atlas, weights, observation counts, standard
//! errors, lobes and whether it changed since the last checkpoint), the report and the basis.
//!
//! ```text
//! RESULT_DIR/
//!   scene.toml                  FORMATS.md scene file (no lighting): one object per part
//!   report.json                 options, per-iteration records, per-part summaries
//!   convergence.png             error against run time
//!   parts/NAME.ply              the part's mesh with atlas UVs
//!   parts/NAME_rho_d.exr        recovered diffuse albedo (linear RGB atlas)
//!   parts/NAME_weight.exr       sum of the observation weights per texel (grey)
//!   parts/NAME_observations.exr number of photos that contributed per texel (grey)
//!   parts/NAME_stderr.exr       standard error of rho_d per texel and channel (RGB); -1 where
//!                               unknown (texel not seen in the last iteration); a result
//!                               written before this file existed reads as all unknown
//!   parts/NAME_coverage.exr     1 covered, 0.5 gutter, 0 empty
//!   parts/NAME_position.exr     texel cache: world position per texel
//!   parts/NAME_normal.exr       texel cache: world normal per texel
//!   parts/NAME_lobes.json       lobes inferred for the part (when BRDF samples were given)
//! ```
//! `NAME_stderr.exr` is derived in docs/SOLVER.md ("Per-texel uncertainty"): the spread of the
//! weighted proposals of the last ratio update beyond their Monte-Carlo noise, plus that noise.
//! `igi_export::sample_albedo` returns it with the albedo (`igi sample`'s `sr,sg,sb`), and
//! `igi_export::export` pictures it as `NAME_stderr.png`.
//!
//! Every file is written atomically, and a checkpoint is one transaction: its changed files,
//! `scene.toml`, `convergence.png` and last `report.json` are first written into `staged/`;
//! the staged `report.json` is the commit point, after which the staged files are renamed into
//! place (report last). A run killed before the commit point leaves the previous checkpoint
//! intact (the staged files are dropped on resume); one killed after it is rolled forward on
//! resume ([`SolveResult::recover`]). So a killed solve resumes from exactly the last
//! checkpoint and never mixes the albedo of one iteration with the report of another.

use crate::parts::{Part, TexelCache};
use crate::record::{SolveOptions, SolveReport};
use crate::ReflectError;
use glam::Vec3;
use igi_brdf::Lobe;
use igi_formats::scene::{AlbedoEntry, LobeEntry, LobeMapEntry, ObjectEntry, SceneFile};
use igi_formats::{f32_decimal, f32_decimals, TomlFile};
use igi_geometry::{read_mesh, write_ply, TriMesh};
use igi_imaging::{read_image, write_exr, HdrImage};
use std::path::{Path, PathBuf};

/// The staging folder of a checkpoint in progress (see the module overview).
pub const STAGED: &str = "staged";

/// The standard error of a texel whose albedo was not measured (not seen, or a result folder
/// from before `NAME_stderr.exr`): negative, never NaN.
pub const UNKNOWN_STDERR: Vec3 = Vec3::splat(-1.0);

/// The state and result of a solve: one [`PartResult`] per part, the report, and the basis the
/// lobes are inferred with.
pub struct SolveResult {
    pub parts: Vec<PartResult>,
    pub report: SolveReport,
    /// The BRDF basis the solve infers lobes with (set by `solve`); with it, `write_state`
    /// writes per-texel lobe maps inferred from each texel's albedo.
    pub basis: Option<igi_brdf::Basis>,
}

/// One part of a solve: its geometry and atlas, and what the solve knows of each texel (atlas
/// index `row * res + column`).
pub struct PartResult {
    pub part: Part,
    /// The diffuse albedo per texel.
    pub rho: Vec<Vec3>,
    /// The sum of the observation weights per texel (empty in a part loaded without its
    /// statistics: a cluster task loads only its own parts' statistics).
    pub weight_sum: Vec<f32>,
    /// The number of photographs that contributed per texel (empty as `weight_sum` is).
    pub observations: Vec<u32>,
    /// The standard error of `rho` per texel and channel, or [`UNKNOWN_STDERR`] (docs/SOLVER.md
    /// derives it from the spread of the weighted proposals and the Monte-Carlo noise of the
    /// rendered radiance; empty as `weight_sum` is).
    pub stderr: Vec<Vec3>,
    /// The part's lobes (empty without a BRDF basis).
    pub lobes: Vec<Lobe>,
    /// Whether the albedo changed since the last [`write_state`](SolveResult::write_state)
    /// (only changed parts are rewritten; all after [`fresh`](SolveResult::fresh), none after
    /// [`load`](SolveResult::load)).
    pub changed: bool,
}

/// A report's parts as a result must hold them: at least one, each named once by a name that
/// can name its files (a name with a path separator would reach outside `parts/`).
fn check_report_parts(report: &SolveReport) -> Result<(), ReflectError> {
    if report.parts.is_empty() {
        return Err(ReflectError::Invalid("the result holds no parts".into()));
    }
    crate::atlas_size::check_names(
        report.parts.iter().map(|p| p.name.as_str()),
        "parts of the result",
    )
}

impl PartResult {
    /// A part not solved yet: every texel at `albedo`, unseen, with an unknown standard error.
    pub fn fresh(part: Part, albedo: Vec3) -> PartResult {
        let n = part.resolution() * part.resolution();
        PartResult {
            part,
            rho: vec![albedo; n],
            weight_sum: vec![0.0; n],
            observations: vec![0; n],
            stderr: vec![UNKNOWN_STDERR; n],
            lobes: Vec::new(),
            changed: true,
        }
    }

    /// The part's name.
    pub fn name(&self) -> &str {
        &self.part.name
    }

    /// The part's atlas resolution (texels per side).
    pub fn resolution(&self) -> usize {
        self.part.resolution()
    }

    /// Whether the part holds its weights, observation counts and standard errors (a cluster
    /// task loads the other parts without them).
    pub fn has_statistics(&self) -> bool {
        self.weight_sum.len() == self.rho.len()
    }

    /// Writes the part's albedo, weight, observation and standard-error atlases into `dir`
    /// (`NAME_rho_d.exr`, `NAME_weight.exr`, `NAME_observations.exr`, `NAME_stderr.exr`).
    pub(crate) fn write_atlases(&self, dir: &Path) -> Result<(), ReflectError> {
        let name = self.name();
        assert!(
            self.has_statistics(),
            "part {name}: loaded without its statistics (load_solving), it cannot be written"
        );
        let r = self.resolution();
        let img = |f: &dyn Fn(usize) -> [f32; 3]| {
            let mut im = HdrImage::new(r, r);
            for (k, px) in im.pixels.iter_mut().enumerate() {
                *px = f(k);
            }
            im
        };
        let rho = img(&|k| self.rho[k].to_array());
        write_exr(&dir.join(format!("{name}_rho_d.exr")), &rho)?;
        let weight = img(&|k| [self.weight_sum[k]; 3]);
        write_exr(&dir.join(format!("{name}_weight.exr")), &weight)?;
        let counts = img(&|k| [self.observations[k] as f32; 3]);
        write_exr(&dir.join(format!("{name}_observations.exr")), &counts)?;
        let stderr = img(&|k| self.stderr[k].to_array());
        write_exr(&dir.join(format!("{name}_stderr.exr")), &stderr)?;
        Ok(())
    }
}

impl AsRef<Part> for PartResult {
    fn as_ref(&self) -> &Part {
        &self.part
    }
}

/// Every part's albedo atlas and lobes at the start of a Jacobi iteration.
pub(crate) type Snapshot = Vec<(Vec<Vec3>, Vec<Lobe>)>;

/// The albedo atlases and lobes a group's scene shows: those of a [`Snapshot`], or the
/// current ones.
#[derive(Clone, Copy)]
pub(crate) enum Albedos<'a> {
    Snapshot(&'a Snapshot),
    Current(&'a [PartResult]),
}

impl Albedos<'_> {
    /// The albedo atlas of part `i`.
    pub(crate) fn rho(&self, i: usize) -> &[Vec3] {
        match self {
            Albedos::Snapshot(s) => &s[i].0,
            Albedos::Current(p) => &p[i].rho,
        }
    }

    /// The lobes of part `i`.
    pub(crate) fn lobes(&self, i: usize) -> &[Lobe] {
        match self {
            Albedos::Snapshot(s) => &s[i].1,
            Albedos::Current(p) => &p[i].lobes,
        }
    }

    /// Every part's albedo atlas and lobes, copied (the snapshot of a Jacobi iteration).
    pub(crate) fn snapshot(parts: &[PartResult]) -> Snapshot {
        parts
            .iter()
            .map(|p| (p.rho.clone(), p.lobes.clone()))
            .collect()
    }
}

impl SolveResult {
    /// A fresh state: every texel at the initial albedo.
    pub fn fresh(parts: Vec<Part>, photo_ids: Vec<String>, opts: &SolveOptions) -> SolveResult {
        let init = Vec3::from_array(opts.initial_albedo);
        let site = parts
            .iter()
            .find_map(|p| p.stored.as_ref().map(|s| s.site.clone()));
        SolveResult {
            parts: parts
                .into_iter()
                .map(|p| PartResult::fresh(p, init))
                .collect(),
            report: SolveReport {
                options: opts.clone(),
                photos: photo_ids,
                iterations: Vec::new(),
                parts: Vec::new(),
                converged: false,
                site,
                pending: None,
                lighting: None,
            },
            basis: None,
        }
    }

    /// Marks every part changed (`true`: the next checkpoint rewrites them all) or unchanged.
    pub fn set_changed(&mut self, changed: bool) {
        self.parts.iter_mut().for_each(|p| p.changed = changed);
    }

    /// The parts' current albedo atlases as textures (as a render reads them).
    pub fn albedo_textures(&self) -> Vec<igi_render::Texture> {
        self.parts
            .iter()
            .map(|p| igi_render::Texture {
                width: p.resolution(),
                height: p.resolution(),
                texels: p.rho.clone(),
            })
            .collect()
    }

    /// The scene of the parts with their current albedo atlases (and no lobes).
    pub fn albedo_scene(&self) -> Result<igi_render::Scene, ReflectError> {
        scene_of_atlases(self.parts.iter().map(|p| (&p.part, p.rho.as_slice())))
    }

    /// Writes the parts' geometry and texel caches (once, at the start of a solve).
    pub fn write_geometry(&self, dir: &Path) -> Result<(), ReflectError> {
        let pdir = dir.join("parts");
        std::fs::create_dir_all(&pdir).map_err(|e| ReflectError::io(&pdir, "create folder", e))?;
        for p in self.parts.iter().map(|p| &p.part) {
            if p.stored.is_none() {
                write_ply(&pdir.join(format!("{}.ply", p.name)), &p.mesh)?;
            }
            let r = p.resolution();
            let mut pos = HdrImage::new(r, r);
            let mut nrm = HdrImage::new(r, r);
            for t in &p.cache.texels {
                pos.pixels[t.index as usize] = t.position.to_array();
                nrm.pixels[t.index as usize] = t.normal.to_array();
            }
            write_exr(&pdir.join(format!("{}_position.exr", p.name)), &pos)?;
            write_exr(&pdir.join(format!("{}_normal.exr", p.name)), &nrm)?;
            write_exr(&pdir.join(format!("{}_coverage.exr", p.name)), &p.coverage)?;
        }
        Ok(())
    }

    /// Writes the current albedo, weights, observation counts and lobes of the changed parts,
    /// then `scene.toml`, the plot and `report.json` (last).
    pub fn write_state(&self, dir: &Path) -> Result<(), ReflectError> {
        let sdir = dir.join(STAGED);
        if sdir.exists() {
            // an earlier checkpoint that never reached its commit point
            std::fs::remove_dir_all(&sdir).map_err(|e| ReflectError::io(&sdir, "remove", e))?;
        }
        std::fs::create_dir_all(sdir.join("parts"))
            .map_err(|e| ReflectError::io(&sdir, "create folder", e))?;
        self.stage(&sdir)?;
        Self::commit_staged(dir)
    }

    /// Writes this checkpoint's changed part files, `scene.toml`, `convergence.png` and, last,
    /// `report.json` into the staging folder `sdir`.
    fn stage(&self, sdir: &Path) -> Result<(), ReflectError> {
        let pdir = sdir.join("parts");
        let store = match self.parts.iter().find_map(|p| p.part.stored.as_ref()) {
            Some(s) => Some(igi_geometry::SiteStore::open(&s.site)?),
            None => None,
        };
        let mut scene = SceneFile::default();
        for (i, pr) in self.parts.iter().enumerate() {
            let p = &pr.part;
            if pr.changed {
                pr.write_atlases(&pdir)?;
                if !pr.lobes.is_empty() {
                    let json = serde_json::to_string_pretty(&pr.lobes).expect("lobes serialise");
                    write_text(&pdir.join(format!("{}_lobes.json", p.name)), &json)?;
                }
                if let Some(map) = self.lobe_map(i) {
                    for (k, (rho, shape)) in map.to_images().iter().enumerate() {
                        write_exr(&pdir.join(format!("{}_lobe{k}_rho.exr", p.name)), rho)?;
                        write_exr(&pdir.join(format!("{}_lobe{k}_shape.exr", p.name)), shape)?;
                    }
                }
            }
            let mesh = match (&p.stored, &store) {
                (None, _) | (_, None) => format!("parts/{}.ply", p.name),
                (Some(s), Some(store)) => {
                    // the prepared site's full-resolution level, by absolute path
                    let f = s.folder(store)?.join("level0.ply");
                    std::fs::canonicalize(&f).unwrap_or(f).display().to_string()
                }
            };
            let albedo = format!("parts/{}_rho_d.exr", p.name);
            let per_texel = self
                .basis
                .as_ref()
                .map_or(0, |b| b.infer(Vec3::splat(0.5)).lobes.len());
            scene
                .object
                .push(self.object_entry(i, &mesh, &albedo, "parts/", per_texel));
        }
        scene.write(
            &sdir.join("scene.toml"),
            &[
                "Recovered reflectance (igi solve). Re-light with:",
                "igi render THIS_FOLDER --lighting L.toml --camera C.json --spp N -o out.exr",
            ],
        )?;
        crate::plot::plot_convergence(&self.report, &sdir.join("convergence.png"))?;
        let json = serde_json::to_string_pretty(&self.report).expect("report serialises");
        write_text(&sdir.join("report.json"), &json)?;
        Ok(())
    }

    /// Moves a committed staging folder (one holding `report.json`) into place: every staged
    /// file first, `report.json` last, then removes the folder. Idempotent: a move killed
    /// half-way is finished by the next call.
    fn commit_staged(dir: &Path) -> Result<(), ReflectError> {
        let sdir = dir.join(STAGED);
        let mv = |from: PathBuf, to: PathBuf| {
            std::fs::rename(&from, &to).map_err(|e| ReflectError::io(&to, "move a staged file", e))
        };
        let spdir = sdir.join("parts");
        if spdir.is_dir() {
            let entries = std::fs::read_dir(&spdir)
                .map_err(|e| ReflectError::io(&spdir, "read folder", e))?;
            for e in entries {
                let e = e.map_err(|e| ReflectError::io(&spdir, "read", e))?;
                let name = e.file_name();
                if name.to_string_lossy().starts_with('.') {
                    continue; // a dead writer's temporary file
                }
                mv(e.path(), dir.join("parts").join(name))?;
            }
        }
        for f in ["scene.toml", "convergence.png", "report.json"] {
            if sdir.join(f).exists() {
                mv(sdir.join(f), dir.join(f))?;
            }
        }
        std::fs::remove_dir_all(&sdir).map_err(|e| ReflectError::io(&sdir, "remove", e))
    }

    /// Repairs a result folder after a killed checkpoint: a staging folder that reached its
    /// commit point (holds `report.json`) is moved into place, one that did not is dropped.
    pub fn recover(dir: &Path) -> Result<(), ReflectError> {
        let sdir = dir.join(STAGED);
        if sdir.join("report.json").is_file() {
            Self::commit_staged(dir)
        } else if sdir.exists() {
            std::fs::remove_dir_all(&sdir).map_err(|e| ReflectError::io(&sdir, "remove", e))
        } else {
            Ok(())
        }
    }

    /// Loads a result folder written by [`write_geometry`](Self::write_geometry) and
    /// [`write_state`](Self::write_state), for resuming or reading.
    pub fn load(dir: &Path) -> Result<SolveResult, ReflectError> {
        Self::load_solving(dir, &|_| true)
    }

    /// [`load`](Self::load) for solving only the parts `solving` names: the other parts get
    /// their geometry, albedo and lobes (what a scene shows) but no weight, observation or
    /// standard-error atlases (empty, never read), so a cluster task reads and holds those for
    /// its own group only. Such a state must not be written back whole.
    pub(crate) fn load_solving(
        dir: &Path,
        solving: &dyn Fn(&str) -> bool,
    ) -> Result<SolveResult, ReflectError> {
        if dir.join(STAGED).join("report.json").is_file() {
            return Err(ReflectError::UnfinishedCheckpoint(dir.to_path_buf()));
        }
        let rp = dir.join("report.json");
        let text = std::fs::read_to_string(&rp).map_err(|e| ReflectError::io(&rp, "read", e))?;
        let report: SolveReport =
            serde_json::from_str(&text).map_err(|e| ReflectError::json(&rp, "solve report", e))?;
        check_report_parts(&report).map_err(|e| ReflectError::ReportParts {
            path: rp.clone(),
            source: Box::new(e),
        })?;
        let pdir = dir.join("parts");
        let parts = report
            .parts
            .iter()
            .map(|s| PartResult::read(&pdir, s, solving(&s.name)))
            .collect::<Result<_, _>>()?;
        Ok(SolveResult {
            parts,
            report,
            basis: None,
        })
    }
}

impl PartResult {
    /// Reads the part `s` of the report from the result's `parts/` folder `pdir`: its geometry
    /// ([`read_part`]), albedo, lobes and, when `solving`, its weight, observation and
    /// standard-error atlases (otherwise empty); every atlas must have the coverage's size.
    /// Unchanged: it is what the folder holds.
    fn read(
        pdir: &Path,
        s: &crate::record::PartSummary,
        solving: bool,
    ) -> Result<PartResult, ReflectError> {
        let name = &s.name;
        let part = read_part(pdir, s)?;
        let r = part.resolution();
        let atlas = |what: &str| read_atlas(pdir, name, what, r);
        let first = |im: HdrImage| im.pixels.iter().map(|p| p[0]).collect::<Vec<f32>>();
        let (weight_sum, observations, stderr) = if solving {
            let counts = first(atlas("observations")?);
            (
                first(atlas("weight")?),
                counts.iter().map(|c| c.max(0.0) as u32).collect(),
                read_stderr(pdir, name, r)?,
            )
        } else {
            (Vec::new(), Vec::new(), Vec::new())
        };
        Ok(PartResult {
            rho: atlas("rho_d")?
                .pixels
                .iter()
                .map(|p| Vec3::from_array(*p))
                .collect(),
            weight_sum,
            observations,
            stderr,
            lobes: read_lobes(&pdir.join(format!("{name}_lobes.json")))?,
            part,
            changed: false,
        })
    }
}

/// The geometry of part `s` in a result's `parts/` folder `pdir`: its mesh (unless it lives in
/// a prepared site), coverage and texel cache (from the position and normal atlases, which must
/// have the coverage's size).
fn read_part(pdir: &Path, s: &crate::record::PartSummary) -> Result<Part, ReflectError> {
    let name = &s.name;
    let mesh = match &s.stored {
        None => read_mesh(&pdir.join(format!("{name}.ply")))?,
        Some(_) => TriMesh::default(),
    };
    let coverage = read_image(&pdir.join(format!("{name}_coverage.exr")))?;
    let r = coverage.width;
    let pos = read_atlas(pdir, name, "position", r)?;
    let nrm = read_atlas(pdir, name, "normal", r)?;
    let texels = TexelCache::covered_texels(&pos, &nrm, &coverage);
    Ok(Part {
        name: name.clone(),
        mesh,
        stored: s.stored.clone(),
        texel_size: s.texel_size_m,
        footprint_m: s.footprint_m,
        cache: TexelCache {
            resolution: r,
            texels,
        },
        coverage,
    })
}

/// `NAME_WHAT.exr` of an `r` x `r` atlas in `pdir`.
pub(crate) fn read_atlas(
    pdir: &Path,
    name: &str,
    what: &str,
    r: usize,
) -> Result<HdrImage, ReflectError> {
    let path = pdir.join(format!("{name}_{what}.exr"));
    let im = read_image(&path)?;
    if im.width != r || im.height != r {
        return Err(ReflectError::AtlasSize {
            path,
            width: im.width,
            height: im.height,
            expected: r,
        });
    }
    Ok(im)
}

/// A part's `NAME_lobes.json`; no lobes when the file does not exist.
fn read_lobes(lp: &Path) -> Result<Vec<Lobe>, ReflectError> {
    if !lp.exists() {
        return Ok(Vec::new());
    }
    let t = std::fs::read_to_string(lp).map_err(|e| ReflectError::io(lp, "read", e))?;
    let lobes: Vec<Lobe> =
        serde_json::from_str(&t).map_err(|e| ReflectError::json(lp, "lobe list", e))?;
    match lobes.iter().position(|l| !l.is_valid()) {
        Some(i) => Err(ReflectError::Invalid(format!(
            "{}: lobe {i} {:?} has invalid parameters (a colour and exponent at least 0, every value finite)",
            lp.display(),
            lobes[i]
        ))),
        None => Ok(lobes),
    }
}

/// A TOML basic string (quoted, with backslashes and quotes escaped).
/// Reads `NAME_stderr.exr` of an `r` x `r` atlas; a missing file (a result written before it
/// existed) reads as unknown everywhere.
pub(crate) fn read_stderr(pdir: &Path, name: &str, r: usize) -> Result<Vec<Vec3>, ReflectError> {
    let path = pdir.join(format!("{name}_stderr.exr"));
    if !path.exists() {
        return Ok(vec![UNKNOWN_STDERR; r * r]);
    }
    Ok(read_atlas(pdir, name, "stderr", r)?
        .pixels
        .iter()
        .map(|p| {
            let v = Vec3::from_array(*p);
            if v.is_finite() && v.min_element() >= 0.0 {
                v
            } else {
                UNKNOWN_STDERR
            }
        })
        .collect())
}

impl SolveResult {
    /// Part `i` as a scene file's `[[object]]` (FORMATS.md): its mesh and albedo texture, and
    /// its per-texel lobe maps `{maps}NAME_lobeK_rho.exr` / `_shape.exr` (with a basis) or its
    /// constant lobes.
    pub fn object_entry(
        &self,
        i: usize,
        mesh: &str,
        albedo: &str,
        maps: &str,
        per_texel: usize,
    ) -> ObjectEntry {
        let name = self.parts[i].name();
        let lobe_maps: Vec<LobeMapEntry> = (0..per_texel)
            .map(|k| LobeMapEntry {
                rho: format!("{maps}{name}_lobe{k}_rho.exr").into(),
                shape: format!("{maps}{name}_lobe{k}_shape.exr").into(),
            })
            .collect();
        let lobes = if per_texel > 0 {
            Vec::new()
        } else {
            self.parts[i]
                .lobes
                .iter()
                .map(|l| LobeEntry {
                    rho: f32_decimals(l.rho.to_array()),
                    cxy: f32_decimal(l.cxy),
                    cz: f32_decimal(l.cz),
                    n: f32_decimal(l.n),
                })
                .collect()
        };
        ObjectEntry {
            mesh: mesh.into(),
            albedo: AlbedoEntry::Texture(albedo.into()),
            lobes,
            lobe_maps,
        }
    }

    /// Per-texel lobes of part `i`, inferred with the basis from every texel's albedo (`None`
    /// without a basis). Each texel gets the lobes `Basis::infer` gives for its `rho_d`.
    pub fn lobe_map(&self, i: usize) -> Option<igi_render::LobeMap> {
        let basis = self.basis.as_ref()?;
        let r = self.parts[i].resolution();
        let per: Vec<Vec<Lobe>> = self.parts[i]
            .rho
            .iter()
            .map(|rho| basis.infer(*rho).lobes)
            .collect();
        let k = per.iter().map(Vec::len).max().unwrap_or(0);
        if k == 0 {
            return None;
        }
        let none = Lobe {
            rho: Vec3::ZERO,
            cxy: 0.0,
            cz: 1.0,
            n: 1.0,
        };
        let lobes = per
            .iter()
            .flat_map(|l| (0..k).map(move |j| l.get(j).copied().unwrap_or(none)))
            .collect();
        Some(igi_render::LobeMap {
            width: r,
            height: r,
            per_texel: k,
            lobes,
        })
    }
}

/// The scene of parts, each with its albedo atlas (and no lobes).
pub(crate) fn scene_of_atlases<'a>(
    atlases: impl Iterator<Item = (&'a Part, &'a [Vec3])>,
) -> Result<igi_render::Scene, ReflectError> {
    let objects = atlases
        .map(|(p, rho)| {
            let r = p.resolution();
            let albedo = igi_render::Albedo::Texture(igi_render::Texture {
                width: r,
                height: r,
                texels: rho.to_vec(),
            });
            Ok((
                p.name.clone(),
                p.full_mesh()?.into_owned(),
                igi_render::Material {
                    lobe_map: None,
                    albedo,
                    lobes: Vec::new(),
                },
            ))
        })
        .collect::<Result<_, ReflectError>>()?;
    Ok(igi_render::Scene::new(objects)?)
}

pub(crate) fn write_text(path: &Path, text: &str) -> Result<(), ReflectError> {
    Ok(igi_files::write_text_atomic(path, text)?)
}

/// The scene file of a result folder (for `igi render RESULT_DIR --lighting ...`).
pub fn load_result_scene(dir: &Path) -> Result<PathBuf, ReflectError> {
    let p = dir.join("scene.toml");
    if !p.is_file() || !dir.join("report.json").is_file() {
        return Err(ReflectError::NotAResult(dir.to_path_buf()));
    }
    Ok(p)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::parts::build_parts;

    fn square(x0: f32) -> TriMesh {
        let mut m = TriMesh::default();
        for [x, y] in [[x0, 0.0], [x0 + 2.0, 0.0], [x0 + 2.0, 2.0], [x0, 2.0]] {
            m.positions.push([x, y, 0.0]);
        }
        m.indices = vec![[0, 1, 2], [0, 2, 3]];
        m.compute_vertex_normals();
        m
    }

    /// A state loaded for solving one part holds the weights, counts and standard errors of
    /// that part only, and every part's geometry and albedo as a full load does.
    #[test]
    fn a_state_loaded_for_one_part_holds_its_statistics_only() {
        let dir = tempfile::tempdir().unwrap();
        let meshes = vec![("a".into(), square(0.0)), ("b".into(), square(3.0))];
        let parts = build_parts(meshes, 16).unwrap();
        let mut state = SolveResult::fresh(parts, vec!["p".into()], &SolveOptions::default());
        for (i, p) in state.parts.iter_mut().enumerate() {
            p.rho
                .iter_mut()
                .enumerate()
                .for_each(|(k, v)| *v = Vec3::splat((i * 256 + k) as f32 / 600.0));
        }
        state.parts[0].weight_sum = vec![1.5; 256];
        state.parts[0].observations = vec![3; 256];
        state.report.parts = state
            .parts
            .iter()
            .map(|p| crate::record::PartSummary::unsolved(&p.part))
            .collect();
        state.write_geometry(dir.path()).unwrap();
        state.write_state(dir.path()).unwrap();
        let full = SolveResult::load(dir.path()).unwrap();
        let light = SolveResult::load_solving(dir.path(), &|name| name == "a").unwrap();
        for (l, f) in light.parts.iter().zip(&full.parts) {
            assert_eq!(l.rho, f.rho);
            assert_eq!(l.lobes, f.lobes);
            assert_eq!(l.part.cache.texels.len(), f.part.cache.texels.len());
            assert_eq!(l.part.coverage.pixels, f.part.coverage.pixels);
        }
        let (l, f) = (&light.parts, &full.parts);
        assert_eq!(l[0].weight_sum, f[0].weight_sum);
        assert_eq!(l[0].observations, vec![3; 256]);
        assert_eq!(l[0].stderr, f[0].stderr);
        assert!(l[0].has_statistics() && f[1].has_statistics());
        assert!(l[1].weight_sum.is_empty() && l[1].observations.is_empty());
        assert!(l[1].stderr.is_empty() && f[1].stderr.len() == 256);
    }

    /// A lobe list whose lobe has a negative exponent or colour is refused naming the file and
    /// the lobe (the exporters and the renderer took it as it was); a valid list reads back.
    #[test]
    fn a_lobe_list_with_a_lobe_that_is_none_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let lp = dir.path().join("ground_lobes.json");
        let lobe = |rho: f32, n: f32| Lobe {
            rho: Vec3::splat(rho),
            cxy: -1.0,
            cz: 1.0,
            n,
        };
        let good = vec![lobe(0.2, 30.0), lobe(0.1, 1e6)];
        std::fs::write(&lp, serde_json::to_string(&good).unwrap()).unwrap();
        assert_eq!(read_lobes(&lp).unwrap(), good);
        for bad in [lobe(0.2, -1.0), lobe(-0.1, 30.0)] {
            let list = vec![good[0], bad];
            std::fs::write(&lp, serde_json::to_string(&list).unwrap()).unwrap();
            let e = read_lobes(&lp).unwrap_err().to_string();
            assert!(
                e.contains("ground_lobes.json: lobe 1") && e.contains("invalid"),
                "{e}"
            );
        }
    }

    /// A folder that is not a result, and an atlas of the wrong size, are refused with typed
    /// errors naming the file.
    #[test]
    fn a_wrong_atlas_or_folder_is_a_typed_error() {
        let dir = tempfile::tempdir().unwrap();
        let e = load_result_scene(dir.path()).unwrap_err();
        assert!(
            matches!(&e, ReflectError::NotAResult(p) if p == dir.path()),
            "{e}"
        );
        let parts = build_parts(vec![("a".into(), square(0.0))], 16).unwrap();
        let mut state = SolveResult::fresh(parts, vec!["p".into()], &SolveOptions::default());
        state.report.parts = vec![crate::record::PartSummary::unsolved(&state.parts[0].part)];
        state.write_geometry(dir.path()).unwrap();
        state.write_state(dir.path()).unwrap();
        let weight = dir.path().join("parts/a_weight.exr");
        write_exr(&weight, &HdrImage::new(8, 8)).unwrap();
        match SolveResult::load(dir.path()) {
            Err(ReflectError::AtlasSize {
                path,
                width: 8,
                height: 8,
                expected: 16,
            }) => assert_eq!(path, weight),
            other => panic!("{:?}", other.err()),
        }
    }
}
