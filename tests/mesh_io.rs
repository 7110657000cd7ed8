//! Mesh file I/O: round trips, hand-written files in every format, every
//! error class, and proptests that no input bytes make a reader panic.

use std::io::Write;
use std::path::{Path, PathBuf};

use lse_deform::Error;
use lse_deform::error::MeshError;
use lse_deform::mesh::generate;
use lse_deform::mesh::io::{PlyEncoding, write_obj, write_off, write_ply};
use lse_deform::mesh::{Mesh, MeshFormat, read_mesh, read_mesh_bytes, write_mesh};
use proptest::prelude::*;

// ---------------------------------------------------------------------------
// helpers

fn obj(text: &str) -> Result<lse_deform::mesh::LoadedMesh, MeshError> {
    read_mesh_bytes(
        text.as_bytes(),
        MeshFormat::Obj,
        lse_deform::limits::MemoryBudget::default(),
    )
}

fn off(text: &str) -> Result<lse_deform::mesh::LoadedMesh, MeshError> {
    read_mesh_bytes(
        text.as_bytes(),
        MeshFormat::Off,
        lse_deform::limits::MemoryBudget::default(),
    )
}

fn ply(bytes: &[u8]) -> Result<lse_deform::mesh::LoadedMesh, MeshError> {
    read_mesh_bytes(
        bytes,
        MeshFormat::Ply,
        lse_deform::limits::MemoryBudget::default(),
    )
}

fn bits(m: &Mesh) -> Vec<[u64; 3]> {
    m.positions()
        .iter()
        .map(|p| [p[0].to_bits(), p[1].to_bits(), p[2].to_bits()])
        .collect()
}

fn assert_identical(a: &Mesh, b: &Mesh) {
    assert_eq!(bits(a), bits(b), "positions differ in some bit");
    assert_eq!(a.faces(), b.faces());
}

/// Meshes with awkward coordinates: -0.0, tiny and huge magnitudes,
/// non-terminating binary fractions.
fn awkward_meshes() -> Vec<Mesh> {
    let tetra = Mesh::new(
        vec![
            [-0.0, 0.1, 1.0 / 3.0],
            [1e5 + 0.1, -2.5e-7, std::f64::consts::PI],
            [123_456.789_012_345_67, 1e5, -1e-20],
            [f64::MIN_POSITIVE * 1e300, 7.0, 0.3],
        ],
        vec![[0, 1, 2], [0, 2, 3], [0, 3, 1], [1, 3, 2]],
    )
    .unwrap();
    // Areas are computed from squared lengths, so coordinates must stay
    // within about 1e±75 for a face not to look degenerate.
    let huge = vec![[0.0, 0.0, 0.0], [1e60, 3e59, 0.0], [1.5e59, 1e60, 7e-60]];
    let tiny: Vec<[f64; 3]> = huge
        .iter()
        .map(|p| [p[0] * 1e-120, p[1] * 1e-120, p[2] * 1e-120])
        .collect();
    vec![
        tetra,
        Mesh::new(huge, vec![[0, 1, 2]]).unwrap(),
        Mesh::new(tiny, vec![[0, 1, 2]]).unwrap(),
    ]
}

fn write_to_vec(mesh: &Mesh, format: &str) -> Vec<u8> {
    let mut out = Vec::new();
    match format {
        "obj" => write_obj(mesh, &mut out).unwrap(),
        "off" => write_off(mesh, &mut out).unwrap(),
        "ply-ascii" => write_ply(mesh, &mut out, PlyEncoding::Ascii).unwrap(),
        "ply-le" => write_ply(mesh, &mut out, PlyEncoding::BinaryLittleEndian).unwrap(),
        "ply-be" => write_ply(mesh, &mut out, PlyEncoding::BinaryBigEndian).unwrap(),
        _ => unreachable!(),
    }
    out
}

fn format_of(name: &str) -> MeshFormat {
    match name {
        "obj" => MeshFormat::Obj,
        "off" => MeshFormat::Off,
        _ => MeshFormat::Ply,
    }
}

const FORMATS: [&str; 5] = ["obj", "off", "ply-ascii", "ply-le", "ply-be"];

struct TempDir(PathBuf);

impl TempDir {
    fn new(tag: &str) -> TempDir {
        let dir =
            std::env::temp_dir().join(format!("lse-deform-mesh-io-{tag}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        TempDir(dir)
    }
    fn path(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn gzip(bytes: &[u8]) -> Vec<u8> {
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    e.write_all(bytes).unwrap();
    e.finish().unwrap()
}

// ---------------------------------------------------------------------------
// round trips

#[test]
fn round_trip_in_memory_is_bit_identical_for_every_format() {
    let mut meshes = awkward_meshes();
    meshes.push(generate::sliver_mesh(6, 3).unwrap());
    meshes.push(generate::bumpy_sphere(2, 0.2, 5).unwrap());
    for mesh in &meshes {
        for f in FORMATS {
            let bytes = write_to_vec(mesh, f);
            let back = read_mesh_bytes(
                &bytes,
                format_of(f),
                lse_deform::limits::MemoryBudget::default(),
            )
            .unwrap_or_else(|e| panic!("{f}: {e}"))
            .mesh;
            assert_identical(mesh, &back);
        }
    }
}

#[test]
fn round_trip_through_files_including_gzip() {
    let dir = TempDir::new("roundtrip");
    let mesh = generate::sliver_mesh(5, 11).unwrap();
    for name in [
        "m.obj", "m.ply", "m.off", "m.obj.gz", "m.ply.gz", "m.OFF.GZ",
    ] {
        let path = dir.path(name);
        write_mesh(&mesh, &path).unwrap();
        let raw = std::fs::read(&path).unwrap();
        assert_eq!(
            raw.starts_with(&[0x1f, 0x8b]),
            name.to_ascii_lowercase().ends_with(".gz"),
            "{name}: gzip iff .gz"
        );
        let loaded = read_mesh(&path, lse_deform::limits::MemoryBudget::default()).unwrap();
        assert_identical(&mesh, &loaded.mesh);
        assert!(loaded.notes.is_empty(), "{name}: {:?}", loaded.notes);
    }
    // The default PLY encoding is binary little-endian with doubles.
    let raw = std::fs::read(dir.path("m.ply")).unwrap();
    let text = String::from_utf8_lossy(&raw[..200]);
    assert!(text.contains("format binary_little_endian 1.0"));
    assert!(text.contains("property double x"));
}

#[test]
fn gzip_is_detected_by_content_with_a_note() {
    let dir = TempDir::new("gzsniff");
    let mesh = generate::grid(2, 2).unwrap();
    let bytes = write_to_vec(&mesh, "obj");
    let path = dir.path("actually-gzipped.obj");
    std::fs::write(&path, gzip(&bytes)).unwrap();
    let loaded = read_mesh(&path, lse_deform::limits::MemoryBudget::default()).unwrap();
    assert_identical(&mesh, &loaded.mesh);
    assert!(loaded.notes[0].contains("gzip-compressed"));
    // In memory as well.
    let loaded = read_mesh_bytes(
        &gzip(&bytes),
        MeshFormat::Obj,
        lse_deform::limits::MemoryBudget::default(),
    )
    .unwrap();
    assert_identical(&mesh, &loaded.mesh);
}

#[test]
fn truncated_or_corrupt_gzip_is_an_error() {
    let mesh = generate::grid(4, 4).unwrap();
    let gz = gzip(&write_to_vec(&mesh, "obj"));
    // Cut: the stream ends early (no silently smaller mesh).
    for cut in [gz.len() / 2, gz.len() - 4] {
        match read_mesh_bytes(
            &gz[..cut],
            MeshFormat::Obj,
            lse_deform::limits::MemoryBudget::default(),
        ) {
            Err(MeshError::Parse { message, .. }) => {
                assert!(message.contains("could not read the data"), "{message}")
            }
            other => panic!("cut {cut}: {other:?}"),
        }
    }
    // From a file, the error names the path.
    let dir = TempDir::new("gzcut");
    let path = dir.path("cut.obj.gz");
    std::fs::write(&path, &gz[..gz.len() / 2]).unwrap();
    match read_mesh(&path, lse_deform::limits::MemoryBudget::default()).unwrap_err() {
        Error::Io { path: p, source } => {
            assert_eq!(p, path);
            assert!(source.to_string().contains("gzip"), "{source}");
        }
        other => panic!("{other:?}"),
    }
}

// ---------------------------------------------------------------------------
// hand-written files

#[test]
fn obj_slash_forms_negative_indices_quads_and_comments() {
    let text = "\
# a unit square as a quad, plus a triangle using relative indices
mtllib square.mtl
o square
v 0 0 0
v 1 0 0 1.0          # w is ignored
v 1 1 0 0.5 0.5 0.5  # so are vertex colours
v 0 1 0
vn 0 0 1
vt 0 0
vt 1 0
vp 0.5
g square
usemtl red
s off

f 1/1/1 2/2/1 3/1/1 4//1
v 2 0 0.5
f -4//1 -1//1 -3//1
f 2/1 3/2 4/1
l 1 2
";
    let loaded = obj(text).unwrap();
    let m = &loaded.mesh;
    assert_eq!(
        m.positions(),
        &[
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
            [2.0, 0.0, 0.5]
        ]
    );
    // Quad (1 2 3 4) fanned to (0 1 2), (0 2 3); -4 -1 -3 after 5 vertices
    // are 1, 4, 2 (0-based); then (1 2 3).
    assert_eq!(m.faces(), &[[0, 1, 2], [0, 2, 3], [1, 4, 2], [1, 2, 3]]);
    assert_eq!(loaded.notes.len(), 1, "{:?}", loaded.notes);
    assert!(loaded.notes[0].contains("1 OBJ polygon(s)"));
    assert!(loaded.notes[0].contains("2 triangles"));
}

#[test]
fn obj_pentagon_is_fanned_and_unknown_records_are_noted() {
    let text = "v 0 0 0\nv 2 0 0\nv 3 1 0\nv 1 2 0\nv -1 1 0\r\nf 1 2 3 4 5\r\ncstype bspline\n";
    let loaded = obj(text).unwrap();
    assert_eq!(loaded.mesh.faces(), &[[0, 1, 2], [0, 2, 3], [0, 3, 4]]);
    assert!(
        loaded
            .notes
            .iter()
            .any(|n| n.contains("'cstype' at line 7"))
    );
}

#[test]
fn obj_missing_final_newline_is_noted() {
    let loaded = obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3").unwrap();
    assert_eq!(loaded.mesh.n_faces(), 1);
    assert!(loaded.notes.iter().any(|n| n.contains("newline")));
}

#[test]
fn ply_ascii_with_extra_properties_elements_and_polygons() {
    let text = "ply\r
format ascii 1.0\r
comment hand-written\r
element vertex 5\r
property float x\r
property float y\r
property float z\r
property uchar red\r
element edge 1\r
property int vertex1\r
property int vertex2\r
element face 2\r
property list uchar uint vertex_index\r
property list uchar float texcoord\r
end_header\r
0 0 0 255\r
1 0 0 0\r
1 1 0 0\r
0 1 0.25 0\r
2 0.5 0 7\r
0 1\r
4 0 1 2 3 0\r
3 1 4 2 2 0.5 0.5\r
";
    let loaded = ply(text.as_bytes()).unwrap();
    let m = &loaded.mesh;
    assert_eq!(m.positions()[3], [0.0, 1.0, 0.25]);
    assert_eq!(m.positions()[4], [2.0, 0.5, 0.0]);
    assert_eq!(m.faces(), &[[0, 1, 2], [0, 2, 3], [1, 4, 2]]);
    assert!(loaded.notes[0].contains("fan-triangulated"));
}

/// Builds a binary PLY: header text, then payload bytes.
fn ply_binary(header: &str, payload: &[u8]) -> Vec<u8> {
    let mut v = header.as_bytes().to_vec();
    v.extend_from_slice(payload);
    v
}

#[test]
fn ply_binary_big_endian_float_coordinates_and_short_indices() {
    let header = "ply
format binary_big_endian 1.0
element vertex 4
property float x
property float y
property float z
element face 1
property list uchar short vertex_indices
end_header
";
    let pts: [[f32; 3]; 4] = [
        [0.0, 0.0, 0.0],
        [1.5, 0.0, 0.0],
        [1.5, 0.1, 0.0],
        [0.0, 1.0, 0.3],
    ];
    let mut payload = Vec::new();
    for p in pts {
        for c in p {
            payload.extend_from_slice(&c.to_be_bytes());
        }
    }
    payload.push(4);
    for i in [0i16, 1, 2, 3] {
        payload.extend_from_slice(&i.to_be_bytes());
    }
    let m = ply(&ply_binary(header, &payload)).unwrap().mesh;
    // f32 values converted exactly to f64.
    assert_eq!(m.positions()[2], [1.5, f64::from(0.1f32), 0.0]);
    assert_eq!(m.positions()[3][2], f64::from(0.3f32));
    assert_eq!(m.faces(), &[[0, 1, 2], [0, 2, 3]]);
}

#[test]
fn ply_binary_little_endian_int_coordinates() {
    let header = "ply
format binary_little_endian 1.0
element vertex 3
property int x
property int y
property uchar z
element face 1
property list uint int vertex_indices
end_header
";
    let mut payload = Vec::new();
    for (x, y, z) in [(0i32, 0i32, 0u8), (10, 0, 1), (0, -10, 2)] {
        payload.extend_from_slice(&x.to_le_bytes());
        payload.extend_from_slice(&y.to_le_bytes());
        payload.push(z);
    }
    payload.extend_from_slice(&3u32.to_le_bytes());
    for i in [0i32, 2, 1] {
        payload.extend_from_slice(&i.to_le_bytes());
    }
    let m = ply(&ply_binary(header, &payload)).unwrap().mesh;
    assert_eq!(
        m.positions(),
        &[[0.0, 0.0, 0.0], [10.0, 0.0, 1.0], [0.0, -10.0, 2.0]]
    );
    assert_eq!(m.faces(), &[[0, 2, 1]]);
}

#[test]
fn off_variants() {
    // Quad with a face colour, comments and blank lines.
    let text = "OFF
# a square
4 1 0

0 0 0
1 0 0   # comment after a vertex
1 1 0
0 1 0
4 0 1 2 3  255 0 0
";
    let loaded = off(text).unwrap();
    assert_eq!(loaded.mesh.faces(), &[[0, 1, 2], [0, 2, 3]]);
    assert!(loaded.notes[0].contains("fan-triangulated"));

    // COFF with per-vertex colours, counts on the header line.
    let text = "COFF 3 1 3\n0 0 0 255 0 0 255\n1 0 0 0 255 0 255\n0 1 0.5 0 0 255 255\n3 0 1 2\n";
    let m = off(text).unwrap().mesh;
    assert_eq!(m.positions()[2], [0.0, 1.0, 0.5]);
    assert_eq!(m.faces(), &[[0, 1, 2]]);

    // NOFF with normals.
    let text = "NOFF\n3 1 0\n0 0 0 0 0 1\n1 0 0 0 0 1\n0 1 0 0 0 1\n3 2 1 0\n";
    assert_eq!(off(text).unwrap().mesh.faces(), &[[2, 1, 0]]);

    // No header line at all: read with a note.
    let loaded = off("3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n").unwrap();
    assert_eq!(loaded.mesh.n_faces(), 1);
    assert!(loaded.notes[0].contains("no 'OFF' header"));
}

#[test]
fn off_unsupported_headers() {
    for (text, needle) in [
        ("4OFF\n3 1 0\n", "4D or n-dimensional"),
        ("nOFF\n3\n3 1 0\n", "4D or n-dimensional"),
        ("OFF BINARY\n", "binary OFF"),
        ("PLY\n3 1 0\n", "expected the header 'OFF'"),
        ("XOFF\n3 1 0\n", "unknown OFF header"),
    ] {
        match off(text) {
            Err(MeshError::Parse {
                format: "OFF",
                line: Some(1),
                message,
            }) => assert!(message.contains(needle), "{text:?}: {message}"),
            other => panic!("{text:?}: {other:?}"),
        }
    }
}

// ---------------------------------------------------------------------------
// errors

const TETRA_OBJ: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";

#[test]
fn obj_truncated_mid_line_gives_located_errors() {
    // Cut inside a vertex line.
    match obj("v 0 0 0\nv 1 0 0\nv 0 1") {
        Err(MeshError::Parse {
            format: "OBJ",
            line: Some(3),
            message,
        }) => assert!(message.contains("expected 3 coordinates"), "{message}"),
        other => panic!("{other:?}"),
    }
    // Cut inside a face line: a face of two vertices.
    let cut = &TETRA_OBJ[..TETRA_OBJ.len() - 3];
    let e = obj(cut).unwrap_err();
    assert_eq!(
        e,
        MeshError::BadFaceSize {
            face: 3,
            sides: 2,
            line: Some(8)
        }
    );
    assert!(e.to_string().contains("line 8"), "{e}");
    // Cut just before the faces that use vertex 3: unreferenced vertex.
    let e = obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\n").unwrap_err();
    assert_eq!(
        e,
        MeshError::UnreferencedVertex {
            vertex: 3,
            count: 1,
            line: Some(4)
        }
    );
    assert!(e.to_string().contains("vertex 3 (line 4)"), "{e}");
}

#[test]
fn obj_every_truncation_is_an_error_or_a_smaller_valid_mesh() {
    let full = obj(TETRA_OBJ).unwrap().mesh;
    for cut in 0..TETRA_OBJ.len() {
        match obj(&TETRA_OBJ[..cut]) {
            Ok(loaded) => {
                assert!(loaded.mesh.n_faces() <= full.n_faces());
                assert_eq!(&full.faces()[..loaded.mesh.n_faces()], loaded.mesh.faces());
            }
            Err(e) => assert!(!e.to_string().is_empty()),
        }
    }
}

#[test]
fn obj_index_errors() {
    // Past the end.
    let e = obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 5\n").unwrap_err();
    assert_eq!(
        e,
        MeshError::IndexOutOfRange {
            face: 1,
            index: 4,
            vertex_count: 4,
            line: Some(6)
        }
    );
    assert!(e.to_string().contains("face 1 (line 6)"), "{e}");
    // Past the end inside a polygon: the face index is that of the fan
    // triangle holding the corner.
    let e = obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 4 3 9\n").unwrap_err();
    assert!(
        matches!(
            e,
            MeshError::IndexOutOfRange {
                face: 2,
                index: 8,
                line: Some(5),
                ..
            }
        ),
        "{e:?}"
    );
    // Zero.
    match obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n") {
        Err(MeshError::Parse {
            line: Some(4),
            message,
            ..
        }) => assert!(message.contains("index 0 is invalid"), "{message}"),
        other => panic!("{other:?}"),
    }
    // Relative index before the first vertex.
    let e = obj("v 0 0 0\nv 1 0 0\nf -1 -2 -3\nv 0 1 0\n").unwrap_err();
    assert_eq!(
        e,
        MeshError::IndexOutOfRange {
            face: 0,
            index: -1,
            vertex_count: 2,
            line: Some(3)
        }
    );
    // Not a number.
    match obj("v 0 0 0\nf 1 x 2\n") {
        Err(MeshError::Parse {
            line: Some(2),
            message,
            ..
        }) => assert!(message.contains("'x'"), "{message}"),
        other => panic!("{other:?}"),
    }
    match obj("v 0 abc 0\n") {
        Err(MeshError::Parse {
            line: Some(1),
            message,
            ..
        }) => assert_eq!(message, "invalid number 'abc'"),
        other => panic!("{other:?}"),
    }
}

#[test]
fn obj_invalid_geometry_errors_carry_lines() {
    // NaN coordinate.
    match obj("v 0 0 0\nv 1 0 0\nv 0 nan 0\nf 1 2 3\n") {
        Err(MeshError::NonFiniteCoordinate {
            vertex: 2,
            value,
            line: Some(3),
        }) => assert!(value.is_nan()),
        other => panic!("{other:?}"),
    }
    // Overflow to infinity.
    let e = obj("v 0 0 0\nv 1e400 0 0\nv 0 1 0\nf 1 2 3\n").unwrap_err();
    assert!(matches!(
        e,
        MeshError::NonFiniteCoordinate {
            vertex: 1,
            line: Some(2),
            ..
        }
    ));
    assert!(e.to_string().contains("vertex 1 (line 2)"), "{e}");
    // Repeated vertex.
    let e = obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 2\n").unwrap_err();
    assert_eq!(
        e,
        MeshError::RepeatedVertex {
            face: 1,
            vertex: 1,
            line: Some(5)
        }
    );
    // Zero area (collinear): read, and named by the mesh's first
    // degenerate face (refused by the cotangent Laplacians).
    let m = obj("v 0 0 0\nv 1 0 0\nv 2 0 0\nv 0 1 0\n# comment\nf 1 2 4\nf 1 2 3\n")
        .unwrap()
        .mesh;
    assert!(
        matches!(
            m.degenerate_face(),
            Some(MeshError::DegenerateFace {
                face: 1,
                vertices: [0, 1, 2],
                ..
            })
        ),
        "{:?}",
        m.degenerate_face()
    );
    // Duplicate face (same vertices, other order).
    let e = obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 2 3 1\n").unwrap_err();
    assert_eq!(
        e,
        MeshError::DuplicateFace {
            face: 1,
            first: 0,
            vertices: [1, 2, 0],
            line: Some(5)
        }
    );
    assert!(e.to_string().contains("line 5"));
    // Face with fewer than 3 vertices.
    assert_eq!(
        obj("v 0 0 0\nv 1 0 0\nf 1 2\n").unwrap_err(),
        MeshError::BadFaceSize {
            face: 0,
            sides: 2,
            line: Some(3)
        }
    );
}

#[test]
fn empty_files_in_every_format() {
    let empty = MeshError::Empty {
        vertices: 0,
        faces: 0,
    };
    assert_eq!(obj("").unwrap_err(), empty);
    assert_eq!(obj("# only a comment\n\n").unwrap_err(), empty);
    assert_eq!(off("").unwrap_err(), empty);
    assert_eq!(off("OFF\n0 0 0\n").unwrap_err(), empty);
    assert_eq!(
        obj("v 0 0 0\n").unwrap_err(),
        MeshError::Empty {
            vertices: 1,
            faces: 0
        }
    );
    assert!(matches!(
        ply(b"").unwrap_err(),
        MeshError::Parse { format: "PLY", .. }
    ));
    let header_only = "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n";
    assert_eq!(ply(header_only.as_bytes()).unwrap_err(), empty);
}

fn tetra() -> Mesh {
    obj(TETRA_OBJ).unwrap().mesh
}

/// Replaces the first occurrence of `from` in the PLY header.
fn patch_header(bytes: &[u8], from: &str, to: &str) -> Vec<u8> {
    let end = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .unwrap()
        + 11;
    let header = String::from_utf8(bytes[..end].to_vec()).unwrap();
    assert!(header.contains(from));
    let mut out = header.replacen(from, to, 1).into_bytes();
    out.extend_from_slice(&bytes[end..]);
    out
}

#[test]
fn binary_ply_with_wrong_element_counts() {
    let good = write_to_vec(&tetra(), "ply-le");
    assert!(ply(&good).is_ok());

    // One vertex too many: 5 × 24 bytes of vertices + 4 faces of at least
    // 1 + 3 × 4 bytes (a face needs three vertices) = 172 > 148 that follow.
    // (Without the three-vertex bound, the fifth vertex would eat 24 bytes
    // of face data and the rest would decode as a face of size 0.)
    let e = ply(&patch_header(&good, "element vertex 4", "element vertex 5")).unwrap_err();
    match &e {
        MeshError::Parse {
            format: "PLY",
            message,
            ..
        } => assert!(
            message.contains("5 'vertex' and 4 'face' elements")
                && message.contains("172 bytes")
                && message.contains("148 bytes"),
            "{message}"
        ),
        other => panic!("{other:?}"),
    }
    // Two vertices too many: now the faces do not fit in what follows.
    let e = ply(&patch_header(&good, "element vertex 4", "element vertex 6")).unwrap_err();
    match &e {
        MeshError::Parse {
            format: "PLY",
            message,
            ..
        } => assert!(
            message.contains("4 'face' elements") || message.contains("ends inside"),
            "{message}"
        ),
        other => panic!("{other:?}"),
    }

    // One vertex too few: the last vertex's bytes are read as faces.
    let e = ply(&patch_header(&good, "element vertex 4", "element vertex 3")).unwrap_err();
    assert!(
        matches!(
            e,
            MeshError::Parse { format: "PLY", .. }
                | MeshError::IndexOutOfRange { .. }
                | MeshError::BadFaceSize { .. }
        ),
        "{e:?}"
    );

    // One face too few: 13 bytes are left over.
    match ply(&patch_header(&good, "element face 4", "element face 3")).unwrap_err() {
        MeshError::Parse { message, .. } => {
            assert!(
                message.contains("13 bytes of data follow the last element"),
                "{message}"
            )
        }
        other => panic!("{other:?}"),
    }

    // One face too many: the data ends inside face 4.
    match ply(&patch_header(&good, "element face 4", "element face 5")).unwrap_err() {
        MeshError::Parse { message, .. } => assert!(
            message.contains("'face' elements") || message.contains("ends inside 'face' element 4"),
            "{message}"
        ),
        other => panic!("{other:?}"),
    }

    // Truncated payload.
    match ply(&good[..good.len() - 5]).unwrap_err() {
        MeshError::Parse { message, .. } => assert!(message.contains("face"), "{message}"),
        other => panic!("{other:?}"),
    }
}

#[test]
fn ply_header_claiming_a_trillion_vertices_is_refused_before_allocating() {
    for encoding in ["ascii", "binary_little_endian", "binary_big_endian"] {
        let text = format!(
            "ply\nformat {encoding} 1.0\nelement vertex 1000000000000\nproperty double x\nproperty double y\nproperty double z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n"
        );
        match ply(text.as_bytes()).unwrap_err() {
            MeshError::Parse {
                format: "PLY",
                line: Some(3),
                message,
            } => assert!(
                message.contains("1000000000000 'vertex' elements"),
                "{message}"
            ),
            other => panic!("{encoding}: {other:?}"),
        }
    }
    // A huge element we would skip is refused the same way.
    let text = "ply\nformat binary_little_endian 1.0\nelement junk 99999999999999\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n";
    match ply(text.as_bytes()).unwrap_err() {
        MeshError::Parse { line, message, .. } => {
            assert_eq!(line, Some(3));
            assert!(message.contains("99999999999999 'junk'"), "{message}");
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn ply_header_problems() {
    let base = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    assert!(ply(base.as_bytes()).is_ok());
    let cases = [
        ("property float z\n", "", "no property 'z'"),
        (
            "element face 1\nproperty list uchar int vertex_indices\n",
            "",
            "no 'face' element",
        ),
        (
            "property list uchar int vertex_indices",
            "property list uchar float vertex_indices",
            "expected a list of integers",
        ),
        (
            "property list uchar int vertex_indices",
            "property list uchar int other",
            "no list property 'vertex_indices'",
        ),
        ("format ascii 1.0", "format ascii", "ormat"),
        ("ply\n", "plx\n", "magic"),
    ];
    for (from, to, needle) in cases {
        let text = base.replacen(from, to, 1);
        match ply(text.as_bytes()) {
            Err(MeshError::Parse {
                format: "PLY",
                message,
                ..
            }) => {
                assert!(
                    message.to_lowercase().contains(&needle.to_lowercase()),
                    "{from:?}: {message}"
                )
            }
            other => panic!("{from:?}: {other:?}"),
        }
    }
    // ASCII payload errors name the line.
    let bad = base.replacen("1 0 0\n", "1 zz 0\n", 1);
    assert!(matches!(
        ply(bad.as_bytes()),
        Err(MeshError::Parse { line: Some(11), .. })
    ));
    let bad = base.replacen("3 0 1 2\n", "3 0 1 7\n", 1);
    assert_eq!(
        ply(bad.as_bytes()).unwrap_err(),
        MeshError::IndexOutOfRange {
            face: 0,
            index: 7,
            vertex_count: 3,
            line: Some(13)
        }
    );
    let bad = base.replacen("3 0 1 2\n", "3 0 -1 2\n", 1);
    assert!(matches!(
        ply(bad.as_bytes()),
        Err(MeshError::IndexOutOfRange {
            index: -1,
            line: Some(13),
            ..
        })
    ));
    let bad = base.replacen("3 0 1 2\n", "2 0 1\n", 1);
    assert!(matches!(
        ply(bad.as_bytes()),
        Err(MeshError::BadFaceSize {
            sides: 2,
            line: Some(13),
            ..
        })
    ));
    let bad = base.replacen("3 0 1 2\n", "3 0 1 2\n1 2 3\n", 1);
    assert!(matches!(
        ply(bad.as_bytes()),
        Err(MeshError::Parse { line: Some(14), .. })
    ));
}

#[test]
fn off_counts_larger_than_the_file() {
    let text = "OFF\n1000000 2000000 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    match off(text).unwrap_err() {
        MeshError::Parse {
            format: "OFF",
            line: Some(2),
            message,
        } => {
            assert!(
                message.contains("1000000 vertices and 2000000 faces"),
                "{message}"
            );
        }
        other => panic!("{other:?}"),
    }
    // Gzip hides the size: the reader finds out at the end of the data.
    match read_mesh_bytes(
        &gzip(text.as_bytes()),
        MeshFormat::Off,
        lse_deform::limits::MemoryBudget::default(),
    )
    .unwrap_err()
    {
        MeshError::Parse { message, .. } => {
            assert!(
                message.contains("after 4 of the 1000000 vertices"),
                "{message}"
            )
        }
        other => panic!("{other:?}"),
    }
    // Counts a little too large for the data that is there.
    match off("OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n").unwrap_err() {
        MeshError::Parse { line, message, .. } => {
            assert_eq!(line, Some(6));
            assert!(message.contains("after 1 of the 2 faces"), "{message}");
        }
        other => panic!("{other:?}"),
    }
    // Too small: data left over.
    match off("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 2 1 0\n").unwrap_err() {
        MeshError::Parse { line, message, .. } => {
            assert_eq!(line, Some(7));
            assert!(message.contains("unexpected data"), "{message}");
        }
        other => panic!("{other:?}"),
    }
    // A face line declaring more vertices than it lists.
    match off("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n99999999999 0 1 2\n").unwrap_err() {
        MeshError::Parse { line, message, .. } => {
            assert_eq!(line, Some(6));
            assert!(
                message.contains("declares 99999999999 vertices"),
                "{message}"
            );
        }
        other => panic!("{other:?}"),
    }
    // Invalid geometry is located.
    assert!(matches!(
        off("OFF\n3 1 0\n0 0 0\n1 0 0\n0 inf 0\n3 0 1 2\n").unwrap_err(),
        MeshError::NonFiniteCoordinate {
            vertex: 2,
            line: Some(5),
            ..
        }
    ));
    assert_eq!(
        off("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n").unwrap_err(),
        MeshError::IndexOutOfRange {
            face: 0,
            index: 3,
            vertex_count: 3,
            line: Some(6)
        }
    );
}

// ---------------------------------------------------------------------------
// proptests: no input makes a reader panic

/// Small valid files of every format, to be mutated.
fn seeds() -> Vec<(MeshFormat, Vec<u8>)> {
    let quad_obj =
        b"# quad\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 1\nf 1/1/1 2/2/1 3//1 4\nf -4 -1 -3\n"
            .to_vec();
    let m = generate::grid(2, 1).unwrap();
    let mut v = vec![
        (MeshFormat::Obj, quad_obj),
        (MeshFormat::Obj, write_to_vec(&m, "obj")),
    ];
    v.push((MeshFormat::Off, write_to_vec(&m, "off")));
    v.push((MeshFormat::Ply, write_to_vec(&m, "ply-ascii")));
    v.push((MeshFormat::Ply, write_to_vec(&m, "ply-le")));
    v.push((MeshFormat::Ply, write_to_vec(&m, "ply-be")));
    v
}

#[derive(Debug, Clone)]
enum Mutation {
    Set(usize, u8),
    Insert(usize, u8),
    Delete(usize),
    Truncate(usize),
    /// Sets a byte to one of the characters that keep a text file plausible.
    Plausible(usize, usize),
}

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        (any::<usize>(), any::<u8>()).prop_map(|(i, b)| Mutation::Set(i, b)),
        (any::<usize>(), any::<u8>()).prop_map(|(i, b)| Mutation::Insert(i, b)),
        any::<usize>().prop_map(Mutation::Delete),
        any::<usize>().prop_map(Mutation::Truncate),
        (any::<usize>(), any::<usize>()).prop_map(|(i, c)| Mutation::Plausible(i, c)),
    ]
}

fn apply(bytes: &mut Vec<u8>, m: &Mutation) {
    const PLAUSIBLE: &[u8] = b"0123456789 -.e/\n#fvnNaI";
    let len = bytes.len();
    if len == 0 {
        return;
    }
    match *m {
        Mutation::Set(i, b) => bytes[i % len] = b,
        Mutation::Insert(i, b) => bytes.insert(i % (len + 1), b),
        Mutation::Delete(i) => {
            bytes.remove(i % len);
        }
        Mutation::Truncate(i) => bytes.truncate(i % len),
        Mutation::Plausible(i, c) => bytes[i % len] = PLAUSIBLE[c % PLAUSIBLE.len()],
    }
}

fn check_no_panic(bytes: &[u8], format: MeshFormat) {
    // Any result is fine; a valid result must be a valid mesh.
    if let Ok(loaded) = read_mesh_bytes(bytes, format, lse_deform::limits::MemoryBudget::default())
    {
        let m = loaded.mesh;
        assert!(Mesh::new(m.positions().to_vec(), m.faces().to_vec()).is_ok());
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn arbitrary_bytes_never_panic_obj(bytes in proptest::collection::vec(any::<u8>(), 0..512)) {
        check_no_panic(&bytes, MeshFormat::Obj);
    }

    #[test]
    fn arbitrary_bytes_never_panic_off(bytes in proptest::collection::vec(any::<u8>(), 0..512)) {
        check_no_panic(&bytes, MeshFormat::Off);
    }

    #[test]
    fn arbitrary_bytes_never_panic_ply(bytes in proptest::collection::vec(any::<u8>(), 0..512)) {
        check_no_panic(&bytes, MeshFormat::Ply);
        // Also behind a valid-looking header.
        let mut with_header = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n".to_vec();
        with_header.extend_from_slice(&bytes);
        check_no_panic(&with_header, MeshFormat::Ply);
    }

    #[test]
    fn mutated_valid_files_never_panic(
        seed in 0usize..6,
        mutations in proptest::collection::vec(mutation(), 1..8),
    ) {
        let (format, mut bytes) = seeds().swap_remove(seed);
        for m in &mutations {
            apply(&mut bytes, m);
        }
        check_no_panic(&bytes, format);
        // And the same bytes gzip-compressed (another code path).
        check_no_panic(&gzip(&bytes), format);
    }
}

#[test]
fn every_seed_file_is_valid_and_every_single_truncation_is_handled() {
    for (format, bytes) in seeds() {
        assert!(
            read_mesh_bytes(&bytes, format, lse_deform::limits::MemoryBudget::default()).is_ok(),
            "{format:?}"
        );
        for cut in 0..bytes.len() {
            check_no_panic(&bytes[..cut], format);
        }
    }
}

/// A face named as of zero area for its size says its true area: a sliver
/// of edges 1 and 1e308 has area 5e307 (it was reported as "zero area
/// (0e0)": its cross product, computed on edges scaled to the longer one,
/// underflowed), and a tetrahedron of corners more than the largest
/// double apart has no face of zero area (its faces were "zero area
/// (NaN)": the edge vectors overflowed).
#[test]
fn a_degenerate_face_near_the_range_of_doubles_is_named_with_its_true_area() {
    let positions = vec![
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1e308],
    ];
    let faces = vec![[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]];
    let mesh = Mesh::new(positions, faces).unwrap();
    let e = mesh.degenerate_face().expect("the sliver is degenerate");
    let MeshError::DegenerateFace { face, area, .. } = e.clone() else {
        panic!("{e:?}");
    };
    assert_eq!(face, 1);
    assert!((area / 5e307 - 1.0).abs() < 1e-12, "{area:e}");
    let message = e.to_string();
    assert!(message.contains("area 5.000e307"), "{message}");
    assert!(!message.contains("0e0)"), "{message}");
    // Corners 3e308 apart: the edge vectors overflow a double.
    let v = 1.5e308;
    let positions = vec![[-v, 0.0, 0.0], [v, 0.0, 0.0], [0.0, v, 0.0], [0.0, 0.0, v]];
    let faces = vec![[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]];
    let mesh = Mesh::new(positions, faces).unwrap();
    assert_eq!(mesh.degenerate_face(), None);
}

#[test]
fn a_missing_mesh_file_is_an_io_error_naming_it() {
    let e = read_mesh(
        Path::new("/nonexistent/dir/m.obj"),
        lse_deform::limits::MemoryBudget::default(),
    )
    .unwrap_err();
    assert!(matches!(e, Error::Io { .. }), "{e}");
    assert!(e.to_string().contains("/nonexistent/dir/m.obj"));
}
