//! Voxel size and stack layout from TIFF metadata: ImageJ's `ImageDescription`
//! (`ImageJ=… images= channels= slices= frames= unit= spacing=` + `XResolution`/`YResolution` in
//! pixels per unit), OME-XML (`<Pixels PhysicalSizeX=… PhysicalSizeXUnit=… SizeZ= SizeC= SizeT=>`)
//! and plain TIFF resolution tags (`ResolutionUnit` = centimetre).

use crate::geometry::Real;

/// Where a voxel size came from.
#[derive(Copy, Clone, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum VoxelSizeSource {
    /// ImageJ `ImageDescription` (`spacing=`, `unit=`) and `XResolution`/`YResolution`.
    ImageJ,
    /// OME-XML `PhysicalSizeX/Y/Z`.
    Ome,
    /// TIFF `XResolution`/`YResolution` with `ResolutionUnit` = centimetre.
    Resolution,
    /// OME-Zarr (NGFF) `multiscales`: the chosen level's `coordinateTransformations` scale and the
    /// axes' units.
    OmeZarr,
    /// HDF5: the dataset's `element_size_um` attribute (z, y, x in µm; PlantSeg, ilastik).
    Hdf5ElementSize,
    /// Given by the caller.
    Caller,
    /// Not in the file and not given: the fallback size was assumed.
    Assumed,
}

/// What the metadata of a stack says. Voxel sizes are `[z, y, x]` in metres, `None` where unknown.
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct StackMetadata {
    pub voxel_size: [Option<Real>; 3],
    pub source: Option<VoxelSizeSource>,
    pub channels: Option<u64>,
    pub frames: Option<u64>,
    /// ImageJ `xorigin`, `yorigin`, `zorigin`: the voxel index (x, y, z) of the physical origin.
    pub origin_voxels: [Option<Real>; 3],
    /// Notes for the user (ignored or odd metadata).
    pub warnings: Vec<String>,
}

/// Metres per unit, for the unit names ImageJ, OME and tifffile write.
pub(crate) fn unit_metres(unit: &str) -> Option<Real> {
    match unit.trim() {
        "micron" | "microns" | "um" | "µm" | "μm" | "\\u00B5m" | "\\u00b5m" | "micrometer" | "micrometre" => {
            Some(1e-6)
        }
        "nm" | "nanometer" | "nanometre" => Some(1e-9),
        "mm" | "millimeter" | "millimetre" => Some(1e-3),
        "cm" | "centimeter" | "centimetre" => Some(1e-2),
        "m" | "meter" | "metre" => Some(1.0),
        "pm" | "picometer" | "picometre" => Some(1e-12),
        "Å" | "\\u00C5" | "angstrom" => Some(1e-10),
        "dm" | "decimeter" | "decimetre" => Some(1e-1),
        "inch" | "in" => Some(0.0254),
        _ => None,
    }
}

fn positive(v: Real) -> Option<Real> {
    (v.is_finite() && v > 0.0).then_some(v)
}

/// Parses the stack metadata. `description` is the first page's `ImageDescription`; `resolution` the
/// `XResolution`, `YResolution` values (pixels per unit) and `ResolutionUnit` code of the first page.
pub(crate) fn parse_metadata(
    description: Option<&str>,
    resolution: (Option<Real>, Option<Real>, Option<u16>),
) -> StackMetadata {
    let (xres, yres, res_unit) = resolution;
    let mut meta = StackMetadata::default();
    let desc = description.map(str::trim_start).unwrap_or("");
    if desc.starts_with("<?xml") || desc.starts_with("<OME") {
        parse_ome(desc, &mut meta);
        if meta.source.is_some() {
            return meta;
        }
    }
    if desc.starts_with("ImageJ=") {
        parse_imagej(desc, xres, yres, &mut meta);
        if meta.source.is_some() {
            return meta;
        }
    }
    // Plain TIFF resolution: trust centimetres only; inches are almost always a 72 dpi default.
    match res_unit {
        Some(3) => {
            let size = |r: Option<Real>| r.and_then(|r| positive(1e-2 / r));
            meta.voxel_size[1] = size(yres);
            meta.voxel_size[2] = size(xres);
            if meta.voxel_size[1].is_some() || meta.voxel_size[2].is_some() {
                meta.source = Some(VoxelSizeSource::Resolution);
            }
        }
        Some(2) if xres.is_some() => meta.warnings.push(format!(
            "ignored the resolution of {} pixels per inch (a print resolution, not a voxel size)",
            xres.unwrap_or_default()
        )),
        _ => {}
    }
    meta
}

fn parse_imagej(desc: &str, xres: Option<Real>, yres: Option<Real>, meta: &mut StackMetadata) {
    let value = |key: &str| {
        desc.lines().find_map(|l| l.split_once('=').filter(|(k, _)| k.trim() == key).map(|(_, v)| v.trim()))
    };
    let number = |key: &str| value(key).and_then(|v| v.parse::<Real>().ok());
    meta.channels = number("channels").map(|c| c as u64);
    meta.frames = number("frames").map(|f| f as u64);
    meta.origin_voxels = [number("xorigin"), number("yorigin"), number("zorigin")];
    let unit = value("unit");
    let Some(factor) = unit.and_then(unit_metres) else {
        if let Some(u) = unit.filter(|u| !matches!(*u, "" | "pixel" | "pixels")) {
            meta.warnings.push(format!("ImageJ unit `{u}` is not a length unit; voxel size ignored"));
        }
        return;
    };
    // ImageJ: XResolution = pixels per unit; `spacing` = z step in units.
    let size = |r: Option<Real>| r.and_then(|r| positive(factor / r));
    meta.voxel_size = [number("spacing").and_then(|s| positive(s * factor)), size(yres), size(xres)];
    if meta.voxel_size.iter().any(Option::is_some) {
        meta.source = Some(VoxelSizeSource::ImageJ);
    }
}

fn parse_ome(desc: &str, meta: &mut StackMetadata) {
    let doc = match roxmltree::Document::parse(desc) {
        Ok(d) => d,
        Err(e) => {
            meta.warnings.push(format!("OME-XML metadata could not be parsed ({e}); ignored"));
            return;
        }
    };
    let Some(pixels) = doc.descendants().find(|n| n.tag_name().name() == "Pixels") else {
        meta.warnings.push("OME-XML metadata has no Pixels element; ignored".into());
        return;
    };
    let attr_num = |name: &str| pixels.attribute(name).and_then(|v| v.trim().parse::<Real>().ok());
    meta.channels = attr_num("SizeC").map(|c| c as u64);
    meta.frames = attr_num("SizeT").map(|t| t as u64);
    let images = doc.descendants().filter(|n| n.tag_name().name() == "Image").count();
    if images > 1 {
        meta.warnings.push(format!("OME-XML describes {images} images; reading the pages as one stack"));
    }
    let size = |axis: &str| {
        let v = attr_num(&format!("PhysicalSize{axis}"))?;
        let unit = pixels.attribute(format!("PhysicalSize{axis}Unit").as_str()).unwrap_or("µm");
        positive(v * unit_metres(unit)?)
    };
    meta.voxel_size = [size("Z"), size("Y"), size("X")];
    if meta.voxel_size.iter().any(Option::is_some) {
        meta.source = Some(VoxelSizeSource::Ome);
    }
}

/// The ImageJ hyperstack description tissuefit writes (units: micron). `origin_voxels` (x, y, z) is
/// the voxel index of the physical origin, ImageJ's `xorigin`/`yorigin`/`zorigin`; written when
/// non-zero.
pub(crate) fn imagej_description(
    slices: usize,
    z_spacing_um: Real,
    max_label: u32,
    origin_voxels: [Real; 3],
) -> String {
    let mut d = format!("ImageJ=1.11a\nimages={slices}\nslices={slices}\nunit=micron\nspacing={z_spacing_um}\n");
    for (key, v) in ["xorigin", "yorigin", "zorigin"].iter().zip(origin_voxels) {
        if v != 0.0 && v.is_finite() {
            d.push_str(&format!("{key}={v}\n"));
        }
    }
    d.push_str(&format!("loop=false\nmin=0.0\nmax={max_label}.0\n"));
    d
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: Option<Real>, b: Real) -> bool {
        a.is_some_and(|a| (a - b).abs() <= 1e-9 * b.abs())
    }

    #[test]
    fn imagej_spacing_unit_and_resolution() {
        let d = "ImageJ=1.53t\nimages=32\nslices=32\nunit=micron\nspacing=0.235\nloop=false\n";
        let m = parse_metadata(Some(d), (Some(1.0 / 0.15), Some(1.0 / 0.15), Some(1)));
        assert_eq!(m.source, Some(VoxelSizeSource::ImageJ));
        assert!(close(m.voxel_size[0], 0.235e-6) && close(m.voxel_size[1], 0.15e-6) && close(m.voxel_size[2], 0.15e-6));
        // ImageJ writes µ as a literal \u00B5 escape.
        let d = "ImageJ=1.53t\nimages=4\nslices=4\nunit=\\u00B5m\nspacing=2\n";
        let m = parse_metadata(Some(d), (Some(2.0), Some(4.0), None));
        assert!(close(m.voxel_size[0], 2e-6) && close(m.voxel_size[1], 0.25e-6) && close(m.voxel_size[2], 0.5e-6));
        // Uncalibrated ImageJ: nothing known.
        let m = parse_metadata(Some("ImageJ=1.53t\nimages=4\nslices=4\n"), (Some(1.0), Some(1.0), None));
        assert_eq!(m.voxel_size, [None; 3]);
        assert_eq!(m.source, None);
        let m =
            parse_metadata(Some("ImageJ=1.53t\nimages=8\nchannels=2\nslices=4\nhyperstack=true\n"), (None, None, None));
        assert_eq!(m.channels, Some(2));
    }

    #[test]
    fn ome_physical_sizes_with_units() {
        let xml = r#"<?xml version="1.0" encoding="UTF-8"?>
<OME xmlns="http://www.openmicroscopy.org/Schemas/OME/2016-06"><Image ID="Image:0"><Pixels ID="Pixels:0"
 DimensionOrder="XYZCT" Type="uint16" SizeX="8" SizeY="6" SizeZ="4" SizeC="1" SizeT="1"
 PhysicalSizeX="150" PhysicalSizeXUnit="nm" PhysicalSizeY="0.15" PhysicalSizeZ="0.5" PhysicalSizeZUnit="µm"/></Image></OME>"#;
        let m = parse_metadata(Some(xml), (None, None, None));
        assert_eq!(m.source, Some(VoxelSizeSource::Ome));
        assert!(close(m.voxel_size[0], 0.5e-6) && close(m.voxel_size[1], 0.15e-6) && close(m.voxel_size[2], 0.15e-6));
        assert_eq!((m.channels, m.frames), (Some(1), Some(1)));
        let m = parse_metadata(Some("<?xml version=\"1.0\"?><OME"), (None, None, None));
        assert_eq!(m.source, None);
        assert!(!m.warnings.is_empty());
    }

    #[test]
    fn plain_resolution_in_centimetres_only() {
        let m = parse_metadata(None, (Some(1e4), Some(2e4), Some(3)));
        assert_eq!(m.source, Some(VoxelSizeSource::Resolution));
        assert!(close(m.voxel_size[2], 1e-6) && close(m.voxel_size[1], 0.5e-6) && m.voxel_size[0].is_none());
        let m = parse_metadata(None, (Some(72.0), Some(72.0), Some(2)));
        assert_eq!(m.voxel_size, [None; 3]);
        assert_eq!(m.warnings.len(), 1);
    }
}
