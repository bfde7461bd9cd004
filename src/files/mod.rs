//! Files at the lowest level, knowing nothing of cells or meshes, so that every layer may use them:
//!
//! - writing atomically under the output policy ([`write_atomically`], [`OutputGroup`],
//!   [`OutputPolicy`]; `atomic.rs`, `output.rs`): a temporary sibling renamed into place, never
//!   replacing anything but a regular file, so a crash never leaves a half-written file that looks
//!   complete;
//! - reading a whole input with a size cap ([`read_capped`], [`read_text_capped`]; `bounded.rs`);
//! - the plausible ranges of lengths and surface tensions a user gives, which catch a unit slip
//!   ([`implausible_length`], [`implausible_tension`]; `plausible.rs`);
//! - the font of every picture's text ([`ensure_font`]; `font.rs`).
//!
//! `io` re-exports all of it next to the tissue formats; modules below `io` (`imaging`'s TIFF
//! writer, `mechanics`' parameter files) import it from here.

mod atomic;
mod bounded;
mod error;
mod font;
mod output;
mod plausible;

pub use atomic::{remove_stale_temporaries, remove_stale_temporaries_of, write_atomically, write_bytes_atomically};
pub use bounded::{MAX_CONFIG_FILE, MAX_TISSUE_FILE, UNSIZED_CAP, read_capped, read_text_capped};
pub use error::FileError;
pub use font::ensure_font;
pub use output::{Format, OutputError, OutputGroup, OutputPolicy, check_target, replace_with};
pub use plausible::{PLAUSIBLE_LENGTH, PLAUSIBLE_TENSION, implausible_length, implausible_tension};
