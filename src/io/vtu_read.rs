//! A VTK XML UnstructuredGrid file (`.vtu`) of any writer, parsed with an XML parser
//! (roxmltree): its piece's points, point data and field data, each array's values in any of
//! VTK's encodings ([`super::vtk_arrays`]).
//!
//! Raw appended data is binary, not XML: the parser reads the file up to the opening tag of its
//! `<AppendedData>` (closed for it), and the data is what follows the `_` after that tag, as
//! VTK's own reader takes it. Every error is a message saying what is wrong; the caller names
//! the file.

use super::vtk_arrays::{self, Encoding, Scalar, Values};
use roxmltree::{Document, Node};
use std::borrow::Cow;

/// A `.vtu` file's text for the XML parser, and its appended data.
pub(super) struct VtuText<'b> {
    xml: Cow<'b, str>,
    /// The bytes after the `_` that opens the appended data (empty without any).
    appended: &'b [u8],
}

impl<'b> VtuText<'b> {
    /// The text of the file `bytes`.
    pub fn of(bytes: &'b [u8]) -> Result<Self, String> {
        let not_utf8 = |_| "the XML is not UTF-8".to_owned();
        const TAG: &[u8] = b"<AppendedData";
        let Some(start) = bytes.windows(TAG.len()).position(|w| w == TAG) else {
            let xml = std::str::from_utf8(bytes).map_err(not_utf8)?;
            return Ok(Self {
                xml: Cow::Borrowed(xml),
                appended: &[],
            });
        };
        let no_data = || "no '_' opens the appended data".to_owned();
        let close = start
            + bytes[start..]
                .iter()
                .position(|&b| b == b'>')
                .ok_or_else(no_data)?;
        let head = std::str::from_utf8(&bytes[..=close]).map_err(not_utf8)?;
        let rest = &bytes[close + 1..];
        let underscore = rest
            .iter()
            .position(|b| !b.is_ascii_whitespace())
            .filter(|&k| rest[k] == b'_')
            .ok_or_else(no_data)?;
        Ok(Self {
            xml: Cow::Owned(format!("{head}</AppendedData></VTKFile>")),
            appended: &rest[underscore + 1..],
        })
    }
}

/// A parsed `.vtu` of one piece.
pub(super) struct Vtu<'t> {
    doc: Document<'t>,
    appended: &'t [u8],
    /// `<AppendedData encoding="base64">` (else raw).
    appended_base64: bool,
    encoding: Encoding,
    points: usize,
}

/// An array of the point data.
pub(super) struct PointArray {
    /// Its name, as the file spells it.
    pub name: String,
    /// Values per point.
    pub components: usize,
    /// `components` values per point, point after point.
    pub values: Values,
}

impl<'t> Vtu<'t> {
    /// Parses `text`: a `<VTKFile type="UnstructuredGrid">` of one `<Piece>`.
    pub fn parse(text: &'t VtuText<'_>) -> Result<Self, String> {
        let doc = Document::parse(&text.xml).map_err(|e| format!("bad XML: {e}"))?;
        let root = doc.root_element();
        if !root.has_tag_name("VTKFile") {
            return Err(format!(
                "<{}> where <VTKFile> should be",
                root.tag_name().name()
            ));
        }
        match root.attribute("type") {
            Some("UnstructuredGrid") => {}
            other => {
                return Err(format!(
                    "type {:?}: only UnstructuredGrid (.vtu) files are read",
                    other.unwrap_or("")
                ));
            }
        }
        let big_endian = match root.attribute("byte_order") {
            Some("LittleEndian") | None => false,
            Some("BigEndian") => true,
            Some(other) => return Err(format!("unknown byte_order {other:?}")),
        };
        let header_bytes = match root.attribute("header_type") {
            Some("UInt32") | None => 4,
            Some("UInt64") => 8,
            Some(other) => {
                return Err(format!(
                    "header_type {other:?}: only UInt32 and UInt64 are read"
                ));
            }
        };
        let zlib = match root.attribute("compressor") {
            None | Some("") => false,
            Some("vtkZLibDataCompressor") => true,
            Some(other) => {
                return Err(format!(
                    "compressor {other:?}: only vtkZLibDataCompressor (or none) is read"
                ));
            }
        };
        let appended_base64 = match children(root, "AppendedData")
            .next()
            .map(|a| a.attribute("encoding"))
        {
            Some(Some("base64")) => true,
            Some(Some("raw")) | None => false,
            Some(other) => {
                return Err(format!(
                    "appended data of encoding {:?}: only raw and base64 are read",
                    other.unwrap_or("")
                ));
            }
        };
        let pieces = one(root, "UnstructuredGrid").map(|grid| children(grid, "Piece").count())?;
        if pieces != 1 {
            return Err(format!("{pieces} <Piece>s: only a file of one is read"));
        }
        let vtu = Self {
            doc,
            appended: text.appended,
            appended_base64,
            encoding: Encoding {
                big_endian,
                header_bytes,
                zlib,
            },
            points: 0,
        };
        let points = vtu
            .piece()
            .attribute("NumberOfPoints")
            .and_then(|n| n.trim().parse().ok())
            .ok_or("no NumberOfPoints in <Piece>")?;
        Ok(Self { points, ..vtu })
    }

    /// Points in the piece.
    pub fn points(&self) -> usize {
        self.points
    }

    /// The piece (there is one: [`Self::parse`] checked).
    fn piece(&self) -> Node<'_, 't> {
        let grid = one(self.doc.root_element(), "UnstructuredGrid").expect("parse checked it");
        children(grid, "Piece").next().expect("parse checked it")
    }

    /// The points' coordinates: 3 values a point.
    pub fn positions(&self) -> Result<Values, String> {
        let array = one(self.piece(), "Points")
            .and_then(|points| one(points, "DataArray"))
            .map_err(|e| format!("<Points>: {e}"))?;
        let (components, values) = self
            .values_of(array, self.points)
            .map_err(|e| format!("the points: {e}"))?;
        match components {
            3 => Ok(values),
            c => Err(format!("the points have {c} components, not 3")),
        }
    }

    /// The first array of the point data whose name is one of `names` (in any case), the names
    /// in order of preference; `None` where there is none.
    pub fn point_data(&self, names: &[&str]) -> Result<Option<PointArray>, String> {
        let arrays: Vec<Node> = children(self.piece(), "PointData")
            .flat_map(|data| children(data, "DataArray"))
            .collect();
        let named = |want: &&str| {
            arrays.iter().find(|a| {
                a.attribute("Name")
                    .is_some_and(|name| name.eq_ignore_ascii_case(want))
            })
        };
        let Some(&array) = names.iter().find_map(named) else {
            return Ok(None);
        };
        let name = array.attribute("Name").unwrap_or_default().to_owned();
        let (components, values) = self
            .values_of(array, self.points)
            .map_err(|e| format!("point data {name:?}: {e}"))?;
        Ok(Some(PointArray {
            name,
            components,
            values,
        }))
    }

    /// The field data array named `name`, `None` where there is none.
    pub fn field_data(&self, name: &str) -> Result<Option<Values>, String> {
        let grid = one(self.doc.root_element(), "UnstructuredGrid").expect("parse checked it");
        let Some(array) = children(grid, "FieldData")
            .flat_map(|data| children(data, "DataArray"))
            .find(|a| a.attribute("Name") == Some(name))
        else {
            return Ok(None);
        };
        let tuples = match array.attribute("NumberOfTuples") {
            Some(n) => n
                .trim()
                .parse()
                .map_err(|_| format!("field data {name:?}: NumberOfTuples {n:?}"))?,
            None => 1,
        };
        let (_, values) = self
            .values_of(array, tuples)
            .map_err(|e| format!("field data {name:?}: {e}"))?;
        Ok(Some(values))
    }

    /// The components and values of the `<DataArray>` `array` of `tuples` tuples.
    fn values_of(&self, array: Node, tuples: usize) -> Result<(usize, Values), String> {
        let scalar = Scalar::named(array.attribute("type").ok_or("no type")?)?;
        let components: usize = match array.attribute("NumberOfComponents") {
            Some(c) => c
                .trim()
                .parse()
                .ok()
                .filter(|&c| c > 0)
                .ok_or_else(|| format!("NumberOfComponents {c:?}"))?,
            None => 1,
        };
        let text = array.text().unwrap_or("");
        let values = match array.attribute("format").unwrap_or("ascii") {
            "ascii" => vtk_arrays::ascii(text, scalar)?,
            "binary" => vtk_arrays::inline(text, scalar, self.encoding)?,
            "appended" => {
                let offset = array.attribute("offset").ok_or("no offset")?;
                let offset = offset
                    .trim()
                    .parse()
                    .map_err(|_| format!("offset {offset:?}"))?;
                vtk_arrays::appended(
                    self.appended,
                    offset,
                    self.appended_base64,
                    scalar,
                    self.encoding,
                )?
            }
            other => {
                return Err(format!(
                    "format {other:?}: only ascii, binary and appended are read"
                ));
            }
        };
        let want = tuples.checked_mul(components);
        if want != Some(values.len()) {
            return Err(format!(
                "{} values, expected {tuples} × {components}",
                values.len()
            ));
        }
        Ok((components, values))
    }
}

/// The child elements of `node` named `name`.
fn children<'a, 'i>(node: Node<'a, 'i>, name: &'static str) -> impl Iterator<Item = Node<'a, 'i>> {
    node.children().filter(move |c| c.has_tag_name(name))
}

/// The one child element of `node` named `name`.
fn one<'a, 'i>(node: Node<'a, 'i>, name: &'static str) -> Result<Node<'a, 'i>, String> {
    let mut found = children(node, name);
    match (found.next(), found.next()) {
        (Some(child), None) => Ok(child),
        (None, _) => Err(format!("no <{name}> in <{}>", node.tag_name().name())),
        (Some(_), Some(_)) => Err(format!(
            "more than one <{name}> in <{}>",
            node.tag_name().name()
        )),
    }
}
