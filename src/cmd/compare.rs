//! `igi compare`: RMSE, relative mean difference and PSNR of image A against reference B.
use crate::report::{print_json, Ctx};
use anyhow::Context;
use igi_render::{compare_images, difference_image};
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug)]
pub struct CompareArgs {
    /// The image to judge. In an RGBA EXR, pixels of alpha 0 (nothing seen there, as
    /// `igi slf render` writes) are not compared; the same holds for B.
    pub a: PathBuf,
    /// The reference (PSNR peak = max of B).
    pub b: PathBuf,
    /// Print the metrics as JSON.
    #[arg(long)]
    pub json: bool,
    /// Write a false-colour picture of |A - B| (PNG).
    #[arg(long)]
    pub diff: Option<PathBuf>,
    /// Per-pixel standard error of A (EXR), to report the RMSE that noise explains.
    #[arg(long)]
    pub stderr_a: Option<PathBuf>,
    /// Per-pixel standard error of B.
    #[arg(long)]
    pub stderr_b: Option<PathBuf>,
    /// Compare only the pixels this RGBA EXR covers (alpha > 0), e.g. another method's render,
    /// so that two methods are judged on the same pixels.
    #[arg(long)]
    pub within: Option<PathBuf>,
}

/// An image whose pixels of alpha 0 (an RGBA EXR's uncovered pixels, e.g. `igi slf render`'s
/// background) are invalid, so that they are not compared.
fn read_covered(p: &Path) -> anyhow::Result<igi_imaging::HdrImage> {
    let mut img = igi_imaging::read_image(p).with_context(|| format!("reading {}", p.display()))?;
    let is_exr = p.extension().is_some_and(|e| e.eq_ignore_ascii_case("exr"));
    if is_exr {
        if let Some(alpha) = igi_imaging::read_exr_alpha(p)? {
            for (v, a) in img.valid.iter_mut().zip(alpha) {
                *v &= a > 0.0;
            }
        }
    }
    Ok(img)
}

pub fn run(a: CompareArgs, _ctx: &Ctx) -> anyhow::Result<()> {
    let read = |p: &PathBuf| {
        igi_imaging::read_image(p).with_context(|| format!("reading {}", p.display()))
    };
    let mut ia = read_covered(&a.a)?;
    let ib = read_covered(&a.b)?;
    if let Some(w) = &a.within {
        let alpha = igi_imaging::read_exr_alpha(w)
            .with_context(|| format!("reading {}", w.display()))?
            .with_context(|| {
                format!(
                    "{}: --within needs an RGBA EXR (it has no alpha)",
                    w.display()
                )
            })?;
        anyhow::ensure!(
            alpha.len() == ia.valid.len(),
            "{}: --within is {} pixels but {} is {}",
            w.display(),
            alpha.len(),
            a.a.display(),
            ia.valid.len()
        );
        for (v, al) in ia.valid.iter_mut().zip(alpha) {
            *v &= al > 0.0;
        }
    }
    let sa = a.stderr_a.as_ref().map(read).transpose()?;
    let sb = a.stderr_b.as_ref().map(read).transpose()?;
    let c = compare_images(&ia, &ib, sa.as_ref(), sb.as_ref())
        .with_context(|| format!("comparing {} with {}", a.a.display(), a.b.display()))?;
    if let Some(d) = &a.diff {
        let img = difference_image(&ia, &ib, None)?;
        igi_imaging::write_png_tonemapped(d, &img, 1.0)?;
    }
    if a.json {
        print_json(&c)?;
    } else {
        println!("pixels compared          {}", c.pixels);
        println!("RMSE                     {:.6e}", c.rmse);
        if let Some(n) = c.noise_rmse {
            println!(
                "RMSE explained by noise  {:.6e}  (ratio {:.3})",
                n,
                c.rmse / n
            );
        }
        println!(
            "relative mean difference {:+.4}%  (mean A {:.6e}, mean B {:.6e})",
            100.0 * c.relative_mean_difference,
            c.mean_a,
            c.mean_b
        );
        println!("PSNR (peak = max of B)   {:.2} dB", c.psnr_db);
    }
    Ok(())
}
