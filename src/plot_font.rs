//! The font every picture is drawn with: DejaVu Sans (`assets/fonts/`, from Debian's
//! `fonts-dejavu-core`), built into the binary, so that a machine with no fonts installed
//! (as many CI containers are) draws the same pictures.

use std::sync::OnceLock;

/// DejaVu Sans 2.37 (licence: `assets/fonts/LICENSE`).
static DEJAVU_SANS: &[u8] = include_bytes!("../assets/fonts/DejaVuSans.ttf");

/// The font family the pictures name (plotters' default for labels too).
pub const FAMILY: &str = "sans-serif";

/// Registers the built-in font as [`FAMILY`], once per process; call before drawing.
pub fn register() -> Result<(), String> {
    static DONE: OnceLock<Result<(), String>> = OnceLock::new();
    DONE.get_or_init(|| {
        plotters::style::register_font(FAMILY, plotters::style::FontStyle::Normal, DEJAVU_SANS)
            .map_err(|_| "the built-in font (assets/fonts/DejaVuSans.ttf) cannot be read".to_string())
    })
    .clone()
}
