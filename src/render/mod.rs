//! Pictures of a tissue without system libraries (`tissuefit render`): an orthographic software
//! rasteriser with a z-buffer, flat Lambert shading (ambient 0.3 + diffuse 0.7·max(0, n̂·l̂), the light
//! coming from over the viewer's shoulder), per-cell, per-kind or per-face-type colours, or numbers per
//! face (tension, pressure, any per-face array) on the viridis scale with a colour bar, and optional
//! triangle edges, supersampled 2×2 and box-filtered for smooth outlines. Enough to show a tissue
//! before and after relaxation; ParaView remains the tool for anything else.

mod raster;

pub use raster::{ColorBy, FaceScalars, RenderOptions, View, png_bytes, render_tissue, viridis, write_png};

/// Why a picture could not be made.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error("the tissue has no cell to draw")]
    Empty,
    #[error("image size {width}x{height}: each side must be between 16 and 8192 pixels")]
    Size { width: u32, height: u32 },
    #[error("cell {cell}: non-finite node coordinates; cannot draw it")]
    NonFinite { cell: u32 },
    #[error("{0}")]
    Scalars(String),
    #[error("writing {path}: {message}")]
    Write { path: std::path::PathBuf, message: String },
}
