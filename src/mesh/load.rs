//! Reading meshes from files: OBJ through `tobj`, PLY through `ply-rs-bw`, STL through
//! `stl_io`. This module only adapts them: it picks the format, checks what they return (indices,
//! finite coordinates, at least one triangle) and turns every failure into one
//! [`Error::Parse`] naming the file and, where it can be known, the line.

use super::{Mesh, Problem};
use crate::error::{Error, Result};
use std::path::Path;

/// Reads a triangle mesh, choosing the format by the file's extension (case-insensitive):
/// `.obj` (Wavefront; polygons are split into triangle fans, lines and points are ignored),
/// `.ply` (ASCII or binary, either byte order; element `vertex` with `x`, `y`, `z` and element
/// `face` with `vertex_indices` or `vertex_index`; polygons split into fans) or `.stl` (ASCII or
/// binary). Only the geometry is kept: normals, texture coordinates, colours and materials are
/// ignored. OBJ vertices come in the order faces first use them, and vertices no face uses are
/// left out (the Stanford bunny's file has 35,947 vertices, its faces use 34,834).
///
/// Errors: [`Error::Io`] when the file cannot be read; [`Error::Parse`] for an unknown
/// extension, an empty or malformed file, a face with fewer than three vertices, an index out of
/// range, a non-finite coordinate, or a file without triangles. `line` is 1-based where the
/// format has lines and the place is known, `None` otherwise.
pub fn load(path: &Path) -> Result<Mesh> {
    // Refuse an unknown extension before touching the file.
    format_of(path)?;
    let bytes = std::fs::read(path).map_err(|error| Error::Io {
        path: path.to_path_buf(),
        error,
    })?;
    load_bytes(path, &bytes)
}

/// As [`load`], from the file's contents already in memory (`bytes`); `name` only picks the
/// format by its extension and names the file in errors.
pub fn load_bytes(name: &Path, bytes: &[u8]) -> Result<Mesh> {
    let read = format_of(name)?;
    if bytes.is_empty() {
        return Err(parse_error(name, None, "the file is empty"));
    }
    read(name, bytes)
}

/// The reader for a file name's extension.
type Reader = fn(&Path, &[u8]) -> Result<Mesh>;

fn format_of(path: &Path) -> Result<Reader> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    Ok(match ext.as_deref() {
        Some("obj") => obj::read,
        Some("ply") => ply::read,
        Some("stl") => stl::read,
        Some(e) => {
            return Err(parse_error(
                path,
                None,
                format!("unknown mesh format `.{e}`: expected .obj, .ply or .stl"),
            ));
        }
        None => {
            return Err(parse_error(
                path,
                None,
                "no file extension to tell the mesh format: expected .obj, .ply or .stl",
            ));
        }
    })
}

fn parse_error(path: &Path, line: Option<u64>, msg: impl Into<String>) -> Error {
    Error::Parse {
        path: path.to_path_buf(),
        line,
        msg: msg.into(),
    }
}

/// The error for a mesh `problem` found after reading; `locate` gives the line and a better
/// message where the format can tell.
fn problem_error(
    path: &Path,
    problem: Problem,
    locate: impl FnOnce(Problem) -> Option<(Option<u64>, String)>,
) -> Error {
    match problem {
        Problem::Empty => parse_error(path, None, "no triangles in the file"),
        _ => match locate(problem) {
            Some((line, msg)) => parse_error(path, line, msg),
            None => parse_error(path, None, problem.describe()),
        },
    }
}

/// Splits a polygon into a fan of triangles around its first vertex.
fn fan(polygon: &[u32], out: &mut Vec<[u32; 3]>) {
    for k in 1..polygon.len().saturating_sub(1) {
        out.push([polygon[0], polygon[k], polygon[k + 1]]);
    }
}

mod obj {
    use super::*;
    use std::io::Cursor;

    /// Statements that shape the mesh; everything else is blanked before `tobj` sees it.
    fn kept(line: &str) -> bool {
        matches!(line.split_whitespace().next(), Some("v" | "f"))
    }

    pub(super) fn read(path: &Path, bytes: &[u8]) -> Result<Mesh> {
        let text = String::from_utf8_lossy(bytes);
        // Texture coordinates, normals, materials, groups, lines and points play no part in
        // the solid. Blanking them (an empty line keeps the numbering) means tobj never
        // follows a texture or normal index or opens a material file, and reads one model.
        let filtered = text
            .lines()
            .map(|l| if kept(l) { l } else { "" })
            .collect::<Vec<_>>()
            .join("\n");
        let options = tobj::LoadOptions {
            triangulate: true,
            single_index: false,
            ignore_points: true,
            ignore_lines: true,
        };
        let mut cursor = Cursor::new(filtered.as_bytes());
        let result = tobj::load_obj_buf(&mut cursor, &options, |_| {
            Err(tobj::LoadError::OpenFileFailed)
        });
        let models = match result {
            Ok((models, _materials)) => models,
            Err(e) => return Err(tobj_error(path, &filtered, e, cursor.position())),
        };
        if let Some((line, msg)) = face_problem(&filtered) {
            return Err(parse_error(path, Some(line), msg));
        }
        // Checked on the text, so that a vertex no face uses is refused too.
        if let Some((line, msg)) = non_finite_vertex(&filtered) {
            return Err(parse_error(path, line, msg));
        }
        let mut mesh = Mesh::default();
        for model in models {
            let offset = u32::try_from(mesh.vertices.len())
                .map_err(|_| parse_error(path, None, "more than 2³² vertices"))?;
            let m = model.mesh;
            mesh.vertices
                .extend(m.positions.chunks_exact(3).map(|c| [c[0], c[1], c[2]]));
            mesh.triangles.extend(
                m.indices
                    .chunks_exact(3)
                    .map(|t| [t[0] + offset, t[1] + offset, t[2] + offset]),
            );
        }
        match mesh.problem() {
            None => Ok(mesh),
            Some(p) => Err(problem_error(path, p, |_| None)),
        }
    }

    /// A tobj error as a parse error. Errors found while reading a statement carry the line
    /// the reader had reached; those found when tobj assembles the model at the end (an index
    /// out of range, an empty face) are located by [`face_problem`].
    fn tobj_error(path: &Path, text: &str, e: tobj::LoadError, position: u64) -> Error {
        use tobj::LoadError as L;
        if matches!(
            e,
            L::FaceVertexOutOfBounds | L::InvalidPolygon | L::FaceColorOutOfBounds
        ) {
            if let Some((line, msg)) = face_problem(text) {
                return parse_error(path, Some(line), msg);
            }
            return parse_error(path, None, e.to_string());
        }
        let read = &text.as_bytes()[..(position as usize).min(text.len())];
        let newlines = read.iter().filter(|&&b| b == b'\n').count() as u64;
        let line = newlines + u64::from(read.last().is_some_and(|&b| b != b'\n'));
        let shown = text
            .lines()
            .nth(line.saturating_sub(1) as usize)
            .unwrap_or("")
            .trim();
        let shown: String = shown.chars().take(80).collect();
        parse_error(path, Some(line.max(1)), format!("{e} in `{shown}`"))
    }

    /// The first face statement with fewer than three vertices or an index that names no
    /// vertex: its line and what is wrong. Indices are 1-based, negative ones count back from
    /// the last vertex read so far (as tobj reads them).
    pub(super) fn face_problem(text: &str) -> Option<(u64, String)> {
        let total = text
            .lines()
            .filter(|l| l.split_whitespace().next() == Some("v"))
            .count();
        let mut seen = 0usize;
        for (n, l) in text.lines().enumerate() {
            let mut words = l.split_whitespace();
            let line = n as u64 + 1;
            match words.next() {
                Some("v") => seen += 1,
                Some("f") => {
                    let corners: Vec<&str> = words.collect();
                    if corners.len() < 3 {
                        return Some((
                            line,
                            format!(
                                "a face needs at least 3 vertices, this one has {}",
                                corners.len()
                            ),
                        ));
                    }
                    for c in corners {
                        let index = c.split('/').next().unwrap_or("");
                        let Ok(i) = index.parse::<i64>() else {
                            return Some((line, format!("bad vertex index `{index}`")));
                        };
                        let ok = match i {
                            0 => false,
                            i if i > 0 => i as u64 <= total as u64,
                            i => i.unsigned_abs() <= seen as u64,
                        };
                        if !ok {
                            return Some((
                                line,
                                format!(
                                    "face refers to vertex {i}, but the file has {total} \
                                     vertices (indices start at 1; negative ones count back \
                                     from the last vertex read, {seen} here)"
                                ),
                            ));
                        }
                    }
                }
                _ => {}
            }
        }
        None
    }

    /// The first vertex statement with a coordinate that is not finite (after the optional
    /// weight w divides it).
    fn non_finite_vertex(text: &str) -> Option<(Option<u64>, String)> {
        text.lines().enumerate().find_map(|(n, l)| {
            let mut words = l.split_whitespace();
            if words.next() != Some("v") {
                return None;
            }
            let values: Vec<f64> = words.filter_map(|w| w.parse().ok()).collect();
            let w = if values.len() == 4 { values[3] } else { 1.0 };
            let bad = values.iter().take(3).any(|x| !(x / w).is_finite());
            bad.then(|| {
                (
                    Some(n as u64 + 1),
                    format!("vertex coordinate is not finite in `{}`", l.trim()),
                )
            })
        })
    }
}

mod ply {
    use super::*;
    use ply_rs_bw::parser::{Parser, Reader};
    use ply_rs_bw::ply::{
        ElementDef, Encoding, Property, PropertyAccess, PropertyAccessResult, PropertyType,
        ScalarType,
    };
    use std::io::Cursor;

    /// The index-list property names in use: the standard one and a common variant.
    const INDEX_NAMES: [&str; 2] = ["vertex_indices", "vertex_index"];

    /// One element of any kind; only the properties the mesh needs are kept.
    #[derive(Debug, Default)]
    struct Element {
        xyz: [f64; 3],
        indices: Vec<i64>,
    }

    impl PropertyAccess for Element {
        fn new() -> Self {
            Self::default()
        }

        fn set_property(&mut self, name: &str, property: Property) -> PropertyAccessResult {
            let axis = match name {
                "x" => Some(0),
                "y" => Some(1),
                "z" => Some(2),
                _ => None,
            };
            if let Some(a) = axis {
                match scalar(&property) {
                    Some(x) => {
                        self.xyz[a] = x;
                        PropertyAccessResult::Set
                    }
                    None => PropertyAccessResult::Ignored,
                }
            } else if INDEX_NAMES.contains(&name) {
                match index_list(property) {
                    Some(list) => {
                        self.indices = list;
                        PropertyAccessResult::Set
                    }
                    None => PropertyAccessResult::Ignored,
                }
            } else {
                PropertyAccessResult::Ignored
            }
        }
    }

    fn scalar(p: &Property) -> Option<f64> {
        Some(match *p {
            Property::Char(x) => x.into(),
            Property::UChar(x) => x.into(),
            Property::Short(x) => x.into(),
            Property::UShort(x) => x.into(),
            Property::Int(x) => x.into(),
            Property::UInt(x) => x.into(),
            Property::Float(x) => x.into(),
            Property::Double(x) => x,
            _ => return None,
        })
    }

    fn index_list(p: Property) -> Option<Vec<i64>> {
        fn widen<T: Into<i64>>(v: Vec<T>) -> Vec<i64> {
            v.into_iter().map(Into::into).collect()
        }
        Some(match p {
            Property::ListChar(v) => widen(v),
            Property::ListUChar(v) => widen(v),
            Property::ListShort(v) => widen(v),
            Property::ListUShort(v) => widen(v),
            Property::ListInt(v) => widen(v),
            Property::ListUInt(v) => widen(v),
            _ => return None,
        })
    }

    fn is_integer(t: &ScalarType) -> bool {
        !matches!(t, ScalarType::Float | ScalarType::Double)
    }

    /// ply-rs-bw's message on one line, without its "Line N: " prefix (the line goes into the
    /// error's own field) and without the grammar's internals that follow "Error:".
    fn message(e: &ply_rs_bw::parser::ParseError) -> String {
        let full = e.to_string().replace("\n\t", "; ").replace('\n', " ");
        let msg = match e.line() {
            Some(l) => full.strip_prefix(&format!("Line {l}: ")).unwrap_or(&full),
            None => &full,
        };
        let msg = msg.split("; Error: ").next().unwrap_or(msg).trim_end();
        format!("bad PLY: {msg}")
    }

    /// 1-based line of the header line that starts with `prefix` (and of `end_header`).
    fn header_line(bytes: &[u8], prefix: &str) -> Option<u64> {
        let words: Vec<&str> = prefix.split_whitespace().collect();
        bytes
            .split(|&b| b == b'\n')
            .map(|l| String::from_utf8_lossy(l))
            .take_while(|l| l.trim() != "end_header" || prefix == "end_header")
            .position(|l| {
                l.split_whitespace()
                    .take(words.len())
                    .eq(words.iter().copied())
            })
            .map(|i| i as u64 + 1)
    }

    pub(super) fn read(path: &Path, bytes: &[u8]) -> Result<Mesh> {
        let parser = Parser::<Element>::new();
        let mut reader = Reader::new(Cursor::new(bytes));
        let header = parser
            .read_header(&mut reader)
            .map_err(|e| parse_error(path, e.line().map(|l| l as u64), message(&e)))?;

        let element = |name: &str| -> Result<&ElementDef> {
            header.elements.get(name).ok_or_else(|| {
                parse_error(
                    path,
                    None,
                    format!(
                        "no `element {name}` in the PLY header: a mesh needs vertices and faces"
                    ),
                )
            })
        };
        let (vertex_def, face_def) = (element("vertex")?, element("face")?);
        let vertex_line = header_line(bytes, "element vertex");
        for axis in ["x", "y", "z"] {
            match vertex_def.properties.get(axis).map(|p| &p.data_type) {
                Some(PropertyType::Scalar(_)) => {}
                Some(PropertyType::List(..)) => {
                    return Err(parse_error(
                        path,
                        vertex_line,
                        format!("PLY vertex property `{axis}` is a list, not a number"),
                    ));
                }
                None => {
                    return Err(parse_error(
                        path,
                        vertex_line,
                        format!("PLY element `vertex` has no property `{axis}`"),
                    ));
                }
            }
        }
        let face_line = header_line(bytes, "element face");
        let index_property = INDEX_NAMES
            .iter()
            .find_map(|n| face_def.properties.get(*n))
            .ok_or_else(|| {
                parse_error(
                    path,
                    face_line,
                    "PLY element `face` has no property `vertex_indices` (or `vertex_index`)",
                )
            })?;
        match &index_property.data_type {
            PropertyType::List(_, t) if is_integer(t) => {}
            other => {
                return Err(parse_error(
                    path,
                    face_line,
                    format!(
                        "PLY face property `{}` must be a list of integers, not {other:?}",
                        index_property.name
                    ),
                ));
            }
        }

        let ascii = header.encoding == Encoding::Ascii;
        let mut payload = parser.read_payload(&mut reader, &header).map_err(|e| {
            let line = if ascii {
                e.line().map(|l| l as u64)
            } else {
                None
            };
            parse_error(path, line, message(&e))
        })?;
        // Where element k of a kind sits: its line in an ASCII file (one element per line
        // after the header), else its number.
        let first_data_line = header_line(bytes, "end_header").unwrap_or(0) + 1;
        let before = |name: &str| -> u64 {
            header
                .elements
                .iter()
                .take_while(|(n, _)| n.as_str() != name)
                .map(|(_, d)| d.count as u64)
                .sum()
        };
        let place = |name: &str, k: usize| -> (Option<u64>, String) {
            if ascii {
                (
                    Some(first_data_line + before(name) + k as u64),
                    String::new(),
                )
            } else {
                (None, format!(" ({name} {k})"))
            }
        };

        let vertices: Vec<[f64; 3]> = payload
            .swap_remove("vertex")
            .unwrap_or_default()
            .into_iter()
            .map(|e| e.xyz)
            .collect();
        if let Some(k) = vertices
            .iter()
            .position(|v| v.iter().any(|x| !x.is_finite()))
        {
            let (line, at) = place("vertex", k);
            return Err(parse_error(
                path,
                line,
                format!("vertex coordinate is not finite{at}"),
            ));
        }
        let n = vertices.len();
        let mut triangles = Vec::new();
        let mut polygon = Vec::new();
        for (k, face) in payload
            .swap_remove("face")
            .unwrap_or_default()
            .into_iter()
            .enumerate()
        {
            if face.indices.len() < 3 {
                let (line, at) = place("face", k);
                return Err(parse_error(
                    path,
                    line,
                    format!(
                        "a face needs at least 3 vertices, this one has {}{at}",
                        face.indices.len()
                    ),
                ));
            }
            polygon.clear();
            for &i in &face.indices {
                match u32::try_from(i) {
                    Ok(i) if (i as usize) < n => polygon.push(i),
                    _ => {
                        let (line, at) = place("face", k);
                        return Err(parse_error(
                            path,
                            line,
                            format!(
                                "face refers to vertex {i}, but the file has {n} vertices \
                                 (indices start at 0){at}"
                            ),
                        ));
                    }
                }
            }
            fan(&polygon, &mut triangles);
        }
        let mesh = Mesh {
            vertices,
            triangles,
        };
        match mesh.problem() {
            None => Ok(mesh),
            Some(p) => Err(problem_error(path, p, |_| None)),
        }
    }
}

mod stl {
    use super::*;
    use std::io::Cursor;

    pub(super) fn read(path: &Path, bytes: &[u8]) -> Result<Mesh> {
        let mut bytes = bytes.to_vec();
        let len = bytes.len() as u64;
        let declared = bytes
            .get(80..84)
            .map(|c| u64::from(u32::from_le_bytes([c[0], c[1], c[2], c[3]])));
        let binary_size = declared.map(|n| 84 + 50 * n);
        // Binary files may start with "solid" too (some exporters write it into the header);
        // a size that matches the declared triangle count, or a NUL byte (never in text, and
        // in nearly every binary STL: zero coordinates, the attribute bytes), tells them apart.
        let ascii = bytes.starts_with(b"solid") && binary_size != Some(len) && !bytes.contains(&0);
        if ascii {
            // stl_io wants "solid " and a name; a bare "solid" line is valid STL as well.
            if matches!(bytes.get(5), None | Some(b'\n' | b'\r')) {
                bytes.insert(5, b' ');
            }
        } else {
            match (declared, binary_size) {
                (Some(n), Some(size)) if len != size => {
                    let why = match len < size {
                        true => "truncated?",
                        false => "more triangles than it declares?",
                    };
                    return Err(parse_error(
                        path,
                        None,
                        format!(
                            "binary STL declares {n} triangles, which take 84 + 50·{n} = {size} \
                             bytes, but the file has {len} bytes ({why})"
                        ),
                    ));
                }
                (None, _) | (_, None) => {
                    return Err(parse_error(
                        path,
                        None,
                        format!(
                            "too short for a binary STL ({len} bytes; the header alone takes \
                             84), and an ASCII STL starts with `solid`"
                        ),
                    ));
                }
                _ => {}
            }
            // Keep stl_io from taking a header that starts with "solid " for ASCII.
            if bytes.starts_with(b"solid") {
                bytes[..5].fill(b' ');
            }
        }
        let indexed = stl_io::read_stl(&mut Cursor::new(&bytes)).map_err(|e| {
            let kind = if ascii { "ASCII" } else { "binary" };
            parse_error(path, None, format!("bad {kind} STL: {e}"))
        })?;
        let vertices: Vec<[f64; 3]> = indexed
            .vertices
            .iter()
            .map(|v| v.0.map(f64::from))
            .collect();
        let mut triangles = Vec::with_capacity(indexed.faces.len());
        for f in &indexed.faces {
            let [a, b, c] = f.vertices.map(|i| u32::try_from(i).unwrap_or(u32::MAX));
            triangles.push([a, b, c]);
        }
        let mesh = Mesh {
            vertices,
            triangles,
        };
        match mesh.problem() {
            None => Ok(mesh),
            Some(p) => Err(problem_error(path, p, |p| match p {
                Problem::NonFinite(v) => {
                    let t = mesh
                        .triangles
                        .iter()
                        .position(|t| t.contains(&(v as u32)))?;
                    Some((None, format!("triangle {t} has a non-finite coordinate")))
                }
                _ => None,
            })),
        }
    }
}
