//! The `SLF_DIR/` folder (FORMATS.md, "Surface light field folder"): `header.json`, the atlas
//! mesh `mesh.ply`, per-grid-point arrays (`texels.bin` u32, `normals.bin` f32 x 3, `median.bin`
//! RGB8 with a scale), the coding (`lumispheres.bin` RGB8 per vertex with an offset and scale,
//! or `prototypes.bin` + `coefficients.bin` u8 per prototype, or `codebook.bin` +
//! `indices.bin` u16/u32; prototypes and codewords RGB8 per vertex like the faired lumispheres,
//! or f32 in folders of earlier builds, [`Header::vectors`]) and `report.json` with the byte
//! counts. All little endian. The folder is written under a temporary name and renamed, so it
//! is never half-written.

use crate::field::{Coding, SurfaceLightField};
use crate::lumisphere::{AngleGain, Octahedron};
use crate::pfa::Pfa;
use crate::quantize::Codebook;
use crate::LightFieldError;
use glam::Vec3;
use igi_geometry::TriMesh;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

/// The `format` of `header.json`.
pub const FORMAT: &str = "igi-slf";

/// `header.json`.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Header {
    pub format: String,
    pub version: u32,
    pub method: String,
    pub level: u32,
    pub resolution: usize,
    pub points: usize,
    /// Subspace dimension (PFA) or codebook size (FQ); 0 otherwise.
    pub q: usize,
    pub codewords: usize,
    pub median_scale: f32,
    /// Offset and scale of every RGB8 lumisphere value (faired lumispheres, prototypes,
    /// codewords): `value = offset + byte / 255 * scale`.
    pub lumisphere_offset: f32,
    pub lumisphere_scale: f32,
    /// How `prototypes.bin` and `codebook.bin` hold their lumisphere values (absent in the
    /// headers of earlier builds, which stored them as f32).
    #[serde(default)]
    pub vectors: VectorEncoding,
    /// The view-angle gain's knots (`AngleGain`: at n . w evenly spaced on [0, 1]); absent in
    /// the headers of earlier builds (no gain: 1 everywhere).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub angle_gain: Vec<f32>,
}

/// The encoding of the lumispheres of `prototypes.bin` and `codebook.bin`.
#[derive(Clone, Copy, Debug, Default, Serialize, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum VectorEncoding {
    /// Three little-endian f32 per vertex (folders of earlier builds).
    #[default]
    F32,
    /// Three bytes per vertex with the header's lumisphere offset and scale (written now).
    Rgb8,
}

/// Byte counts of the stored folder (`report.json`).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct StoreReport {
    pub files: BTreeMap<String, u64>,
    /// Median texture plus the lumisphere coding.
    pub colour_bytes: u64,
    /// Mesh, texel indices, normals.
    pub geometry_bytes: u64,
    /// Pointwise-faired RGB8 lumispheres of the same points (points x N_s x 3).
    pub faired_rgb8_bytes: u64,
    /// faired_rgb8_bytes / colour_bytes.
    pub compression_ratio: f64,
    /// Anything the caller adds (gather report, timings, PSNR).
    pub extra: serde_json::Value,
}

fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> LightFieldError + '_ {
    move |source| LightFieldError::Io {
        path: path.to_path_buf(),
        source,
    }
}

fn q8(x: f32, lo: f32, scale: f32) -> u8 {
    if !(scale > 0.0) {
        return 0;
    }
    ((x - lo) / scale * 255.0).round().clamp(0.0, 255.0) as u8
}

fn dq8(b: u8, lo: f32, scale: f32) -> f32 {
    lo + b as f32 / 255.0 * scale
}

fn f32_bytes(v: impl Iterator<Item = f32>) -> Vec<u8> {
    v.flat_map(|x| x.to_le_bytes()).collect()
}

/// Checks, before any work, that `dir` may receive a field: absent, empty, or an earlier
/// `SLF_DIR` (which [`save`] replaces); anything else is refused rather than deleted.
pub fn check_output(dir: &Path) -> Result<(), LightFieldError> {
    if !dir.exists() {
        return Ok(());
    }
    let refuse = |msg: &str| LightFieldError::Format {
        path: dir.to_path_buf(),
        msg: msg.into(),
    };
    if !dir.is_dir() {
        return Err(refuse("exists and is not a folder"));
    }
    let mut entries = std::fs::read_dir(dir).map_err(io_err(dir))?;
    if entries.next().is_none() {
        return Ok(());
    }
    let header = std::fs::read_to_string(dir.join("header.json")).unwrap_or_default();
    match serde_json::from_str::<Header>(&header) {
        Ok(h) if h.format == FORMAT => Ok(()),
        _ => Err(refuse(
            "holds files but no surface light field (header.json); refusing to replace it: choose a new folder",
        )),
    }
}

/// Saves the field and its atlas mesh to `dir` (replacing it). `extra` goes into report.json.
pub fn save(
    dir: &Path,
    field: &SurfaceLightField,
    mesh: &TriMesh,
    extra: serde_json::Value,
) -> Result<StoreReport, LightFieldError> {
    let staging = igi_files::Staging::begin(dir)?;
    check_output(dir)?;
    save_staged(staging, field, mesh, extra)
}

/// [`save`] through a staging folder claimed before the work (`igi_files::Staging`: the
/// output's lock, a staging name of this process, dead runs' staging removed), renamed into
/// place at the end; an earlier field there is replaced.
pub fn save_staged(
    staging: igi_files::Staging,
    field: &SurfaceLightField,
    mesh: &TriMesh,
    extra: serde_json::Value,
) -> Result<StoreReport, LightFieldError> {
    let tmp = staging.path().to_path_buf();
    let (header, files) = encode(field);
    let mut sizes = BTreeMap::new();
    for (name, bytes) in &files {
        let p = tmp.join(name);
        std::fs::write(&p, bytes).map_err(io_err(&p))?;
        sizes.insert(name.clone(), bytes.len() as u64);
    }
    let hp = tmp.join("header.json");
    std::fs::write(&hp, serde_json::to_string_pretty(&header).expect("header"))
        .map_err(io_err(&hp))?;
    igi_geometry::write_ply(&tmp.join("mesh.ply"), mesh)?;
    sizes.insert(
        "mesh.ply".into(),
        std::fs::metadata(tmp.join("mesh.ply"))
            .map_err(io_err(&hp))?
            .len(),
    );
    let report = report(field, &sizes, extra);
    let rp = tmp.join("report.json");
    std::fs::write(&rp, serde_json::to_string_pretty(&report).expect("report"))
        .map_err(io_err(&rp))?;
    // check_output let only an earlier field (or an empty folder) stand there
    staging.commit(true)?;
    Ok(report)
}

fn report(
    field: &SurfaceLightField,
    sizes: &BTreeMap<String, u64>,
    extra: serde_json::Value,
) -> StoreReport {
    let geometry = ["mesh.ply", "texels.bin", "normals.bin"];
    let geometry_bytes = sizes
        .iter()
        .filter(|(k, _)| geometry.contains(&k.as_str()))
        .map(|(_, v)| v)
        .sum();
    let colour_bytes = sizes
        .iter()
        .filter(|(k, _)| !geometry.contains(&k.as_str()))
        .map(|(_, v)| v)
        .sum::<u64>();
    let faired = (field.texels.len() * field.oct.len() * 3) as u64;
    StoreReport {
        files: sizes.clone(),
        colour_bytes,
        geometry_bytes,
        faired_rgb8_bytes: faired,
        compression_ratio: faired as f64 / colour_bytes.max(1) as f64,
        extra,
    }
}

/// The header and the binary files of a field.
fn encode(f: &SurfaceLightField) -> (Header, Vec<(String, Vec<u8>)>) {
    let median_scale = f
        .median
        .iter()
        .map(|m| m.max_element())
        .fold(0.0f32, f32::max)
        .max(1e-12);
    let mut files = vec![
        (
            "texels.bin".to_string(),
            f.texels.iter().flat_map(|t| t.to_le_bytes()).collect(),
        ),
        (
            "normals.bin".to_string(),
            f32_bytes(f.normal.iter().flat_map(|n| n.to_array())),
        ),
        (
            "median.bin".to_string(),
            f.median
                .iter()
                .flat_map(|m| m.to_array().map(|x| q8(x, 0.0, median_scale)))
                .collect(),
        ),
    ];
    let mut h = Header {
        format: FORMAT.into(),
        version: 1,
        method: f.coding.name().into(),
        level: f.oct.level,
        resolution: f.resolution,
        points: f.texels.len(),
        q: 0,
        codewords: 0,
        median_scale,
        lumisphere_offset: 0.0,
        lumisphere_scale: 0.0,
        vectors: VectorEncoding::Rgb8,
        angle_gain: f.gain.knots.clone(),
    };
    encode_coding(&f.coding, &mut h, &mut files);
    (h, files)
}

/// The coding's binary files, and its numbers in the header.
fn encode_coding(coding: &Coding, h: &mut Header, files: &mut Vec<(String, Vec<u8>)>) {
    match coding {
        Coding::MedianOnly => {}
        Coding::Faired(l) => files.push(("lumispheres.bin".into(), rgb8_lumispheres(l, h))),
        Coding::Pfa(p) => {
            h.q = p.prototypes.len() - 1;
            files.push(("prototypes.bin".into(), rgb8_lumispheres(&p.prototypes, h)));
            files.push((
                "coefficients.bin".into(),
                p.coefficients
                    .iter()
                    .flatten()
                    .map(|a| q8(*a, 0.0, 1.0))
                    .collect(),
            ));
        }
        Coding::Quantized(c) => {
            h.codewords = c.codewords.len();
            files.push(("codebook.bin".into(), rgb8_lumispheres(&c.codewords, h)));
            let idx: Vec<u8> = if c.codewords.len() <= 1 << 16 {
                c.index
                    .iter()
                    .flat_map(|i| (*i as u16).to_le_bytes())
                    .collect()
            } else {
                c.index.iter().flat_map(|i| i.to_le_bytes()).collect()
            };
            files.push(("indices.bin".into(), idx));
        }
    }
}

/// Lumispheres as RGB8 per vertex over their whole range (from at most 0 to at least 0), the
/// offset and scale written into the header.
fn rgb8_lumispheres(l: &[Vec<Vec3>], h: &mut Header) -> Vec<u8> {
    let values = || l.iter().flatten();
    let lo = values().map(|v| v.min_element()).fold(0.0f32, f32::min);
    let hi = values().map(|v| v.max_element()).fold(0.0f32, f32::max);
    h.lumisphere_offset = lo;
    h.lumisphere_scale = hi - lo;
    values()
        .flat_map(|v| v.to_array().map(|x| q8(x, lo, hi - lo)))
        .collect()
}

/// The file `name` of `dir`, which must hold `want` bytes (a `u128`, so that a header's counts
/// cannot overflow the product).
fn read(dir: &Path, name: &str, want: u128) -> Result<Vec<u8>, LightFieldError> {
    let p = dir.join(name);
    let b = std::fs::read(&p).map_err(io_err(&p))?;
    if b.len() as u128 != want {
        return Err(LightFieldError::Format {
            path: p,
            msg: format!("{} bytes, expected {want}", b.len()),
        });
    }
    Ok(b)
}

/// [`vec3s`] of file `name` of `dir`, every component finite.
fn finite_vec3s(dir: &Path, name: &str, b: &[u8]) -> Result<Vec<Vec3>, LightFieldError> {
    let v = vec3s(b);
    match v.iter().position(|x| !x.is_finite()) {
        None => Ok(v),
        Some(i) => Err(LightFieldError::Format {
            path: dir.join(name),
            msg: format!("value {i} is {} (not finite)", v[i]),
        }),
    }
}

fn vec3s(b: &[u8]) -> Vec<Vec3> {
    b.chunks(12)
        .map(|c| {
            Vec3::from_array([0, 4, 8].map(|o| f32::from_le_bytes(c[o..o + 4].try_into().unwrap())))
        })
        .collect()
}

/// Loads a field and its mesh from `dir` (the stored, 8-bit quantised values).
pub fn load(dir: &Path) -> Result<(SurfaceLightField, TriMesh), LightFieldError> {
    let hp = dir.join("header.json");
    let h = read_header(&hp)?;
    let oct = Octahedron::new(h.level);
    let (p, n) = (h.points as u128, oct.len());
    let texels: Vec<u32> = read(dir, "texels.bin", 4 * p)?
        .chunks(4)
        .map(|c| u32::from_le_bytes(c.try_into().unwrap()))
        .collect();
    if let Some(t) = texels
        .iter()
        .find(|t| **t as usize >= h.resolution * h.resolution)
    {
        return Err(LightFieldError::Format {
            path: dir.join("texels.bin"),
            msg: format!("texel {t} outside the {0} x {0} atlas", h.resolution),
        });
    }
    let normal = finite_vec3s(dir, "normals.bin", &read(dir, "normals.bin", 12 * p)?)?;
    let median = read(dir, "median.bin", 3 * p)?
        .chunks(3)
        .map(|c| Vec3::from_array([0, 1, 2].map(|k| dq8(c[k], 0.0, h.median_scale))))
        .collect();
    let coding = match h.method.as_str() {
        "median" => Coding::MedianOnly,
        "fair" => read_faired(dir, &h, n)?,
        "pfa" => read_pfa(dir, &h, n)?,
        "fq" => read_quantized(dir, &h, n)?,
        m => {
            return Err(LightFieldError::Format {
                path: hp,
                msg: format!("unknown method {m:?}"),
            })
        }
    };
    let mesh = igi_geometry::read_mesh(&dir.join("mesh.ply"))?;
    Ok((
        SurfaceLightField::new(oct, h.resolution, texels, median, normal, coding).with_gain(
            AngleGain {
                knots: h.angle_gain.clone(),
            },
        ),
        mesh,
    ))
}

/// Read and check `header.json`.
fn read_header(hp: &Path) -> Result<Header, LightFieldError> {
    let text = std::fs::read_to_string(hp).map_err(io_err(hp))?;
    let h: Header = serde_json::from_str(&text).map_err(|e| LightFieldError::Format {
        path: hp.to_path_buf(),
        msg: e.to_string(),
    })?;
    if h.format != FORMAT || h.version != 1 || h.level > 6 {
        return Err(LightFieldError::Format {
            path: hp.to_path_buf(),
            msg: format!(
                "not an igi-slf version 1 header (format {:?}, version {}, level {})",
                h.format, h.version, h.level
            ),
        });
    }
    if h.angle_gain.len() == 1 || h.angle_gain.iter().any(|g| !(g.is_finite() && *g > 0.0)) {
        return Err(LightFieldError::Format {
            path: hp.to_path_buf(),
            msg: format!(
                "angle_gain must be absent or at least 2 positive finite knots, not {:?}",
                h.angle_gain
            ),
        });
    }
    check_counts(&h).map_err(|msg| LightFieldError::Format {
        path: hp.to_path_buf(),
        msg,
    })?;
    igi_files::check_alloc_default(
        &format!(
            "the texel lookup of {} (resolution {})",
            hp.display(),
            h.resolution
        ),
        (h.resolution as u128).saturating_pow(2).saturating_mul(8),
    )?;
    Ok(h)
}

/// The largest stored value a field may hold (a median, a lumisphere value, their sum times
/// the view-angle gain): far above any radiance, far below `f32::MAX`, so that rendering
/// cannot overflow.
const LARGEST_VALUE: f32 = 1e30;

/// The largest knot of the header's view-angle gain (1 without one).
fn largest_gain(h: &Header) -> f32 {
    h.angle_gain.iter().copied().fold(1.0f32, f32::max)
}

/// What the header's counts and scales must be for its arrays to mean a field: an atlas with
/// room for its points, one coding's counts, scales whose values stay finite when rendered.
fn check_counts(h: &Header) -> Result<(), String> {
    if h.resolution == 0 || h.points as u128 > (h.resolution as u128).saturating_pow(2) {
        return Err(format!(
            "{} points do not fit a {} x {} atlas",
            h.points, h.resolution, h.resolution
        ));
    }
    match h.method.as_str() {
        "pfa" if !(1..=u32::MAX as usize).contains(&h.q) => {
            return Err(format!("PFA needs q in 1..={} (got {})", u32::MAX, h.q))
        }
        "fq" if !(1..=u32::MAX as usize).contains(&h.codewords) => {
            return Err(format!(
                "a codebook needs 1..={} codewords (got {})",
                u32::MAX,
                h.codewords
            ))
        }
        _ => {}
    }
    for (name, scale) in [
        ("median_scale", h.median_scale),
        ("lumisphere_scale", h.lumisphere_scale),
    ] {
        if !(scale >= 0.0) {
            return Err(format!("{name} {scale} is not a scale (at least 0)"));
        }
    }
    let gain = largest_gain(h);
    let largest = (h.median_scale + h.lumisphere_offset.abs() + h.lumisphere_scale) * gain;
    if !(largest <= LARGEST_VALUE) {
        return Err(format!(
            "its values reach {largest:e} (median_scale + |lumisphere_offset| + lumisphere_scale, \
             times the largest angle_gain {gain}), above {LARGEST_VALUE:e}"
        ));
    }
    Ok(())
}

/// The faired lumispheres of `h.points` points with `n` directions each.
fn read_faired(dir: &Path, h: &Header, n: usize) -> Result<Coding, LightFieldError> {
    let l = read_lumispheres(dir, "lumispheres.bin", h, VectorEncoding::Rgb8, n, h.points)?;
    Ok(Coding::Faired(l))
}

/// `count` lumispheres of `n` vertices from file `name`, in `encoding`.
fn read_lumispheres(
    dir: &Path,
    name: &str,
    h: &Header,
    encoding: VectorEncoding,
    n: usize,
    count: usize,
) -> Result<Vec<Vec<Vec3>>, LightFieldError> {
    let values: Vec<Vec3> = match encoding {
        VectorEncoding::F32 => {
            let values = finite_vec3s(dir, name, &read(dir, name, 12 * (n * count) as u128)?)?;
            let limit = LARGEST_VALUE / largest_gain(h);
            if let Some(v) = values.iter().find(|v| !(v.abs().max_element() <= limit)) {
                return Err(LightFieldError::Format {
                    path: dir.join(name),
                    msg: format!("lumisphere value {v} beyond +-{limit:e} (the gain times it would overflow)"),
                });
            }
            values
        }
        VectorEncoding::Rgb8 => read(dir, name, 3 * (n * count) as u128)?
            .chunks(3)
            .map(|c| {
                Vec3::from_array(
                    [0, 1, 2].map(|k| dq8(c[k], h.lumisphere_offset, h.lumisphere_scale)),
                )
            })
            .collect(),
    };
    Ok(values.chunks(n).map(|c| c.to_vec()).collect())
}

/// The principal-function prototypes and each point's coefficients (normalised to sum 1).
fn read_pfa(dir: &Path, h: &Header, n: usize) -> Result<Coding, LightFieldError> {
    let k = h.q + 1;
    let protos = read_lumispheres(dir, "prototypes.bin", h, h.vectors, n, k)?;
    let coefficients = read(dir, "coefficients.bin", (k * h.points) as u128)?
        .chunks(k)
        .map(|c| {
            let s: f32 = c.iter().map(|b| *b as f32).sum::<f32>().max(1.0);
            c.iter().map(|b| *b as f32 / s).collect()
        })
        .collect();
    Ok(Coding::Pfa(Pfa {
        prototypes: protos,
        coefficients,
        energy_history: Vec::new(),
    }))
}

/// The codebook and each point's codeword index (16-bit unless there are more than 2^16).
fn read_quantized(dir: &Path, h: &Header, n: usize) -> Result<Coding, LightFieldError> {
    let k = h.codewords;
    let codewords = read_lumispheres(dir, "codebook.bin", h, h.vectors, n, k)?;
    let wide = k > 1 << 16;
    let b = read(
        dir,
        "indices.bin",
        (if wide { 4 } else { 2 }) * h.points as u128,
    )?;
    let index: Vec<u32> = if wide {
        b.chunks(4)
            .map(|c| u32::from_le_bytes(c.try_into().unwrap()))
            .collect()
    } else {
        b.chunks(2)
            .map(|c| u16::from_le_bytes([c[0], c[1]]) as u32)
            .collect()
    };
    if index.iter().any(|i| *i as usize >= k) {
        return Err(LightFieldError::Format {
            path: dir.join("indices.bin"),
            msg: "codeword index out of range".into(),
        });
    }
    Ok(Coding::Quantized(Codebook { codewords, index }))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A field of three grid points on a 4 x 4 atlas, with lumisphere values in [-0.4, 2.6].
    fn field(coding: Coding) -> SurfaceLightField {
        let oct = Octahedron::new(1);
        let median = vec![Vec3::new(0.2, 0.3, 0.4); 3];
        let normal = vec![Vec3::Z; 3];
        SurfaceLightField::new(oct, 4, vec![0, 5, 15], median, normal, coding)
    }

    fn lumispheres(count: usize, n: usize) -> Vec<Vec<Vec3>> {
        (0..count)
            .map(|k| {
                (0..n)
                    .map(|i| {
                        let x = (k * n + i) as f32 / (count * n) as f32;
                        Vec3::new(-0.4 + 3.0 * x, 1.0 - x, 0.5 * x)
                    })
                    .collect()
            })
            .collect()
    }

    fn mesh() -> TriMesh {
        TriMesh {
            positions: vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            uvs: Some(vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]),
            indices: vec![[0, 1, 2]],
            ..TriMesh::default()
        }
    }

    fn stored_vectors(f: &SurfaceLightField) -> Vec<Vec<Vec3>> {
        match &f.coding {
            Coding::Pfa(p) => p.prototypes.clone(),
            Coding::Quantized(c) => c.codewords.clone(),
            _ => unreachable!(),
        }
    }

    fn max_difference(a: &[Vec<Vec3>], b: &[Vec<Vec3>]) -> f32 {
        assert_eq!(a.len(), b.len());
        a.iter()
            .flatten()
            .zip(b.iter().flatten())
            .map(|(x, y)| (*x - *y).abs().max_element())
            .fold(0.0, f32::max)
    }

    /// Prototypes and codewords are stored as RGB8 over their range (about 3): within half a
    /// step of it / 255, at a quarter of the f32 bytes.
    #[test]
    fn prototypes_and_codewords_round_trip_as_rgb8() {
        let n = Octahedron::new(1).len();
        let codings = [
            Coding::Pfa(Pfa {
                prototypes: lumispheres(3, n),
                coefficients: vec![vec![0.2, 0.3, 0.5]; 3],
                energy_history: Vec::new(),
            }),
            Coding::Quantized(Codebook {
                codewords: lumispheres(4, n),
                index: vec![3, 0, 2],
            }),
        ];
        for coding in codings {
            let dir = tempfile::tempdir().unwrap();
            let out = dir.path().join("slf");
            let f = field(coding);
            let report = save(&out, &f, &mesh(), serde_json::json!({})).unwrap();
            let h = read_header(&out.join("header.json")).unwrap();
            assert_eq!(h.vectors, VectorEncoding::Rgb8);
            let (lo, scale) = (h.lumisphere_offset, h.lumisphere_scale);
            assert!(
                (lo + 0.4).abs() < 1e-6 && scale > 2.9 && scale < 3.0,
                "{lo} {scale}"
            );
            let name = if h.q > 0 {
                "prototypes.bin"
            } else {
                "codebook.bin"
            };
            let count = stored_vectors(&f).len();
            assert_eq!(report.files[name], (3 * n * count) as u64);
            let (loaded, _) = load(&out).unwrap();
            let err = max_difference(&stored_vectors(&f), &stored_vectors(&loaded));
            assert!(err <= 0.5 * scale / 255.0 + 1e-5, "{name}: {err}");
            assert!(err > 0.0, "{name}: RGB8 cannot hold these values exactly");
        }
    }

    /// The view-angle gain is kept exactly; a folder without one (earlier builds) loads with
    /// none, and a header with a bad one is refused by name.
    #[test]
    fn the_angle_gain_round_trips_and_a_bad_one_is_refused() {
        let gain = AngleGain {
            knots: vec![4.5, 3.0, 1.25, 1.0],
        };
        let f = field(Coding::MedianOnly).with_gain(gain.clone());
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("slf");
        save(&out, &f, &mesh(), serde_json::json!({})).unwrap();
        assert_eq!(load(&out).unwrap().0.gain, gain);
        let hp = out.join("header.json");
        let mut header: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&hp).unwrap()).unwrap();
        header.as_object_mut().unwrap().remove("angle_gain");
        std::fs::write(&hp, header.to_string()).unwrap();
        assert_eq!(load(&out).unwrap().0.gain, AngleGain::default());
        for bad in [serde_json::json!([1.0]), serde_json::json!([1.0, -2.0])] {
            header["angle_gain"] = bad;
            std::fs::write(&hp, header.to_string()).unwrap();
            let err = load(&out).unwrap_err().to_string();
            assert!(
                err.contains("header.json") && err.contains("angle_gain"),
                "{err}"
            );
        }
    }

    /// Headers whose counts overflowed the byte counts (a panic in a debug build, a wrong
    /// "expected" size in a release one), asked for an atlas lookup beyond memory, or scaled
    /// values past f32, and a non-finite normal: each refused, naming the file and the field.
    #[test]
    fn headers_that_cannot_mean_a_field_are_refused_naming_the_field() {
        let n = Octahedron::new(1).len();
        let f = field(Coding::Pfa(Pfa {
            prototypes: lumispheres(3, n),
            coefficients: vec![vec![0.2, 0.3, 0.5]; 3],
            energy_history: Vec::new(),
        }));
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("slf");
        save(&out, &f, &mesh(), serde_json::json!({})).unwrap();
        let hp = out.join("header.json");
        let good = std::fs::read_to_string(&hp).unwrap();
        let header: serde_json::Value = serde_json::from_str(&good).unwrap();
        use serde_json::json;
        for (key, value, says) in [
            (
                "points",
                json!(1u64 << 62),
                "points do not fit a 4 x 4 atlas",
            ),
            ("points", json!(17), "points do not fit a 4 x 4 atlas"),
            ("resolution", json!(0), "do not fit a 0 x 0 atlas"),
            ("resolution", json!(u64::MAX), "the texel lookup"),
            ("resolution", json!(1u64 << 16), "IGI_MAX_MEMORY"),
            ("q", json!(u64::MAX), "PFA needs q"),
            ("q", json!(0), "PFA needs q"),
            (
                "median_scale",
                json!(-1.0),
                "median_scale -1 is not a scale",
            ),
            ("lumisphere_scale", json!(3e38), "its values reach"),
            ("angle_gain", json!([1e37, 1.0]), "largest angle_gain"),
        ] {
            let mut h = header.clone();
            h[key] = value;
            std::fs::write(&hp, h.to_string()).unwrap();
            let err = with_sources(load(&out).unwrap_err());
            assert!(
                err.contains("header.json") && err.contains(says),
                "{key}: {err}"
            );
        }
        std::fs::write(&hp, &good).unwrap();
        assert!(load(&out).is_ok());
        let np = out.join("normals.bin");
        let mut normals = std::fs::read(&np).unwrap();
        normals[12..16].copy_from_slice(&f32::NAN.to_le_bytes());
        std::fs::write(&np, normals).unwrap();
        let err = load(&out).unwrap_err().to_string();
        assert!(
            err.contains("normals.bin") && err.contains("value 1"),
            "{err}"
        );
    }

    /// An error and its sources, as the command line prints them.
    fn with_sources(e: LightFieldError) -> String {
        let mut text = e.to_string();
        let mut source = std::error::Error::source(&e);
        while let Some(s) = source {
            text += &format!(": {s}");
            source = s.source();
        }
        text
    }

    /// A folder of an earlier build (f32 codebook, no `vectors` in the header) still loads,
    /// exactly.
    #[test]
    fn an_f32_codebook_of_an_earlier_build_loads() {
        let n = Octahedron::new(1).len();
        let codewords = lumispheres(2, n);
        let f = field(Coding::Quantized(Codebook {
            codewords: codewords.clone(),
            index: vec![1, 0, 1],
        }));
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("slf");
        save(&out, &f, &mesh(), serde_json::json!({})).unwrap();
        let hp = out.join("header.json");
        let mut header: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&hp).unwrap()).unwrap();
        header.as_object_mut().unwrap().remove("vectors");
        std::fs::write(&hp, header.to_string()).unwrap();
        let bytes = f32_bytes(codewords.iter().flatten().flat_map(|v| v.to_array()));
        std::fs::write(out.join("codebook.bin"), bytes).unwrap();
        let (loaded, _) = load(&out).unwrap();
        assert_eq!(stored_vectors(&loaded), codewords);
        // The same f32 file under an RGB8 header is the wrong size, named.
        header["vectors"] = "rgb8".into();
        std::fs::write(&hp, header.to_string()).unwrap();
        let err = load(&out).unwrap_err().to_string();
        assert!(
            err.contains("codebook.bin") && err.contains("expected"),
            "{err}"
        );
    }
}
