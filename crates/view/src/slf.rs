//! A surface light field's view-dependent colour as the page draws it: the field's tables in
//! one block of `f32` (`/igi/slf.bin`, read by the page into one RGBA float texture, four
//! values a texel) and where each table starts (`scene.json`'s `slf`). The page's shader
//! evaluates what `igi_lightfield::SurfaceLightField::radiance_at` evaluates: per fragment the
//! view direction reflected about the normal, located on the subdivided octahedron as
//! `Octahedron::locate` does, and the bilinear blend of the four nearest texels' grid points,
//! each its median plus its lumisphere (the coding's terms: one faired lumisphere, one
//! codeword, or the PFA prototypes with their weights).
//!
//! Tables, in texels of four `f32`:
//! * `texels`: per atlas texel (row 0 at the top, as the field numbers them): the grid point
//!   whose own texel it is (or -1), the grid point it reads at its centre (`point_at`,
//!   gutters included; or -1);
//! * `points`: per grid point `1 + terms` texels: its median (RGB), then per term the
//!   lumisphere's number and its weight;
//! * `lumispheres`: per lumisphere its value (RGB, median removed) at each vertex;
//! * `keys`: the octahedron's vertex of each lattice key `((x + n) (2n + 1) + y + n) 2 + (z < 0)`
//!   (or -1);
//! * `gain`: the view-angle gain's knots (`AngleGain`, `gainKnots` of them, evenly spaced in
//!   n . w on [0, 1]; none: 1), which multiply the lumisphere terms.

use glam::Vec2;
use igi_lightfield::field::Coding;
use igi_lightfield::SurfaceLightField;

/// The light field's tables for the page.
pub struct PageField {
    /// `scene.json`'s `slf`: the sizes and where each table starts (in texels).
    pub json: serde_json::Value,
    /// The tables, four little-endian `f32` a texel.
    pub bin: Vec<u8>,
}

/// The tables of `field` (the module's overview lists them); `scale` is what the page
/// multiplies the radiance by (the median texture's: its 99th percentile to 1).
pub fn page_field(field: &SurfaceLightField, scale: f32) -> PageField {
    let mut data: Vec<[f32; 4]> = Vec::new();
    let texels = texel_table(field, &mut data);
    let (terms, lumispheres) = match &field.coding {
        Coding::MedianOnly => (0, Vec::new()),
        Coding::Faired(f) => (1, f.iter().collect::<Vec<_>>()),
        Coding::Quantized(c) => (1, c.codewords.iter().collect()),
        Coding::Pfa(p) => (p.prototypes.len(), p.prototypes.iter().collect()),
    };
    let points = data.len();
    for p in 0..field.median.len() {
        data.push(field.median[p].extend(0.0).to_array());
        for (l, w) in point_terms(&field.coding, p) {
            data.push([l as f32, w, 0.0, 0.0]);
        }
    }
    let lumi = data.len();
    for l in &lumispheres {
        data.extend(l.iter().map(|v| v.extend(0.0).to_array()));
    }
    let keys = data.len();
    data.extend(key_table(field).into_iter().map(|v| [v, 0.0, 0.0, 0.0]));
    let gain = data.len();
    data.extend(field.gain.knots.iter().map(|g| [*g, 0.0, 0.0, 0.0]));
    let json = serde_json::json!({
        "resolution": field.resolution,
        "n": field.oct.n,
        "vertices": field.oct.len(),
        "terms": terms,
        "scale": scale,
        "coding": field.coding.name(),
        "texels": texels,
        "points": points,
        "lumispheres": lumi,
        "keys": keys,
        "gain": gain,
        "gainKnots": field.gain.knots.len(),
        "size": data.len(),
    });
    let bin = data
        .iter()
        .flatten()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    PageField { json, bin }
}

/// Per atlas texel, its own grid point and the point it reads (appended to `data`); returns
/// where the table starts.
fn texel_table(field: &SurfaceLightField, data: &mut Vec<[f32; 4]>) -> usize {
    let start = data.len();
    let r = field.resolution;
    for t in 0..r * r {
        let (x, y) = (t % r, t / r);
        let uv = Vec2::new(
            (x as f32 + 0.5) / r as f32,
            1.0 - (y as f32 + 0.5) / r as f32,
        );
        let read = field.point_at(uv);
        let own = read.filter(|&p| field.texels[p] as usize == t);
        let f = |p: Option<usize>| p.map_or(-1.0, |p| p as f32);
        data.push([f(own), f(read), 0.0, 0.0]);
    }
    start
}

/// The lumispheres (their numbers) and weights whose sum is point `p`'s lumisphere.
fn point_terms(coding: &Coding, p: usize) -> Vec<(usize, f32)> {
    match coding {
        Coding::MedianOnly => Vec::new(),
        Coding::Faired(_) => vec![(p, 1.0)],
        Coding::Quantized(c) => vec![(c.index[p] as usize, 1.0)],
        Coding::Pfa(pfa) => pfa.coefficients[p].iter().copied().enumerate().collect(),
    }
}

/// The vertex of every lattice key of the octahedron (-1 where none).
fn key_table(field: &SurfaceLightField) -> Vec<f32> {
    let n = field.oct.n;
    let side = (2 * n + 1) as usize;
    let mut keys = vec![-1.0f32; side * side * 2];
    for (v, p) in field.oct.points.iter().enumerate() {
        let [x, y, z] = (*p * n as f32).round().to_array().map(|c| c as i32);
        let key = ((x + n) as usize * side + (y + n) as usize) * 2 + usize::from(z < 0);
        keys[key] = v as f32;
    }
    keys
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    /// What the page's shader does, in Rust, on the tables: it must give
    /// `SurfaceLightField::radiance_at` (here on a PFA field with two prototypes that vary with
    /// direction, over many directions and texture coordinates).
    #[test]
    fn the_tables_give_the_fields_radiance() {
        let oct = igi_lightfield::Octahedron::new(2);
        let r = 4;
        let texels: Vec<u32> = vec![0, 5, 6, 9, 10, 15];
        let median: Vec<Vec3> = (0..texels.len())
            .map(|p| Vec3::new(0.1 * p as f32, 0.5, 0.2))
            .collect();
        let proto = |k: f32| -> Vec<Vec3> {
            (0..oct.len())
                .map(|v| oct.direction(v) * k + Vec3::splat(0.3))
                .collect()
        };
        let pfa = igi_lightfield::pfa::Pfa {
            prototypes: vec![proto(0.4), proto(-0.2)],
            coefficients: (0..texels.len())
                .map(|p| vec![p as f32 / 5.0, 1.0 - p as f32 / 5.0])
                .collect(),
            energy_history: Vec::new(),
        };
        let field = SurfaceLightField::new(
            oct,
            r,
            texels.clone(),
            median,
            vec![Vec3::Z; texels.len()],
            Coding::Pfa(pfa),
        )
        .with_gain(igi_lightfield::AngleGain {
            knots: vec![3.0, 1.5, 1.0],
        });
        let page = page_field(&field, 2.0);
        let data: Vec<f32> = page
            .bin
            .chunks(4)
            .map(|b| f32::from_le_bytes(b.try_into().unwrap()))
            .collect();
        let texel = |k: usize| &data[4 * k..4 * k + 4];
        let j = |k: &str| page.json[k].as_u64().unwrap() as usize;
        let mut worst = 0.0f32;
        for i in 0..200 {
            let uv = Vec2::new((i % 17) as f32 / 16.0, (i / 17 % 12) as f32 / 11.0);
            let w = Vec3::new((i as f32 * 0.7).sin(), (i as f32 * 1.3).cos(), 0.8).normalize();
            let n = Vec3::new(0.2, -0.1, 1.0).normalize();
            let want = field.radiance_at(uv, w, n).unwrap_or(Vec3::ZERO);
            let got = shade(uv, w, n, texel, j);
            worst = worst.max((got - want).abs().max_element());
        }
        assert!(worst < 1e-5, "{worst}");
    }

    /// The shader of `assets/index.html` (`slfShader`), line for line.
    fn shade<'a>(
        uv: Vec2,
        w: Vec3,
        n: Vec3,
        texel: impl Fn(usize) -> &'a [f32],
        j: impl Fn(&str) -> usize,
    ) -> Vec3 {
        let (res, nn, nv, terms) = (j("resolution"), j("n") as i32, j("vertices"), j("terms"));
        let r = igi_lightfield::lumisphere::reflect_about_normal(w, n);
        let p = igi_lightfield::lumisphere::h_map(r);
        let sg = |x: f32| if x < 0.0 { -1 } else { 1 };
        let (sx, sy, sz) = (sg(p.x), sg(p.y), sg(p.z));
        let (a, b) = (p.x.abs() * nn as f32, p.y.abs() * nn as f32);
        let i = (a.floor() as i32).clamp(0, nn);
        let jj = (b.floor() as i32).clamp(0, nn - i);
        let (fa, fb) = (a - i as f32, b - jj as f32);
        let side = 2 * nn + 1;
        let vert = |i: i32, k: i32| {
            let (x, y, z) = (sx * i, sy * k, sz * (nn - i - k));
            let key = ((x + nn) * side + y + nn) * 2 + i32::from(z < 0);
            texel(j("keys") + key as usize)[0] as usize
        };
        let (vs, ws) = if i + jj >= nn {
            ([vert(i, nn - i); 3], [1.0, 0.0, 0.0])
        } else if fa + fb <= 1.0 || i + jj + 2 > nn {
            (
                [vert(i, jj), vert(i + 1, jj), vert(i, jj + 1)],
                [1.0 - fa - fb, fa, fb],
            )
        } else {
            (
                [vert(i + 1, jj + 1), vert(i + 1, jj), vert(i, jj + 1)],
                [fa + fb - 1.0, 1.0 - fb, 1.0 - fa],
            )
        };
        let ws = {
            let w = ws.map(|x: f32| x.max(0.0));
            let s = w[0] + w[1] + w[2];
            if s > 0.0 {
                w.map(|x| x / s)
            } else {
                [1.0, 0.0, 0.0]
            }
        };
        let gain = {
            let (g0, k) = (j("gain"), j("gainKnots"));
            let x = n.dot(w).clamp(0.0, 1.0) * (k.max(2) - 1) as f32;
            let i = (x.floor() as usize).min(k.max(2) - 2);
            let f = x - i as f32;
            match k {
                0 => 1.0,
                1 => texel(g0)[0],
                _ => texel(g0 + i)[0] * (1.0 - f) + texel(g0 + i + 1)[0] * f,
            }
        };
        let point = |p: usize| {
            let at = j("points") + p * (1 + terms);
            let m = texel(at);
            let mut c = Vec3::new(m[0], m[1], m[2]);
            for t in 0..terms {
                let tw = texel(at + 1 + t);
                let l = tw[0] as usize;
                for k in 0..3 {
                    let v = texel(j("lumispheres") + l * nv + vs[k]);
                    c += Vec3::new(v[0], v[1], v[2]) * ws[k] * tw[1] * gain;
                }
            }
            c
        };
        let (u, v) = igi_geometry::texels::clamp_uv(uv);
        let x = u * res as f32 - 0.5;
        let y = (1.0 - v) * res as f32 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let (mut sum, mut wsum) = (Vec3::ZERO, 0.0f32);
        for (dy, wy) in [(0, 1.0 - fy), (1, fy)] {
            for (dx, wx) in [(0, 1.0 - fx), (1, fx)] {
                let (tx, ty) = (x0 as i64 + dx, y0 as i64 + dy);
                let wt = wx * wy;
                if wt <= 0.0 || tx < 0 || ty < 0 || tx >= res as i64 || ty >= res as i64 {
                    continue;
                }
                let own = texel(j("texels") + ty as usize * res + tx as usize)[0];
                if own < 0.0 {
                    continue;
                }
                sum += point(own as usize) * wt;
                wsum += wt;
            }
        }
        if wsum > 0.0 {
            return (sum / wsum).max(Vec3::ZERO);
        }
        let tx = ((u * res as f32) as usize).min(res - 1);
        let ty = (((1.0 - v) * res as f32) as usize).min(res - 1);
        let read = texel(j("texels") + ty * res + tx)[1];
        if read < 0.0 {
            Vec3::ZERO
        } else {
            point(read as usize).max(Vec3::ZERO)
        }
    }
}
