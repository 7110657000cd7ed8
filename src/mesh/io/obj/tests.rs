//! The OBJ reader and writer, also through the format-dispatching
//! [`read_mesh_bytes`] (gzip included). A child file of `obj`: it imports
//! `mesh::io`, which imports `obj`, so `obj` itself must not.

use std::io::Write as _;

use flate2::Compression;
use flate2::write::GzEncoder;

use super::*;
use crate::error::MeshError;
use crate::mesh::io::shared::unwrap_io;
use crate::mesh::io::{MeshFormat, read_mesh_bytes};

fn obj(text: &str) -> Result<LoadedMesh, MeshError> {
    unwrap_io(read_obj(text.as_bytes(), MemoryBudget::unlimited()))
}

fn parse_error_at(line: usize, message: &str) -> MeshError {
    MeshError::Parse {
        format: "OBJ",
        line: Some(line),
        message: message.into(),
    }
}

#[test]
fn vertex_line_parser_alone() {
    assert_eq!(
        parse_obj_vertex(tokens(b"0.5 -1 2e-3 1.0"), 3),
        Ok([0.5, -1.0, 0.002])
    );
    assert_eq!(
        parse_obj_vertex(tokens(b"0.5 -1"), 3),
        Err(parse_error_at(
            3,
            "expected 3 coordinates after 'v', found 2"
        ))
    );
    assert_eq!(
        parse_obj_vertex(tokens(b"0.5 one 2"), 3),
        Err(parse_error_at(3, "invalid number 'one'"))
    );
}

#[test]
fn index_mapping_alone() {
    assert_eq!(obj_index(1, 10, 1), Ok(0));
    assert_eq!(obj_index(10, 10, 1), Ok(9));
    assert_eq!(obj_index(-1, 10, 1), Ok(9));
    assert_eq!(obj_index(-10, 10, 1), Ok(0));
    assert_eq!(obj_index(-11, 10, 1), Ok(-1));
    assert_eq!(
        obj_index(0, 10, 6),
        Err(parse_error_at(
            6,
            "face index 0 is invalid (OBJ indices start at 1)"
        ))
    );
}

#[test]
fn face_line_parser_alone_keeps_the_vertex_of_each_corner() {
    let mut poly = Vec::new();
    let keep = |index: i64, _corner: usize| Ok(index as usize);
    parse_obj_face(tokens(b"1/4/2 2//5 -1 3/1"), 2, 5, keep, &mut poly).unwrap();
    assert_eq!(poly, [0, 1, 4, 2]);
    assert_eq!(
        parse_obj_face(tokens(b"1 x/2 3"), 2, 5, keep, &mut poly),
        Err(parse_error_at(2, "invalid face index 'x/2'"))
    );
    // Corners are numbered as read: the resolver sees 0, 1, 2.
    let mut corners = Vec::new();
    parse_obj_face(
        tokens(b"3 2 1"),
        2,
        5,
        |index, corner| {
            corners.push(corner);
            Ok(index as usize)
        },
        &mut poly,
    )
    .unwrap();
    assert_eq!((corners, poly), (vec![0, 1, 2], vec![2, 1, 0]));
}

#[test]
fn unknown_records_and_notes_alone() {
    let mut unknown = Unknown::default();
    assert_eq!(obj_notes(&unknown, false, 9), Vec::<String>::new());
    for (keyword, line) in [
        ("curv", 2),
        ("curv", 3),
        ("parm", 4),
        ("cstype", 5),
        ("deg", 6),
    ] {
        unknown.record(keyword.as_bytes(), line);
    }
    assert_eq!(
        obj_notes(&unknown, true, 9),
        [
            "ignored 5 OBJ line(s) of unsupported record types (e.g. 'curv' at line 2, 'parm' at line 4, 'cstype' at line 5)",
            "the OBJ file does not end with a newline: if it was cut off, line 9 may be incomplete",
        ]
    );
}

const TRIANGLE: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";

#[test]
fn crlf_tabs_blank_lines_and_comments_glued_to_tokens() {
    let text =
        "v 0 0 0\r\nv\t1\t0\t0\r\n#full line\r\n\r\n   \r\nv 0 1 0#glued\r\nf 1 2 3#glued\r\n";
    let loaded = obj(text).unwrap();
    assert_eq!(
        loaded.mesh.positions(),
        &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]
    );
    assert_eq!(loaded.mesh.faces(), &[[0, 1, 2]]);
    assert_eq!(loaded.notes, Vec::<String>::new());
}

#[test]
fn number_forms_and_bad_vertex_lines() {
    let text = "v +1 -2.5e1 .5\nv 5. 0 0\nv 0 1E2 0\nf 1 2 3\n";
    assert_eq!(
        obj(text).unwrap().mesh.positions(),
        &[[1.0, -25.0, 0.5], [5.0, 0.0, 0.0], [0.0, 100.0, 0.0]]
    );
    assert_eq!(
        obj("v 1 2\n").unwrap_err(),
        parse_error_at(1, "expected 3 coordinates after 'v', found 2")
    );
    assert_eq!(
        obj("v 0 0 0\nv 1,5 0 0\n").unwrap_err(),
        parse_error_at(2, "invalid number '1,5'")
    );
    assert_eq!(
        obj("v 0 0 0\nv 0 0 -inf\n").unwrap_err(),
        MeshError::NonFiniteCoordinate {
            vertex: 1,
            value: f64::NEG_INFINITY,
            line: Some(2),
        }
    );
}

#[test]
fn texture_and_normal_indices_are_not_read() {
    // Only the part before the first '/' is parsed: a texture index of
    // 999 or a normal index 'abc' is not checked.
    let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/999/abc 2/x 3//\n";
    assert_eq!(obj(text).unwrap().mesh.faces(), &[[0, 1, 2]]);
    assert_eq!(
        obj("v 0 0 0\nf /1/1 1 1\n").unwrap_err(),
        parse_error_at(2, "invalid face index '/1/1'")
    );
}

#[test]
fn relative_indices_count_back_from_the_vertices_read_so_far() {
    // After 3 vertices, -3 -2 -1 are 0 1 2; after 4, -3 is 1, -1 is 3,
    // -2 is 2; absolute and relative indices mix in one face.
    let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\nv 1 1 0\nf -3 -1 3\n";
    assert_eq!(obj(text).unwrap().mesh.faces(), &[[0, 1, 2], [1, 3, 2]]);
}

#[test]
fn out_of_range_indices_name_the_face_and_the_line() {
    // A relative index before the first vertex: 4 − 9 = −5, in corner 4
    // of a pentagon after one face, i.e. in its third triangle (face 3).
    let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 1 2 3 4 -9\n";
    assert_eq!(
        obj(text).unwrap_err(),
        MeshError::IndexOutOfRange {
            face: 3,
            index: -5,
            vertex_count: 4,
            line: Some(6),
        }
    );
    // Too large an absolute index is caught when the mesh is built, with
    // the line of its face (0-based index 3 of 3 vertices).
    assert_eq!(
        obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n").unwrap_err(),
        MeshError::IndexOutOfRange {
            face: 0,
            index: 3,
            vertex_count: 3,
            line: Some(4),
        }
    );
    assert_eq!(
        obj("v 0 0 0\nf 1 2 99999999999999999999\n").unwrap_err(),
        parse_error_at(2, "invalid face index '99999999999999999999'")
    );
    assert_eq!(
        obj("v 0 0 0\nf\n").unwrap_err(),
        MeshError::BadFaceSize {
            face: 0,
            sides: 0,
            line: Some(2),
        }
    );
}

#[test]
fn polygons_are_fanned_from_their_first_vertex_with_a_note() {
    // A unit square (1 2 3 4) and a pentagon (2 5 6 7 3) sharing the
    // edge 2–3.
    let text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\nv 2.5 0.5 0\nv 2 1 0\n\
                f 1 2 3 4\nf 2 5 6 7 3\n";
    let loaded = obj(text).unwrap();
    assert_eq!(
        loaded.mesh.faces(),
        &[[0, 1, 2], [0, 2, 3], [1, 4, 5], [1, 5, 6], [1, 6, 2]]
    );
    assert_eq!(
        loaded.notes,
        vec![
            "2 OBJ polygon(s) with more than 3 vertices were fan-triangulated into 5 triangles"
                .to_string()
        ]
    );
}

#[test]
fn unknown_records_are_counted_and_three_kinds_named() {
    let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\ncurv 1\ncurv 2\nvn 0 0 1\nparm u 0\nl 1 2\ndeg 3\nbmat u\nf 1 2 3\n";
    assert_eq!(
        obj(text).unwrap().notes,
        vec![
            "ignored 5 OBJ line(s) of unsupported record types (e.g. 'curv' at line 4, 'parm' at line 7, 'deg' at line 9)"
                .to_string()
        ]
    );
}

#[test]
fn missing_final_newline_note_names_the_last_line() {
    let note = |l: usize| {
        format!(
            "the OBJ file does not end with a newline: if it was cut off, line {l} may be incomplete"
        )
    };
    assert_eq!(obj(TRIANGLE.trim_end()).unwrap().notes, vec![note(4)]);
    assert_eq!(
        obj(&format!("{TRIANGLE}# end")).unwrap().notes,
        vec![note(5)]
    );
}

#[test]
fn gzip_including_several_members_is_read_by_content() {
    let gz = |part: &str| {
        let mut e = GzEncoder::new(Vec::new(), Compression::default());
        e.write_all(part.as_bytes()).unwrap();
        e.finish().unwrap()
    };
    let expected_positions = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    let one = read_mesh_bytes(
        &gz(TRIANGLE),
        MeshFormat::Obj,
        crate::limits::MemoryBudget::default(),
    )
    .unwrap();
    assert_eq!(one.mesh.positions(), &expected_positions);
    assert_eq!(one.mesh.faces(), &[[0, 1, 2]]);
    // Two concatenated gzip members (as `cat a.gz b.gz` makes) are one
    // stream; the cut falls inside a line.
    let mut two = gz("v 0 0 0\nv 1 0 ");
    two.extend(gz("0\nv 0 1 0\nf 1 2 3\n"));
    let two = read_mesh_bytes(
        &two,
        MeshFormat::Obj,
        crate::limits::MemoryBudget::default(),
    )
    .unwrap();
    assert_eq!(two.mesh.positions(), &expected_positions);
    assert_eq!(two.mesh.faces(), &[[0, 1, 2]]);
    // A gzip stream cut short is a parse error, not a shorter mesh.
    let whole = gz(TRIANGLE);
    let cut = &whole[..whole.len() - 8];
    assert!(matches!(
        read_mesh_bytes(cut, MeshFormat::Obj, crate::limits::MemoryBudget::default()),
        Err(MeshError::Parse {
            format: "OBJ",
            line: None,
            ..
        })
    ));
}

fn awkward_triangle() -> Mesh {
    Mesh::new(
        vec![
            [0.1, -0.0, 1e21],
            [1.0, 0.30000000000000004, -3.0],
            [1e-7, 0.0, 123456789.0],
        ],
        vec![[0, 1, 2]],
    )
    .unwrap()
}

#[test]
fn writer_text_is_one_based_shortest_round_trip_decimal() {
    let mut out = Vec::new();
    write_obj(&awkward_triangle(), &mut out).unwrap();
    assert_eq!(
        String::from_utf8(out).unwrap(),
        "# written by lse-deform: 3 vertices, 1 faces\n\
         v 0.1 -0 1000000000000000000000\n\
         v 1 0.30000000000000004 -3\n\
         v 0.0000001 0 123456789\n\
         f 1 2 3\n"
    );
}

#[test]
fn write_then_read_is_bit_identical() {
    let mut out = Vec::new();
    write_obj(&awkward_triangle(), &mut out).unwrap();
    let back = unwrap_io(read_obj(&out[..], MemoryBudget::unlimited())).unwrap();
    assert_eq!(back.notes, Vec::<String>::new());
    assert_eq!(back.mesh.faces(), &[[0, 1, 2]]);
    let bits: Vec<[u64; 3]> = back
        .mesh
        .positions()
        .iter()
        .map(|p| p.map(f64::to_bits))
        .collect();
    // -0.0 keeps its sign bit; 0.1 + 0.2 keeps its last ulp.
    let expected: Vec<[u64; 3]> = [
        [0.1, -0.0, 1e21],
        [1.0, 0.30000000000000004, -3.0],
        [1e-7, 0.0, 123456789.0],
    ]
    .iter()
    .map(|p| p.map(f64::to_bits))
    .collect();
    assert_eq!(bits, expected);
    assert_eq!(bits[0][1], 1 << 63);
}
