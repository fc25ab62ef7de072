//! The result folder of a solve: writing it, resuming from it, re-lighting it (export and
//! sampling read it in `igi-export`).
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

/// The state and result of a solve.
pub struct SolveResult {
    pub parts: Vec<Part>,
    /// Per part, per atlas texel (`row * res + column`): the diffuse albedo.
    pub rho: Vec<Vec<Vec3>>,
    pub weight_sum: Vec<Vec<f32>>,
    pub observations: Vec<Vec<u32>>,
    /// Per part, per atlas texel: the standard error of `rho` per channel, or
    /// [`UNKNOWN_STDERR`] (docs/SOLVER.md derives it from the spread of the weighted proposals
    /// and the Monte-Carlo noise of the rendered radiance).
    pub stderr: Vec<Vec<Vec3>>,
    /// Lobes per part (empty without a BRDF basis).
    pub lobes: Vec<Vec<Lobe>>,
    pub report: SolveReport,
    /// Parts whose albedo changed since the last [`write_state`](Self::write_state) (only
    /// those are rewritten; all after [`fresh`](Self::fresh), none after [`load`](Self::load)).
    pub changed: Vec<bool>,
    /// The BRDF basis the solve infers lobes with (set by `solve`); with it, `write_state`
    /// writes per-texel lobe maps inferred from each texel's albedo.
    pub basis: Option<igi_brdf::Basis>,
}

impl SolveResult {
    /// A fresh state: every texel at the initial albedo.
    pub fn fresh(parts: Vec<Part>, photo_ids: Vec<String>, opts: &SolveOptions) -> SolveResult {
        let init = Vec3::from_array(opts.initial_albedo);
        let rho = parts
            .iter()
            .map(|p| vec![init; p.resolution() * p.resolution()])
            .collect();
        let weight_sum = parts
            .iter()
            .map(|p| vec![0.0; p.resolution() * p.resolution()])
            .collect();
        let observations = parts
            .iter()
            .map(|p| vec![0; p.resolution() * p.resolution()])
            .collect();
        let stderr = parts
            .iter()
            .map(|p| vec![UNKNOWN_STDERR; p.resolution() * p.resolution()])
            .collect();
        let lobes = parts.iter().map(|_| Vec::new()).collect();
        let changed = vec![true; parts.len()];
        let site = parts
            .iter()
            .find_map(|p| p.stored.as_ref().map(|s| s.site.clone()));
        SolveResult {
            parts,
            rho,
            weight_sum,
            observations,
            stderr,
            lobes,
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
            changed,
            basis: None,
        }
    }

    /// Writes the parts' geometry and texel caches (once, at the start of a solve).
    pub fn write_geometry(&self, dir: &Path) -> Result<(), ReflectError> {
        let pdir = dir.join("parts");
        std::fs::create_dir_all(&pdir).map_err(|e| ReflectError::io(&pdir, "create folder", e))?;
        for p in &self.parts {
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
        let store = match self.parts.iter().find_map(|p| p.stored.as_ref()) {
            Some(s) => Some(igi_geometry::SiteStore::open(&s.site)?),
            None => None,
        };
        let mut scene = SceneFile::default();
        for (i, p) in self.parts.iter().enumerate() {
            let r = p.resolution();
            let img = |f: &dyn Fn(usize) -> [f32; 3]| {
                let mut im = HdrImage::new(r, r);
                for (k, px) in im.pixels.iter_mut().enumerate() {
                    *px = f(k);
                }
                im
            };
            if self.changed.get(i).copied().unwrap_or(true) {
                assert_eq!(
                    self.weight_sum[i].len(),
                    r * r,
                    "part {}: loaded without its statistics (load_solving), it cannot be written",
                    p.name
                );
                write_exr(
                    &pdir.join(format!("{}_rho_d.exr", p.name)),
                    &img(&|k| self.rho[i][k].to_array()),
                )?;
                write_exr(
                    &pdir.join(format!("{}_weight.exr", p.name)),
                    &img(&|k| [self.weight_sum[i][k]; 3]),
                )?;
                write_exr(
                    &pdir.join(format!("{}_observations.exr", p.name)),
                    &img(&|k| [self.observations[i][k] as f32; 3]),
                )?;
                write_exr(
                    &pdir.join(format!("{}_stderr.exr", p.name)),
                    &img(&|k| self.stderr[i][k].to_array()),
                )?;
                if !self.lobes[i].is_empty() {
                    let json =
                        serde_json::to_string_pretty(&self.lobes[i]).expect("lobes serialise");
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
            return Err(ReflectError::file(
                dir,
                "a solve was killed while committing a checkpoint; run the same `igi solve` again to finish it",
            ));
        }
        let rp = dir.join("report.json");
        let text = std::fs::read_to_string(&rp).map_err(|e| ReflectError::io(&rp, "read", e))?;
        let report: SolveReport =
            serde_json::from_str(&text).map_err(|e| ReflectError::json(&rp, "solve report", e))?;
        let pdir = dir.join("parts");
        let mut parts = Vec::new();
        let (mut rho, mut weight_sum, mut observations, mut stderr, mut lobes) =
            (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for s in &report.parts {
            let p = StoredPart::read(&pdir, s, solving(&s.name))?;
            rho.push(p.rho);
            weight_sum.push(p.weight_sum);
            observations.push(p.observations);
            stderr.push(p.stderr);
            lobes.push(p.lobes);
            parts.push(p.part);
        }
        let changed = vec![false; parts.len()];
        Ok(SolveResult {
            parts,
            rho,
            weight_sum,
            observations,
            stderr,
            lobes,
            report,
            changed,
            basis: None,
        })
    }
}

/// One part of a result folder as read back from `parts/`.
struct StoredPart {
    part: Part,
    rho: Vec<Vec3>,
    weight_sum: Vec<f32>,
    observations: Vec<u32>,
    stderr: Vec<Vec3>,
    lobes: Vec<Lobe>,
}

impl StoredPart {
    /// Reads the part `s` of the report from the result's `parts/` folder `pdir`: its geometry
    /// ([`read_part`]), albedo, lobes and, when `solving`, its weight, observation and
    /// standard-error atlases (otherwise empty); every atlas must have the coverage's size.
    fn read(
        pdir: &Path,
        s: &crate::record::PartSummary,
        solving: bool,
    ) -> Result<StoredPart, ReflectError> {
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
        Ok(StoredPart {
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
        return Err(ReflectError::file(
            &path,
            format!("is {}x{}, expected {r}x{r}", im.width, im.height),
        ));
    }
    Ok(im)
}

/// A part's `NAME_lobes.json`; no lobes when the file does not exist.
fn read_lobes(lp: &Path) -> Result<Vec<Lobe>, ReflectError> {
    if !lp.exists() {
        return Ok(Vec::new());
    }
    let t = std::fs::read_to_string(lp).map_err(|e| ReflectError::io(lp, "read", e))?;
    serde_json::from_str(&t).map_err(|e| ReflectError::json(lp, "lobe list", e))
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
        let name = &self.parts[i].name;
        let lobe_maps: Vec<LobeMapEntry> = (0..per_texel)
            .map(|k| LobeMapEntry {
                rho: format!("{maps}{name}_lobe{k}_rho.exr").into(),
                shape: format!("{maps}{name}_lobe{k}_shape.exr").into(),
            })
            .collect();
        let lobes = if per_texel > 0 {
            Vec::new()
        } else {
            self.lobes[i]
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
        let per: Vec<Vec<Lobe>> = self.rho[i]
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

pub(crate) fn write_text(path: &Path, text: &str) -> Result<(), ReflectError> {
    Ok(igi_files::write_text_atomic(path, text)?)
}

/// The scene file of a result folder (for `igi render RESULT_DIR --lighting ...`).
pub fn load_result_scene(dir: &Path) -> Result<PathBuf, ReflectError> {
    let p = dir.join("scene.toml");
    if !p.is_file() || !dir.join("report.json").is_file() {
        return Err(ReflectError::file(
            dir,
            "not a solve result folder (no scene.toml and report.json)",
        ));
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
        for (i, rho) in state.rho.iter_mut().enumerate() {
            rho.iter_mut()
                .enumerate()
                .for_each(|(k, v)| *v = Vec3::splat((i * 256 + k) as f32 / 600.0));
        }
        state.weight_sum[0] = vec![1.5; 256];
        state.observations[0] = vec![3; 256];
        state.report.parts = state
            .parts
            .iter()
            .map(crate::record::PartSummary::unsolved)
            .collect();
        state.write_geometry(dir.path()).unwrap();
        state.write_state(dir.path()).unwrap();
        let full = SolveResult::load(dir.path()).unwrap();
        let light = SolveResult::load_solving(dir.path(), &|name| name == "a").unwrap();
        assert_eq!(light.rho, full.rho);
        assert_eq!(light.lobes, full.lobes);
        assert_eq!(light.weight_sum[0], full.weight_sum[0]);
        assert_eq!(light.observations[0], vec![3; 256]);
        assert_eq!(light.stderr[0], full.stderr[0]);
        assert!(light.weight_sum[1].is_empty() && light.observations[1].is_empty());
        assert!(light.stderr[1].is_empty() && full.stderr[1].len() == 256);
        for (l, f) in light.parts.iter().zip(&full.parts) {
            assert_eq!(l.cache.texels.len(), f.cache.texels.len());
            assert_eq!(l.coverage.pixels, f.coverage.pixels);
        }
    }
}
