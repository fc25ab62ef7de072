//! Fonts for the plots people look at (plotters with its `ab_glyph` text backend).
//!
//! plotters draws text only with fonts registered at run time. `register_fonts` registers
//! DejaVu Sans (Debian's `fonts-dejavu-core`, installed by `scripts/deps.sh`) as "sans-serif",
//! once per process. Without the font, plots are still drawn, only without text.

use std::sync::OnceLock;

/// Where DejaVu Sans is looked for, in order.
const CANDIDATES: [&str; 3] = [
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
];

/// Registers the "sans-serif" font for plotters; returns whether a font is available.
pub fn register_fonts() -> bool {
    static DONE: OnceLock<bool> = OnceLock::new();
    *DONE.get_or_init(|| {
        for path in CANDIDATES {
            if let Ok(bytes) = std::fs::read(path) {
                let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
                if plotters::style::register_font(
                    "sans-serif",
                    plotters::style::FontStyle::Normal,
                    bytes,
                )
                .is_ok()
                {
                    return true;
                }
            }
        }
        false
    })
}
