//! ParaView XML PolyData (`.vtp`): one triangle surface per cell, all cells in one piece.
//!
//! Layout written: `VTKFile type="PolyData" version="1.0" byte_order="LittleEndian"
//! header_type="UInt64"`, one `Piece` whose points are every cell's nodes (each cell's nodes contiguous,
//! cells in tissue order) and whose polys are every cell's triangles. All arrays are raw appended
//! binary (one little-endian UInt64 byte count, then the values), which ParaView reads without decoding
//! and we write without formatting a single number: a frame of a million triangles is a few `memcpy`s.
//!
//! Cell data (one tuple per triangle): `cell_id` (Int64), `kind` (Int32, [`CellKind::code`]),
//! `cell_type` (Int32), `face_type` (Int32, [`FaceType::code`]), `face_area` (Float64, m²),
//! `cell_volume` (m³), `cell_area` (m²), `target_volume` (m³) and any extra per-cell fields, each
//! repeated on the cell's faces so that ParaView can colour by them; `interface_label` (Int64, the
//! id of the body on the face's other side, 0 = the medium) when every cell carries interface labels
//! ([`Cell::interface_labels`], a multi-material input); `surface_tension_apical|lateral|basal` (N/m)
//! and `adhesion_apical|lateral|basal` (Pa/m), NaN where the cell keeps its type's value, when some
//! cell has its own ([`CellOverrides`]). An optional dataset-level `TimeValue` field
//! carries the simulated time (s).
//!
//! Lengths are metres unless the dataset-level field data holds a `length_unit` string array (VTK's
//! ASCII encoding of a string: its character codes, then 0; `um` is `117 109 0`), which
//! [`write_vtp_in`] writes for files in µm: then the points, areas and volumes (and the extra fields,
//! which the caller scales) are in that unit, ParaView's axes read micrometres, and the reader converts
//! the tissue back to metres.
//!
//! The reader takes what the writer writes plus inline ASCII arrays (and big-endian, UInt32 headers,
//! any integer or float type, polygons with more than three corners, several pieces). Base64 and
//! compressed data are refused with [`IoError::Unsupported`]. Faces are grouped into cells by the
//! `cell_id` array; a cell's nodes are the points its faces use, in increasing point index, so a
//! written tissue reads back with identical node and face order.

use super::units::metres_per_unit;
use super::{IoError, OutputUnit, write_atomically};
use crate::geometry::{Real, Vec3};
use crate::mesh::{Cell, CellId, CellKind, CellMesh, CellOverrides, FaceType, Tissue};
use roxmltree::Node;
use std::collections::HashMap;
use std::fmt::Write as _;
use std::io::{self, Write};
use std::path::Path;

/// One value per cell, in `tissue.cells()` order, written as per-face cell data; or one value per face
/// (all cells' faces in order, [`Tissue::face_count`] values), written as it is.
#[derive(Clone, Copy, Debug)]
pub struct CellField<'a> {
    pub name: &'a str,
    pub values: &'a [Real],
}

/// Names of the cell-data arrays every file gets; extra fields may not reuse them.
const STANDARD_FIELDS: [&str; 8] =
    ["cell_id", "kind", "cell_type", "face_type", "face_area", "cell_volume", "cell_area", "target_volume"];

/// What users are told when a file uses an encoding we do not read.
const RESAVE_HINT: &str = "re-save it from ParaView (File > Save Data, .vtp) with Data Mode 'Ascii', or \
     'Appended' with 'Encode Appended Data' off and Compressor Type 'None', or convert it with `tissuefit convert`";

/// Writes `tissue` as a `.vtp` file, atomically. `extra` fields need one value per cell or one per
/// face; `time` (s), when given, is stored as the dataset's `TimeValue`.
pub fn write_vtp(path: &Path, tissue: &Tissue, extra: &[CellField<'_>], time: Option<Real>) -> Result<(), IoError> {
    let header = vtp_header(path, tissue, extra, time, OutputUnit::Metre)?;
    write_atomically(path, |w| write_vtp_body(w, &header, tissue, extra)).map_err(IoError::from)
}

/// [`write_vtp`] with lengths in `unit`: the points (and so the face areas, cell volumes and areas,
/// target volumes) scaled from metres and the unit recorded as the `length_unit` field. `extra` fields
/// are written as given: a caller with a length-dimensioned field scales it ([`OutputUnit::factor`]).
/// In SI this is [`write_vtp`], byte for byte.
pub fn write_vtp_in(
    path: &Path,
    tissue: &Tissue,
    extra: &[CellField<'_>],
    time: Option<Real>,
    unit: OutputUnit,
) -> Result<(), IoError> {
    if unit.is_si() {
        return write_vtp(path, tissue, extra, time);
    }
    let scaled = scaled_tissue(tissue, unit);
    let header = vtp_header(path, &scaled, extra, time, unit)?;
    write_atomically(path, |w| write_vtp_body(w, &header, &scaled, extra)).map_err(IoError::from)
}

/// A copy of `tissue` with its lengths in `unit`.
fn scaled_tissue(tissue: &Tissue, unit: OutputUnit) -> Tissue {
    let mut scaled = tissue.clone();
    scaled.scale(Vec3::repeat(unit.factor(1)));
    scaled
}

/// The bytes of the `.vtp` file [`write_vtp`] would write to `path` (named in errors), for writers that
/// stage several files together ([`super::OutputGroup`]).
pub fn vtp_bytes(
    path: &Path,
    tissue: &Tissue,
    extra: &[CellField<'_>],
    time: Option<Real>,
) -> Result<Vec<u8>, IoError> {
    let header = vtp_header(path, tissue, extra, time, OutputUnit::Metre)?;
    let mut bytes = Vec::new();
    write_vtp_body(&mut bytes, &header, tissue, extra)
        .map_err(|source| IoError::Write { path: path.to_path_buf(), source })?;
    Ok(bytes)
}

/// [`vtp_bytes`] with lengths in `unit` (as [`write_vtp_in`]: points scaled from metres, the unit
/// recorded); in SI, [`vtp_bytes`] byte for byte.
pub fn vtp_bytes_in(
    path: &Path,
    tissue: &Tissue,
    extra: &[CellField<'_>],
    time: Option<Real>,
    unit: OutputUnit,
) -> Result<Vec<u8>, IoError> {
    if unit.is_si() {
        return vtp_bytes(path, tissue, extra, time);
    }
    let scaled = scaled_tissue(tissue, unit);
    let header = vtp_header(path, &scaled, extra, time, unit)?;
    let mut bytes = Vec::new();
    write_vtp_body(&mut bytes, &header, &scaled, extra)
        .map_err(|source| IoError::Write { path: path.to_path_buf(), source })?;
    Ok(bytes)
}

/// Checks the fields and returns the XML header.
fn vtp_header(
    path: &Path,
    tissue: &Tissue,
    extra: &[CellField<'_>],
    time: Option<Real>,
    unit: OutputUnit,
) -> Result<String, IoError> {
    let invalid = |message: String| IoError::Write {
        path: path.to_path_buf(),
        source: io::Error::new(io::ErrorKind::InvalidInput, message),
    };
    for (k, field) in extra.iter().enumerate() {
        if field.values.len() != tissue.len() && field.values.len() != tissue.face_count() {
            return Err(invalid(format!(
                "extra field '{}' has {} values for {} cells ({} faces)",
                field.name,
                field.values.len(),
                tissue.len(),
                tissue.face_count()
            )));
        }
        if STANDARD_FIELDS.contains(&field.name)
            || CellOverrides::ARRAY_NAMES.iter().flatten().any(|n| *n == field.name)
            || extra[..k].iter().any(|f| f.name == field.name)
        {
            return Err(invalid(format!("extra field name '{}' is used twice", field.name)));
        }
    }
    if let Some(t) = time
        && !t.is_finite()
    {
        return Err(invalid(format!("time {t} is not finite")));
    }

    let (volumes, areas) = cell_measures(tissue);
    let frame = Frame { tissue, volumes: &volumes, areas: &areas };
    Ok(xml_header(&frame, &arrays(tissue, extra), time, unit))
}

fn cell_measures(tissue: &Tissue) -> (Vec<Real>, Vec<Real>) {
    let cells = tissue.cells();
    (cells.iter().map(|c| c.mesh().signed_volume()).collect(), cells.iter().map(|c| c.mesh().area()).collect())
}

fn arrays<'a>(tissue: &Tissue, extra: &[CellField<'a>]) -> Vec<Array<'a>> {
    let mut arrays = vec![
        Array::Points,
        Array::Connectivity,
        Array::Offsets,
        Array::CellId,
        Array::Kind,
        Array::CellType,
        Array::FaceType,
        Array::FaceArea,
        Array::CellVolume,
        Array::CellArea,
        Array::TargetVolume,
    ];
    if !tissue.is_empty() && tissue.cells().iter().all(|c| c.interface_labels().is_some()) {
        arrays.push(Array::InterfaceLabel);
    }
    if tissue.cells().iter().any(|c| !c.overrides().is_empty()) {
        arrays.extend((0..2).flat_map(|q| (0..3).map(move |t| Array::Override(q, t))));
    }
    arrays.extend(extra.iter().map(|f| Array::Extra(f.name, f.values)));
    arrays
}

/// Writes the header and the appended arrays.
fn write_vtp_body(w: &mut impl Write, header: &str, tissue: &Tissue, extra: &[CellField<'_>]) -> io::Result<()> {
    let (volumes, areas) = cell_measures(tissue);
    let frame = Frame { tissue, volumes: &volumes, areas: &areas };
    w.write_all(header.as_bytes())?;
    let mut buf = Vec::new();
    for array in &arrays(tissue, extra) {
        buf.clear();
        array.fill(&frame, &mut buf);
        debug_assert_eq!(buf.len(), array.byte_len(&frame));
        w.write_all(&(buf.len() as u64).to_le_bytes())?;
        w.write_all(&buf)?;
    }
    w.write_all(b"\n  </AppendedData>\n</VTKFile>\n")
}

/// The tissue being written and its per-cell measures.
struct Frame<'a> {
    tissue: &'a Tissue,
    volumes: &'a [Real],
    areas: &'a [Real],
}

/// One appended array of the written file, in file order.
enum Array<'a> {
    Points,
    Connectivity,
    Offsets,
    CellId,
    Kind,
    CellType,
    FaceType,
    FaceArea,
    CellVolume,
    CellArea,
    TargetVolume,
    InterfaceLabel,
    /// A per-cell override ([`CellOverrides`]): quantity index and face type code; NaN where the
    /// cell keeps its type's value.
    Override(usize, usize),
    Extra(&'a str, &'a [Real]),
}

impl Array<'_> {
    fn name(&self) -> &str {
        match self {
            Array::Points => "Points",
            Array::Connectivity => "connectivity",
            Array::Offsets => "offsets",
            Array::CellId => "cell_id",
            Array::Kind => "kind",
            Array::CellType => "cell_type",
            Array::FaceType => "face_type",
            Array::FaceArea => "face_area",
            Array::CellVolume => "cell_volume",
            Array::CellArea => "cell_area",
            Array::TargetVolume => "target_volume",
            Array::InterfaceLabel => "interface_label",
            Array::Override(q, t) => CellOverrides::ARRAY_NAMES[*q][*t],
            Array::Extra(name, _) => name,
        }
    }

    /// VTK type name and size in bytes of one value.
    fn vtk_type(&self) -> (&'static str, usize) {
        match self {
            Array::Connectivity | Array::Offsets | Array::CellId | Array::InterfaceLabel => ("Int64", 8),
            Array::Kind | Array::CellType | Array::FaceType => ("Int32", 4),
            _ => ("Float64", 8),
        }
    }

    fn byte_len(&self, frame: &Frame) -> usize {
        let values = match self {
            Array::Points => 3 * frame.tissue.node_count(),
            Array::Connectivity => 3 * frame.tissue.face_count(),
            _ => frame.tissue.face_count(),
        };
        values * self.vtk_type().1
    }

    /// Appends the array's little-endian bytes to `buf`.
    fn fill(&self, frame: &Frame, buf: &mut Vec<u8>) {
        let cells = frame.tissue.cells();
        buf.reserve(self.byte_len(frame));
        // Per-cell values repeated on each of the cell's faces.
        let per_cell_f64 = |buf: &mut Vec<u8>, value: &dyn Fn(usize, &Cell) -> Real| {
            for (i, c) in cells.iter().enumerate() {
                let bytes = value(i, c).to_le_bytes();
                (0..c.mesh().face_count()).for_each(|_| buf.extend_from_slice(&bytes));
            }
        };
        let per_cell_i32 = |buf: &mut Vec<u8>, value: &dyn Fn(&Cell) -> i32| {
            for c in cells {
                let bytes = value(c).to_le_bytes();
                (0..c.mesh().face_count()).for_each(|_| buf.extend_from_slice(&bytes));
            }
        };
        match self {
            Array::Points => {
                for p in cells.iter().flat_map(|c| c.mesh().positions()) {
                    for x in p.iter() {
                        buf.extend_from_slice(&x.to_le_bytes());
                    }
                }
            }
            Array::Connectivity => {
                let mut base = 0i64;
                for c in cells {
                    for &i in c.mesh().triangles().iter().flatten() {
                        buf.extend_from_slice(&(base + i64::from(i)).to_le_bytes());
                    }
                    base += c.mesh().node_count() as i64;
                }
            }
            Array::Offsets => {
                for f in 1..=frame.tissue.face_count() as i64 {
                    buf.extend_from_slice(&(3 * f).to_le_bytes());
                }
            }
            Array::CellId => {
                for c in cells {
                    let bytes = i64::from(c.id().0).to_le_bytes();
                    (0..c.mesh().face_count()).for_each(|_| buf.extend_from_slice(&bytes));
                }
            }
            Array::Kind => per_cell_i32(buf, &|c| c.kind().code() as i32),
            Array::CellType => per_cell_i32(buf, &|c| c.cell_type() as i32),
            Array::FaceType => {
                for &t in cells.iter().flat_map(|c| c.face_types()) {
                    buf.extend_from_slice(&(t.code() as i32).to_le_bytes());
                }
            }
            Array::FaceArea => {
                for c in cells {
                    for a in c.mesh().face_areas() {
                        buf.extend_from_slice(&a.to_le_bytes());
                    }
                }
            }
            Array::CellVolume => per_cell_f64(buf, &|i, _| frame.volumes[i]),
            Array::CellArea => per_cell_f64(buf, &|i, _| frame.areas[i]),
            Array::TargetVolume => per_cell_f64(buf, &|_, c| c.target_volume()),
            Array::InterfaceLabel => {
                // Written only when every cell has labels (`arrays`).
                for &l in cells.iter().flat_map(|c| c.interface_labels().unwrap_or_default()) {
                    buf.extend_from_slice(&i64::from(l).to_le_bytes());
                }
            }
            Array::Override(q, t) => per_cell_f64(buf, &|_, c| c.overrides().values(*q)[*t].unwrap_or(Real::NAN)),
            Array::Extra(_, values) if values.len() == cells.len() => per_cell_f64(buf, &|i, _| values[i]),
            Array::Extra(_, values) => {
                for v in values.iter() {
                    buf.extend_from_slice(&v.to_le_bytes());
                }
            }
        }
    }
}

/// Everything before the first appended byte.
fn xml_header(frame: &Frame, arrays: &[Array], time: Option<Real>, unit: OutputUnit) -> String {
    let mut offsets = Vec::with_capacity(arrays.len());
    let mut offset = 0usize;
    for a in arrays {
        offsets.push(offset);
        offset += 8 + a.byte_len(frame);
    }
    let data_array = |s: &mut String, k: usize, indent: &str| {
        let a = &arrays[k];
        let components = if matches!(a, Array::Points) { " NumberOfComponents=\"3\"" } else { "" };
        let _ = writeln!(
            s,
            "{indent}<DataArray type=\"{}\" Name=\"{}\"{components} format=\"appended\" offset=\"{}\"/>",
            a.vtk_type().0,
            escape_xml(a.name()),
            offsets[k]
        );
    };

    let mut s = String::with_capacity(4096);
    s.push_str("<?xml version=\"1.0\"?>\n");
    s.push_str("<VTKFile type=\"PolyData\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">\n");
    s.push_str("  <PolyData>\n");
    if time.is_some() || !unit.is_si() {
        s.push_str("    <FieldData>\n");
        if let Some(t) = time {
            let _ = writeln!(
                s,
                "      <DataArray type=\"Float64\" Name=\"TimeValue\" NumberOfTuples=\"1\" format=\"ascii\">\
                 {t:e}</DataArray>"
            );
        }
        if !unit.is_si() {
            let codes: Vec<String> = unit.name().bytes().chain([0]).map(|b| b.to_string()).collect();
            let _ = writeln!(
                s,
                "      <DataArray type=\"String\" Name=\"{LENGTH_UNIT_FIELD}\" NumberOfTuples=\"1\" format=\"ascii\">\
                 {}</DataArray>",
                codes.join(" ")
            );
        }
        s.push_str("    </FieldData>\n");
    }
    let _ = writeln!(
        s,
        "    <Piece NumberOfPoints=\"{}\" NumberOfVerts=\"0\" NumberOfLines=\"0\" NumberOfStrips=\"0\" \
             NumberOfPolys=\"{}\">",
        frame.tissue.node_count(),
        frame.tissue.face_count()
    );
    s.push_str("      <CellData Scalars=\"cell_id\">\n");
    (3..arrays.len()).for_each(|k| data_array(&mut s, k, "        "));
    s.push_str("      </CellData>\n      <Points>\n");
    data_array(&mut s, 0, "        ");
    s.push_str("      </Points>\n      <Polys>\n");
    data_array(&mut s, 1, "        ");
    data_array(&mut s, 2, "        ");
    s.push_str("      </Polys>\n    </Piece>\n  </PolyData>\n");
    s.push_str("  <AppendedData encoding=\"raw\">\n   _");
    s
}

/// The dataset-level field naming the unit of the file's lengths.
pub const LENGTH_UNIT_FIELD: &str = "length_unit";

/// Escapes text for an XML attribute value or element content.
pub(super) fn escape_xml(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for ch in text.chars() {
        match ch {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            '\n' => out.push_str("&#10;"),
            '\r' => out.push_str("&#13;"),
            '\t' => out.push_str("&#9;"),
            c => out.push(c),
        }
    }
    out
}

/// Reads a `.vtp` file written by [`write_vtp`] or by ParaView (ASCII or raw appended data).
/// Lengths in metres: a file that records its `length_unit` is converted.
pub fn read_vtp(path: &Path) -> Result<Tissue, IoError> {
    let bytes = super::read_capped(path, super::MAX_TISSUE_FILE)
        .map_err(|source| IoError::Open { path: path.to_path_buf(), source })?;
    parse_vtp(path, &bytes).map(|(tissue, _)| tissue)
}

/// Parses the bytes of a `.vtp` file; `path` only names it in errors. Returns the tissue in metres
/// and the unit the file recorded (`length_unit`, from which it was converted) with its metres per
/// unit, if any.
pub(crate) fn parse_vtp(path: &Path, bytes: &[u8]) -> Result<(Tissue, Option<(String, Real)>), IoError> {
    parse_vtp_with(path, bytes, &[]).map(|(tissue, unit, _)| (tissue, unit))
}

/// Per-face values of a tissue read from a `.vtp` file (see [`read_vtp_face_values`]).
#[derive(Clone, Debug)]
pub struct FaceValues {
    /// The cell-data array they were read from.
    pub name: String,
    /// One value per triangle, cells in the tissue's order, triangles in each cell's order (a
    /// polygon split into triangles gives each its value; NaN where a piece lacks the array).
    pub values: Vec<Real>,
}

/// Reads a `.vtp` tissue and, per triangle, the values of the first of `names` that the file has as
/// a one-component cell-data array (e.g. `tension` in `tensions.vtp`, `tension_mn_per_m` in a
/// per-cell fit's `tissue.vtp`). An error names the arrays the file has when it has none of them.
pub fn read_vtp_face_values(path: &Path, names: &[&str]) -> Result<(Tissue, FaceValues), IoError> {
    let bytes = super::read_capped(path, super::MAX_TISSUE_FILE)
        .map_err(|source| IoError::Open { path: path.to_path_buf(), source })?;
    if names.is_empty() {
        return Err(IoError::parse(path, None, "no cell-data array name given to read"));
    }
    let (tissue, _, values) = parse_vtp_with(path, &bytes, names)?;
    let values = values.ok_or_else(|| IoError::parse(path, None, "internal: the cell-data array was not read"))?;
    Ok((tissue, values))
}

type Parsed = (Tissue, Option<(String, Real)>, Option<FaceValues>);

fn parse_vtp_with(path: &Path, bytes: &[u8], names: &[&str]) -> Result<Parsed, IoError> {
    let (xml, appended) = split_appended(path, bytes)?;
    let doc = roxmltree::Document::parse(&xml)
        .map_err(|e| IoError::parse(path, Some(e.pos().row as usize), format!("malformed XML: {e}")))?;
    let root = doc.root_element();
    let parse_err = |node: Node, message: String| IoError::parse(path, Some(line_of(&doc, node)), message);
    let unsupported = |message: String| IoError::Unsupported { path: path.to_path_buf(), message };

    if !root.has_tag_name("VTKFile") {
        return Err(parse_err(root, format!("not a VTK XML file: the root element is <{}>", root.tag_name().name())));
    }
    match root.attribute("type") {
        Some("PolyData") => {}
        Some(other) => {
            return Err(unsupported(format!(
                "this is a VTK XML {other} file; read_vtp reads PolyData (.vtp) files only"
            )));
        }
        None => return Err(parse_err(root, "<VTKFile> has no type attribute".into())),
    }
    let big_endian = match root.attribute("byte_order") {
        None | Some("LittleEndian") => false,
        Some("BigEndian") => true,
        Some(other) => return Err(parse_err(root, format!("unknown byte_order '{other}'"))),
    };
    let header_size = match root.attribute("header_type") {
        None | Some("UInt32") => 4,
        Some("UInt64") => 8,
        Some(other) => {
            return Err(unsupported(format!("header_type '{other}' is not supported (UInt32 or UInt64 are)")));
        }
    };
    let poly_data = element_child(root, "PolyData").ok_or_else(|| parse_err(root, "no <PolyData> element".into()))?;

    // VTK names a compressor even in ASCII files, where it does not apply; it matters for binary data.
    let compressor = root.attribute("compressor");
    let reader = ArrayReader { path, doc: &doc, appended, compressor, big_endian, header_size };
    let mut faces = Faces { field_names: names.iter().map(|n| n.to_string()).collect(), ..Faces::default() };
    let mut pieces = 0;
    for piece in poly_data.children().filter(|n| n.has_tag_name("Piece")) {
        reader.read_piece(piece, &mut faces)?;
        pieces += 1;
    }
    if pieces == 0 {
        return Err(parse_err(poly_data, "<PolyData> has no <Piece>".into()));
    }
    let unit = match element_child(poly_data, "FieldData").and_then(|f| named(f, LENGTH_UNIT_FIELD)) {
        Some(node) => Some(read_unit(&reader, node)?),
        None => None,
    };
    let values = if names.is_empty() {
        None
    } else {
        let Some(name) = faces.field_found.clone() else {
            let has = if faces.array_names.is_empty() {
                "none".to_owned()
            } else {
                faces.array_names.iter().cloned().collect::<Vec<_>>().join(", ")
            };
            return Err(IoError::parse(
                path,
                None,
                format!("no cell-data array named {} (the file's cell-data arrays: {has})", names.join(" or ")),
            ));
        };
        Some(name)
    };
    let (mut tissue, field) = faces.into_tissue(path)?;
    if let Some((_, metres)) = &unit
        && *metres != 1.0
    {
        tissue.scale(Vec3::repeat(*metres));
    }
    Ok((tissue, unit, values.map(|name| FaceValues { name, values: field })))
}

/// The `length_unit` field: one string (VTK's ASCII string encoding, character codes ended by 0, or
/// the bare name) naming a length unit; returns it and metres per unit.
fn read_unit(reader: &ArrayReader, node: Node) -> Result<(String, Real), IoError> {
    let text = node.text().unwrap_or("").trim();
    let name = match (node.attribute("type"), node.attribute("format")) {
        (Some("String"), Some("ascii")) => {
            let codes: Option<Vec<u8>> =
                text.split_ascii_whitespace().map(|t| t.parse::<u8>().ok()).take_while(|c| *c != Some(0)).collect();
            codes.and_then(|c| String::from_utf8(c).ok())
        }
        _ => None,
    };
    let name = name.ok_or_else(|| {
        reader.error(
            node,
            format!("field '{LENGTH_UNIT_FIELD}' is not one ASCII String (character codes ended by 0, e.g. 117 109 0 for um)"),
        )
    })?;
    let metres = metres_per_unit(&name).ok_or_else(|| {
        reader.error(node, format!("field '{LENGTH_UNIT_FIELD}' names `{name}`, not a length unit (m, mm, um, nm)"))
    })?;
    Ok((name, metres))
}

/// Splits the file into its XML text (closed with `</VTKFile>` when an appended section was cut off)
/// and the raw appended bytes after the `_` marker.
fn split_appended<'a>(path: &Path, bytes: &'a [u8]) -> Result<(String, Option<&'a [u8]>), IoError> {
    let utf8 = |b: &'a [u8]| {
        std::str::from_utf8(b).map_err(|e| {
            let line = b[..e.valid_up_to()].iter().filter(|&&c| c == b'\n').count() + 1;
            IoError::parse(path, Some(line), "the XML text is not valid UTF-8")
        })
    };
    const TAG: &[u8] = b"<AppendedData";
    let Some(start) = bytes.windows(TAG.len()).position(|w| w == TAG) else {
        return Ok((utf8(bytes)?.to_owned(), None));
    };
    let head = utf8(&bytes[..start])?;
    let line = head.matches('\n').count() + 1;
    let rest = &bytes[start..];
    let end = rest
        .iter()
        .position(|&b| b == b'>')
        .ok_or_else(|| IoError::parse(path, Some(line), "unterminated <AppendedData> tag"))?;
    let tag = utf8(&rest[..=end])?;
    let tag_xml = if tag.ends_with("/>") { tag.to_owned() } else { format!("{tag}</AppendedData>") };
    let tag_doc = roxmltree::Document::parse(&tag_xml)
        .map_err(|e| IoError::parse(path, Some(line), format!("malformed <AppendedData> tag: {e}")))?;
    match tag_doc.root_element().attribute("encoding") {
        Some("raw") => {}
        Some("base64") => {
            return Err(IoError::Unsupported {
                path: path.to_path_buf(),
                message: format!("the appended data is base64-encoded, which tissuefit does not read; {RESAVE_HINT}"),
            });
        }
        Some(other) => {
            return Err(IoError::parse(path, Some(line), format!("unknown AppendedData encoding '{other}'")));
        }
        None => return Err(IoError::parse(path, Some(line), "<AppendedData> has no encoding attribute")),
    }
    let data = if tag.ends_with("/>") {
        &[][..]
    } else {
        let after = &rest[end + 1..];
        let skip = after.iter().take_while(|b| b.is_ascii_whitespace()).count();
        match after.get(skip..) {
            Some([b'_', data @ ..]) => data,
            _ => return Err(IoError::parse(path, Some(line), "the appended data does not start with '_'")),
        }
    };
    Ok((format!("{head}</VTKFile>"), Some(data)))
}

/// 1-based line of an element.
fn line_of(doc: &roxmltree::Document, node: Node) -> usize {
    doc.text_pos_at(node.range().start).row as usize
}

/// The first child element named `name`.
fn element_child<'a, 'i>(node: Node<'a, 'i>, name: &str) -> Option<Node<'a, 'i>> {
    node.children().find(|n| n.has_tag_name(name))
}

/// The child `<DataArray>` with `Name="name"`.
fn named<'a, 'i>(parent: Node<'a, 'i>, name: &str) -> Option<Node<'a, 'i>> {
    parent.children().find(|n| n.has_tag_name("DataArray") && n.attribute("Name") == Some(name))
}

/// Element type of a data array.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Scalar {
    I8,
    I16,
    I32,
    I64,
    U8,
    U16,
    U32,
    U64,
    F32,
    F64,
}

impl Scalar {
    fn parse(name: &str) -> Option<Self> {
        Some(match name {
            "Int8" | "Char" => Scalar::I8,
            "Int16" => Scalar::I16,
            "Int32" => Scalar::I32,
            "Int64" => Scalar::I64,
            "UInt8" | "UChar" => Scalar::U8,
            "UInt16" => Scalar::U16,
            "UInt32" => Scalar::U32,
            "UInt64" => Scalar::U64,
            "Float32" => Scalar::F32,
            "Float64" => Scalar::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::I64 | Scalar::U64 | Scalar::F64 => 8,
        }
    }

    fn is_float(self) -> bool {
        matches!(self, Scalar::F32 | Scalar::F64)
    }
}

/// Values of one array, widened to `i64` or `f64`.
enum Values {
    Int(Vec<i64>),
    Float(Vec<f64>),
}

impl Values {
    fn len(&self) -> usize {
        match self {
            Values::Int(v) => v.len(),
            Values::Float(v) => v.len(),
        }
    }

    fn into_f64(self) -> Vec<f64> {
        match self {
            Values::Int(v) => v.into_iter().map(|x| x as f64).collect(),
            Values::Float(v) => v,
        }
    }

    /// Integers; floats are accepted when they hold integral values. Errors with the index of the
    /// first value that is not an integer.
    fn into_i64(self) -> Result<Vec<i64>, usize> {
        match self {
            Values::Int(v) => Ok(v),
            Values::Float(v) => v
                .iter()
                .enumerate()
                .map(|(k, &x)| {
                    // 2^63 is exact in f64; every integral float in [-2^63, 2^63) fits i64.
                    let limit = -(i64::MIN as f64);
                    let fits = x.fract() == 0.0 && (-limit..limit).contains(&x);
                    if fits { Ok(x as i64) } else { Err(k) }
                })
                .collect(),
        }
    }
}

/// Decodes fixed-size values of type `$t` from `$bytes` (a multiple of `$n` bytes long).
macro_rules! decode {
    ($bytes:expr, $big:expr, $t:ty, $n:literal) => {{
        let (chunks, _) = $bytes.as_chunks::<$n>();
        chunks.iter().map(move |c| if $big { <$t>::from_be_bytes(*c) } else { <$t>::from_le_bytes(*c) })
    }};
}

/// Reads data arrays, with what is needed to name the file and line in errors.
struct ArrayReader<'a> {
    path: &'a Path,
    doc: &'a roxmltree::Document<'a>,
    appended: Option<&'a [u8]>,
    compressor: Option<&'a str>,
    big_endian: bool,
    header_size: usize,
}

impl ArrayReader<'_> {
    fn error(&self, node: Node, message: impl Into<String>) -> IoError {
        IoError::parse(self.path, Some(line_of(self.doc, node)), message)
    }

    fn unsupported(&self, message: String) -> IoError {
        IoError::Unsupported { path: self.path.to_path_buf(), message }
    }

    /// A non-negative integer attribute; `default` when absent (`None`: required).
    fn count_attribute(&self, node: Node, name: &str, default: Option<usize>) -> Result<usize, IoError> {
        match (node.attribute(name), default) {
            (Some(text), _) => text.trim().parse().map_err(|_| {
                self.error(node, format!("<{}> attribute {name}=\"{text}\" is not a count", node.tag_name().name()))
            }),
            (None, Some(d)) => Ok(d),
            (None, None) => Err(self.error(node, format!("<{}> has no {name} attribute", node.tag_name().name()))),
        }
    }

    /// Reads a data array of `tuples` × `components` values.
    fn read_array(&self, node: Node, components: usize, tuples: usize) -> Result<Values, IoError> {
        let name = node.attribute("Name").unwrap_or("(unnamed)");
        let err = |message: String| self.error(node, format!("DataArray '{name}': {message}"));
        let found_components = self.count_attribute(node, "NumberOfComponents", Some(1))?;
        if found_components != components {
            return Err(err(format!("has {found_components} components; expected {components}")));
        }
        if node.has_attribute("NumberOfTuples") {
            let found = self.count_attribute(node, "NumberOfTuples", None)?;
            if found != tuples {
                return Err(err(format!("NumberOfTuples is {found}; expected {tuples}")));
            }
        }
        let type_name = node.attribute("type").ok_or_else(|| err("has no type attribute".into()))?;
        let scalar = Scalar::parse(type_name).ok_or_else(|| {
            self.unsupported(format!("DataArray '{name}' has type '{type_name}', which tissuefit does not read"))
        })?;
        let values = match node.attribute("format") {
            Some("ascii") => self.parse_ascii(node.text().unwrap_or(""), scalar).map_err(err)?,
            Some("appended") => {
                if let Some(compressor) = self.compressor {
                    return Err(self.unsupported(format!(
                        "the appended data is compressed ({compressor}), which tissuefit does not read; {RESAVE_HINT}"
                    )));
                }
                let offset = self.count_attribute(node, "offset", None)?;
                let bytes = self.appended_block(offset).map_err(err)?;
                self.decode(bytes, scalar).map_err(err)?
            }
            Some("binary") => {
                return Err(self.unsupported(format!(
                    "DataArray '{name}' is inline base64 (format=\"binary\"), which tissuefit does not read; \
                     {RESAVE_HINT}"
                )));
            }
            Some(other) => return Err(err(format!("unknown format '{other}'"))),
            None => return Err(err("has no format attribute".into())),
        };
        let expected = tuples.checked_mul(components).ok_or_else(|| err(format!("{tuples} tuples is too many")))?;
        if values.len() != expected {
            return Err(err(format!(
                "has {} values; expected {expected} ({tuples} tuples of {components} components)",
                values.len()
            )));
        }
        Ok(values)
    }

    fn parse_ascii(&self, text: &str, scalar: Scalar) -> Result<Values, String> {
        let bad = |k: usize, token: &str| format!("value {k} '{token}' is not a number");
        if scalar.is_float() {
            let values =
                text.split_ascii_whitespace().enumerate().map(|(k, t)| t.parse::<f64>().map_err(|_| bad(k, t)));
            Ok(Values::Float(values.collect::<Result<_, _>>()?))
        } else {
            let values =
                text.split_ascii_whitespace().enumerate().map(|(k, t)| t.parse::<i64>().map_err(|_| bad(k, t)));
            Ok(Values::Int(values.collect::<Result<_, _>>()?))
        }
    }

    /// The bytes of the appended block at `offset` (after its byte-count header).
    fn appended_block(&self, offset: usize) -> Result<&[u8], String> {
        let data = self.appended.ok_or("is format=\"appended\" but the file has no <AppendedData> section")?;
        let truncated = || {
            format!(
                "truncated: the block at offset {offset} runs past the end of the appended data ({} bytes)",
                data.len()
            )
        };
        let body_start = offset.checked_add(self.header_size).ok_or_else(truncated)?;
        let header = data.get(offset..body_start).ok_or_else(truncated)?;
        let fold = |acc: u64, &b: &u8| (acc << 8) | u64::from(b);
        let byte_count = if self.big_endian { header.iter().fold(0, fold) } else { header.iter().rev().fold(0, fold) };
        let body_end =
            usize::try_from(byte_count).ok().and_then(|n| body_start.checked_add(n)).ok_or_else(truncated)?;
        data.get(body_start..body_end).ok_or_else(truncated)
    }

    fn decode(&self, bytes: &[u8], scalar: Scalar) -> Result<Values, String> {
        if !bytes.len().is_multiple_of(scalar.size()) {
            return Err(format!("{} bytes is not a whole number of {scalar:?} values", bytes.len()));
        }
        let big = self.big_endian;
        Ok(match scalar {
            Scalar::I8 => Values::Int(decode!(bytes, big, i8, 1).map(i64::from).collect()),
            Scalar::I16 => Values::Int(decode!(bytes, big, i16, 2).map(i64::from).collect()),
            Scalar::I32 => Values::Int(decode!(bytes, big, i32, 4).map(i64::from).collect()),
            Scalar::I64 => Values::Int(decode!(bytes, big, i64, 8).collect()),
            Scalar::U8 => Values::Int(decode!(bytes, big, u8, 1).map(i64::from).collect()),
            Scalar::U16 => Values::Int(decode!(bytes, big, u16, 2).map(i64::from).collect()),
            Scalar::U32 => Values::Int(decode!(bytes, big, u32, 4).map(i64::from).collect()),
            Scalar::U64 => Values::Int(
                decode!(bytes, big, u64, 8)
                    .enumerate()
                    .map(|(k, v)| i64::try_from(v).map_err(|_| format!("value {k} ({v}) exceeds the Int64 range")))
                    .collect::<Result<_, _>>()?,
            ),
            Scalar::F32 => Values::Float(decode!(bytes, big, f32, 4).map(f64::from).collect()),
            Scalar::F64 => Values::Float(decode!(bytes, big, f64, 8).collect()),
        })
    }

    /// An integer array; errors name the first value that is not an integer.
    fn read_ints(&self, node: Node, components: usize, tuples: usize) -> Result<Vec<i64>, IoError> {
        self.read_array(node, components, tuples)?.into_i64().map_err(|k| {
            let name = node.attribute("Name").unwrap_or("(unnamed)");
            self.error(node, format!("DataArray '{name}': value {k} is not an integer"))
        })
    }

    /// Reads one piece's points, polygons and per-face cell data into `faces`.
    fn read_piece(&self, piece: Node, faces: &mut Faces) -> Result<(), IoError> {
        let n_points = self.count_attribute(piece, "NumberOfPoints", None)?;
        let n_verts = self.count_attribute(piece, "NumberOfVerts", Some(0))?;
        let n_lines = self.count_attribute(piece, "NumberOfLines", Some(0))?;
        let n_strips = self.count_attribute(piece, "NumberOfStrips", Some(0))?;
        let n_polys = self.count_attribute(piece, "NumberOfPolys", Some(0))?;
        if n_strips > 0 {
            return Err(self.unsupported(format!(
                "the file has {n_strips} triangle strips, which tissuefit does not read; apply the Triangulate \
                 filter in ParaView and re-save it"
            )));
        }

        let points = element_child(piece, "Points").ok_or_else(|| self.error(piece, "<Piece> has no <Points>"))?;
        let array =
            element_child(points, "DataArray").ok_or_else(|| self.error(points, "<Points> has no <DataArray>"))?;
        let coords = self.read_array(array, 3, n_points)?.into_f64();
        let base = faces.positions.len();
        faces.positions.extend(coords.as_chunks::<3>().0.iter().map(|&[x, y, z]| Vec3::new(x, y, z)));
        if u32::try_from(faces.positions.len()).is_err() {
            return Err(self.error(array, format!("{} points exceed the u32 index range", faces.positions.len())));
        }
        let first_face = faces.cell_id.len();
        if n_polys == 0 {
            return Ok(());
        }

        let polys = element_child(piece, "Polys")
            .ok_or_else(|| self.error(piece, format!("<Piece> has NumberOfPolys=\"{n_polys}\" but no <Polys>")))?;
        let offsets_node =
            named(polys, "offsets").ok_or_else(|| self.error(polys, "<Polys> has no 'offsets' array"))?;
        let offsets = self.read_ints(offsets_node, 1, n_polys)?;
        let mut start = 0i64;
        for (k, &end) in offsets.iter().enumerate() {
            if end <= start {
                return Err(self
                    .error(offsets_node, format!("offsets are not increasing at polygon {k} ({end} after {start})")));
            }
            if end - start < 3 {
                return Err(self
                    .error(offsets_node, format!("polygon {k} has {} corners; a face needs at least 3", end - start)));
            }
            start = end;
        }
        let conn_node =
            named(polys, "connectivity").ok_or_else(|| self.error(polys, "<Polys> has no 'connectivity' array"))?;
        // `start` is now the last offset: the number of connectivity entries the offsets use.
        let n_corners =
            usize::try_from(start).map_err(|_| self.error(offsets_node, "offsets exceed the address range"))?;
        let connectivity = self.read_ints(conn_node, 1, n_corners)?;
        let mut begin = 0usize;
        for (k, &end) in offsets.iter().enumerate() {
            let end = end as usize; // positive and ≤ n_corners: checked above.
            for &i in connectivity.get(begin..end).unwrap_or_default() {
                if !(0..n_points as i64).contains(&i) {
                    return Err(self.error(
                        conn_node,
                        format!("polygon {k} refers to point {i}, but the piece has {n_points} points"),
                    ));
                }
                faces.corners.push((base + i as usize) as u32);
            }
            faces.polygon_ends.push(faces.corners.len());
            begin = end;
        }

        // Cell data: verts and lines come before the polys (strips were refused above).
        let n_cells = n_verts
            .checked_add(n_lines)
            .and_then(|n| n.checked_add(n_polys))
            .ok_or_else(|| self.error(piece, "too many cells"))?;
        let skip = n_verts + n_lines;
        let cell_data = element_child(piece, "CellData");
        let field = |name: &str| cell_data.and_then(|cd| named(cd, name));
        let face_error =
            |node: Node, k: usize, what: String| self.error(node, format!("face {}: {what}", first_face + k));

        let id_node = field("cell_id").ok_or_else(|| {
            self.error(piece, "no cell_id cell-data array: cannot tell which cell each face belongs to")
        })?;
        for (k, &v) in self.read_ints(id_node, 1, n_cells)?.iter().skip(skip).enumerate() {
            let id =
                u32::try_from(v).map_err(|_| face_error(id_node, k, format!("cell_id {v} is not a valid cell id")))?;
            faces.cell_id.push(id);
        }
        match field("kind") {
            Some(node) => {
                for (k, &v) in self.read_ints(node, 1, n_cells)?.iter().skip(skip).enumerate() {
                    let kind = u32::try_from(v).ok().and_then(CellKind::from_code).ok_or_else(|| {
                        face_error(
                            node,
                            k,
                            format!("invalid kind code {v} (0 epithelial, 1 ecm, 2 lumen, 3 nucleus, 4 static)"),
                        )
                    })?;
                    faces.kind.push(kind);
                }
            }
            None => faces.kind.resize(faces.cell_id.len(), CellKind::Epithelial),
        }
        match field("cell_type") {
            Some(node) => {
                for (k, &v) in self.read_ints(node, 1, n_cells)?.iter().skip(skip).enumerate() {
                    let t = u32::try_from(v).map_err(|_| face_error(node, k, format!("invalid cell_type {v}")))?;
                    faces.cell_type.push(t);
                }
            }
            None => faces.cell_type.resize(faces.cell_id.len(), 0),
        }
        match field("face_type") {
            Some(node) => {
                for (k, &v) in self.read_ints(node, 1, n_cells)?.iter().skip(skip).enumerate() {
                    let t = u32::try_from(v).ok().and_then(FaceType::from_code).ok_or_else(|| {
                        face_error(node, k, format!("invalid face_type code {v} (0 apical, 1 lateral, 2 basal)"))
                    })?;
                    faces.face_type.push(t);
                }
            }
            None => faces.face_type.resize(faces.cell_id.len(), FaceType::default()),
        }
        match field("target_volume") {
            Some(node) => {
                let values = self.read_array(node, 1, n_cells)?.into_f64();
                faces.target_volume.extend(values.iter().skip(skip).map(|&v| Some(v)));
            }
            None => faces.target_volume.resize(faces.cell_id.len(), None),
        }
        match field("interface_label") {
            Some(node) => {
                for (k, &v) in self.read_ints(node, 1, n_cells)?.iter().skip(skip).enumerate() {
                    let l = u32::try_from(v).map_err(|_| {
                        face_error(node, k, format!("invalid interface_label {v} (a cell id, 0 = the medium)"))
                    })?;
                    faces.interface_label.push(Some(l));
                }
            }
            None => faces.interface_label.resize(faces.cell_id.len(), None),
        }
        if let Some(cd) = cell_data {
            faces.array_names.extend(
                cd.children()
                    .filter(|n| n.has_tag_name("DataArray"))
                    .filter_map(|n| n.attribute("Name"))
                    .map(String::from),
            );
        }
        if !faces.field_names.is_empty() {
            match faces.field_names.iter().find_map(|name| field(name).map(|node| (name.clone(), node))) {
                Some((name, node)) => {
                    let values = self.read_array(node, 1, n_cells)?.into_f64();
                    faces.field.extend(values.iter().skip(skip));
                    faces.field_found.get_or_insert(name);
                }
                None => faces.field.resize(faces.cell_id.len(), Real::NAN),
            }
        }
        for (k, name) in CellOverrides::ARRAY_NAMES.iter().flatten().enumerate() {
            match field(name) {
                Some(node) => {
                    let values = self.read_array(node, 1, n_cells)?.into_f64();
                    faces.overrides[k].extend(values.iter().skip(skip).map(|&v| (!v.is_nan()).then_some(v)));
                }
                None => faces.overrides[k].resize(faces.cell_id.len(), None),
            }
        }
        Ok(())
    }
}

/// Every face of the file (over all pieces), with global point indices.
#[derive(Default)]
struct Faces {
    positions: Vec<Vec3>,
    /// Corners of all polygons, concatenated; polygon `f` is `corners[polygon_ends[f-1]..polygon_ends[f]]`.
    corners: Vec<u32>,
    polygon_ends: Vec<usize>,
    cell_id: Vec<u32>,
    kind: Vec<CellKind>,
    cell_type: Vec<u32>,
    face_type: Vec<FaceType>,
    target_volume: Vec<Option<Real>>,
    /// Per face, the body on its other side (`interface_label`), where the file has it.
    interface_label: Vec<Option<u32>>,
    /// Per face, the cell's overrides ([`CellOverrides::ARRAY_NAMES`] flattened; `None`: NaN or no
    /// array).
    overrides: [Vec<Option<Real>>; 6],
    /// The cell-data arrays asked for by name, in order of preference (empty: none).
    field_names: Vec<String>,
    /// Per face, the first of `field_names` the face's piece has (NaN: none).
    field: Vec<Real>,
    /// The name read, if any piece had one.
    field_found: Option<String>,
    /// Every cell-data array name met, for errors.
    array_names: std::collections::BTreeSet<String>,
}

impl Faces {
    /// Groups faces into cells (in order of first appearance).
    /// Also returns, per triangle of the tissue (cells in order), the value of `field` (empty when
    /// no field was asked for).
    fn into_tissue(self, path: &Path) -> Result<(Tissue, Vec<Real>), IoError> {
        let n_faces = self.polygon_ends.len();
        debug_assert!(
            [self.cell_id.len(), self.kind.len(), self.cell_type.len(), self.face_type.len()]
                .iter()
                .all(|&n| n == n_faces)
        );
        let mut index_of: HashMap<u32, usize> = HashMap::new();
        let mut members: Vec<Vec<usize>> = Vec::new();
        for (f, &id) in self.cell_id.iter().enumerate() {
            let cell = *index_of.entry(id).or_insert_with(|| {
                members.push(Vec::new());
                members.len() - 1
            });
            if let Some(&first) = members[cell].first()
                && (self.kind[f] != self.kind[first] || self.cell_type[f] != self.cell_type[first])
            {
                return Err(IoError::parse(
                    path,
                    None,
                    format!(
                        "face {f}: cell {id} has kind {} and cell_type {} here but kind {} and cell_type {} on \
                         face {first}",
                        self.kind[f], self.cell_type[f], self.kind[first], self.cell_type[first]
                    ),
                ));
            }
            members[cell].push(f);
        }

        let polygon = |f: usize| {
            let begin = if f == 0 { 0 } else { self.polygon_ends[f - 1] };
            &self.corners[begin..self.polygon_ends[f]]
        };
        // Local index of each global point in the cell being assembled (u32::MAX: unused).
        let mut local = vec![u32::MAX; self.positions.len()];
        let mut cells = Vec::with_capacity(members.len());
        let mut field = Vec::new();
        for faces in &members {
            let first = faces[0];
            let id = CellId(self.cell_id[first]);
            let mut used: Vec<u32> = faces.iter().flat_map(|&f| polygon(f).iter().copied()).collect();
            used.sort_unstable();
            used.dedup();
            for (k, &g) in used.iter().enumerate() {
                local[g as usize] = k as u32;
            }
            let positions = used.iter().map(|&g| self.positions[g as usize]).collect();
            let remapped: Vec<u32> =
                faces.iter().flat_map(|&f| polygon(f).iter().map(|&g| local[g as usize])).collect();
            let mut polygons: Vec<&[u32]> = Vec::with_capacity(faces.len());
            let mut begin = 0;
            for &f in faces {
                let end = begin + polygon(f).len();
                polygons.push(&remapped[begin..end]);
                begin = end;
            }
            for &g in &used {
                local[g as usize] = u32::MAX;
            }
            let (mesh, source) = CellMesh::from_polygons(positions, &polygons).map_err(|source| IoError::Mesh {
                path: path.to_path_buf(),
                cell: id,
                source,
            })?;
            if !self.field_names.is_empty() {
                field.extend(source.iter().map(|&p| self.field[faces[p as usize]]));
            }
            let face_types = source.iter().map(|&p| self.face_type[faces[p as usize]]).collect();
            let mut cell = Cell::new(id, self.kind[first], self.cell_type[first], mesh)
                .with_face_types(face_types)
                .map_err(|source| IoError::Tissue { path: path.to_path_buf(), source })?;
            if let Some(v) = self.target_volume[first] {
                cell = cell.with_target_volume(v);
            }
            let mut overrides = CellOverrides::default();
            for (k, values) in self.overrides.iter().enumerate() {
                let value = values[first];
                let name = CellOverrides::ARRAY_NAMES[k / 3][k % 3];
                if let Some(f) = faces.iter().find(|&&f| values[f].map(Real::to_bits) != value.map(Real::to_bits)) {
                    return Err(IoError::parse(
                        path,
                        None,
                        format!("face {f}: cell {id} has {name} {:?} here but {value:?} on face {first}", values[*f]),
                    ));
                }
                overrides.values_mut(k / 3)[k % 3] = value;
            }
            if let Some((name, v)) = overrides.invalid() {
                return Err(IoError::parse(
                    path,
                    None,
                    format!("cell {id}: {name} = {v}: a cell's own tension or adhesion must be a finite number ≥ 0"),
                ));
            }
            cell = cell.with_overrides(overrides);
            let labels: Option<Vec<u32>> = source.iter().map(|&p| self.interface_label[faces[p as usize]]).collect();
            if let Some(labels) = labels {
                cell = cell
                    .with_interface_labels(labels)
                    .map_err(|source| IoError::Tissue { path: path.to_path_buf(), source })?;
            }
            cells.push(cell);
        }
        let tissue =
            Tissue::from_cells(cells).map_err(|source| IoError::Tissue { path: path.to_path_buf(), source })?;
        Ok((tissue, field))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shapes::icosphere;

    /// Two icosphere cells of different kinds, cell types, face types and target volumes.
    fn two_cells() -> Tissue {
        let a = icosphere(5e-6, 2, Vec3::new(1e-6, -2e-6, 3e-6));
        let b = icosphere(3e-6, 1, Vec3::new(1.2e-5, 0.0, 0.0));
        let types_a = (0..a.face_count()).map(|f| FaceType::ALL[f % 3]).collect();
        let types_b = (0..b.face_count()).map(|f| FaceType::ALL[(f / 2) % 3]).collect();
        let va = a.signed_volume();
        let cell_a = Cell::new(CellId(7), CellKind::Epithelial, 1, a)
            .with_face_types(types_a)
            .unwrap()
            .with_target_volume(1.1 * va);
        let cell_b =
            Cell::new(CellId(3), CellKind::Lumen, 2, b).with_face_types(types_b).unwrap().with_target_volume(0.3e-16);
        Tissue::from_cells(vec![cell_a, cell_b]).unwrap()
    }

    /// The XML part of a written file, parsed.
    fn header_of(bytes: &[u8]) -> String {
        let (xml, _) = split_appended(Path::new("x.vtp"), bytes).unwrap();
        xml
    }

    fn assert_same_tissue(back: &Tissue, tissue: &Tissue) {
        assert_eq!(back.len(), tissue.len());
        for (r, c) in back.cells().iter().zip(tissue.cells()) {
            assert_eq!(r.id(), c.id());
            assert_eq!(r.kind(), c.kind());
            assert_eq!(r.cell_type(), c.cell_type());
            assert_eq!(r.mesh().triangles(), c.mesh().triangles());
            assert_eq!(r.face_types(), c.face_types());
            assert_eq!(r.target_volume().to_bits(), c.target_volume().to_bits());
            let bits = |m: &CellMesh| {
                m.positions().iter().flat_map(|p| p.iter().map(|x| x.to_bits()).collect::<Vec<_>>()).collect::<Vec<_>>()
            };
            assert_eq!(bits(r.mesh()), bits(c.mesh()));
        }
        assert_eq!(back, tissue);
    }

    #[test]
    fn round_trip_is_exact() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("frame.vtp");
        let tissue = two_cells();
        let pressure = [12.5, -3.0];
        write_vtp(&path, &tissue, &[CellField { name: "pressure", values: &pressure }], None).unwrap();
        let back = read_vtp(&path).unwrap();
        assert_same_tissue(&back, &tissue);

        let bytes = std::fs::read(&path).unwrap();
        let xml = header_of(&bytes);
        let doc = roxmltree::Document::parse(&xml).unwrap();
        assert!(doc.descendants().any(|n| n.attribute("Name") == Some("pressure")));
        assert!(!doc.descendants().any(|n| n.attribute("Name") == Some("TimeValue")));
        // No temporary left behind.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    /// Per-cell tensions and adhesions travel through both tissue formats (NaN in a `.vtp`, −1 in a
    /// legacy file where the cell keeps its type's value), and files without them stay as before.
    #[test]
    fn per_cell_overrides_round_trip_through_vtp_and_legacy_files() {
        let dir = tempfile::tempdir().unwrap();
        let mut tissue = two_cells();
        let plain = vtp_bytes(Path::new("plain.vtp"), &tissue, &[], None).unwrap();
        assert!(!String::from_utf8_lossy(&plain).contains("surface_tension_apical"));
        tissue.cells_mut()[0].overrides_mut().surface_tension = [Some(7.5e-4), None, Some(1.25e-3)];
        tissue.cells_mut()[0].overrides_mut().adhesion[1] = Some(0.0);
        let options = crate::io::ReadOptions::default();
        for name in ["t.vtp", "t.vtk"] {
            let path = dir.path().join(name);
            crate::io::write_tissue(&path, &tissue, &[]).unwrap();
            let back = crate::io::read_tissue(&path, &options).unwrap().tissue;
            assert_eq!(back.cells()[0].overrides(), tissue.cells()[0].overrides(), "{name}");
            assert!(back.cells()[1].overrides().is_empty(), "{name}");
        }
        // A negative value in a file is refused naming the cell and the array.
        let path = dir.path().join("bad.vtk");
        tissue.cells_mut()[1].overrides_mut().adhesion[2] = Some(-5.0);
        crate::io::write_tissue(&path, &tissue, &[]).unwrap();
        let error = crate::io::read_tissue(&path, &options).unwrap_err().to_string();
        assert!(error.contains("cell_adhesion_basal of cell 1 is -5"), "{error}");
        let path = dir.path().join("bad.vtp");
        crate::io::write_tissue(&path, &tissue, &[]).unwrap();
        let error = crate::io::read_tissue(&path, &options).unwrap_err().to_string();
        assert!(error.contains("cell 3: adhesion_basal = -5"), "{error}");
    }

    #[test]
    fn cell_data_values_are_written_per_face() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("frame.vtp");
        let tissue = two_cells();
        let pressure = [12.5, -3.0];
        write_vtp(&path, &tissue, &[CellField { name: "pressure", values: &pressure }], None).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let (xml, appended) = split_appended(&path, &bytes).unwrap();
        let doc = roxmltree::Document::parse(&xml).unwrap();
        let reader =
            ArrayReader { path: &path, doc: &doc, appended, compressor: None, big_endian: false, header_size: 8 };
        let n_faces = tissue.face_count();
        let array = |name: &str| doc.descendants().find(|n| n.attribute("Name") == Some(name)).unwrap();
        let values = |name: &str| reader.read_array(array(name), 1, n_faces).unwrap().into_f64();
        let first = tissue.cells()[0].mesh().face_count();
        let p = values("pressure");
        assert!(p[..first].iter().all(|&v| v == 12.5) && p[first..].iter().all(|&v| v == -3.0));
        let v = values("cell_volume");
        assert_eq!(v[0], tissue.cells()[0].mesh().signed_volume());
        assert_eq!(v[n_faces - 1], tissue.cells()[1].mesh().signed_volume());
        let a: Real = values("face_area")[..first].iter().sum();
        assert!((a - tissue.cells()[0].mesh().area()).abs() <= 1e-12 * a);
        assert_eq!(values("kind")[n_faces - 1], CellKind::Lumen.code() as f64);
    }

    #[test]
    fn time_value_is_stored_when_given() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("frame.vtp");
        let t = 2.5e-3 / 3.0;
        write_vtp(&path, &two_cells(), &[], Some(t)).unwrap();
        let xml = header_of(&std::fs::read(&path).unwrap());
        let doc = roxmltree::Document::parse(&xml).unwrap();
        let field = doc.descendants().find(|n| n.has_tag_name("FieldData")).expect("FieldData");
        let time = field.children().find(|n| n.attribute("Name") == Some("TimeValue")).expect("TimeValue");
        assert_eq!(time.attribute("NumberOfTuples"), Some("1"));
        assert_eq!(time.text().unwrap().trim().parse::<f64>().unwrap().to_bits(), t.to_bits());
        assert_same_tissue(&read_vtp(&path).unwrap(), &two_cells());
    }

    /// A file in µm: points × 1e6, the unit recorded as VTK writes a string (`117 109 0`), read back
    /// in metres (within rounding: × 1e6 then × 1e-6), the time kept beside it.
    #[test]
    fn a_file_in_micrometres_records_its_unit_and_reads_back_in_metres() {
        let dir = tempfile::tempdir().unwrap();
        let (si, um) = (dir.path().join("si.vtp"), dir.path().join("um.vtp"));
        let tissue = two_cells();
        write_vtp(&si, &tissue, &[], Some(2.0)).unwrap();
        write_vtp_in(&um, &tissue, &[], Some(2.0), OutputUnit::Micrometre).unwrap();
        let xml = header_of(&std::fs::read(&um).unwrap());
        let doc = roxmltree::Document::parse(&xml).unwrap();
        let field = doc.descendants().find(|n| n.has_tag_name("FieldData")).expect("FieldData");
        let unit = field.children().find(|n| n.attribute("Name") == Some(LENGTH_UNIT_FIELD)).expect("length_unit");
        assert_eq!((unit.attribute("type"), unit.text()), (Some("String"), Some("117 109 0")));
        assert!(field.children().any(|n| n.attribute("Name") == Some("TimeValue")));
        // In SI the writer is the plain one, byte for byte.
        let again = dir.path().join("si2.vtp");
        write_vtp_in(&again, &tissue, &[], Some(2.0), OutputUnit::Metre).unwrap();
        assert_eq!(std::fs::read(&si).unwrap(), std::fs::read(&again).unwrap());

        let back = read_vtp(&um).unwrap();
        assert_eq!(back.len(), tissue.len());
        for (r, c) in back.cells().iter().zip(tissue.cells()) {
            assert_eq!((r.id(), r.kind(), r.face_types()), (c.id(), c.kind(), c.face_types()));
            assert_eq!(r.mesh().triangles(), c.mesh().triangles());
            for (p, q) in r.mesh().positions().iter().zip(c.mesh().positions()) {
                assert!((p - q).norm() <= 1e-12 * q.norm().max(1e-6), "{p} vs {q}");
            }
            let (v, w) = (r.target_volume(), c.target_volume());
            assert!((v - w).abs() <= 1e-12 * w, "{v} vs {w}");
        }
        // The raw points are the SI ones × 1e6.
        let text = std::fs::read(&um).unwrap();
        let (_, appended) = split_appended(&um, &text).unwrap();
        let reader =
            ArrayReader { path: &um, doc: &doc, appended, compressor: None, big_endian: false, header_size: 8 };
        let points = doc.descendants().find(|n| n.has_tag_name("Points")).unwrap();
        let array = points.children().find(|n| n.has_tag_name("DataArray")).unwrap();
        let raw = reader.read_array(array, 3, tissue.node_count()).unwrap().into_f64();
        let first = tissue.cells()[0].mesh().positions()[0];
        assert_eq!(raw[..3], [first.x * 1e6, first.y * 1e6, first.z * 1e6]);

        // A unit that is not one is an error naming the field.
        let at = text.windows(9).position(|w| w == b"117 109 0").unwrap();
        let mut bad = text.clone();
        bad[at..at + 9].copy_from_slice(b"102 116 0");
        let err = parse_vtp(&um, &bad).unwrap_err().to_string();
        assert!(err.contains("length_unit") && err.contains("`ft`"), "{err}");
    }

    #[test]
    fn bad_extra_fields_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("frame.vtp");
        let short = [1.0];
        assert!(write_vtp(&path, &two_cells(), &[CellField { name: "p", values: &short }], None).is_err());
        let ok = [1.0, 2.0];
        assert!(write_vtp(&path, &two_cells(), &[CellField { name: "kind", values: &ok }], None).is_err());
        assert!(!path.exists());
    }

    #[test]
    fn empty_tissue_round_trips() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("empty.vtp");
        write_vtp(&path, &Tissue::new(), &[], Some(0.0)).unwrap();
        assert!(read_vtp(&path).unwrap().is_empty());
    }

    #[test]
    fn truncated_file_is_an_error_naming_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("whole.vtp");
        write_vtp(&path, &two_cells(), &[], Some(1.0)).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let footer = b"\n  </AppendedData>\n</VTKFile>\n".len();
        let cut_path = dir.path().join("cut.vtp");
        // Every cut before the end of the data (header included) is an error, never a panic.
        let data_end = bytes.len() - footer;
        for cut in (0..data_end).step_by(97).chain([data_end - 1]) {
            std::fs::write(&cut_path, &bytes[..cut]).unwrap();
            let err = read_vtp(&cut_path).expect_err("truncated file read as valid").to_string();
            assert!(err.contains("cut.vtp"), "{err}");
        }
        std::fs::write(&cut_path, &bytes[..data_end - 1]).unwrap();
        let err = read_vtp(&cut_path).unwrap_err().to_string();
        assert!(err.contains("truncated"), "{err}");
    }

    #[test]
    fn corrupted_bytes_never_panic() {
        let a = CellMesh::from_triangles(
            vec![Vec3::zeros(), Vec3::x(), Vec3::y(), Vec3::z()],
            vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
        )
        .unwrap();
        let tissue = Tissue::from_cells(vec![Cell::new(CellId(1), CellKind::Static, 0, a)]).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("tet.vtp");
        write_vtp(&path, &tissue, &[], None).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let mut oks = 0;
        for k in 0..bytes.len() {
            for value in [0u8, 0x7f, 0xff, b'9'] {
                let mut corrupt = bytes.clone();
                corrupt[k] = value;
                oks += usize::from(parse_vtp(&path, &corrupt).is_ok());
            }
        }
        // Some corruptions (inside coordinates) are still readable files; the point is no panic.
        assert!(oks > 0);
    }

    /// A tetrahedron (cell 5) and a square pyramid whose base is a quad (cell 2), faces interleaved.
    const ASCII: &str = r#"<?xml version="1.0"?>
<VTKFile type="PolyData" version="0.1" byte_order="LittleEndian">
  <PolyData>
    <Piece NumberOfPoints="9" NumberOfVerts="0" NumberOfLines="0" NumberOfStrips="0" NumberOfPolys="9">
      <Points>
        <DataArray type="Float32" Name="Points" NumberOfComponents="3" format="ascii">
          0 0 0  1 0 0  0 1 0  0 0 1
          2 0 0  3 0 0  3 1 0  2 1 0  2.5 0.5 1
        </DataArray>
      </Points>
      <CellData>
        <DataArray type="Int32" Name="cell_id" format="ascii">5 2 5 2 5 2 5 2 2</DataArray>
        <DataArray type="UInt8" Name="kind" format="ascii">0 2 0 2 0 2 0 2 2</DataArray>
        <DataArray type="Int64" Name="face_type" format="ascii">0 2 1 0 1 0 0 0 0</DataArray>
      </CellData>
      <Polys>
        <DataArray type="Int64" Name="connectivity" format="ascii">
          0 2 1  4 7 6 5  0 1 3  4 5 8  0 3 2  5 6 8  1 2 3  6 7 8  7 4 8
        </DataArray>
        <DataArray type="Int64" Name="offsets" format="ascii">3 7 10 13 16 19 22 25 28</DataArray>
      </Polys>
    </Piece>
  </PolyData>
</VTKFile>
"#;

    fn read_text(dir: &Path, name: &str, text: &str) -> Result<Tissue, IoError> {
        let path = dir.join(name);
        std::fs::write(&path, text).unwrap();
        read_vtp(&path)
    }

    #[test]
    fn ascii_file_with_a_quad_is_read_and_triangulated() {
        let dir = tempfile::tempdir().unwrap();
        let tissue = read_text(dir.path(), "hand.vtp", ASCII).unwrap();
        let ids: Vec<u32> = tissue.cells().iter().map(|c| c.id().0).collect();
        assert_eq!(ids, [5, 2]);
        let [tet, pyramid] = tissue.cells() else { panic!("two cells expected") };
        assert_eq!(tet.kind(), CellKind::Epithelial);
        assert_eq!(pyramid.kind(), CellKind::Lumen);
        assert_eq!(tet.mesh().node_count(), 4);
        assert_eq!(pyramid.mesh().node_count(), 5);
        assert_eq!(pyramid.mesh().face_count(), 6);
        tet.mesh().validate().unwrap();
        pyramid.mesh().validate().unwrap();
        assert!((tet.mesh().signed_volume() - 1.0 / 6.0).abs() < 1e-12);
        assert!((pyramid.mesh().signed_volume() - 1.0 / 3.0).abs() < 1e-12);
        assert_eq!(tet.face_types(), [FaceType::Apical, FaceType::Lateral, FaceType::Lateral, FaceType::Apical]);
        // The quad's two triangles are basal, the four sides apical.
        assert_eq!(pyramid.face_types().iter().filter(|&&t| t == FaceType::Basal).count(), 2);
        assert_eq!(pyramid.target_volume(), pyramid.mesh().signed_volume());
        assert_eq!(pyramid.mesh().position(crate::mesh::NodeId(4)), Vec3::new(2.5, 0.5, 1.0));
    }

    #[test]
    fn malformed_ascii_files_are_errors_naming_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let cases: &[(&str, &str, &str, &str)] = &[
            ("point index", "7 4 8\n", "7 4 9\n", "refers to point 9"),
            ("missing cell_id", r#"Name="cell_id""#, r#"Name="label""#, "no cell_id cell-data array"),
            ("bad number", "2.5 0.5 1", "2.5 zero 1", "is not a number"),
            (
                "wrong tuples",
                r#"Name="kind" format"#,
                r#"Name="kind" NumberOfTuples="8" format"#,
                "NumberOfTuples is 8",
            ),
            ("short array", "0 2 0 2 0 2 0 2 2<", "0 2 0 2 0 2 0 2<", "has 8 values"),
            ("offsets decrease", "3 7 10 13", "3 7 6 13", "not increasing"),
            ("offsets past the end", "22 25 28<", "22 25 29<", "has 28 values; expected 29"),
            ("missing points", "Points>", "Pointz>", "no <Points>"),
            ("invalid kind", "0 2 0 2 0 2 0 2 2<", "0 2 0 2 0 2 0 2 7<", "face 8: invalid kind code 7"),
            ("invalid face type", "0 2 1 0 1", "0 2 1 0 -1", "face 4: invalid face_type code -1"),
            ("mixed kinds in a cell", "0 2 0 2 0 2 0 2 2<", "0 2 0 2 0 2 0 2 1<", "face 8: cell 2"),
            ("not xml", "</VTKFile>", "", "malformed XML"),
            ("inline base64", r#"Name="kind" format="ascii""#, r#"Name="kind" format="binary""#, "re-save"),
            ("unstructured grid", r#"type="PolyData""#, r#"type="UnstructuredGrid""#, "PolyData"),
        ];
        for (what, from, to, expected) in cases {
            assert!(ASCII.contains(from), "{what}: pattern not in the template");
            let text = ASCII.replace(from, to);
            let name = format!("{}.vtp", what.replace(' ', "_"));
            let err = read_text(dir.path(), &name, &text).expect_err(what).to_string();
            assert!(err.contains(&name), "{what}: {err}");
            assert!(err.contains(expected), "{what}: {err}");
        }
        let err = read_text(dir.path(), "b64.vtp", &ASCII.replacen(r#"format="ascii""#, r#"format="binary""#, 1))
            .unwrap_err();
        assert!(matches!(err, IoError::Unsupported { .. }), "{err}");
        // NaN coordinates are read (validate() reports them), not refused.
        let nan = read_text(dir.path(), "nan.vtp", &ASCII.replacen("2.5 0.5 1", "nan 0.5 1", 1)).unwrap();
        assert!(nan.cells()[1].mesh().validate().is_err());
    }

    /// VTK's writer names its default compressor in ASCII files too, where nothing is compressed.
    #[test]
    fn compressor_attribute_only_matters_for_binary_data() {
        let dir = tempfile::tempdir().unwrap();
        let attr = r#"byte_order="LittleEndian" compressor="vtkZLibDataCompressor""#;
        let ascii = ASCII.replacen(r#"byte_order="LittleEndian""#, attr, 1);
        assert_eq!(read_text(dir.path(), "ascii.vtp", &ascii).unwrap().len(), 2);

        let path = dir.path().join("zlib.vtp");
        write_vtp(&path, &two_cells(), &[], None).unwrap();
        let mut bytes = std::fs::read(&path).unwrap();
        let plain = br#"byte_order="LittleEndian""#;
        let at = bytes.windows(plain.len()).position(|w| w == plain).unwrap();
        bytes.splice(at..at + plain.len(), attr.bytes());
        std::fs::write(&path, &bytes).unwrap();
        let err = read_vtp(&path).unwrap_err();
        assert!(matches!(err, IoError::Unsupported { .. }), "{err}");
        assert!(err.to_string().contains("compressed") && err.to_string().contains("zlib.vtp"), "{err}");
    }

    #[test]
    fn appended_base64_is_unsupported() {
        let dir = tempfile::tempdir().unwrap();
        let text = ASCII.replace("</VTKFile>", "<AppendedData encoding=\"base64\">_AAAA</AppendedData></VTKFile>");
        let err = read_text(dir.path(), "b64.vtp", &text).unwrap_err();
        assert!(matches!(err, IoError::Unsupported { .. }) && err.to_string().contains("base64"), "{err}");
    }

    /// A hand-built raw appended file: big-endian, UInt32 headers, Float32 points, narrow integers.
    #[test]
    fn big_endian_narrow_types_are_read() {
        let points: [f32; 12] = [0., 0., 0., 1., 0., 0., 0., 1., 0., 0., 0., 1.];
        let connectivity: [i32; 12] = [0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3];
        let offsets: [u16; 4] = [3, 6, 9, 12];
        let ids: [u64; 4] = [9; 4];
        let mut blocks: Vec<Vec<u8>> = vec![
            points.iter().flat_map(|v| v.to_be_bytes()).collect(),
            connectivity.iter().flat_map(|v| v.to_be_bytes()).collect(),
            offsets.iter().flat_map(|v| v.to_be_bytes()).collect(),
            ids.iter().flat_map(|v| v.to_be_bytes()).collect(),
        ];
        let mut data = Vec::new();
        let mut at = Vec::new();
        for b in &mut blocks {
            at.push(data.len());
            data.extend_from_slice(&(b.len() as u32).to_be_bytes());
            data.append(b);
        }
        let xml = format!(
            r#"<VTKFile type="PolyData" version="0.1" byte_order="BigEndian">
<PolyData><Piece NumberOfPoints="4" NumberOfPolys="4">
<Points><DataArray type="Float32" NumberOfComponents="3" format="appended" offset="{}"/></Points>
<Polys><DataArray type="Int32" Name="connectivity" format="appended" offset="{}"/>
<DataArray type="UInt16" Name="offsets" format="appended" offset="{}"/></Polys>
<CellData><DataArray type="UInt64" Name="cell_id" format="appended" offset="{}"/></CellData>
</Piece></PolyData>
<AppendedData encoding="raw">
 _"#,
            at[0], at[1], at[2], at[3]
        );
        let mut bytes = xml.into_bytes();
        bytes.extend_from_slice(&data);
        bytes.extend_from_slice(b"\n</AppendedData></VTKFile>");
        let (tissue, _) = parse_vtp(Path::new("be.vtp"), &bytes).unwrap();
        let [cell] = tissue.cells() else { panic!("one cell expected") };
        assert_eq!(cell.id(), CellId(9));
        assert_eq!(cell.mesh().triangles(), [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]);
        assert_eq!(cell.mesh().position(crate::mesh::NodeId(3)), Vec3::z());
        cell.mesh().validate().unwrap();
    }

    #[test]
    fn missing_file_is_an_open_error() {
        let err = read_vtp(Path::new("/nonexistent/dir/frame.vtp")).unwrap_err();
        assert!(matches!(err, IoError::Open { .. }) && err.to_string().contains("frame.vtp"));
    }
}
