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
    /// By the per-face tension of a `tensions.vtp` or a per-cell fit's `tissue.vtp` (a colour bar
    /// beside).
    Tension,
    /// By the cell pressure of a `tensions.vtp` or a per-cell fit's `tissue.vtp` (a colour bar
    /// beside).
    Pressure,
    /// By any one-component per-face array of a `.vtp` file, named with `--field`.
    Field,
}

impl ColorBy {
    /// Whether faces are coloured by numbers (from [`RenderOptions::scalars`]).
    pub fn is_scalar(self) -> bool {
        matches!(self, Self::Tension | Self::Pressure | Self::Field)
    }
}

/// Numbers to colour faces by: one per triangle, cells in the tissue's order.
#[derive(Clone, Debug)]
pub struct FaceScalars {
    /// The colour bar's title (name and unit).
    pub label: String,
    pub values: Vec<Real>,
    /// The values at the ends of the colour scale (default: the smallest and largest finite value).
    pub range: Option<(Real, Real)>,
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
    /// The numbers behind a scalar [`ColorBy`] (required for those, ignored otherwise).
    pub scalars: Option<FaceScalars>,
    /// Moves each cell away from the tissue's centre by this fraction of its centre's distance, so
    /// that the faces between cells (where the tensions of a map are) come into view; 0: as is.
    pub explode: Real,
}

impl Default for RenderOptions {
    fn default() -> Self {
        Self {
            width: 800,
            height: 600,
            color_by: ColorBy::Cell,
            view: View::Iso,
            edges: false,
            scalars: None,
            explode: 0.0,
        }
    }
}

/// The colour of faces without a value (NaN).
const NO_VALUE: [Real; 3] = [0.78, 0.78, 0.78];

/// Viridis (perceptually uniform, readable in grey and by the colour-blind), sampled at nine stops.
const VIRIDIS: [[u8; 3]; 9] = [
    [68, 1, 84],
    [71, 44, 122],
    [59, 81, 139],
    [44, 113, 142],
    [33, 144, 141],
    [39, 173, 129],
    [92, 200, 99],
    [170, 220, 50],
    [253, 231, 37],
];

/// The colour of `t` in [0, 1] (clamped) on the viridis scale.
pub fn viridis(t: Real) -> [Real; 3] {
    let x = t.clamp(0.0, 1.0) * (VIRIDIS.len() - 1) as Real;
    let i = (x.floor() as usize).min(VIRIDIS.len() - 2);
    let f = x - i as Real;
    std::array::from_fn(|k| ((1.0 - f) * VIRIDIS[i][k] as Real + f * VIRIDIS[i + 1][k] as Real) / 255.0)
}

/// The colour scale's ends: the given range or the finite values' extent (widened when flat).
fn scalar_range(scalars: &FaceScalars) -> Result<(Real, Real), RenderError> {
    let (lo, hi) = match scalars.range {
        Some(r) => r,
        None => scalars
            .values
            .iter()
            .filter(|v| v.is_finite())
            .fold((Real::INFINITY, Real::NEG_INFINITY), |(lo, hi), &v| (lo.min(v), hi.max(v))),
    };
    if !(lo.is_finite() && hi.is_finite()) {
        return Err(RenderError::Scalars(format!("'{}' has no finite value to colour by", scalars.label)));
    }
    if hi < lo {
        return Err(RenderError::Scalars(format!("colour range {lo}..{hi}: the lower end is above the upper")));
    }
    Ok(if hi == lo { (lo - 0.5 * lo.abs().max(1e-12), hi + 0.5 * hi.abs().max(1e-12)) } else { (lo, hi) })
}

/// Width in pixels of the colour-bar strip of a `width`-pixel picture.
fn legend_width(width: u32) -> u32 {
    (width / 5).clamp(70, 180).min(width / 2)
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

/// Draws `tissue` into an RGB image of `options.width` × `options.height` pixels; coloured by numbers,
/// the right-hand strip holds the colour bar.
pub fn render_tissue(tissue: &Tissue, options: &RenderOptions) -> Result<RgbImage, RenderError> {
    let (w, h) = (options.width, options.height);
    if !(16..=8192).contains(&w) || !(16..=8192).contains(&h) {
        return Err(RenderError::Size { width: w, height: h });
    }
    if tissue.is_empty() {
        return Err(RenderError::Empty);
    }
    if !options.color_by.is_scalar() {
        return rasterise(tissue, options, w, h, None);
    }
    let scalars = options.scalars.as_ref().ok_or_else(|| {
        RenderError::Scalars(format!("colouring by {:?} needs the per-face values", options.color_by))
    })?;
    if scalars.values.len() != tissue.face_count() {
        return Err(RenderError::Scalars(format!(
            "'{}' has {} values for {} faces",
            scalars.label,
            scalars.values.len(),
            tissue.face_count()
        )));
    }
    let range = scalar_range(scalars)?;
    let legend = legend_width(w);
    let tissue_img = rasterise(tissue, options, w - legend, h, Some((scalars, range)))?;
    let mut img = RgbImage::from_pixel(w, h, image::Rgb(BACKGROUND));
    image::imageops::replace(&mut img, &tissue_img, 0, 0);
    draw_colour_bar(&mut img, w - legend, scalars, range);
    Ok(img)
}

/// The colour bar in the strip right of `x0`: the scale (viridis, high at the top) with its ends and
/// middle labelled, the title above, and a grey swatch "no value" when some face has none.
fn draw_colour_bar(img: &mut RgbImage, x0: u32, scalars: &FaceScalars, (lo, hi): (Real, Real)) {
    use plotters::prelude::*;
    crate::files::ensure_font();
    let (w, h) = img.dimensions();
    let layout = BarLayout::new(w, h, &scalars.label);
    let (top, bottom, bar_x, bar_w, font_px) = (layout.top, layout.bottom, layout.x, layout.width, layout.font_px);
    let root = BitMapBackend::with_buffer(img, (w, h)).into_drawing_area();
    let rgb = |c: [Real; 3]| RGBColor((c[0] * 255.0) as u8, (c[1] * 255.0) as u8, (c[2] * 255.0) as u8);
    for y in top..bottom {
        let t = 1.0 - (y - top) as Real / (bottom - top - 1).max(1) as Real;
        let _ = root.draw(&Rectangle::new([(bar_x, y), (bar_x + bar_w, y + 1)], rgb(viridis(t)).filled()));
    }
    let _ = root.draw(&Rectangle::new([(bar_x - 1, top - 1), (bar_x + bar_w, bottom)], BLACK.stroke_width(1)));
    let style = ("sans-serif", font_px).into_font().color(&BLACK);
    let label = |v: Real| {
        let m = lo.abs().max(hi.abs());
        if m != 0.0 && !(1e-2..1e4).contains(&m) { format!("{v:.2e}") } else { format!("{v:.3}") }
    };
    for (t, v) in [(0.0, lo), (0.5, 0.5 * (lo + hi)), (1.0, hi)] {
        let y = bottom - 1 - (t * (bottom - top - 1) as Real) as i32;
        let _ = root.draw(&PathElement::new([(bar_x + bar_w, y), (bar_x + bar_w + 4, y)], BLACK));
        let _ = root.draw(&Text::new(label(v), (bar_x + bar_w + 6, y - font_px as i32 / 2), style.clone()));
    }
    for (k, line) in layout.title.iter().enumerate() {
        let y = layout.margin + k as i32 * (font_px * 1.2) as i32;
        let _ = root.draw(&Text::new(line.clone(), (x0 as i32 + 4, y), style.clone()));
    }
    if scalars.values.iter().any(|v| !v.is_finite()) {
        let y = bottom + (font_px * 1.5) as i32;
        let _ = root.draw(&Rectangle::new([(bar_x, y), (bar_x + bar_w, y + font_px as i32)], rgb(NO_VALUE).filled()));
        let _ = root.draw(&Text::new("no value", (bar_x + bar_w + 6, y), style.clone()));
    }
    let _ = root.present();
}

/// Where the colour bar of a `w` × `h` picture goes: the title wrapped at spaces into lines that fit
/// the strip, then the bar (rows `top..bottom`, columns `x..x + width`).
struct BarLayout {
    title: Vec<String>,
    margin: i32,
    top: i32,
    bottom: i32,
    x: i32,
    width: i32,
    font_px: Real,
}

impl BarLayout {
    fn new(w: u32, h: u32, label: &str) -> Self {
        let strip = legend_width(w);
        let x0 = (w - strip) as Real;
        let font_px = (h as Real / 30.0).clamp(10.0, 22.0);
        let max_chars = ((strip as Real - 8.0) / (0.55 * font_px)).max(4.0) as usize;
        let mut title: Vec<String> = Vec::new();
        for word in label.split(' ') {
            match title.last_mut() {
                Some(line) if line.chars().count() + 1 + word.chars().count() <= max_chars => {
                    line.push(' ');
                    line.push_str(word);
                }
                _ => title.push(word.to_owned()),
            }
        }
        title.truncate(5);
        let margin = (h as Real * 0.02) as i32;
        let top = margin + (title.len() as Real * font_px * 1.2 + font_px) as i32;
        let bottom = (h as Real * 0.85) as i32;
        Self {
            title,
            margin,
            top: top.min(bottom - 10),
            bottom,
            x: (x0 + strip as Real * 0.12) as i32,
            width: ((strip as Real * 0.2) as i32).max(8),
            font_px,
        }
    }
}

/// Rasterises `tissue` into `w` × `h` pixels; `scalars` (with the colour range) colour the faces when
/// given.
fn rasterise(
    tissue: &Tissue,
    options: &RenderOptions,
    w: u32,
    h: u32,
    scalars: Option<(&FaceScalars, (Real, Real))>,
) -> Result<RgbImage, RenderError> {
    let (right, up, toward) = basis(options.view);
    for cell in tissue.cells() {
        if cell.mesh().positions().iter().any(|p| !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite())) {
            return Err(RenderError::NonFinite { cell: cell.id().0 });
        }
    }
    // Each cell's shift of an exploded view: `explode` × (its node mean − the mean of those).
    let centres: Vec<Vec3> = tissue
        .cells()
        .iter()
        .map(|c| c.mesh().positions().iter().sum::<Vec3>() / c.mesh().positions().len().max(1) as Real)
        .collect();
    let middle = centres.iter().sum::<Vec3>() / centres.len() as Real;
    let shifts: Vec<Vec3> = centres.iter().map(|c| options.explode * (c - middle)).collect();
    // Screen bounds of every node.
    let (mut lo, mut hi) = ([Real::INFINITY; 2], [Real::NEG_INFINITY; 2]);
    for (cell, shift) in tissue.cells().iter().zip(&shifts) {
        for p in cell.mesh().positions() {
            let p = p + shift;
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
    let mut first_face = 0;
    for (cell, shift) in tissue.cells().iter().zip(&shifts) {
        let mesh = cell.mesh();
        let offset = first_face;
        first_face += mesh.face_count();
        let screen: Vec<[Real; 3]> = mesh.positions().iter().map(|p| to_screen(&(p + shift))).collect();
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
                ColorBy::Tension | ColorBy::Pressure | ColorBy::Field => match scalars {
                    Some((s, (lo, hi))) => {
                        let v = s.values[offset + f];
                        if v.is_finite() { viridis((v - lo) / (hi - lo)) } else { NO_VALUE }
                    }
                    None => NO_VALUE,
                },
            };
            // Two-sided: a face seen from behind (inside an open cut) is lit by its reversed normal.
            // Numbers keep more of their colour (milder shading) so the scale stays readable.
            let lit = (normal / n).dot(&light).abs();
            let shade = if scalars.is_some() { 0.6 + 0.4 * lit } else { 0.3 + 0.7 * lit };
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
    let bytes = png_bytes(img).map_err(err)?;
    write_bytes_atomically(path, &bytes).map_err(|e| err(e.to_string()))
}

/// `img` encoded as PNG.
pub fn png_bytes(img: &RgbImage) -> Result<Vec<u8>, String> {
    let mut bytes = std::io::Cursor::new(Vec::new());
    img.write_to(&mut bytes, ImageOutputFormat::Png).map_err(|e| e.to_string())?;
    Ok(bytes.into_inner())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{Cell, CellId, shapes::icosphere};

    /// Two unit spheres side by side along x (cell 1 at x = −1.5, cell 2 at x = +1.5).
    fn pair() -> Tissue {
        let cells = [(1, -1.5), (2, 1.5)]
            .map(|(id, x)| Cell::new(CellId(id), CellKind::Epithelial, 0, icosphere(1.0, 2, Vec3::new(x, 0.0, 0.0))));
        Tissue::from_cells(cells.into()).unwrap()
    }

    fn by_values(tissue: &Tissue, per_cell: [Real; 2], range: Option<(Real, Real)>) -> RenderOptions {
        let values = tissue.cells().iter().zip(per_cell).flat_map(|(c, v)| vec![v; c.mesh().face_count()]).collect();
        RenderOptions {
            width: 400,
            height: 200,
            view: View::Z,
            color_by: ColorBy::Field,
            scalars: Some(FaceScalars { label: "tension (mN/m)".into(), values, range }),
            ..RenderOptions::default()
        }
    }

    /// Mean colour of the drawn (non-white) pixels with x in `xs`.
    fn mean_colour(img: &RgbImage, xs: std::ops::Range<u32>) -> [Real; 3] {
        let (mut sum, mut n) = ([0.0; 3], 0.0);
        for (x, _, p) in img.enumerate_pixels() {
            if xs.contains(&x) && p.0 != BACKGROUND {
                (0..3).for_each(|i| sum[i] += p.0[i] as Real);
                n += 1.0;
            }
        }
        assert!(n > 100.0, "{n} pixels drawn in {xs:?}");
        sum.map(|s| s / n)
    }

    #[test]
    fn numbers_are_coloured_on_the_viridis_scale_with_a_colour_bar() {
        let tissue = pair();
        let img = render_tissue(&tissue, &by_values(&tissue, [0.5, 2.0], None)).unwrap();
        let strip = legend_width(400);
        // The tissue fills the left part: the low cell (left) is viridis' purple (blue above green),
        // the high one (right) its yellow (green above blue); shading only darkens.
        let tissue_w = 400 - strip;
        let low = mean_colour(&img, 0..tissue_w / 2);
        let high = mean_colour(&img, tissue_w / 2..tissue_w);
        assert!(low[2] > low[1] + 20.0 && high[1] > high[2] + 80.0, "low {low:?}, high {high:?}");
        // The bar: the top of the scale is the highest value's colour, the bottom the lowest's.
        let layout = BarLayout::new(400, 200, "tension (mN/m)");
        let bar_x = (layout.x + 2) as u32;
        let (top, bottom) = (layout.top as u32 + 1, layout.bottom as u32 - 2);
        let near = |p: [u8; 3], c: [Real; 3]| (0..3).all(|i| (p[i] as Real - c[i] * 255.0).abs() <= 12.0);
        assert!(near(img.get_pixel(bar_x, top).0, viridis(1.0)), "{:?}", img.get_pixel(bar_x, top));
        assert!(near(img.get_pixel(bar_x, bottom).0, viridis(0.0)), "{:?}", img.get_pixel(bar_x, bottom));
        // A range that puts both cells at the top of the scale colours them alike.
        let img = render_tissue(&tissue, &by_values(&tissue, [0.5, 2.0], Some((-10.0, 0.1)))).unwrap();
        let (a, b) = (mean_colour(&img, 0..tissue_w / 2), mean_colour(&img, tissue_w / 2..tissue_w));
        assert!((0..3).all(|i| (a[i] - b[i]).abs() < 8.0), "{a:?} vs {b:?}");
    }

    #[test]
    fn missing_and_mismatched_numbers_are_errors_or_grey() {
        let tissue = pair();
        let mut options = by_values(&tissue, [Real::NAN, 1.0], None);
        let img = render_tissue(&tissue, &options).unwrap();
        // The cell without values is grey (channels equal).
        let grey = mean_colour(&img, 0..(400 - legend_width(400)) / 2);
        assert!((grey[0] - grey[1]).abs() < 2.0 && (grey[1] - grey[2]).abs() < 2.0, "{grey:?}");
        options.scalars.as_mut().unwrap().values.pop();
        let e = render_tissue(&tissue, &options).unwrap_err().to_string();
        assert!(e.contains("values for") && e.contains("faces"), "{e}");
        let all_nan = by_values(&tissue, [Real::NAN; 2], None);
        let e = render_tissue(&tissue, &all_nan).unwrap_err().to_string();
        assert!(e.contains("no finite value"), "{e}");
        let e = render_tissue(&tissue, &RenderOptions { color_by: ColorBy::Tension, ..RenderOptions::default() })
            .unwrap_err()
            .to_string();
        assert!(e.contains("needs the per-face values"), "{e}");
    }
}
