//! PLY: the reader (header and element decoding by `ply-rs-bw`) and the
//! writer (what is accepted: see the parent module's documentation).

use std::io::{self, Write};

use ply_rs_bw::parser::{Parser, Reader};
use ply_rs_bw::ply::{
    ElementDef, Encoding, Header, PropertyAccess, PropertyAccessResult, PropertyType, ScalarType,
};

use super::shared::{Builder, LoadedMesh, ReadError, check_declared_counts, tokens};
use crate::error::MeshError;
use crate::limits::MemoryBudget;
use crate::mesh::Mesh;

/// Encoding of a written PLY file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlyEncoding {
    /// `format ascii 1.0`, coordinates in shortest round-trip decimal.
    Ascii,
    /// `format binary_little_endian 1.0` (the default of [`write_mesh`](super::write_mesh)).
    BinaryLittleEndian,
    /// `format binary_big_endian 1.0`.
    BinaryBigEndian,
}

/// Face-index list of a PLY element, in the file's integer type.
enum IndexList {
    I8(Vec<i8>),
    U8(Vec<u8>),
    I16(Vec<i16>),
    U16(Vec<u16>),
    I32(Vec<i32>),
    U32(Vec<u32>),
}

impl IndexList {
    fn to_i64(&self) -> Vec<i64> {
        match self {
            IndexList::I8(v) => v.iter().map(|&x| i64::from(x)).collect(),
            IndexList::U8(v) => v.iter().map(|&x| i64::from(x)).collect(),
            IndexList::I16(v) => v.iter().map(|&x| i64::from(x)).collect(),
            IndexList::U16(v) => v.iter().map(|&x| i64::from(x)).collect(),
            IndexList::I32(v) => v.iter().map(|&x| i64::from(x)).collect(),
            IndexList::U32(v) => v.iter().map(|&x| i64::from(x)).collect(),
        }
    }
}

/// One decoded PLY element: the properties we use, the rest ignored.
struct PlyElement {
    xyz: [f64; 3],
    indices: Option<IndexList>,
}

fn xyz_slot(name: &str) -> Option<usize> {
    match name {
        "x" => Some(0),
        "y" => Some(1),
        "z" => Some(2),
        _ => None,
    }
}

fn is_index_list(name: &str) -> bool {
    name == "vertex_indices" || name == "vertex_index"
}

impl PlyElement {
    fn scalar(&mut self, name: &str, value: f64) -> PropertyAccessResult {
        match xyz_slot(name) {
            Some(k) => {
                self.xyz[k] = value;
                PropertyAccessResult::Set
            }
            None => PropertyAccessResult::Ignored,
        }
    }

    fn list(&mut self, name: &str, list: IndexList) -> PropertyAccessResult {
        if is_index_list(name) {
            self.indices = Some(list);
            PropertyAccessResult::Set
        } else {
            PropertyAccessResult::Ignored
        }
    }
}

impl PropertyAccess for PlyElement {
    fn new() -> Self {
        PlyElement {
            xyz: [0.0; 3],
            indices: None,
        }
    }
    fn set_char(&mut self, name: &str, v: i8) -> PropertyAccessResult {
        self.scalar(name, f64::from(v))
    }
    fn set_uchar(&mut self, name: &str, v: u8) -> PropertyAccessResult {
        self.scalar(name, f64::from(v))
    }
    fn set_short(&mut self, name: &str, v: i16) -> PropertyAccessResult {
        self.scalar(name, f64::from(v))
    }
    fn set_ushort(&mut self, name: &str, v: u16) -> PropertyAccessResult {
        self.scalar(name, f64::from(v))
    }
    fn set_int(&mut self, name: &str, v: i32) -> PropertyAccessResult {
        self.scalar(name, f64::from(v))
    }
    fn set_uint(&mut self, name: &str, v: u32) -> PropertyAccessResult {
        self.scalar(name, f64::from(v))
    }
    fn set_float(&mut self, name: &str, v: f32) -> PropertyAccessResult {
        self.scalar(name, f64::from(v))
    }
    fn set_double(&mut self, name: &str, v: f64) -> PropertyAccessResult {
        self.scalar(name, v)
    }
    fn set_list_char(&mut self, name: &str, v: Vec<i8>) -> PropertyAccessResult {
        self.list(name, IndexList::I8(v))
    }
    fn set_list_uchar(&mut self, name: &str, v: Vec<u8>) -> PropertyAccessResult {
        self.list(name, IndexList::U8(v))
    }
    fn set_list_short(&mut self, name: &str, v: Vec<i16>) -> PropertyAccessResult {
        self.list(name, IndexList::I16(v))
    }
    fn set_list_ushort(&mut self, name: &str, v: Vec<u16>) -> PropertyAccessResult {
        self.list(name, IndexList::U16(v))
    }
    fn set_list_int(&mut self, name: &str, v: Vec<i32>) -> PropertyAccessResult {
        self.list(name, IndexList::I32(v))
    }
    fn set_list_uint(&mut self, name: &str, v: Vec<u32>) -> PropertyAccessResult {
        self.list(name, IndexList::U32(v))
    }
}

fn scalar_size(t: &ScalarType) -> u128 {
    match t {
        ScalarType::Char | ScalarType::UChar => 1,
        ScalarType::Short | ScalarType::UShort => 2,
        ScalarType::Int | ScalarType::UInt | ScalarType::Float => 4,
        ScalarType::Double => 8,
    }
}

fn is_integer(t: &ScalarType) -> bool {
    !matches!(t, ScalarType::Float | ScalarType::Double)
}

/// Least number of payload bytes one element can take: binary, the scalar
/// sizes plus the count of each list (lists may be empty); ASCII, one
/// character and one separator per property. At least 1 either way. In a
/// binary file the vertex index list of a face counts with three items: a
/// face with fewer vertices is refused anyway, so this stays a lower bound
/// for every file the reader accepts, and a header that overstates its
/// vertex count is caught here instead of face bytes being misread as
/// coordinates. (In ASCII a short face is reported with its line instead.)
fn min_element_bytes(name: &str, def: &ElementDef, encoding: Encoding) -> u128 {
    let is_face_indices = |prop: &str| name == "face" && is_index_list(prop);
    let n: u128 = match encoding {
        Encoding::Ascii => 2 * def.properties.len() as u128,
        Encoding::BinaryLittleEndian | Encoding::BinaryBigEndian => def
            .properties
            .iter()
            .map(|(prop, p)| match &p.data_type {
                PropertyType::Scalar(t) => scalar_size(t),
                PropertyType::List(count, item) if is_face_indices(prop) => {
                    scalar_size(count) + 3 * scalar_size(item)
                }
                PropertyType::List(count, _) => scalar_size(count),
            })
            .sum(),
    };
    n.max(1)
}

/// The message of a `ply-rs-bw` error, without its line prefix.
fn ply_message(e: &ply_rs_bw::parser::ParseError) -> String {
    match ply_error(e) {
        MeshError::Parse { message, .. } => message,
        other => other.to_string(),
    }
}

/// A `ply-rs-bw` error as a [`MeshError`]: its line kept, its message made
/// single-line and bounded in length.
fn ply_error(e: &ply_rs_bw::parser::ParseError) -> MeshError {
    let mut message = e.to_string();
    if let Some(l) = e.line() {
        let prefix = format!("Line {l}: ");
        if let Some(rest) = message.strip_prefix(&prefix) {
            message = rest.to_string();
        }
    }
    let mut message = message.replace("\n\t", "; ").replace('\n', " ");
    if message.chars().count() > 300 {
        message = format!("{}…", message.chars().take(300).collect::<String>());
    }
    MeshError::Parse {
        format: "PLY",
        line: e.line(),
        message,
    }
}

fn ply_header_error(line: Option<usize>, message: impl Into<String>) -> MeshError {
    MeshError::Parse {
        format: "PLY",
        line,
        message: message.into(),
    }
}

/// Reads a PLY file: the header (decoded by `ply-rs-bw`, then checked by
/// [`check_ply_vertex`], [`check_ply_face`] and, against the bytes that
/// follow it, [`check_ply_sizes`]), then every element in the declared
/// order ([`read_ply_element`]), vertices and faces going to the builder
/// ([`add_ply_element`]), and nothing after the last but whitespace
/// ([`check_ply_trailing`]).
pub(super) fn read_ply(bytes: &[u8], budget: MemoryBudget) -> Result<LoadedMesh, ReadError> {
    const F: &str = "PLY";
    let parser = Parser::<PlyElement>::new();
    let mut reader = Reader::new(bytes);
    let header = parser.read_header(&mut reader).map_err(|e| ply_error(&e))?;
    let mut payload: &[u8] = reader.into_inner();
    let header_bytes = bytes.get(..bytes.len() - payload.len()).unwrap_or_default();
    let header_lines = header_bytes.iter().filter(|&&c| c == b'\n').count();
    let vertex_def = check_ply_vertex(&header, header_bytes)?;
    let face_def = check_ply_face(&header, header_bytes)?;
    check_ply_sizes(&header, payload.len(), header_bytes)?;
    check_declared_counts(vertex_def.count, face_def.count, budget)?;
    let mut b = Builder::within(budget);
    b.positions.reserve(vertex_def.count);
    let ascii = header.encoding == Encoding::Ascii;
    let mut line = header_lines;
    let mut deferred: Option<MeshError> = None;
    for (name, def) in &header.elements {
        for i in 0..def.count {
            let element = read_ply_element(
                &parser,
                header.encoding,
                &mut payload,
                &mut line,
                name,
                def,
                i,
            )?;
            if let Err(e) = add_ply_element(&mut b, name, &element, ascii.then_some(line)) {
                // Report it only once the data proved structurally sound: if
                // the counts do not match the data, a garbage value here is a
                // symptom, and the mismatch is the error to report.
                deferred.get_or_insert(e);
            }
        }
    }
    check_ply_trailing(payload, ascii.then_some(line + 1))?;
    if let Some(e) = deferred {
        return Err(e.into());
    }
    Ok(b.finish(F, Vec::new())?)
}

/// The 1-based line of `header_bytes` that declares element `name`
/// (`element NAME …`), for messages.
fn element_line(header_bytes: &[u8], name: &str) -> Option<usize> {
    header_bytes
        .split(|&c| c == b'\n')
        .position(|l| {
            let mut t = tokens(l);
            t.next() == Some(b"element") && t.next() == Some(name.as_bytes())
        })
        .map(|i| i + 1)
}

/// The header's `vertex` element, which must exist and have scalar
/// properties `x`, `y` and `z`.
fn check_ply_vertex<'h>(
    header: &'h Header,
    header_bytes: &[u8],
) -> Result<&'h ElementDef, MeshError> {
    let vertex_def = header
        .elements
        .get("vertex")
        .ok_or_else(|| ply_header_error(None, "the header declares no 'vertex' element"))?;
    for name in ["x", "y", "z"] {
        match vertex_def.properties.get(name).map(|p| &p.data_type) {
            Some(PropertyType::Scalar(_)) => {}
            Some(PropertyType::List(..)) => {
                return Err(ply_header_error(
                    element_line(header_bytes, "vertex"),
                    format!("vertex property '{name}' is a list; expected a number"),
                ));
            }
            None => {
                return Err(ply_header_error(
                    element_line(header_bytes, "vertex"),
                    format!("the 'vertex' element has no property '{name}'"),
                ));
            }
        }
    }
    Ok(vertex_def)
}

/// The header's `face` element, which must exist (else a hint: triangle
/// strips, or a point cloud) and have an index list property (see
/// [`is_index_list`]) of integers.
fn check_ply_face<'h>(
    header: &'h Header,
    header_bytes: &[u8],
) -> Result<&'h ElementDef, MeshError> {
    let Some(face_def) = header.elements.get("face") else {
        let hint = if header.elements.contains_key("tristrips") {
            " (triangle strips, element 'tristrips', are not supported: convert them to faces)"
        } else {
            " (a point cloud has no triangles to deform)"
        };
        return Err(ply_header_error(
            None,
            format!("the header declares no 'face' element{hint}"),
        ));
    };
    let index_prop = face_def
        .properties
        .iter()
        .find(|(name, _)| is_index_list(name))
        .map(|(_, p)| p);
    match index_prop.map(|p| &p.data_type) {
        Some(PropertyType::List(count, item)) if is_integer(count) && is_integer(item) => {
            Ok(face_def)
        }
        Some(t) => Err(ply_header_error(
            element_line(header_bytes, "face"),
            format!("face property 'vertex_indices' has type {t:?}; expected a list of integers"),
        )),
        None => Err(ply_header_error(
            element_line(header_bytes, "face"),
            "the 'face' element has no list property 'vertex_indices' (or 'vertex_index')",
        )),
    }
}

/// The declared counts must fit in the `payload_len` bytes after the
/// header: each element needs at least [`min_element_bytes`], summed in
/// declaration order; ASCII gets one byte of slack (a missing final
/// newline). The first element whose running sum does not fit is named.
fn check_ply_sizes(
    header: &Header,
    payload_len: usize,
    header_bytes: &[u8],
) -> Result<(), MeshError> {
    let mut needed: u128 = 0;
    let mut declared: Vec<String> = Vec::new();
    for (name, def) in &header.elements {
        needed = needed
            .saturating_add(def.count as u128 * min_element_bytes(name, def, header.encoding));
        declared.push(format!("{} '{name}'", def.count));
        let slack = u128::from(header.encoding == Encoding::Ascii);
        if needed > payload_len as u128 + slack {
            return Err(ply_header_error(
                element_line(header_bytes, name),
                format!(
                    "the header declares {} elements, which need at least {needed} bytes, but only {payload_len} bytes follow the header (wrong count or truncated file)",
                    declared.join(" and "),
                ),
            ));
        }
    }
    Ok(())
}

/// Decodes element `i` of `name` (`def`) from the front of `payload`,
/// advancing it. In ASCII an element is one line (`line`, the last line
/// read, advances by one); in binary, a short read is a truncated file.
fn read_ply_element(
    parser: &Parser<PlyElement>,
    encoding: Encoding,
    payload: &mut &[u8],
    line: &mut usize,
    name: &str,
    def: &ElementDef,
    i: usize,
) -> Result<PlyElement, MeshError> {
    match encoding {
        Encoding::Ascii => {
            if payload.is_empty() {
                return Err(ply_header_error(
                    Some(*line),
                    format!(
                        "the data ends after {i} of the {} '{name}' elements (the header's counts do not match the data, or the file is truncated)",
                        def.count
                    ),
                ));
            }
            let end = payload
                .iter()
                .position(|&c| c == b'\n')
                .map_or(payload.len(), |p| p + 1);
            let (text, rest) = payload.split_at(end);
            *payload = rest;
            *line += 1;
            let text = std::str::from_utf8(text)
                .map_err(|_| ply_header_error(Some(*line), "the line is not valid text (UTF-8)"))?;
            parser
                .read_ascii_element(text, def)
                .map_err(|e| ply_header_error(Some(*line), ply_message(&e)))
        }
        Encoding::BinaryLittleEndian | Encoding::BinaryBigEndian => {
            let r = if encoding == Encoding::BinaryLittleEndian {
                parser.read_little_endian_element(payload, def)
            } else {
                parser.read_big_endian_element(payload, def)
            };
            r.map_err(|e| {
                if e.kind() == io::ErrorKind::UnexpectedEof {
                    ply_header_error(
                        None,
                        format!(
                            "the data ends inside '{name}' element {i} of {} (the header's counts do not match the data, or the file is truncated)",
                            def.count
                        ),
                    )
                } else {
                    ply_header_error(None, format!("'{name}' element {i}: {}", ply_message(&e)))
                }
            })
        }
    }
}

/// Adds a decoded element to the builder: a `vertex` its position, a `face`
/// its polygon (each index range-checked in turn); other elements are
/// skipped. `here` is the element's line (ASCII) for errors.
fn add_ply_element(
    b: &mut Builder,
    name: &str,
    element: &PlyElement,
    here: Option<usize>,
) -> Result<(), MeshError> {
    match name {
        "vertex" => b.vertex(element.xyz, here),
        "face" => {
            let indices = element
                .indices
                .as_ref()
                .map(IndexList::to_i64)
                .unwrap_or_default();
            let poly = indices
                .iter()
                .enumerate()
                .map(|(corner, &index)| b.resolve(index, corner, here))
                .collect::<Result<Vec<usize>, MeshError>>()?;
            b.polygon(&poly, here)
        }
        _ => Ok(()),
    }
}

/// Refuses anything but whitespace after the last element; `line` is the
/// first line after it (ASCII).
fn check_ply_trailing(payload: &[u8], line: Option<usize>) -> Result<(), MeshError> {
    match payload.iter().position(|c| !c.is_ascii_whitespace()) {
        Some(p) => {
            let extra = payload.len() - p;
            Err(ply_header_error(
                line,
                format!(
                    "{extra} bytes of data follow the last element (the header's element counts do not match the data)"
                ),
            ))
        }
        None => Ok(()),
    }
}

/// Writes PLY with `property double x, y, z` and
/// `property list uchar int vertex_indices`. Fails with
/// `io::ErrorKind::InvalidInput` if a vertex index does not fit in a 32-bit
/// signed `int`. Pass a buffered writer for speed.
pub fn write_ply<W: Write>(mesh: &Mesh, mut w: W, encoding: PlyEncoding) -> io::Result<()> {
    if i32::try_from(mesh.n_vertices()).is_err() {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!(
                "{} vertices: PLY 'int' vertex indices cannot address more than {} vertices",
                mesh.n_vertices(),
                i32::MAX
            ),
        ));
    }
    let format = match encoding {
        PlyEncoding::Ascii => "ascii",
        PlyEncoding::BinaryLittleEndian => "binary_little_endian",
        PlyEncoding::BinaryBigEndian => "binary_big_endian",
    };
    write!(
        w,
        "ply\nformat {format} 1.0\ncomment written by lse-deform\nelement vertex {}\nproperty double x\nproperty double y\nproperty double z\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
        mesh.n_vertices(),
        mesh.n_faces()
    )?;
    // Indices are < n_vertices ≤ i32::MAX (checked above).
    let idx = |i: usize| i32::try_from(i).unwrap_or(i32::MAX);
    match encoding {
        PlyEncoding::Ascii => {
            for p in mesh.positions() {
                writeln!(w, "{} {} {}", p[0], p[1], p[2])?;
            }
            for f in mesh.faces() {
                writeln!(w, "3 {} {} {}", f[0], f[1], f[2])?;
            }
        }
        PlyEncoding::BinaryLittleEndian | PlyEncoding::BinaryBigEndian => {
            let le = encoding == PlyEncoding::BinaryLittleEndian;
            let f64_bytes = |x: f64| if le { x.to_le_bytes() } else { x.to_be_bytes() };
            let i32_bytes = |x: i32| if le { x.to_le_bytes() } else { x.to_be_bytes() };
            for p in mesh.positions() {
                for &c in p {
                    w.write_all(&f64_bytes(c))?;
                }
            }
            for f in mesh.faces() {
                w.write_all(&[3])?;
                for &i in f {
                    w.write_all(&i32_bytes(idx(i)))?;
                }
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::io::shared::unwrap_io;

    fn ply(bytes: &[u8]) -> Result<LoadedMesh, MeshError> {
        unwrap_io(read_ply(bytes, MemoryBudget::unlimited()))
    }

    fn parse_error(line: Option<usize>, message: &str) -> MeshError {
        MeshError::Parse {
            format: "PLY",
            line,
            message: message.into(),
        }
    }

    fn with_payload(header: &str, payload: &[u8]) -> Vec<u8> {
        let mut bytes = header.as_bytes().to_vec();
        bytes.extend_from_slice(payload);
        bytes
    }

    /// Decodes `text` as a header alone; returns it and its bytes.
    fn header_of(text: &str) -> (Header, Vec<u8>) {
        let parser = Parser::<PlyElement>::new();
        let mut reader = Reader::new(text.as_bytes());
        let header = parser.read_header(&mut reader).unwrap();
        (header, text.as_bytes().to_vec())
    }

    const ASCII_HEAD: &str = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";

    #[test]
    fn element_line_alone() {
        let bytes = ASCII_HEAD.as_bytes();
        assert_eq!(element_line(bytes, "vertex"), Some(3));
        assert_eq!(element_line(bytes, "face"), Some(7));
        assert_eq!(element_line(bytes, "edge"), None);
    }

    #[test]
    fn vertex_and_face_checks_alone() {
        let (header, bytes) = header_of(ASCII_HEAD);
        assert_eq!(check_ply_vertex(&header, &bytes).unwrap().count, 2);
        assert_eq!(check_ply_face(&header, &bytes).unwrap().count, 1);
        let (header, bytes) = header_of(&ASCII_HEAD.replace("property float y\n", ""));
        assert_eq!(
            check_ply_vertex(&header, &bytes).unwrap_err(),
            parse_error(Some(3), "the 'vertex' element has no property 'y'")
        );
        let (header, bytes) = header_of(&ASCII_HEAD.replace("vertex_indices", "corners"));
        assert_eq!(
            check_ply_face(&header, &bytes).unwrap_err(),
            parse_error(
                Some(7),
                "the 'face' element has no list property 'vertex_indices' (or 'vertex_index')"
            )
        );
        let (header, bytes) =
            header_of("ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nend_header\n");
        assert_eq!(
            check_ply_face(&header, &bytes).unwrap_err(),
            parse_error(
                None,
                "the header declares no 'face' element (a point cloud has no triangles to deform)"
            )
        );
    }

    #[test]
    fn size_check_alone_names_the_first_element_that_does_not_fit() {
        // ASCII: 2 bytes per property at least, so 2 vertices need 12 bytes
        // and the face 2 more; one byte of slack.
        let (header, bytes) = header_of(ASCII_HEAD);
        assert_eq!(check_ply_sizes(&header, 13, &bytes), Ok(()));
        assert_eq!(
            check_ply_sizes(&header, 12, &bytes),
            Err(parse_error(
                Some(7),
                "the header declares 2 'vertex' and 1 'face' elements, which need at least 14 bytes, but only 12 bytes follow the header (wrong count or truncated file)"
            ))
        );
        assert_eq!(
            check_ply_sizes(&header, 10, &bytes),
            Err(parse_error(
                Some(3),
                "the header declares 2 'vertex' elements, which need at least 12 bytes, but only 10 bytes follow the header (wrong count or truncated file)"
            ))
        );
    }

    #[test]
    fn element_reader_alone_advances_payload_and_line() {
        let (header, _) = header_of(ASCII_HEAD);
        let parser = Parser::<PlyElement>::new();
        let (vertex, face) = (&header.elements["vertex"], &header.elements["face"]);
        let mut payload: &[u8] = b"1 2 3\n3 0 1 1\n";
        let mut line = 9;
        let v = read_ply_element(
            &parser,
            Encoding::Ascii,
            &mut payload,
            &mut line,
            "vertex",
            vertex,
            0,
        )
        .unwrap();
        assert_eq!(
            (v.xyz, line, payload),
            ([1.0, 2.0, 3.0], 10, &b"3 0 1 1\n"[..])
        );
        let f = read_ply_element(
            &parser,
            Encoding::Ascii,
            &mut payload,
            &mut line,
            "face",
            face,
            0,
        )
        .unwrap();
        assert_eq!(
            f.indices.as_ref().map(IndexList::to_i64),
            Some(vec![0, 1, 1])
        );
        assert_eq!((line, payload.len()), (11, 0));
        assert_eq!(
            read_ply_element(
                &parser,
                Encoding::Ascii,
                &mut payload,
                &mut line,
                "face",
                face,
                1
            )
            .err(),
            Some(parse_error(
                Some(11),
                "the data ends after 1 of the 1 'face' elements (the header's counts do not match the data, or the file is truncated)"
            ))
        );
        let mut short: &[u8] = &[0, 0, 0];
        assert_eq!(
            read_ply_element(
                &parser,
                Encoding::BinaryLittleEndian,
                &mut short,
                &mut line,
                "vertex",
                vertex,
                1
            )
            .err(),
            Some(parse_error(
                None,
                "the data ends inside 'vertex' element 1 of 2 (the header's counts do not match the data, or the file is truncated)"
            ))
        );
    }

    #[test]
    fn add_element_alone_routes_vertices_and_faces_and_skips_others() {
        let mut b = Builder::within(MemoryBudget::unlimited());
        for (name, xyz, indices) in [
            ("vertex", [1.0, 0.0, 0.0], None),
            ("vertex", [0.0, 1.0, 0.0], None),
            ("vertex", [0.0, 0.0, 1.0], None),
            ("edge", [9.0, 9.0, 9.0], Some(IndexList::U8(vec![0, 1]))),
            ("face", [0.0; 3], Some(IndexList::I32(vec![2, 1, 0]))),
        ] {
            add_ply_element(&mut b, name, &PlyElement { xyz, indices }, Some(4)).unwrap();
        }
        let bad = PlyElement {
            xyz: [0.0; 3],
            indices: Some(IndexList::I16(vec![0, 1, -1])),
        };
        assert_eq!(
            add_ply_element(&mut b, "face", &bad, Some(5)),
            Err(MeshError::IndexOutOfRange {
                face: 1,
                index: -1,
                vertex_count: 3,
                line: Some(5)
            })
        );
        let mesh = b.finish("PLY", Vec::new()).unwrap().mesh;
        assert_eq!(
            mesh.positions(),
            &[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
        );
        assert_eq!(mesh.faces(), &[[2, 1, 0]]);
    }

    #[test]
    fn trailing_check_alone() {
        assert_eq!(check_ply_trailing(b" \r\n\n", Some(8)), Ok(()));
        assert_eq!(
            check_ply_trailing(b"\n1 2\n", Some(8)),
            Err(parse_error(
                Some(8),
                "4 bytes of data follow the last element (the header's element counts do not match the data)"
            ))
        );
    }

    const SQUARE_AND_APEX: [[f64; 3]; 5] = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
        [2.0, 0.5, 0.0],
    ];

    #[test]
    fn ascii_faces_before_vertices_with_properties_in_any_order() {
        // 'vertex_index' with int counts, the face element first, and the
        // vertex element's x, y, z among an ignored list and scalar.
        let text = "ply\nformat ascii 1.0\n\
                    element face 2\nproperty list int int vertex_index\n\
                    element vertex 5\nproperty double z\nproperty list uchar float extra\n\
                    property double x\nproperty uchar red\nproperty double y\nend_header\n\
                    4 0 1 2 3\n3 1 4 2\n\
                    0 2 9 9 0 7 0\n0 0 1 1 0\n0 1 5 1 1 1\n0 0 0 1 1\n0 0 2 0 0.5\n";
        let loaded = ply(text.as_bytes()).unwrap();
        assert_eq!(loaded.mesh.positions(), &SQUARE_AND_APEX);
        assert_eq!(loaded.mesh.faces(), &[[0, 1, 2], [0, 2, 3], [1, 4, 2]]);
        assert_eq!(
            loaded.notes,
            vec![
                "1 PLY polygon(s) with more than 3 vertices were fan-triangulated into 2 triangles"
                    .to_string()
            ]
        );
    }

    const BINARY_HEADER: &str = "ply\nformat binary_little_endian 1.0\nelement vertex 3\n\
        property float x\nproperty float y\nproperty float z\n\
        element face 1\nproperty list uchar char vertex_indices\nend_header\n";

    /// The payload of a unit right triangle in [`BINARY_HEADER`]'s layout,
    /// with the given face bytes.
    fn triangle_payload(face: &[u8]) -> Vec<u8> {
        let mut payload = Vec::new();
        for c in [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0] {
            payload.extend_from_slice(&c.to_le_bytes());
        }
        payload.extend_from_slice(face);
        payload
    }

    #[test]
    fn binary_char_indices_are_signed_and_uchar_ones_are_not() {
        let good = with_payload(BINARY_HEADER, &triangle_payload(&[3, 0, 1, 2]));
        assert_eq!(ply(&good).unwrap().mesh.faces(), &[[0, 1, 2]]);
        // 0xff is −1 as a char: out of range, without a line (binary).
        let bad = with_payload(BINARY_HEADER, &triangle_payload(&[3, 0, 1, 0xff]));
        assert_eq!(
            ply(&bad).unwrap_err(),
            MeshError::IndexOutOfRange {
                face: 0,
                index: -1,
                vertex_count: 3,
                line: None,
            }
        );
        // As a uchar it is 255.
        let header = BINARY_HEADER.replace("uchar char", "uchar uchar");
        assert_eq!(
            ply(&with_payload(&header, &triangle_payload(&[3, 0, 1, 0xff]))).unwrap_err(),
            MeshError::IndexOutOfRange {
                face: 0,
                index: 255,
                vertex_count: 3,
                line: None,
            }
        );
    }

    #[test]
    fn truncated_binary_body_errors() {
        // 36 bytes of vertices and a face needing at least 1 + 3 = 4: a quad
        // cut after its third index passes the size check and ends inside
        // the face.
        let cut = with_payload(BINARY_HEADER, &triangle_payload(&[4, 0, 1, 2]));
        assert_eq!(
            ply(&cut).unwrap_err(),
            parse_error(
                None,
                "the data ends inside 'face' element 0 of 1 (the header's counts do not match the data, or the file is truncated)"
            )
        );
        // Cut inside the vertices: refused from the header's counts, at the
        // line declaring the vertex element (line 3).
        let payload = triangle_payload(&[]);
        let short = with_payload(BINARY_HEADER, &payload[..35]);
        assert_eq!(
            ply(&short).unwrap_err(),
            parse_error(
                Some(3),
                "the header declares 3 'vertex' elements, which need at least 36 bytes, but only 35 bytes follow the header (wrong count or truncated file)"
            )
        );
    }

    #[test]
    fn bytes_after_the_last_element_are_an_error_unless_whitespace() {
        let mut payload = triangle_payload(&[3, 0, 1, 2]);
        payload.extend_from_slice(b"\n \r\n\t");
        assert_eq!(
            ply(&with_payload(BINARY_HEADER, &payload))
                .unwrap()
                .mesh
                .faces(),
            &[[0, 1, 2]]
        );
        // Counted from the first byte that is not whitespace.
        payload.extend_from_slice(b"xy");
        assert_eq!(
            ply(&with_payload(BINARY_HEADER, &payload)).unwrap_err(),
            parse_error(
                None,
                "2 bytes of data follow the last element (the header's element counts do not match the data)"
            )
        );
    }

    #[test]
    fn least_element_sizes_by_encoding() {
        let header = |format: &str| {
            format!(
                "ply\nformat {format} 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\n\
                 element face 1\nproperty list uchar int vertex_indices\nproperty list ushort float texcoord\n\
                 element edge 1\nproperty list uchar int vertex_indices\n\
                 element nothing 1\nend_header\n"
            )
        };
        let sizes = |format: &str| -> Vec<u128> {
            let text = header(format);
            let parsed = Parser::<PlyElement>::new()
                .read_header(&mut Reader::new(text.as_bytes()))
                .unwrap();
            parsed
                .elements
                .iter()
                .map(|(name, def)| min_element_bytes(name, def, parsed.encoding))
                .collect()
        };
        // vertex 3·4 + 1; face (1 + 3·4) + 2; an index list outside 'face'
        // may be empty: 1; no properties: still 1.
        assert_eq!(sizes("binary_big_endian"), vec![13, 15, 1, 1]);
        // ASCII: a character and a separator per property.
        assert_eq!(sizes("ascii"), vec![8, 4, 2, 1]);
    }

    fn awkward_triangle() -> Mesh {
        Mesh::new(
            vec![
                [0.1, -0.0, 1e21],
                [1.0, 0.30000000000000004, -3.0],
                [5e-324, 0.0, 123456789.0],
            ],
            vec![[0, 1, 2]],
        )
        .unwrap()
    }

    const WRITTEN_HEADER: &str = "comment written by lse-deform\nelement vertex 3\n\
        property double x\nproperty double y\nproperty double z\nelement face 1\n\
        property list uchar int vertex_indices\nend_header\n";

    #[test]
    fn ascii_writer_text() {
        let mesh = Mesh::new(
            vec![[0.1, -0.0, 1e21], [1.0, 0.5, -3.0], [1e-7, 0.0, 2.0]],
            vec![[2, 0, 1]],
        )
        .unwrap();
        let mut out = Vec::new();
        write_ply(&mesh, &mut out, PlyEncoding::Ascii).unwrap();
        assert_eq!(
            String::from_utf8(out).unwrap(),
            format!(
                "ply\nformat ascii 1.0\n{WRITTEN_HEADER}\
                 0.1 -0 1000000000000000000000\n1 0.5 -3\n0.0000001 0 2\n3 2 0 1\n"
            )
        );
    }

    #[test]
    fn binary_writer_bytes_in_both_byte_orders() {
        let mesh = Mesh::new(
            vec![[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -2.0]],
            vec![[0, 1, 2]],
        )
        .unwrap();
        let one_be = [0x3f, 0xf0, 0, 0, 0, 0, 0, 0];
        let minus_two_be = [0xc0, 0, 0, 0, 0, 0, 0, 0];
        let zero = [0u8; 8];
        let mut big: Vec<u8> = Vec::new();
        for c in [
            one_be,
            zero,
            zero,
            zero,
            one_be,
            zero,
            zero,
            zero,
            minus_two_be,
        ] {
            big.extend_from_slice(&c);
        }
        big.extend_from_slice(&[3, 0, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 2]);
        let mut little: Vec<u8> = Vec::new();
        for mut c in [
            one_be,
            zero,
            zero,
            zero,
            one_be,
            zero,
            zero,
            zero,
            minus_two_be,
        ] {
            c.reverse();
            little.extend_from_slice(&c);
        }
        little.extend_from_slice(&[3, 0, 0, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0]);
        for (encoding, word, payload) in [
            (PlyEncoding::BinaryBigEndian, "binary_big_endian", big),
            (
                PlyEncoding::BinaryLittleEndian,
                "binary_little_endian",
                little,
            ),
        ] {
            let mut out = Vec::new();
            write_ply(&mesh, &mut out, encoding).unwrap();
            let expected = with_payload(
                &format!("ply\nformat {word} 1.0\n{WRITTEN_HEADER}"),
                &payload,
            );
            assert_eq!(out, expected, "{word}");
        }
    }

    #[test]
    fn write_then_read_is_bit_identical_in_every_encoding() {
        let expected: Vec<[u64; 3]> = [
            [0.1, -0.0, 1e21],
            [1.0, 0.30000000000000004, -3.0],
            [5e-324, 0.0, 123456789.0],
        ]
        .iter()
        .map(|p| p.map(f64::to_bits))
        .collect();
        for encoding in [
            PlyEncoding::Ascii,
            PlyEncoding::BinaryLittleEndian,
            PlyEncoding::BinaryBigEndian,
        ] {
            let mut out = Vec::new();
            write_ply(&awkward_triangle(), &mut out, encoding).unwrap();
            let back = ply(&out).unwrap();
            assert_eq!(back.notes, Vec::<String>::new(), "{encoding:?}");
            assert_eq!(back.mesh.faces(), &[[0, 1, 2]], "{encoding:?}");
            let bits: Vec<[u64; 3]> = back
                .mesh
                .positions()
                .iter()
                .map(|p| p.map(f64::to_bits))
                .collect();
            assert_eq!(bits, expected, "{encoding:?}");
        }
    }
}
