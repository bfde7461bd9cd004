//! The rasteriser: project, z-buffer, shade, downsample.

use super::RenderError;
use crate::geometry::{Real, Vec3};
use crate::io::write_bytes_atomically;
use crate::mesh::{CellKind, FaceType, Tissue};
use image::{ImageOutputFormat, RgbImage};
use std::path::Path;

/// What decides a face's colour.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum ColorBy {
    /// One colour per cell id (a fixed palette; the same id gets the same colour in every picture).
    Cell,
    /// By cell kind: epithelial, ECM, lumen, nucleus, static.
    Kind,
    /// By face type: apical, lateral, basal.
    FaceType,
}

/// Where the (orthographic) camera looks from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum View {
    /// From (+1, −1, +1), z up.
    Iso,
    /// From +x, z up.
    X,
    /// From −y, z up.
    Y,
    /// From +z, y up.
    Z,
}

/// How to draw.
#[derive(Clone, Debug)]
pub struct RenderOptions {
    pub width: u32,
    pub height: u32,
    pub color_by: ColorBy,
    pub view: View,
    /// Darken triangle edges.
    pub edges: bool,
}

impl Default for RenderOptions {
    fn default() -> Self {
        Self { width: 800, height: 600, color_by: ColorBy::Cell, view: View::Iso, edges: false }
    }
}

/// Background colour (white).
pub const BACKGROUND: [u8; 3] = [255, 255, 255];
/// Supersampling factor per side.
const SUPERSAMPLE: u32 = 2;

/// Camera basis: right, up, and toward the viewer (all unit, right-handed).
fn basis(view: View) -> (Vec3, Vec3, Vec3) {
    let (toward, up) = match view {
        View::Iso => (Vec3::new(1.0, -1.0, 1.0).normalize(), Vec3::z()),
        View::X => (Vec3::x(), Vec3::z()),
        View::Y => (-Vec3::y(), Vec3::z()),
        View::Z => (Vec3::z(), Vec3::y()),
    };
    let right = up.cross(&toward).normalize();
    let up = toward.cross(&right);
    (right, up, toward)
}

/// Distinct colours for ids: hues stepped by the golden angle, two lightness levels.
fn palette(i: u32) -> [Real; 3] {
    let h = (i as Real * 0.618_033_988_75).fract() * 6.0;
    let (s, v) = if i.is_multiple_of(2) { (0.55, 0.95) } else { (0.65, 0.8) };
    let c = v * s;
    let x = c * (1.0 - ((h % 2.0) - 1.0).abs());
    let (r, g, b) = match h as u32 {
        0 => (c, x, 0.0),
        1 => (x, c, 0.0),
        2 => (0.0, c, x),
        3 => (0.0, x, c),
        4 => (x, 0.0, c),
        _ => (c, 0.0, x),
    };
    let m = v - c;
    [r + m, g + m, b + m]
}

fn kind_color(kind: CellKind) -> [Real; 3] {
    match kind {
        CellKind::Epithelial => [0.95, 0.65, 0.35],
        CellKind::Ecm => [0.6, 0.75, 0.6],
        CellKind::Lumen => [0.55, 0.75, 0.95],
        CellKind::Nucleus => [0.6, 0.45, 0.8],
        CellKind::Static => [0.7, 0.7, 0.7],
    }
}

fn face_type_color(t: FaceType) -> [Real; 3] {
    match t {
        FaceType::Apical => [0.9, 0.35, 0.3],
        FaceType::Lateral => [0.35, 0.7, 0.4],
        FaceType::Basal => [0.3, 0.5, 0.9],
    }
}

/// Draws `tissue` into an RGB image of `options.width` × `options.height` pixels.
pub fn render_tissue(tissue: &Tissue, options: &RenderOptions) -> Result<RgbImage, RenderError> {
    let (w, h) = (options.width, options.height);
    if !(16..=8192).contains(&w) || !(16..=8192).contains(&h) {
        return Err(RenderError::Size { width: w, height: h });
    }
    if tissue.is_empty() {
        return Err(RenderError::Empty);
    }
    let (right, up, toward) = basis(options.view);
    // Screen bounds of every node.
    let (mut lo, mut hi) = ([Real::INFINITY; 2], [Real::NEG_INFINITY; 2]);
    for cell in tissue.cells() {
        for p in cell.mesh().positions() {
            if !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite()) {
                return Err(RenderError::NonFinite { cell: cell.id().0 });
            }
            let (u, v) = (p.dot(&right), p.dot(&up));
            lo = [lo[0].min(u), lo[1].min(v)];
            hi = [hi[0].max(u), hi[1].max(v)];
        }
    }
    let (sw, sh) = (w * SUPERSAMPLE, h * SUPERSAMPLE);
    // Fit with a 6 % margin on each side, keeping the aspect ratio.
    let span = [(hi[0] - lo[0]).max(Real::MIN_POSITIVE), (hi[1] - lo[1]).max(Real::MIN_POSITIVE)];
    let scale = (0.88 * sw as Real / span[0]).min(0.88 * sh as Real / span[1]);
    let centre = [(lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0];
    let to_screen = |p: &Vec3| -> [Real; 3] {
        [
            sw as Real / 2.0 + (p.dot(&right) - centre[0]) * scale,
            sh as Real / 2.0 - (p.dot(&up) - centre[1]) * scale,
            p.dot(&toward),
        ]
    };
    let light = (toward + 0.4 * up + 0.25 * right).normalize();
    let mut depth = vec![Real::NEG_INFINITY; (sw * sh) as usize];
    let mut color = vec![BACKGROUND.map(|c| c as Real / 255.0); (sw * sh) as usize];
    // Edge half-width in supersampled pixels.
    let edge_width = 0.6 * SUPERSAMPLE as Real;
    for cell in tissue.cells() {
        let mesh = cell.mesh();
        let screen: Vec<[Real; 3]> = mesh.positions().iter().map(to_screen).collect();
        for (f, tri) in mesh.triangles().iter().enumerate() {
            let [a, b, c] = tri.map(|i| mesh.positions()[i as usize]);
            let normal = (b - a).cross(&(c - a));
            let n = normal.norm();
            if n == 0.0 {
                continue;
            }
            let base = match options.color_by {
                ColorBy::Cell => palette(cell.id().0),
                ColorBy::Kind => kind_color(cell.kind()),
                ColorBy::FaceType => face_type_color(cell.face_types().get(f).copied().unwrap_or_default()),
            };
            // Two-sided: a face seen from behind (inside an open cut) is lit by its reversed normal.
            let shade = 0.3 + 0.7 * (normal / n).dot(&light).abs();
            let rgb = base.map(|x| (x * shade).min(1.0));
            let [p0, p1, p2] = tri.map(|i| screen[i as usize]);
            let area = (p1[0] - p0[0]) * (p2[1] - p0[1]) - (p1[1] - p0[1]) * (p2[0] - p0[0]);
            if area.abs() < 1e-12 {
                continue;
            }
            let x0 = p0[0].min(p1[0]).min(p2[0]).floor().max(0.0) as u32;
            let x1 = (p0[0].max(p1[0]).max(p2[0]).ceil().min(sw as Real - 1.0)).max(0.0) as u32;
            let y0 = p0[1].min(p1[1]).min(p2[1]).floor().max(0.0) as u32;
            let y1 = (p0[1].max(p1[1]).max(p2[1]).ceil().min(sh as Real - 1.0)).max(0.0) as u32;
            let lengths = [dist(p1, p2), dist(p2, p0), dist(p0, p1)];
            for y in y0..=y1 {
                for x in x0..=x1 {
                    let (px, py) = (x as Real + 0.5, y as Real + 0.5);
                    let e = |s: [Real; 3], t: [Real; 3]| (t[0] - s[0]) * (py - s[1]) - (t[1] - s[1]) * (px - s[0]);
                    let wts = [e(p1, p2) / area, e(p2, p0) / area, e(p0, p1) / area];
                    if wts.iter().any(|&l| l < -1e-9) {
                        continue;
                    }
                    let z = wts[0] * p0[2] + wts[1] * p1[2] + wts[2] * p2[2];
                    let k = (y * sw + x) as usize;
                    if z <= depth[k] {
                        continue;
                    }
                    depth[k] = z;
                    // Distance to the nearest edge in pixels: barycentric × 2·area / edge length.
                    let near_edge = options.edges
                        && (0..3).any(|i| lengths[i] > 0.0 && wts[i] * area.abs() / lengths[i] < edge_width);
                    color[k] = if near_edge { rgb.map(|x| x * 0.45) } else { rgb };
                }
            }
        }
    }
    // Box filter down to the requested size.
    let mut img = RgbImage::new(w, h);
    let n = (SUPERSAMPLE * SUPERSAMPLE) as Real;
    for (x, y, pixel) in img.enumerate_pixels_mut() {
        let mut sum = [0.0; 3];
        for dy in 0..SUPERSAMPLE {
            for dx in 0..SUPERSAMPLE {
                let c = color[((y * SUPERSAMPLE + dy) * sw + x * SUPERSAMPLE + dx) as usize];
                (0..3).for_each(|i| sum[i] += c[i]);
            }
        }
        pixel.0 = sum.map(|s| (s / n * 255.0).round().clamp(0.0, 255.0) as u8);
    }
    Ok(img)
}

fn dist(a: [Real; 3], b: [Real; 3]) -> Real {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt()
}

/// Encodes `img` as PNG and writes it to `path` (temporary name, then renamed).
pub fn write_png(path: &Path, img: &RgbImage) -> Result<(), RenderError> {
    let err = |message: String| RenderError::Write { path: path.to_path_buf(), message };
    let mut bytes = std::io::Cursor::new(Vec::new());
    img.write_to(&mut bytes, ImageOutputFormat::Png).map_err(|e| err(e.to_string()))?;
    write_bytes_atomically(path, bytes.get_ref()).map_err(|e| err(e.to_string()))
}
