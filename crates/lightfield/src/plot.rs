//! The error-against-size plot of the codings (docs/LIGHTFIELD.md): held-out PSNR against the
//! colour bytes of each stored field, colour bytes on a logarithmic axis.

use crate::LightFieldError;
use igi_plot::{write_chart, Axis, Chart, Series, BLUE_RGB};
use std::path::Path;

/// One stored field: its label (the method), colour bytes and held-out PSNR (dB).
#[derive(Clone, Debug, serde::Serialize)]
pub struct SizePoint {
    pub label: String,
    pub colour_bytes: u64,
    pub psnr_db: f64,
}

/// Writes the plot as a PNG (atomically).
pub fn plot_error_against_size(path: &Path, points: &[SizePoint]) -> Result<(), LightFieldError> {
    let bytes = points.iter().map(|p| p.colour_bytes.max(1) as f64);
    let (xlo, xhi) = bytes.fold((f64::INFINITY, 0f64), |(a, b), x| (a.min(x), b.max(x)));
    let psnr = points.iter().map(|p| p.psnr_db).filter(|p| p.is_finite());
    let (ylo, yhi) = psnr.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), y| {
        (a.min(y), b.max(y))
    });
    if points.is_empty() || !(ylo <= yhi) {
        return Err(LightFieldError::Format {
            path: path.to_path_buf(),
            msg: "nothing to plot (no finite PSNR)".into(),
        });
    }
    let mut marks = Series::dots(
        points
            .iter()
            .map(|p| (p.colour_bytes.max(1) as f64, p.psnr_db))
            .collect(),
        BLUE_RGB,
        5,
    );
    marks.point_labels = points.iter().map(|p| p.label.clone()).collect();
    let chart = Chart {
        title: "surface light field: held-out PSNR against colour bytes".into(),
        x: Axis::log("colour bytes (median + coding)", xlo / 1.5..xhi * 1.5),
        y: Axis::linear("held-out PSNR (dB)", (ylo - 1.0)..(yhi + 1.0)),
        series: vec![marks],
    };
    write_chart(path, (800, 500), &chart)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_a_png_and_refuses_an_empty_plot() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("plot.png");
        let pts = [("fair", 7_900_000, 22.0), ("pfa2", 70_000, 21.5)].map(|(l, b, y)| SizePoint {
            label: l.into(),
            colour_bytes: b,
            psnr_db: y,
        });
        plot_error_against_size(&p, &pts).unwrap();
        let img = igi_imaging::read_image(&p).unwrap();
        assert_eq!((img.width, img.height), (800, 500));
        assert!(plot_error_against_size(&dir.path().join("none.png"), &[]).is_err());
        assert!(!dir.path().join("none.png").exists());
    }
}
