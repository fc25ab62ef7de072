//! Visual hull by octree carving of a regular grid of cells over the rig's bounding box.
//!
//! A cell is carved by a view when its centre projects, inside the frame, onto a known
//! background pixel (nearest pixel; pixel centres at integer coordinates). Pixels outside the
//! frame, pixels with an invalid matte and centres behind the camera are unknown and carve
//! nothing. Blocks of cells are decided at once where a view's projected block (the bounding
//! rectangle of its eight projected corners, padded by two pixels) is all known background
//! (the whole block is carved) or holds no known background (no cell of it is carved by that
//! view); otherwise the block is split in eight.
//!
//! For every cell the carving records the index of the **first** view (in the given order)
//! that carves it, so the volume after the first k views and the view that emptied the hull
//! come for free.

use crate::views::View;
use glam::DVec3;
use rayon::prelude::*;

/// The index of a view in a carving (the first view that carves a cell).
pub type ViewIndex = u16;

/// Marker for a cell no view carves.
pub const KEPT: ViewIndex = ViewIndex::MAX;

/// The most views a hull is carved from (Matusik et al.'s rig had 6 cameras x 36 turntable
/// positions = 216). `igi hull build` refuses more before any work.
pub const MAX_VIEWS: usize = 1024;

/// The cell grid over a box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CellGrid {
    pub min: DVec3,
    pub max: DVec3,
    /// Cells per axis.
    pub dims: [usize; 3],
}

impl CellGrid {
    /// A grid with `n` cells along every axis of the box (cell = box extent / n per axis).
    pub fn new(min: DVec3, max: DVec3, n: usize) -> CellGrid {
        CellGrid {
            min,
            max,
            dims: [n; 3],
        }
    }

    /// Edge lengths of one cell.
    pub fn cell_size(&self) -> DVec3 {
        (self.max - self.min)
            / DVec3::new(
                self.dims[0] as f64,
                self.dims[1] as f64,
                self.dims[2] as f64,
            )
    }

    /// Centre of cell (i, j, k).
    pub fn center(&self, c: [usize; 3]) -> DVec3 {
        self.min + (DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64) + 0.5) * self.cell_size()
    }

    /// The lower corner of cell (i, j, k) (cell `dims` gives the box's upper corner).
    pub fn corner(&self, c: [usize; 3]) -> DVec3 {
        self.min + DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64) * self.cell_size()
    }

    /// Flat index of cell (i, j, k) (x fastest).
    pub fn index(&self, c: [usize; 3]) -> usize {
        c[0] + self.dims[0] * (c[1] + self.dims[1] * c[2])
    }

    pub fn len(&self) -> usize {
        self.dims.iter().product()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// The pixel nearest the projection of `p` in `view`, when it lies in front and inside the frame.
fn pixel_of(view: &View, p: DVec3) -> Option<(usize, usize)> {
    let px = view.camera.project(p)?;
    let (w, h) = (view.silhouette.width as f64, view.silhouette.height as f64);
    // the frame is (-0.5, w - 0.5) x (-0.5, h - 0.5) (a pixel's nearest centre rounds half up);
    // inside it x + 0.5 > 0, so truncation rounds, without a libm call
    let inside = px.x > -0.5 && px.y > -0.5 && px.x < w - 0.5 && px.y < h - 0.5;
    inside.then_some(((px.x + 0.5) as usize, (px.y + 0.5) as usize))
}

/// Band views that carve a cell whatever the views that see it as object.
pub const BAND_AGREEMENT: usize = 2;

/// Marker for a cell carved because no view sees it as object (see [`carve_band_votes`]).
pub const UNSEEN: ViewIndex = KEPT - 1;

/// Weigh the evidence [`carve`] left aside, for the cells it kept:
/// - Frame-band background ([`View::is_band_background`]) is weak evidence, not absent: where
///   the object runs out of the frame, a surface in shadow can read like the backdrop in one
///   view (the dino's foot, which the other views see as object: kept). A cell is carved when
///   the views that see it as band background are at least one, and at least
///   [`BAND_AGREEMENT`] or as many as the views that see it inside their silhouettes; it
///   records the first of them.
/// - A cell that no view sees inside its silhouette has nothing for it: outside every frame,
///   or only in bands and invalid mattes. It is carved and records [`UNSEEN`]. Without this,
///   space beside thin parts that run out of the frames, and space outside every input frame
///   that a new view sees, would stay as phantom volume.
///
/// Boxes of cells are decided at once where no view sees any of the box on band background and
/// some view sees all of it inside its silhouette (every cell keeps); otherwise the box is split
/// in eight, down to single cells.
///
/// Returns the cells carved.
pub fn carve_band_votes(grid: &CellGrid, views: &[&View], carver: &mut [ViewIndex]) -> usize {
    let tables: Vec<VoteTable> = views.iter().map(|v| VoteTable::new(v)).collect();
    let carver_ref: &[ViewIndex] = carver;
    let changes: Vec<(usize, ViewIndex)> = blocks(grid)
        .into_par_iter()
        .flat_map_iter(|(lo, hi)| {
            let mut out = Vec::new();
            vote_range(grid, &tables, carver_ref, lo, hi, &mut out);
            out
        })
        .collect();
    for &(i, v) in &changes {
        carver[i] = v;
    }
    changes.len()
}

/// The band vote of the cell centred at `p`: the first band view that carves it, [`UNSEEN`]
/// when no view sees it as object, `None` when it stays (see [`carve_band_votes`]).
fn cell_vote(tables: &[VoteTable], p: DVec3) -> Option<ViewIndex> {
    let (mut first, mut background, mut object) = (None, 0usize, 0usize);
    for (v, t) in tables.iter().enumerate() {
        let Some((x, y)) = pixel_of(t.view, p) else {
            continue;
        };
        if t.view.is_band_background(x, y) {
            first = first.or(Some(v));
            background += 1;
        } else if t.view.silhouette.get(x, y) {
            object += 1;
        }
    }
    match first {
        Some(v) if background >= object.min(BAND_AGREEMENT) => Some(v as ViewIndex),
        _ if object == 0 => Some(UNSEEN),
        _ => None,
    }
}

/// Records in `out` the band votes of the kept cells in [lo, hi) that are carved.
fn vote_range(
    grid: &CellGrid,
    tables: &[VoteTable],
    carver: &[ViewIndex],
    lo: [usize; 3],
    hi: [usize; 3],
    out: &mut Vec<(usize, ViewIndex)>,
) {
    if (0..3).all(|a| hi[a] - lo[a] == 1) {
        let i = grid.index(lo);
        if carver[i] == KEPT {
            if let Some(v) = cell_vote(tables, grid.center(lo)) {
                out.push((i, v));
            }
        }
        return;
    }
    let (blo, bhi) = (grid.corner(lo), grid.corner(hi));
    let keeps = || {
        let rects: Option<Vec<[i64; 4]>> = tables
            .iter()
            .map(|t| projected_rect(t.view, blo, bhi))
            .collect();
        rects.is_some_and(|r| {
            let zip = || tables.iter().zip(&r);
            zip().all(|(t, r)| t.band.count(r).0 == 0)
                && zip().any(|(t, r)| t.object.count(r) == (area(r), true))
        })
    };
    if keeps() {
        return;
    }
    for (clo, chi) in octants(lo, hi) {
        vote_range(grid, tables, carver, clo, chi, out);
    }
}

/// A view's band-background and object (silhouette, not band background) pixel counts.
struct VoteTable<'a> {
    view: &'a View,
    band: PixelCount,
    object: PixelCount,
}

impl<'a> VoteTable<'a> {
    fn new(view: &'a View) -> Self {
        VoteTable {
            view,
            band: PixelCount::of(view, View::is_band_background),
            object: PixelCount::of(view, |v, x, y| {
                v.silhouette.get(x, y) && !v.is_band_background(x, y)
            }),
        }
    }
}

/// Summed-area table of one class of a view's pixels: the count over any rectangle at once.
struct PixelCount {
    width: usize,
    height: usize,
    /// (w + 1) x (h + 1) prefix sums.
    sums: Vec<u32>,
}

impl PixelCount {
    /// The table of the pixels of `view` for which `class(view, x, y)` holds.
    fn of(view: &View, class: impl Fn(&View, usize, usize) -> bool) -> Self {
        let (width, height) = (view.silhouette.width, view.silhouette.height);
        let mut sums = vec![0u32; (width + 1) * (height + 1)];
        for y in 0..height {
            let mut row = 0u32;
            for x in 0..width {
                row += class(view, x, y) as u32;
                sums[(y + 1) * (width + 1) + x + 1] = sums[y * (width + 1) + x + 1] + row;
            }
        }
        PixelCount {
            width,
            height,
            sums,
        }
    }

    /// Pixels of the class in the inclusive rectangle `[x0, y0, x1, y1]` (clipped to the frame),
    /// and whether the rectangle lies inside the frame.
    fn count(&self, r: &[i64; 4]) -> (u64, bool) {
        let (w, h) = (self.width as i64, self.height as i64);
        let inside = r[0] >= 0 && r[1] >= 0 && r[2] < w && r[3] < h;
        let (x0, y0, x1, y1) = (r[0].max(0), r[1].max(0), r[2].min(w - 1), r[3].min(h - 1));
        if x0 > x1 || y0 > y1 {
            return (0, inside);
        }
        let s = |x: i64, y: i64| self.sums[(y * (w + 1) + x) as usize] as i64;
        let n = s(x1 + 1, y1 + 1) - s(x0, y1 + 1) - s(x1 + 1, y0) + s(x0, y0);
        (n as u64, inside)
    }
}

/// Pixels in the inclusive rectangle `[x0, y0, x1, y1]`.
fn area(r: &[i64; 4]) -> u64 {
    ((r[2] - r[0] + 1) * (r[3] - r[1] + 1)) as u64
}

/// The pixel rectangle (inclusive, padded by two pixels) that holds the projection of the box
/// [lo, hi] in `view`: the bounds of its eight projected corners. `None` when a corner lies
/// behind the camera or the bounds are not finite.
fn projected_rect(view: &View, lo: DVec3, hi: DVec3) -> Option<[i64; 4]> {
    let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
    for c in 0..8 {
        let p = DVec3::new(
            if c & 1 == 0 { lo.x } else { hi.x },
            if c & 2 == 0 { lo.y } else { hi.y },
            if c & 4 == 0 { lo.z } else { hi.z },
        );
        if !(view.camera.pose.apply(p).z > 1e-9) {
            return None;
        }
        let px = view.camera.project(p)?;
        x0 = x0.min(px.x);
        y0 = y0.min(px.y);
        x1 = x1.max(px.x);
        y1 = y1.max(px.y);
    }
    let pad = 2.0;
    let r = [x0 - pad, y0 - pad, x1 + pad, y1 + pad];
    if r.iter().any(|v| !v.is_finite() || v.abs() > 1e7) {
        return None;
    }
    Some([
        r[0].floor() as i64,
        r[1].floor() as i64,
        r[2].ceil() as i64,
        r[3].ceil() as i64,
    ])
}

/// The octree's first level: blocks of 16 cells a side (the last ones clipped), for rayon.
fn blocks(grid: &CellGrid) -> Vec<([usize; 3], [usize; 3])> {
    let block = 16usize;
    let nb = grid.dims.map(|d| d.div_ceil(block));
    (0..nb[2])
        .flat_map(|k| (0..nb[1]).flat_map(move |j| (0..nb[0]).map(move |i| [i, j, k])))
        .map(|b| {
            let lo = [0, 1, 2].map(|a| b[a] * block);
            let hi = [0, 1, 2].map(|a| ((b[a] + 1) * block).min(grid.dims[a]));
            (lo, hi)
        })
        .collect()
}

/// The (up to) eight non-empty octants of the box [lo, hi).
fn octants(lo: [usize; 3], hi: [usize; 3]) -> impl Iterator<Item = ([usize; 3], [usize; 3])> {
    let mid = [0, 1, 2].map(|a| (lo[a] + hi[a]).div_ceil(2));
    (0..8)
        .map(move |oct| {
            let clo = [0, 1, 2].map(|a| if oct >> a & 1 == 0 { lo[a] } else { mid[a] });
            let chi = [0, 1, 2].map(|a| if oct >> a & 1 == 0 { mid[a] } else { hi[a] });
            (clo, chi)
        })
        .filter(|(clo, chi)| (0..3).all(|a| clo[a] < chi[a]))
}

/// Known-background pixel counts of a view, for carving.
struct ViewTable<'a> {
    view: &'a View,
    bg: PixelCount,
}

impl<'a> ViewTable<'a> {
    fn new(view: &'a View) -> Self {
        ViewTable {
            view,
            bg: PixelCount::of(view, View::is_background),
        }
    }

    /// Does this view carve the cell centred at `p`?
    fn carves_point(&self, p: DVec3) -> bool {
        pixel_of(self.view, p).is_some_and(|(x, y)| self.view.is_background(x, y))
    }

    /// Decision for a box: Some(true) = all carved, Some(false) = none carved, None = mixed.
    fn classify_box(&self, lo: DVec3, hi: DVec3) -> Option<bool> {
        let r = projected_rect(self.view, lo, hi)?;
        let (n, inside) = self.bg.count(&r);
        if n == 0 {
            Some(false)
        } else if inside && n == area(&r) {
            Some(true)
        } else {
            None
        }
    }
}

/// For every cell of `grid`, the index of the first view that carves it, or [`KEPT`].
/// At most [`MAX_VIEWS`] views (callers check; more is a programming error).
pub fn carve(grid: &CellGrid, views: &[&View]) -> Vec<ViewIndex> {
    assert!(views.len() <= MAX_VIEWS, "at most {MAX_VIEWS} views");
    let tables: Vec<ViewTable> = views.iter().map(|v| ViewTable::new(v)).collect();
    let results: Vec<([usize; 3], [usize; 3], Vec<ViewIndex>)> = blocks(grid)
        .into_par_iter()
        .map(|(lo, hi)| {
            let size = [0, 1, 2].map(|a| hi[a] - lo[a]);
            let mut local = vec![KEPT; size[0] * size[1] * size[2]];
            carve_range(
                grid,
                &tables,
                lo,
                hi,
                0,
                &mut |c: [usize; 3], v: ViewIndex| {
                    local[(c[0] - lo[0]) + size[0] * ((c[1] - lo[1]) + size[1] * (c[2] - lo[2]))] =
                        v;
                },
            );
            (lo, size, local)
        })
        .collect();
    let mut out = vec![KEPT; grid.len()];
    for (lo, size, local) in results {
        for k in 0..size[2] {
            for j in 0..size[1] {
                for i in 0..size[0] {
                    out[grid.index([lo[0] + i, lo[1] + j, lo[2] + k])] =
                        local[i + size[0] * (j + size[1] * k)];
                }
            }
        }
    }
    out
}

/// Carve the cells in [lo, hi) from view `first` on; `set(cell, view)` records a carve.
fn carve_range(
    grid: &CellGrid,
    tables: &[ViewTable],
    lo: [usize; 3],
    hi: [usize; 3],
    first: usize,
    set: &mut dyn FnMut([usize; 3], ViewIndex),
) {
    let single = (0..3).all(|a| hi[a] - lo[a] == 1);
    if single {
        let p = grid.center(lo);
        if let Some(v) = (first..tables.len()).find(|&v| tables[v].carves_point(p)) {
            set(lo, v as ViewIndex);
        }
        return;
    }
    let (blo, bhi) = (grid.corner(lo), grid.corner(hi));
    for v in first..tables.len() {
        match tables[v].classify_box(blo, bhi) {
            Some(false) => continue,
            Some(true) => {
                for k in lo[2]..hi[2] {
                    for j in lo[1]..hi[1] {
                        for i in lo[0]..hi[0] {
                            set([i, j, k], v as ViewIndex);
                        }
                    }
                }
                return;
            }
            None => {
                for (clo, chi) in octants(lo, hi) {
                    carve_range(grid, tables, clo, chi, v, set);
                }
                return;
            }
        }
    }
}

/// Cells kept after the first `k` views: those whose first carving view is `>= k` (a cell no
/// view sees as object, [`UNSEEN`], is never volume).
pub fn volume_after(carver: &[ViewIndex], k: usize) -> usize {
    carver
        .iter()
        .filter(|&&v| v != UNSEEN && v as usize >= k)
        .count()
}

/// Per cell, the bit set of every view that carves its centre (direct test, no early out):
/// for volume-against-views studies over many view orders.
#[derive(Clone, Debug)]
pub struct ViewSets {
    /// 64-bit words per cell.
    words: usize,
    bits: Vec<u64>,
}

impl ViewSets {
    /// Cells in the grid.
    pub fn len(&self) -> usize {
        self.bits.len() / self.words
    }

    /// Whether the grid has no cell.
    pub fn is_empty(&self) -> bool {
        self.bits.is_empty()
    }

    /// Whether view `v` carves cell `cell`.
    pub fn carves(&self, cell: usize, v: usize) -> bool {
        self.bits[cell * self.words + v / 64] >> (v % 64) & 1 == 1
    }

    /// Whether no view carves cell `cell`.
    pub fn kept(&self, cell: usize) -> bool {
        self.bits[cell * self.words..(cell + 1) * self.words]
            .iter()
            .all(|&w| w == 0)
    }
}

/// The views carving each cell of `grid` (see [`ViewSets`]). At most [`MAX_VIEWS`] views.
pub fn carve_sets(grid: &CellGrid, views: &[&View]) -> ViewSets {
    assert!(views.len() <= MAX_VIEWS, "at most {MAX_VIEWS} views");
    let tables: Vec<ViewTable> = views.iter().map(|v| ViewTable::new(v)).collect();
    let words = views.len().div_ceil(64).max(1);
    let mut bits = vec![0u64; grid.len() * words];
    bits.par_chunks_mut(words)
        .enumerate()
        .for_each(|(i, cell)| {
            let c = [
                i % grid.dims[0],
                (i / grid.dims[0]) % grid.dims[1],
                i / (grid.dims[0] * grid.dims[1]),
            ];
            let p = grid.center(c);
            for (v, t) in tables.iter().enumerate() {
                if t.carves_point(p) {
                    cell[v / 64] |= 1 << (v % 64);
                }
            }
        });
    ViewSets { words, bits }
}
