//! Parser of legacy ASCII VTK files (versions 2.0–5.1) into a neutral grid: points, cells as
//! connectivity lists with their VTK types, and the numeric cell-data arrays.
//!
//! Hand-written rather than vtkio: vtkio 0.7.0-rc2 rejects two of the seven real files in
//! `shared/data/real` (a VTK 5.1 file with `vtktypeint64` arrays, and ParaView `METADATA` blocks
//! without a blank line) with messages such as "Parse error: Tag" that name neither line nor problem.
//! This parser reports `file:line: what` for every malformed input and never panics.

use super::IoError;
use crate::geometry::{Real, Vec3};
use std::path::Path;

/// A numeric data array attached to cells (`FIELD` arrays and `SCALARS`).
#[derive(Clone, Debug)]
pub(crate) struct DataArray {
    pub name: String,
    pub components: usize,
    pub values: Vec<Real>,
    pub line: usize,
}

/// The content of a legacy VTK file that tissuefit uses.
#[derive(Clone, Debug, Default)]
pub(crate) struct LegacyGrid {
    pub points: Vec<Vec3>,
    pub points_line: usize,
    /// CSR: cell `c` has `connectivity[offsets[c]..offsets[c+1]]` (for polyhedra, the face stream
    /// `nFaces, (k, ids…)…`).
    pub offsets: Vec<usize>,
    pub connectivity: Vec<u32>,
    pub cells_line: usize,
    pub cell_types: Vec<u8>,
    pub cell_data: Vec<DataArray>,
}

impl LegacyGrid {
    pub fn cell_count(&self) -> usize {
        self.offsets.len().saturating_sub(1)
    }

    pub fn cell(&self, c: usize) -> &[u32] {
        &self.connectivity[self.offsets[c]..self.offsets[c + 1]]
    }

    /// The cell-data array with this name (case-insensitive).
    pub fn array(&self, name: &str) -> Option<&DataArray> {
        self.cell_data.iter().find(|a| a.name.eq_ignore_ascii_case(name))
    }
}

/// Whitespace tokenizer over the file bytes that tracks line numbers.
struct Cursor<'a> {
    text: &'a [u8],
    pos: usize,
    line: usize,
    path: &'a Path,
}

impl<'a> Cursor<'a> {
    fn err(&self, message: impl Into<String>) -> IoError {
        IoError::parse(self.path, Some(self.line), message)
    }

    fn skip_space(&mut self) {
        while let Some(&b) = self.text.get(self.pos) {
            match b {
                b'\n' => self.line += 1,
                b' ' | b'\t' | b'\r' | 0x0c => {}
                _ => break,
            }
            self.pos += 1;
        }
    }

    /// Next whitespace-separated token, or `None` at end of file.
    fn token(&mut self) -> Result<Option<&'a str>, IoError> {
        self.skip_space();
        let start = self.pos;
        while self.text.get(self.pos).is_some_and(|b| !b.is_ascii_whitespace()) {
            self.pos += 1;
        }
        if start == self.pos {
            return Ok(None);
        }
        std::str::from_utf8(&self.text[start..self.pos])
            .map(Some)
            .map_err(|_| self.err("invalid (non-UTF-8) bytes; is this a binary file?"))
    }

    fn peek(&mut self) -> Result<Option<&'a str>, IoError> {
        let (pos, line) = (self.pos, self.line);
        let t = self.token();
        (self.pos, self.line) = (pos, line);
        t
    }

    fn expect(&mut self, what: &str) -> Result<&'a str, IoError> {
        self.token()?.ok_or_else(|| self.err(format!("file ends while reading {what} (truncated file?)")))
    }

    fn count(&mut self, what: &str) -> Result<usize, IoError> {
        let t = self.expect(what)?;
        t.parse().map_err(|_| self.err(format!("expected {what} (a non-negative integer), found `{t}`")))
    }

    fn real(&mut self, what: &str) -> Result<Real, IoError> {
        let t = self.expect(what)?;
        t.parse().map_err(|_| self.err(format!("expected {what} (a number), found `{t}`")))
    }

    fn index(&mut self, what: &str) -> Result<u32, IoError> {
        // Fast path for the common case, a plain decimal that fits in u32 (most of a file's tokens
        // are point indices); anything else takes the general parse for its exact error message.
        let (pos, line) = (self.pos, self.line);
        self.skip_space();
        let start = self.pos;
        let mut value: u64 = 0;
        while let Some(&b) = self.text.get(self.pos) {
            if !b.is_ascii_digit() || self.pos - start >= 10 {
                break;
            }
            value = value * 10 + u64::from(b - b'0');
            self.pos += 1;
        }
        let ends = self.text.get(self.pos).is_none_or(|b| b.is_ascii_whitespace());
        if self.pos > start && ends && value <= u64::from(u32::MAX) {
            return Ok(value as u32);
        }
        (self.pos, self.line) = (pos, line);
        let t = self.expect(what)?;
        match t.parse::<i64>() {
            Ok(v) if (0..=u32::MAX as i64).contains(&v) => Ok(v as u32),
            Ok(v) => Err(self.err(format!("{what} {v} is out of range"))),
            Err(_) => Err(self.err(format!("expected {what} (an integer), found `{t}`"))),
        }
    }

    /// Consumes the rest of the current line, returning it trimmed.
    fn rest_of_line(&mut self) -> &'a str {
        let start = self.pos;
        while self.text.get(self.pos).is_some_and(|&b| b != b'\n') {
            self.pos += 1;
        }
        let s = std::str::from_utf8(&self.text[start..self.pos]).unwrap_or("");
        if self.pos < self.text.len() {
            self.pos += 1;
            self.line += 1;
        }
        s.trim()
    }

    /// Skips an optional `METADATA` block after a data array: `COMPONENT_NAMES` lines and
    /// `INFORMATION n` followed by n key entries of two lines each (`NAME … LOCATION …`, `DATA …`).
    fn skip_metadata(&mut self, components: usize) -> Result<(), IoError> {
        if !self.peek()?.is_some_and(|t| t.eq_ignore_ascii_case("METADATA")) {
            return Ok(());
        }
        self.token()?;
        loop {
            match self.peek()? {
                Some(t) if t.eq_ignore_ascii_case("COMPONENT_NAMES") => {
                    self.token()?;
                    for _ in 0..components {
                        self.expect("a component name")?;
                    }
                }
                Some(t) if t.eq_ignore_ascii_case("INFORMATION") => {
                    self.token()?;
                    let n = self.count("the number of INFORMATION entries")?;
                    self.rest_of_line();
                    for _ in 0..n {
                        self.skip_space();
                        self.rest_of_line(); // NAME … LOCATION …
                        self.skip_space();
                        self.rest_of_line(); // DATA …
                    }
                }
                _ => return Ok(()),
            }
        }
    }
}

fn is_section(t: &str) -> bool {
    [
        "POINTS",
        "CELLS",
        "CELL_TYPES",
        "CELL_DATA",
        "POINT_DATA",
        "POLYGONS",
        "VERTICES",
        "LINES",
        "TRIANGLE_STRIPS",
        "FIELD",
        "DATASET",
        "METADATA",
    ]
    .iter()
    .any(|k| t.eq_ignore_ascii_case(k))
}

/// Parses the text of a legacy VTK file.
pub(crate) fn parse_legacy(path: &Path, text: &[u8]) -> Result<LegacyGrid, IoError> {
    let mut c = Cursor { text, pos: 0, line: 1, path };
    let header = c.rest_of_line();
    header.strip_prefix("# vtk DataFile Version").ok_or_else(|| {
        IoError::parse(
            path,
            Some(1),
            format!(
                "not a legacy VTK file: the first line is `{}`, expected `# vtk DataFile Version x.y`",
                truncate(header)
            ),
        )
    })?;
    c.rest_of_line(); // title
    let format = c.rest_of_line();
    if format.eq_ignore_ascii_case("BINARY") {
        return Err(IoError::Unsupported {
            path: path.into(),
            message:
                "binary legacy VTK is not supported; save the file as ASCII (ParaView: File type ASCII) or as .vtp"
                    .into(),
        });
    }
    if !format.eq_ignore_ascii_case("ASCII") {
        return Err(IoError::parse(
            path,
            Some(3),
            format!("line 3 must be ASCII or BINARY, found `{}`", truncate(format)),
        ));
    }
    let mut g = LegacyGrid::default();
    let mut dataset = None;
    while let Some(t) = c.token()? {
        let upper = t.to_ascii_uppercase();
        match upper.as_str() {
            "DATASET" => {
                let kind = c.expect("the dataset type")?.to_ascii_uppercase();
                if kind != "UNSTRUCTURED_GRID" && kind != "POLYDATA" {
                    return Err(c.err(format!(
                        "dataset type {kind} is not supported; tissuefit reads UNSTRUCTURED_GRID and POLYDATA"
                    )));
                }
                dataset = Some(kind);
            }
            "POINTS" => {
                g.points_line = c.line;
                let n = c.count("the number of points")?;
                c.expect("the point data type")?;
                g.points.reserve(n.min(text.len() / 6));
                for i in 0..n {
                    let line = c.line;
                    let p = Vec3::new(c.real("a coordinate")?, c.real("a coordinate")?, c.real("a coordinate")?);
                    if !p.iter().all(|v| v.is_finite()) {
                        return Err(IoError::parse(
                            path,
                            Some(line),
                            format!("point {i} has a non-finite coordinate ({}, {}, {})", p.x, p.y, p.z),
                        ));
                    }
                    g.points.push(p);
                }
                c.skip_metadata(3)?;
            }
            "CELLS" | "POLYGONS" => {
                if !g.offsets.is_empty() {
                    return Err(c.err(format!("a second {upper} section; tissuefit reads one cell block per file")));
                }
                g.cells_line = c.line;
                let n = c.count("the number of cells")?;
                let size = c.count("the size of the cell list")?;
                if c.peek()?.is_some_and(|t| t.eq_ignore_ascii_case("OFFSETS")) {
                    parse_offsets_connectivity(&mut c, &mut g, n, size)?;
                } else {
                    parse_cell_list(&mut c, &mut g, n, size)?;
                }
                if upper == "POLYGONS" {
                    g.cell_types = vec![7; g.cell_count()];
                }
            }
            "CELL_TYPES" => {
                let n = c.count("the number of cell types")?;
                if n != g.cell_count() {
                    return Err(c.err(format!("CELL_TYPES lists {n} cells but CELLS has {}", g.cell_count())));
                }
                g.cell_types = (0..n)
                    .map(|_| {
                        let v = c.index("a cell type")?;
                        u8::try_from(v).map_err(|_| c.err(format!("cell type {v} is not a VTK cell type")))
                    })
                    .collect::<Result<_, _>>()?;
            }
            "CELL_DATA" | "POINT_DATA" => {
                let n = c.count("the number of tuples")?;
                let on_cells = upper == "CELL_DATA";
                if on_cells && n != g.cell_count() {
                    return Err(c.err(format!("CELL_DATA has {n} tuples but the file has {} cells", g.cell_count())));
                }
                if !on_cells && n != g.points.len() {
                    return Err(c.err(format!("POINT_DATA has {n} tuples but the file has {} points", g.points.len())));
                }
                let arrays = parse_attributes(&mut c, n)?;
                if on_cells {
                    g.cell_data.extend(arrays);
                }
            }
            "FIELD" => {
                // Dataset-level field data (e.g. TIME): parsed for its length, not used.
                parse_field(&mut c, None)?;
            }
            "METADATA" => {
                return Err(c.err("METADATA block outside a data array"));
            }
            "VERTICES" | "LINES" | "TRIANGLE_STRIPS" => {
                return Err(
                    c.err(format!("{upper} are not supported; a tissue file holds polyhedra, triangles or polygons"))
                );
            }
            _ => {
                return Err(c.err(format!(
                    "unexpected `{}`; expected a section keyword such as POINTS, CELLS or CELL_DATA",
                    truncate(t)
                )));
            }
        }
    }
    if dataset.is_none() {
        return Err(IoError::parse(path, None, "no DATASET line"));
    }
    if g.points.is_empty() {
        return Err(IoError::parse(path, None, "no POINTS: the file holds no geometry"));
    }
    if g.offsets.is_empty() {
        return Err(IoError::parse(path, None, "no CELLS or POLYGONS section: the file holds no cells"));
    }
    if g.cell_types.len() != g.cell_count() {
        return Err(IoError::parse(path, Some(g.cells_line), "CELLS without a CELL_TYPES section"));
    }
    let np = g.points.len();
    for (c_idx, &t) in g.cell_types.iter().enumerate() {
        let ids = g.cell(c_idx);
        let bad = if t == 42 {
            let faces = polyhedron_faces(ids)
                .map_err(|m| IoError::parse(path, Some(g.cells_line), format!("cell {c_idx} (polyhedron): {m}")))?;
            faces.into_iter().flatten().copied().find(|&i| i as usize >= np)
        } else {
            ids.iter().copied().find(|&i| i as usize >= np)
        };
        if let Some(i) = bad {
            return Err(IoError::parse(
                path,
                Some(g.cells_line),
                format!("cell {c_idx} refers to point {i}, but the file has {np} points (0..{})", np - 1),
            ));
        }
    }
    Ok(g)
}

/// Splits a polyhedron face stream `nFaces, (k, ids…)…` into its faces; errors describe a stream
/// whose counts do not match its length.
pub(crate) fn polyhedron_faces(stream: &[u32]) -> Result<Vec<&[u32]>, String> {
    let (&faces, mut rest) = stream.split_first().ok_or("empty polyhedron record")?;
    // Each face takes at least one integer of the stream: a corrupt face count cannot over-allocate.
    let mut out = Vec::with_capacity((faces as usize).min(rest.len()));
    for f in 0..faces {
        let (&k, tail) =
            rest.split_first().ok_or_else(|| format!("the face stream announces {faces} faces but ends after {f}"))?;
        if tail.len() < k as usize {
            return Err(format!("face {f} announces {k} points but the record has only {} left", tail.len()));
        }
        let (face, tail) = tail.split_at(k as usize);
        out.push(face);
        rest = tail;
    }
    if !rest.is_empty() {
        return Err(format!("{} integers left over after the {faces} faces of the face stream", rest.len()));
    }
    Ok(out)
}

/// Legacy (≤ 5.0) cell list: `n` records `k id₁ … id_k`, `size` integers in all.
fn parse_cell_list(c: &mut Cursor, g: &mut LegacyGrid, n: usize, size: usize) -> Result<(), IoError> {
    // Declared counts are not trusted for allocation: every record takes at least two characters.
    g.offsets.reserve(n.min(c.text.len() / 2) + 1);
    g.offsets.push(0);
    g.connectivity.reserve(size.min(c.text.len() / 2));
    let mut consumed = 0usize;
    for cell in 0..n {
        let k = c.count("the size of a cell record")?;
        consumed += 1 + k;
        if consumed > size {
            return Err(
                c.err(format!("cell {cell} needs {k} more integers, past the {size} announced in the CELLS line"))
            );
        }
        for _ in 0..k {
            let v = c.index("a point index")?;
            g.connectivity.push(v);
        }
        g.offsets.push(g.connectivity.len());
    }
    if consumed != size {
        return Err(c.err(format!("the CELLS line announces {size} integers but the {n} cell records hold {consumed}")));
    }
    Ok(())
}

/// VTK 5.x cell block: `OFFSETS type` with `n` offsets and `CONNECTIVITY type` with `size` ids.
fn parse_offsets_connectivity(c: &mut Cursor, g: &mut LegacyGrid, n: usize, size: usize) -> Result<(), IoError> {
    c.token()?;
    c.expect("the OFFSETS data type")?;
    if n == 0 {
        return Err(c.err("CELLS with OFFSETS needs at least one offset"));
    }
    g.offsets = (0..n).map(|_| c.count("an offset")).collect::<Result<_, _>>()?;
    if g.offsets[0] != 0 || g.offsets.windows(2).any(|w| w[1] < w[0]) || g.offsets[n - 1] != size {
        return Err(c.err(format!("OFFSETS must start at 0, never decrease, and end at the connectivity size {size}")));
    }
    let kw = c.expect("CONNECTIVITY")?;
    if !kw.eq_ignore_ascii_case("CONNECTIVITY") {
        return Err(c.err(format!("expected CONNECTIVITY after the offsets, found `{}`", truncate(kw))));
    }
    c.expect("the CONNECTIVITY data type")?;
    g.connectivity = (0..size).map(|_| c.index("a point index")).collect::<Result<_, _>>()?;
    Ok(())
}

/// Parses attribute arrays of a CELL_DATA/POINT_DATA block of `n` tuples, until the next section.
fn parse_attributes(c: &mut Cursor, n: usize) -> Result<Vec<DataArray>, IoError> {
    let mut arrays = Vec::new();
    while let Some(t) = c.peek()? {
        let upper = t.to_ascii_uppercase();
        let components = match upper.as_str() {
            "FIELD" => {
                c.token()?;
                arrays.extend(parse_field(c, Some(n))?);
                continue;
            }
            "SCALARS" => {
                c.token()?;
                let line = c.line;
                let name = c.expect("the array name")?.to_string();
                let t = c.expect("the data type")?;
                check_numeric_type(c, t)?;
                // Optional component count, then LOOKUP_TABLE name.
                let mut components = 1;
                if let Some(t) = c.peek()?
                    && let Ok(k) = t.parse::<usize>()
                {
                    c.token()?;
                    components = k;
                }
                let kw = c.expect("LOOKUP_TABLE")?;
                if !kw.eq_ignore_ascii_case("LOOKUP_TABLE") {
                    return Err(c.err(format!("expected LOOKUP_TABLE after SCALARS {name}, found `{}`", truncate(kw))));
                }
                c.expect("the lookup table name")?;
                let values = read_values(c, n, components, &name)?;
                c.skip_metadata(components)?;
                arrays.push(DataArray { name, components, values, line });
                continue;
            }
            "VECTORS" | "NORMALS" => 3,
            "TENSORS" => 9,
            "COLOR_SCALARS" | "TEXTURE_COORDINATES" => 0,
            "LOOKUP_TABLE" => {
                c.token()?;
                c.expect("the lookup table name")?;
                let size = c.count("the lookup table size")?;
                read_values(c, size, 4, "LOOKUP_TABLE")?;
                continue;
            }
            _ if is_section(t) => break,
            _ => return Err(c.err(format!("unexpected `{}` in a data section", truncate(t)))),
        };
        c.token()?;
        let name = c.expect("the array name")?.to_string();
        let components = if components == 0 {
            let k = c.count("the number of components")?;
            if upper == "TEXTURE_COORDINATES" {
                c.expect("the data type")?;
            }
            k
        } else {
            let t = c.expect("the data type")?;
            check_numeric_type(c, t)?;
            components
        };
        read_values(c, n, components, &name)?;
        c.skip_metadata(components)?;
    }
    Ok(arrays)
}

/// `FIELD name k` followed by k arrays `name components tuples type values…`.
fn parse_field(c: &mut Cursor, tuples: Option<usize>) -> Result<Vec<DataArray>, IoError> {
    c.expect("the field name")?;
    let k = c.count("the number of field arrays")?;
    let mut arrays = Vec::with_capacity(k.min(c.text.len() / 2));
    for _ in 0..k {
        let line = c.line;
        let name = c.expect("a field array name")?.to_string();
        let components = c.count("the number of components")?;
        let n = c.count("the number of tuples")?;
        let t = c.expect("the data type")?;
        check_numeric_type(c, t)?;
        if let Some(expected) = tuples
            && n != expected
        {
            return Err(IoError::parse(
                c.path,
                Some(line),
                format!("field array {name} has {n} tuples, expected {expected}"),
            ));
        }
        let values = read_values(c, n, components, &name)?;
        c.skip_metadata(components)?;
        arrays.push(DataArray { name, components, values, line });
    }
    Ok(arrays)
}

fn check_numeric_type(c: &Cursor, t: &str) -> Result<(), IoError> {
    const NUMERIC: [&str; 12] = [
        "bit",
        "char",
        "short",
        "int",
        "long",
        "float",
        "double",
        "vtkidtype",
        "unsigned_char",
        "unsigned_short",
        "unsigned_int",
        "unsigned_long",
    ];
    let lower = t.to_ascii_lowercase();
    if NUMERIC.contains(&lower.as_str()) || lower.starts_with("vtktype") {
        Ok(())
    } else {
        Err(c.err(format!(
            "data type `{}` is not supported (string arrays cannot be read); remove the array or save it as numbers",
            truncate(t)
        )))
    }
}

/// Reads `tuples`·`components` numbers of array `name`; a declared size that overflows is an error.
fn read_values(c: &mut Cursor, tuples: usize, components: usize, name: &str) -> Result<Vec<Real>, IoError> {
    let count = tuples.checked_mul(components).ok_or_else(|| {
        c.err(format!("array {name} declares {tuples} tuples of {components} components, more than any file holds"))
    })?;
    let mut v = Vec::with_capacity(count.min(c.text.len() / 2));
    for _ in 0..count {
        let t = c.expect("array values")?;
        v.push(
            t.parse()
                .map_err(|_| c.err(format!("expected a value of array {name} (a number), found `{}`", truncate(t))))?,
        );
    }
    Ok(v)
}

fn truncate(s: &str) -> &str {
    match s.char_indices().nth(60) {
        Some((i, _)) => &s[..i],
        None => s,
    }
}
