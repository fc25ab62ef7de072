//! `igi compare`: RMSE, relative mean difference and PSNR of image A against reference B.
use crate::report::{print_json, Ctx};
use igi_imaging::metrics::{compare_files, CompareRequest};
use std::path::PathBuf;

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

pub fn run(a: CompareArgs, _ctx: &Ctx) -> anyhow::Result<()> {
    let req = CompareRequest {
        a: a.a,
        b: a.b,
        within: a.within,
        stderr_a: a.stderr_a,
        stderr_b: a.stderr_b,
        diff: a.diff,
    };
    let c = compare_files(&req)?;
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
