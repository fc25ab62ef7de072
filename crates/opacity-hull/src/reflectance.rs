//! The surface reflectance field (Matusik et al. 2002, Sec. 5 and 6): per view, the light
//! images (the object under one distant light of unit irradiance at a time) kept only in the
//! 8 x 8 blocks that surfels project into, compressed by PCA across the lights, and relit by
//! Eq. 3 on the coefficients.
//!
//! * **Blocks:** a block is kept when a surfel visible in the view projects into it, counting
//!   the four pixels its bilinear sample reads (so every sample the renderer takes is stored).
//!   Blocks at the right and bottom edges may be narrower than 8.
//! * **PCA:** per block, the `L x n` matrix of the `L` light images' values (`n` = pixels x 3
//!   channels) is decomposed by SVD (nalgebra, f64). The stored components are the principal
//!   directions about the origin: no mean is subtracted, since a mean costs as many numbers as
//!   a component and the best rank-(k+1) fit through the origin is never worse than a mean plus
//!   k components. A component stores `n` basis values and `L` coefficients (`U S`).
//! * **Ranks (a global budget, as the paper):** the squared reconstruction error of a block at
//!   rank k is the sum of its squared singular values beyond k. Components of all blocks of all
//!   views are taken greedily by error removed per stored number (the next squared singular
//!   value over `n + L`) until the total squared error is within the budget
//!   `N (target x mean)^2`, `N` the number of kept values and `mean` their mean: the RMS
//!   reconstruction error over all kept values is at most `target` (1 %) of the mean radiance.
//!   A first pass computes only the singular values (one view's light images in memory at a
//!   time), a second recomputes each block's SVD and truncates it; the achieved RMS is measured
//!   on the stored f32 numbers.
//! * **Relighting (Eq. 3):** `image = sum_i weight_i * image_i`; per block and channel
//!   `a_k = sum_i weight_i c_ik` first, then `value_j = sum_k basis_kj a_k`.
//! * **Storage:** `HULL_DIR/reflectance/reflectance.json` (header: views, light directions,
//!   sizes, the numbers below) and `reflectance/ID.bin` per view: little-endian, magic
//!   `IGIRFLD1`, u32 width, height, lights, blocks, then per block u32 bx, by, rank,
//!   `rank x lights` f32 coefficients (component-major), `rank x n` f32 basis values
//!   (component-major, pixel row-major, RGB).

use crate::surfel::Surfels;
use crate::views::View;
use crate::HullError;
use glam::DVec3;
use igi_camera::rig::{Rig, RigView};
use igi_formats::rig::is_light_direction;
use igi_imaging::{read_image, HdrImage};
use nalgebra::DMatrix;
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// Block side in pixels.
pub const BLOCK: usize = 8;
/// The folder inside a hull folder.
pub const FOLDER: &str = "reflectance";
/// The header's file name inside [`FOLDER`].
pub const HEADER: &str = "reflectance.json";
const MAGIC: &[u8; 8] = b"IGIRFLD1";
const FORMAT: &str = "igi-reflectance-1";

/// Options of the PCA.
#[derive(Clone, Copy, Debug)]
pub struct FieldOptions {
    /// RMS reconstruction error over all kept values, as a fraction of their mean (the paper 1%).
    pub target_relative_rms: f64,
}

impl Default for FieldOptions {
    fn default() -> Self {
        FieldOptions {
            target_relative_rms: 0.01,
        }
    }
}

/// One kept block: its place and its truncated SVD across the lights.
#[derive(Clone, Debug, PartialEq)]
pub struct Block {
    /// Block column and row (pixel x = 8 bx, y = 8 by).
    pub bx: u32,
    pub by: u32,
    pub rank: u32,
    /// `coefficients[k * lights + i]`: component k in light image i.
    pub coefficients: Vec<f32>,
    /// `basis[k * n + j]`: component k at value j (pixel row-major, RGB).
    pub basis: Vec<f32>,
}

/// The reflectance field of one view.
#[derive(Clone, Debug, PartialEq)]
pub struct ViewField {
    pub id: String,
    pub width: usize,
    pub height: usize,
    /// Unit directions toward the lights (world frame), in the rig's order.
    pub directions: Vec<[f64; 3]>,
    pub blocks: Vec<Block>,
}

impl ViewField {
    /// Pixel width and height of block (bx, by).
    pub fn block_dims(&self, bx: u32, by: u32) -> (usize, usize) {
        block_dims(self.width, self.height, bx, by)
    }

    /// Numbers stored (coefficients and basis values).
    pub fn floats(&self) -> usize {
        self.blocks
            .iter()
            .map(|b| b.coefficients.len() + b.basis.len())
            .sum()
    }

    /// Eq. 3: the view under lights of RGB `weights` (one per light), from the coefficients.
    /// Pixels outside the kept blocks are black.
    pub fn relight(&self, weights: &[[f64; 3]]) -> HdrImage {
        let l = self.directions.len();
        assert_eq!(weights.len(), l, "one weight per light");
        let mut img = HdrImage::new(self.width, self.height);
        for b in &self.blocks {
            let (bw, bh) = self.block_dims(b.bx, b.by);
            let n = bw * bh * 3;
            let a: Vec<[f64; 3]> = (0..b.rank as usize)
                .map(|k| {
                    let c = &b.coefficients[k * l..(k + 1) * l];
                    let mut s = [0.0f64; 3];
                    for (ci, w) in c.iter().zip(weights) {
                        for ch in 0..3 {
                            s[ch] += *ci as f64 * w[ch];
                        }
                    }
                    s
                })
                .collect();
            for py in 0..bh {
                for px in 0..bw {
                    let mut v = [0.0f64; 3];
                    for (k, ak) in a.iter().enumerate() {
                        let base = k * n + (py * bw + px) * 3;
                        for ch in 0..3 {
                            v[ch] += b.basis[base + ch] as f64 * ak[ch];
                        }
                    }
                    let (x, y) = (b.bx as usize * BLOCK + px, b.by as usize * BLOCK + py);
                    img.set(x, y, v.map(|c| c as f32));
                }
            }
        }
        img
    }
}

fn block_dims(width: usize, height: usize, bx: u32, by: u32) -> (usize, usize) {
    let (x0, y0) = (bx as usize * BLOCK, by as usize * BLOCK);
    (
        BLOCK.min(width.saturating_sub(x0)),
        BLOCK.min(height.saturating_sub(y0)),
    )
}

/// What the build reports (and the header stores).
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ReflectanceReport {
    /// Views with light images.
    pub views: usize,
    /// Light images in all (views x lights).
    pub light_images: usize,
    pub blocks_kept: usize,
    /// Blocks of all the light images' views.
    pub blocks_total: usize,
    pub mean_components: f64,
    pub max_components: u32,
    /// Numbers stored (coefficients + basis values).
    pub floats_stored: usize,
    /// Numbers in the light images (width x height x 3 each).
    pub light_image_floats: usize,
    /// Numbers in the kept blocks of the light images.
    pub kept_block_floats: usize,
    /// `light_image_floats / floats_stored`.
    pub ratio: f64,
    /// `kept_block_floats / floats_stored` (the PCA alone).
    pub ratio_kept: f64,
    /// Mean of the kept values.
    pub mean_radiance: f64,
    /// RMS reconstruction error over the kept values (measured on the stored numbers).
    pub rms: f64,
    pub relative_rms: f64,
    pub target_relative_rms: f64,
    pub seconds: f64,
}

/// Pass 1 of one view: its kept blocks, their squared singular values, and the sums.
struct Analysis {
    view: usize,
    lights: usize,
    blocks: Vec<(u32, u32)>,
    /// Squared singular values per block, descending.
    s2: Vec<Vec<f64>>,
    /// Values per block (`lights x n`).
    sizes: Vec<usize>,
    sum: f64,
    total_blocks: usize,
    image_floats: usize,
}

/// Build the reflectance fields of the rig's views that have light images (`None` when none
/// has). `views` are the loaded views in the rig's order, `surfels` their surfels.
pub fn build_fields(
    rig: &Rig,
    views: &[View],
    surfels: &Surfels,
    opts: FieldOptions,
) -> Result<Option<(Vec<ViewField>, ReflectanceReport)>, HullError> {
    let start = std::time::Instant::now();
    let lit: Vec<usize> = (0..views.len())
        .filter(|&v| !rig.views[v].lights.is_empty())
        .collect();
    if lit.is_empty() {
        return Ok(None);
    }
    let analyses = lit
        .iter()
        .map(|&v| analyse_view(rig, &rig.views[v], &views[v], v, surfels))
        .collect::<Result<Vec<_>, _>>()?;
    let ranks = choose_ranks(&analyses, opts.target_relative_rms);
    let mut fields = Vec::with_capacity(lit.len());
    let mut err2 = 0.0;
    for (a, r) in analyses.iter().zip(&ranks) {
        let (field, e) = compress_view(rig, &rig.views[a.view], &views[a.view], a, r)?;
        err2 += e;
        fields.push(field);
    }
    let mut report = summarise(&analyses, &fields, err2, opts);
    report.seconds = start.elapsed().as_secs_f64();
    Ok(Some((fields, report)))
}

/// Before any work: every light image of the rig exists and has its view's camera size (read
/// from its header).
pub fn check_light_files(rig: &Rig) -> Result<(), HullError> {
    for rv in rig.views.iter().filter(|rv| !rv.lights.is_empty()) {
        let camera = rig.load_camera(rv)?;
        let want = (camera.width as usize, camera.height as usize);
        for l in &rv.lights {
            if let Err(e) = std::fs::metadata(&l.image) {
                return Err(rig
                    .view_message(rv, format!("light image {}: {e}", l.image.display()))
                    .into());
            }
            let got = igi_imaging::io::image_size(&l.image).map_err(|e| rig.view_error(rv, e))?;
            if got != want {
                return Err(rig
                    .view_message(
                        rv,
                        format!(
                            "light image {} is {}x{} but the view's camera is {}x{}",
                            l.image.display(),
                            got.0,
                            got.1,
                            want.0,
                            want.1
                        ),
                    )
                    .into());
            }
        }
    }
    Ok(())
}

/// The view's light images, each checked against the camera's size.
fn read_light_images(rig: &Rig, rv: &RigView, view: &View) -> Result<Vec<HdrImage>, HullError> {
    let (w, h) = (view.camera.width as usize, view.camera.height as usize);
    rv.lights
        .iter()
        .map(|l| {
            let img = read_image(&l.image).map_err(|e| rig.view_error(rv, e))?;
            if (img.width, img.height) != (w, h) {
                return Err(rig
                    .view_message(
                        rv,
                        format!(
                            "light image {} is {}x{} but the view's camera is {w}x{h}",
                            l.image.display(),
                            img.width,
                            img.height
                        ),
                    )
                    .into());
            }
            Ok(img)
        })
        .collect()
}

/// The blocks that the surfels visible in view `v` project into (with their bilinear taps),
/// sorted by row then column.
pub fn kept_blocks(surfels: &Surfels, v: usize, view: &View) -> Vec<(u32, u32)> {
    let (w, h) = (view.camera.width as usize, view.camera.height as usize);
    let (bw, bh) = (w.div_ceil(BLOCK), h.div_ceil(BLOCK));
    let mut keep = vec![false; bw * bh];
    for s in 0..surfels.len() {
        if !surfels.visible[s * surfels.views + v] {
            continue;
        }
        let p = DVec3::from_array(surfels.positions[s].map(f64::from));
        let Some(px) = view.camera.project(p) else {
            continue;
        };
        if !(px.x.is_finite() && px.y.is_finite()) {
            continue;
        }
        let x0 = px.x.floor().clamp(0.0, w as f64 - 1.0) as usize;
        let y0 = px.y.floor().clamp(0.0, h as f64 - 1.0) as usize;
        for y in [y0, (y0 + 1).min(h - 1)] {
            for x in [x0, (x0 + 1).min(w - 1)] {
                keep[(y / BLOCK) * bw + x / BLOCK] = true;
            }
        }
    }
    (0..bw * bh)
        .filter(|&i| keep[i])
        .map(|i| ((i % bw) as u32, (i / bw) as u32))
        .collect()
}

/// The `lights x n` matrix of block (bx, by).
fn block_matrix(images: &[HdrImage], bx: u32, by: u32) -> DMatrix<f64> {
    let (w, h) = (images[0].width, images[0].height);
    let (bw, bh) = block_dims(w, h, bx, by);
    let (x0, y0) = (bx as usize * BLOCK, by as usize * BLOCK);
    DMatrix::from_fn(images.len(), bw * bh * 3, |i, j| {
        let (p, ch) = (j / 3, j % 3);
        images[i].get(x0 + p % bw, y0 + p / bw)[ch] as f64
    })
}

fn svd_error(view: &str, bx: u32, by: u32) -> HullError {
    HullError::Svd {
        view: view.to_string(),
        bx,
        by,
    }
}

/// Pass 1: blocks, squared singular values, sums.
fn analyse_view(
    rig: &Rig,
    rv: &RigView,
    view: &View,
    v: usize,
    surfels: &Surfels,
) -> Result<Analysis, HullError> {
    let images = read_light_images(rig, rv, view)?;
    let blocks = kept_blocks(surfels, v, view);
    let per_block = blocks
        .par_iter()
        .map(|&(bx, by)| {
            let m = block_matrix(&images, bx, by);
            let (size, sum) = (m.len(), m.sum());
            let svd = nalgebra::SVD::try_new(m, false, false, f64::EPSILON, 10_000)
                .ok_or_else(|| svd_error(&view.id, bx, by))?;
            let s2: Vec<f64> = svd.singular_values.iter().map(|s| s * s).collect();
            Ok((s2, size, sum))
        })
        .collect::<Result<Vec<_>, HullError>>()?;
    let (w, h) = (view.camera.width as usize, view.camera.height as usize);
    Ok(Analysis {
        view: v,
        lights: images.len(),
        s2: per_block.iter().map(|b| b.0.clone()).collect(),
        sizes: per_block.iter().map(|b| b.1).collect(),
        sum: per_block.iter().map(|b| b.2).sum(),
        blocks,
        total_blocks: w.div_ceil(BLOCK) * h.div_ceil(BLOCK),
        image_floats: images.len() * w * h * 3,
    })
}

/// The global greedy choice of ranks (see the module docs): `ranks[view][block]`.
fn choose_ranks(analyses: &[Analysis], target: f64) -> Vec<Vec<u32>> {
    let n: usize = analyses.iter().map(|a| a.sizes.iter().sum::<usize>()).sum();
    let sum: f64 = analyses.iter().map(|a| a.sum).sum();
    let mean = if n > 0 {
        (sum / n as f64).max(0.0)
    } else {
        0.0
    };
    let budget = n as f64 * (target * mean).powi(2);
    // (error removed per number, view, block, component)
    let mut items: Vec<(f64, usize, usize, usize)> = Vec::new();
    for (a_i, a) in analyses.iter().enumerate() {
        for (b, s2) in a.s2.iter().enumerate() {
            let cost = (a.sizes[b] / a.lights + a.lights) as f64;
            for (k, &e) in s2.iter().enumerate() {
                items.push((e / cost, a_i, b, k));
            }
        }
    }
    items.sort_by(|x, y| {
        y.0.total_cmp(&x.0)
            .then(x.1.cmp(&y.1))
            .then(x.2.cmp(&y.2))
            .then(x.3.cmp(&y.3))
    });
    // the error left after taking the first t items, summed from the smallest (no cancellation)
    let mut left = vec![0.0f64; items.len() + 1];
    for t in (0..items.len()).rev() {
        let (_, a_i, b, k) = items[t];
        left[t] = left[t + 1] + analyses[a_i].s2[b][k];
    }
    let take = (0..=items.len())
        .find(|&t| left[t] <= budget)
        .unwrap_or(items.len());
    let mut ranks: Vec<Vec<u32>> = analyses.iter().map(|a| vec![0; a.blocks.len()]).collect();
    for &(_, a_i, b, k) in &items[..take] {
        ranks[a_i][b] = k as u32 + 1;
    }
    ranks
}

/// Pass 2: the truncated SVD of every kept block of one view, and its squared error as stored.
fn compress_view(
    rig: &Rig,
    rv: &RigView,
    view: &View,
    a: &Analysis,
    ranks: &[u32],
) -> Result<(ViewField, f64), HullError> {
    let images = read_light_images(rig, rv, view)?;
    let out = a
        .blocks
        .par_iter()
        .zip(ranks)
        .map(|(&(bx, by), &rank)| {
            let m = block_matrix(&images, bx, by);
            let block = truncate(&m, rank as usize).ok_or_else(|| svd_error(&view.id, bx, by))?;
            let block = Block { bx, by, ..block };
            Ok((stored_error(&m, &block), block))
        })
        .collect::<Result<Vec<_>, HullError>>()?;
    let err2 = out.iter().map(|x| x.0).sum();
    let field = ViewField {
        id: view.id.clone(),
        width: view.camera.width as usize,
        height: view.camera.height as usize,
        directions: rv.lights.iter().map(|l| l.direction).collect(),
        blocks: out.into_iter().map(|x| x.1).collect(),
    };
    Ok((field, err2))
}

/// The first `rank` components of `m` (`lights x n`) as f32 (block place left at 0).
fn truncate(m: &DMatrix<f64>, rank: usize) -> Option<Block> {
    let (l, n) = m.shape();
    let mut block = Block {
        bx: 0,
        by: 0,
        rank: rank as u32,
        coefficients: Vec::with_capacity(rank * l),
        basis: Vec::with_capacity(rank * n),
    };
    if rank == 0 {
        return Some(block);
    }
    let svd = nalgebra::SVD::try_new(m.clone(), true, true, f64::EPSILON, 10_000)?;
    let (u, vt) = (svd.u?, svd.v_t?);
    for k in 0..rank {
        let s = svd.singular_values[k];
        block
            .coefficients
            .extend((0..l).map(|i| (u[(i, k)] * s) as f32));
        block.basis.extend((0..n).map(|j| vt[(k, j)] as f32));
    }
    Some(block)
}

/// Squared error of the stored block against the data.
fn stored_error(m: &DMatrix<f64>, b: &Block) -> f64 {
    let (l, n) = m.shape();
    let mut e = 0.0;
    for i in 0..l {
        for j in 0..n {
            let r: f64 = (0..b.rank as usize)
                .map(|k| b.coefficients[k * l + i] as f64 * b.basis[k * n + j] as f64)
                .sum();
            e += (m[(i, j)] - r).powi(2);
        }
    }
    e
}

fn summarise(
    analyses: &[Analysis],
    fields: &[ViewField],
    err2: f64,
    opts: FieldOptions,
) -> ReflectanceReport {
    let n: usize = analyses.iter().map(|a| a.sizes.iter().sum::<usize>()).sum();
    let sum: f64 = analyses.iter().map(|a| a.sum).sum();
    let blocks: Vec<&Block> = fields.iter().flat_map(|f| &f.blocks).collect();
    let floats: usize = fields.iter().map(ViewField::floats).sum();
    let image_floats: usize = analyses.iter().map(|a| a.image_floats).sum();
    let ratio = |x: usize| {
        if floats > 0 {
            x as f64 / floats as f64
        } else {
            0.0
        }
    };
    let mean = if n > 0 { sum / n as f64 } else { 0.0 };
    let rms = if n > 0 { (err2 / n as f64).sqrt() } else { 0.0 };
    ReflectanceReport {
        views: fields.len(),
        light_images: analyses.iter().map(|a| a.lights).sum(),
        blocks_kept: blocks.len(),
        blocks_total: analyses.iter().map(|a| a.total_blocks).sum(),
        mean_components: blocks.iter().map(|b| b.rank as f64).sum::<f64>()
            / blocks.len().max(1) as f64,
        max_components: blocks.iter().map(|b| b.rank).max().unwrap_or(0),
        floats_stored: floats,
        light_image_floats: image_floats,
        kept_block_floats: n,
        ratio: ratio(image_floats),
        ratio_kept: ratio(n),
        mean_radiance: mean,
        rms,
        relative_rms: if mean > 0.0 { rms / mean } else { 0.0 },
        target_relative_rms: opts.target_relative_rms,
        seconds: 0.0,
    }
}

/// `reflectance.json`.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
struct Header {
    format: String,
    block: usize,
    summary: ReflectanceReport,
    views: Vec<ViewHeader>,
}

#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
struct ViewHeader {
    id: String,
    file: String,
    width: usize,
    height: usize,
    directions: Vec<[f64; 3]>,
    blocks: usize,
    floats: usize,
}

/// Write the fields and their header into `hull_dir/reflectance/` (inside the build's
/// temporary folder, which is renamed into place as a whole).
pub fn write_fields(
    hull_dir: &Path,
    fields: &[ViewField],
    report: &ReflectanceReport,
) -> Result<(), HullError> {
    let dir = hull_dir.join(FOLDER);
    std::fs::create_dir_all(&dir).map_err(|e| HullError::io(&dir, e))?;
    let mut views = Vec::with_capacity(fields.len());
    for f in fields {
        let file = format!("{}.bin", f.id);
        let path = dir.join(&file);
        std::fs::write(&path, encode(f)).map_err(|e| HullError::io(&path, e))?;
        views.push(ViewHeader {
            id: f.id.clone(),
            file,
            width: f.width,
            height: f.height,
            directions: f.directions.clone(),
            blocks: f.blocks.len(),
            floats: f.floats(),
        });
    }
    let header = Header {
        format: FORMAT.into(),
        block: BLOCK,
        summary: report.clone(),
        views,
    };
    igi_files::write_text_atomic(
        &dir.join(HEADER),
        &serde_json::to_string_pretty(&header).expect("header"),
    )?;
    Ok(())
}

fn encode(f: &ViewField) -> Vec<u8> {
    let mut out = Vec::with_capacity(24 + f.floats() * 4 + f.blocks.len() * 12);
    out.extend_from_slice(MAGIC);
    for x in [f.width, f.height, f.directions.len(), f.blocks.len()] {
        out.extend_from_slice(&(x as u32).to_le_bytes());
    }
    for b in &f.blocks {
        for x in [b.bx, b.by, b.rank] {
            out.extend_from_slice(&x.to_le_bytes());
        }
        for x in b.coefficients.iter().chain(&b.basis) {
            out.extend_from_slice(&x.to_le_bytes());
        }
    }
    out
}

/// Read the fields of a hull folder; `None` when it has none (built without light images).
pub fn read_fields(hull_dir: &Path) -> Result<Option<Vec<ViewField>>, HullError> {
    let dir = hull_dir.join(FOLDER);
    let hpath = dir.join(HEADER);
    if !hpath.exists() {
        return Ok(None);
    }
    let text = std::fs::read_to_string(&hpath).map_err(|e| HullError::io(&hpath, e))?;
    let bad = |path: &Path, msg: String| HullError::HullFolder {
        path: path.to_path_buf(),
        msg,
    };
    let header: Header = serde_json::from_str(&text).map_err(|e| bad(&hpath, e.to_string()))?;
    if header.format != FORMAT || header.block != BLOCK {
        return Err(bad(
            &hpath,
            format!(
                "format {:?} with {} px blocks; expected {FORMAT:?} with {BLOCK}",
                header.format, header.block
            ),
        ));
    }
    for v in &header.views {
        if let Some(d) = v.directions.iter().find(|d| !is_light_direction(**d)) {
            let msg = format!("view {:?}: light direction {d:?} is not a direction", v.id);
            return Err(bad(&hpath, msg));
        }
    }
    let mut fields = Vec::with_capacity(header.views.len());
    for v in &header.views {
        let path = dir.join(&v.file);
        let bytes = std::fs::read(&path).map_err(|e| HullError::io(&path, e))?;
        let f = decode(&bytes, v).map_err(|msg| bad(&path, msg))?;
        fields.push(f);
    }
    Ok(Some(fields))
}

/// A little-endian reader over a byte slice.
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn take(&mut self, n: usize) -> Result<&[u8], String> {
        let end = self.at.checked_add(n).filter(|&e| e <= self.bytes.len());
        let end = end.ok_or_else(|| format!("truncated at byte {}", self.at))?;
        let s = &self.bytes[self.at..end];
        self.at = end;
        Ok(s)
    }

    fn u32(&mut self) -> Result<u32, String> {
        Ok(u32::from_le_bytes(self.take(4)?.try_into().expect("4")))
    }

    fn f32s(&mut self, n: usize) -> Result<Vec<f32>, String> {
        let raw = self.take(n.checked_mul(4).ok_or("size overflow")?)?;
        let v: Vec<f32> = raw
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes(c.try_into().expect("4")))
            .collect();
        if v.iter().any(|x| !x.is_finite()) {
            return Err("holds a non-finite number".into());
        }
        Ok(v)
    }
}

fn decode(bytes: &[u8], v: &ViewHeader) -> Result<ViewField, String> {
    let mut r = Reader { bytes, at: 0 };
    if r.take(8)? != MAGIC {
        return Err("not a reflectance-field file (bad magic)".into());
    }
    let (w, h, l, nb) = (r.u32()?, r.u32()?, r.u32()?, r.u32()?);
    let (w, h, l, nb) = (w as usize, h as usize, l as usize, nb as usize);
    if (w, h, l, nb) != (v.width, v.height, v.directions.len(), v.blocks) {
        return Err(format!(
            "holds {w}x{h}, {l} lights, {nb} blocks; the header says {}x{}, {} lights, {} blocks",
            v.width,
            v.height,
            v.directions.len(),
            v.blocks
        ));
    }
    // a block takes at least its 12-byte head: no more capacity than the bytes can hold
    let mut blocks = Vec::with_capacity(nb.min(bytes.len() / 12));
    for _ in 0..nb {
        let (bx, by, rank) = (r.u32()?, r.u32()?, r.u32()?);
        let (bw, bh) = block_dims(w, h, bx, by);
        if bw == 0 || bh == 0 || rank as usize > l.min(bw * bh * 3) {
            return Err(format!(
                "block ({bx}, {by}) of rank {rank} does not fit {w}x{h}"
            ));
        }
        let coefficients = r.f32s(rank as usize * l)?;
        let basis = r.f32s(rank as usize * bw * bh * 3)?;
        blocks.push(Block {
            bx,
            by,
            rank,
            coefficients,
            basis,
        });
    }
    if r.at != bytes.len() {
        return Err(format!("{} bytes after the last block", bytes.len() - r.at));
    }
    Ok(ViewField {
        id: v.id.clone(),
        width: w,
        height: h,
        directions: v.directions.clone(),
        blocks,
    })
}

/// The reflectance folder of a hull folder.
pub fn folder(hull_dir: &Path) -> PathBuf {
    hull_dir.join(FOLDER)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// An analysis of the given `lights x n` blocks (as pass 1 makes it).
    fn analysis(blocks: &[DMatrix<f64>]) -> Analysis {
        let s2 = blocks
            .iter()
            .map(|m| {
                let svd = nalgebra::SVD::new(m.clone(), false, false);
                svd.singular_values.iter().map(|s| s * s).collect()
            })
            .collect();
        Analysis {
            view: 0,
            lights: blocks[0].nrows(),
            blocks: (0..blocks.len() as u32).map(|i| (i, 0)).collect(),
            s2,
            sizes: blocks.iter().map(|m| m.len()).collect(),
            sum: blocks.iter().map(|m| m.sum()).sum(),
            total_blocks: blocks.len(),
            image_floats: 0,
        }
    }

    fn rank2(rng: &mut rand_pcg::Pcg64, l: usize, n: usize) -> DMatrix<f64> {
        let a = DMatrix::from_fn(l, 2, |_, _| rng.gen_range(0.0..1.0));
        let b = DMatrix::from_fn(2, n, |_, _| rng.gen_range(0.0..2.0));
        a * b
    }

    #[test]
    fn a_rank_two_block_set_is_recovered_exactly_with_two_components() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(3);
        let blocks: Vec<DMatrix<f64>> = (0..5).map(|_| rank2(&mut rng, 15, 192)).collect();
        let a = analysis(&blocks);
        // a target far below f32 rounding still needs only the two true components
        let ranks = choose_ranks(std::slice::from_ref(&a), 1e-9);
        assert_eq!(ranks, vec![vec![2; 5]]);
        for m in &blocks {
            let b = truncate(m, 2).unwrap();
            let rel = (stored_error(m, &b) / m.norm_squared()).sqrt();
            // f32 storage: measured 3.3e-8 to 3.9e-8
            assert!(rel < 5e-7, "relative error {rel:e}");
        }
    }

    #[test]
    fn the_global_rms_target_is_met_with_the_fewest_components() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(9);
        // low-rank blocks of different brightness plus noise: the budget goes where it pays
        let blocks: Vec<DMatrix<f64>> = (0..12)
            .map(|i| {
                let noise = DMatrix::from_fn(15, 192, |_, _| rng.gen_range(-0.02..0.02));
                rank2(&mut rng, 15, 192) * (1.0 + i as f64) + noise
            })
            .collect();
        let a = analysis(&blocks);
        let ranks = choose_ranks(std::slice::from_ref(&a), 0.01);
        let n: usize = blocks.iter().map(|m| m.len()).sum();
        let mean = a.sum / n as f64;
        let err2 = |ranks: &[u32]| -> f64 {
            blocks
                .iter()
                .zip(ranks)
                .map(|(m, &r)| stored_error(m, &truncate(m, r as usize).unwrap()))
                .sum()
        };
        let rel = (err2(&ranks[0]) / n as f64).sqrt() / mean;
        assert!(rel <= 0.01, "relative RMS {rel}");
        // one component fewer anywhere breaks the target
        for b in 0..blocks.len() {
            if ranks[0][b] == 0 {
                continue;
            }
            let mut fewer = ranks[0].clone();
            fewer[b] -= 1;
            let rel = (err2(&fewer) / n as f64).sqrt() / mean;
            assert!(rel > 0.01, "block {b} could drop a component: {rel}");
        }
        // and zero radiance needs nothing and gives no NaN
        let zero = analysis(&[DMatrix::zeros(15, 192)]);
        assert_eq!(choose_ranks(&[zero], 0.01), vec![vec![0]]);
    }

    #[test]
    fn fields_round_trip_through_the_store_and_relight_linearly() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(4);
        // a 12 x 10 view: blocks (0, 0) full and (1, 1) 4 x 2 at the corner
        let blocks: Vec<Block> = [(0u32, 0u32, 64usize), (1, 1, 8)]
            .iter()
            .map(|&(bx, by, px)| Block {
                bx,
                by,
                rank: 2,
                coefficients: (0..6).map(|_| rng.gen_range(-1.0..1.0)).collect(),
                basis: (0..2 * px * 3).map(|_| rng.gen_range(-1.0..1.0)).collect(),
            })
            .collect();
        let f = ViewField {
            id: "v0".into(),
            width: 12,
            height: 10,
            directions: vec![[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            blocks,
        };
        let dir = tempfile::tempdir().unwrap();
        write_fields(
            dir.path(),
            std::slice::from_ref(&f),
            &ReflectanceReport::default(),
        )
        .unwrap();
        let back = read_fields(dir.path()).unwrap().unwrap();
        assert_eq!(back, vec![f.clone()]);
        // relighting is linear in the weights: light 1 alone is that light's reconstruction
        let img = f.relight(&[[0.0; 3], [2.0, 2.0, 2.0], [0.0; 3]]);
        let (b, l) = (&f.blocks[1], 3);
        let (x, y, j) = (8 + 3, 8 + 1, (4 + 3) * 3 + 2);
        let n = 4 * 2 * 3;
        let expect =
            2.0 * (b.coefficients[1] * b.basis[j] + b.coefficients[l + 1] * b.basis[n + j]);
        assert!((img.get(x, y)[2] - expect).abs() < 1e-6);
        assert_eq!(img.get(11, 0), [0.0; 3], "outside the kept blocks");
        // a damaged file is refused with its name
        let bin = dir.path().join("reflectance/v0.bin");
        let bytes = std::fs::read(&bin).unwrap();
        std::fs::write(&bin, &bytes[..bytes.len() - 4]).unwrap();
        let e = read_fields(dir.path()).unwrap_err().to_string();
        assert!(e.contains("v0.bin") && e.contains("truncated"), "{e}");
        assert!(read_fields(&dir.path().join("none")).unwrap().is_none());
        // a file and header that both claim 2^32 - 1 blocks: truncated, not an allocation of
        // 275 GB; a light direction that is none is refused naming the header
        let hp = dir.path().join(FOLDER).join(HEADER);
        let good = std::fs::read_to_string(&hp).unwrap();
        let mut h: serde_json::Value = serde_json::from_str(&good).unwrap();
        h["views"][0]["blocks"] = u32::MAX.into();
        std::fs::write(&hp, h.to_string()).unwrap();
        let mut many = bytes.clone();
        many[20..24].copy_from_slice(&u32::MAX.to_le_bytes());
        std::fs::write(&bin, many).unwrap();
        let e = read_fields(dir.path()).unwrap_err().to_string();
        assert!(e.contains("v0.bin") && e.contains("truncated"), "{e}");
        let mut h: serde_json::Value = serde_json::from_str(&good).unwrap();
        h["views"][0]["directions"][1] = serde_json::json!([0.0, 0.0, 0.0]);
        std::fs::write(&hp, h.to_string()).unwrap();
        let e = read_fields(dir.path()).unwrap_err().to_string();
        assert!(
            e.contains(HEADER) && e.contains("is not a direction"),
            "{e}"
        );
    }
}
