//! `lse-deform render`: the PNG a user gets for their own result.

use std::path::Path;

mod common;
use common::{path_in, run, stderr};

/// Width, height and RGB pixels of a PNG.
fn read_png(path: &str) -> (u32, u32, Vec<[u8; 3]>) {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!(info.color_type, png::ColorType::Rgb);
    let pixels = buf[..info.buffer_size()]
        .chunks(3)
        .map(|c| [c[0], c[1], c[2]])
        .collect();
    (info.width, info.height, pixels)
}

/// A sphere, the tool's scene on it (fixed bottom, handle dragged at the
/// top) and the deformed mesh.
fn deformed_sphere(dir: &Path) -> (String, String, String) {
    let mesh = path_in(dir, "sphere.obj");
    let o = run(&["generate", "icosphere", "--vertices", "600", "-o", &mesh]);
    assert!(o.status.success(), "{}", stderr(&o));
    let scene = path_in(dir, "scene.json");
    let o = run(&["scene", &mesh, "-o", &scene]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = path_in(dir, "deformed.obj");
    let o = run(&["deform", &mesh, "-c", &scene, "-o", &out]);
    assert!(o.status.success(), "{}", stderr(&o));
    (mesh, scene, out)
}

const WHITE: [u8; 3] = [255, 255, 255];

/// Every pixel of the outermost row and column is background.
fn border_is_background(w: u32, h: u32, px: &[[u8; 3]]) -> bool {
    (0..w).all(|x| px[x as usize] == WHITE && px[((h - 1) * w + x) as usize] == WHITE)
        && (0..h).all(|y| px[(y * w) as usize] == WHITE && px[(y * w + w - 1) as usize] == WHITE)
}

#[test]
fn ghost_displacement_map_and_framing() {
    let dir = tempfile::tempdir().unwrap();
    let (mesh, scene, deformed) = deformed_sphere(dir.path());
    let with_ghost = path_in(dir.path(), "ghost.png");
    let args = [
        "render",
        &mesh,
        &deformed,
        "--constraints",
        &scene,
        "--size",
        "320x260",
        "-o",
    ];
    let o = run(&[&args[..], &[&with_ghost]].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    let (w, h, ghost) = read_png(&with_ghost);
    assert_eq!((w, h), (320, 260));
    assert!(
        border_is_background(w, h, &ghost),
        "the mesh is framed inside"
    );
    let no_ghost = path_in(dir.path(), "plain.png");
    let o = run(&[&args[..], &[&no_ghost, "--no-ghost"]].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    let (_, _, plain) = read_png(&no_ghost);
    // Where the original stood and the deformed mesh does not, the ghost
    // tints the background blue.
    let tinted = ghost
        .iter()
        .zip(&plain)
        .filter(|(g, q)| **q == WHITE && g[2] as i32 > g[0] as i32 + 20)
        .count();
    assert!(tinted > 50, "ghost pixels over the background: {tinted}");
    // Constraint groups are drawn in the group colour (red for "fixed").
    assert!(plain.iter().any(|c| c[0] > 150 && c[1] < 60 && c[2] < 60));

    let map = path_in(dir.path(), "map.png");
    let o = run(&[
        "render",
        &mesh,
        &deformed,
        "--color",
        "displacement",
        "--no-ghost",
        "--size",
        "300x300",
        "-o",
        &map,
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (w, h, px) = read_png(&map);
    assert_eq!((w, h), (300, 300));
    // Viridis: the handle region (largest displacement) shaded yellow, the
    // fixed region (none) shaded purple, and both ends in the legend bar.
    let yellow = |c: &[u8; 3]| c[0] > 80 && c[1] > 100 && c[2] < 80;
    let purple = |c: &[u8; 3]| c[2] as i32 > c[1] as i32 + 30 && c[0] > c[1];
    let above_legend = &px[..(w * (h - 64)) as usize];
    assert!(above_legend.iter().any(yellow) && above_legend.iter().any(purple));
    assert!(border_is_background(w, h, &px));
}

#[test]
fn a_difference_map_between_two_deformations() {
    let dir = tempfile::tempdir().unwrap();
    let (mesh, scene, exact) = deformed_sphere(dir.path());
    let soft = path_in(dir.path(), "penalty.obj");
    let o = run(&[
        "deform", &mesh, "-c", &scene, "--method", "penalty", "--weight", "10", "-o", &soft,
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = path_in(dir.path(), "diff.png");
    let o = run(&[
        "render",
        &mesh,
        &soft,
        "--color",
        "difference",
        "--against",
        &exact,
        "--size",
        "240x240",
        "-o",
        &out,
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (w, h, _) = read_png(&out);
    assert_eq!((w, h), (240, 240));
}

#[test]
fn bad_inputs_are_one_line_errors_with_exit_code_2() {
    let dir = tempfile::tempdir().unwrap();
    let (mesh, _, deformed) = deformed_sphere(dir.path());
    let other = path_in(dir.path(), "grid.obj");
    let o = run(&["generate", "grid", "--vertices", "100", "-o", &other]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = path_in(dir.path(), "x.png");
    let missing = path_in(dir.path(), "missing.obj");
    let jpg = path_in(dir.path(), "x.jpg");
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (
            vec![&mesh, &other, "-o", &out],
            "vertices, but the mesh has",
        ),
        (vec![&missing, "-o", &out], "missing.obj"),
        (vec![&mesh, "--size", "0x10", "-o", &out], "WIDTHxHEIGHT"),
        (vec![&mesh, "--size", "big", "-o", &out], "WIDTHxHEIGHT"),
        (vec![&mesh, "--size", "9000x100", "-o", &out], "invalid"),
        (
            vec![&mesh, &deformed, "--size", "100x50", "-o", &out],
            "no room",
        ),
        (
            vec![&mesh, "--color", "displacement", "-o", &out],
            "needs a DEFORMED",
        ),
        (
            vec![&mesh, &deformed, "--color", "difference", "-o", &out],
            "--against",
        ),
        (vec![&mesh, "--elevation", "95", "-o", &out], "elevation"),
        (vec![&mesh, "-o", &jpg], ".png"),
    ];
    for (args, needle) in cases {
        let o = run(&[&["render"][..], &args].concat());
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {e}");
        assert!(e.contains(needle), "{args:?}: expected '{needle}' in {e}");
        assert!(!e.contains("panicked"), "{e}");
    }
    assert!(!Path::new(&out).exists());
}

/// `deform` pulls the three corners of a face to one point: the mesh it
/// writes has faces of zero area. It reads back (with a warning naming
/// them), renders (alone and over the original), and deforms again with the
/// uniform Laplacian; as the rest shape of the cotangent Laplacian it is
/// refused naming the face and why. (Before, every reader refused it.)
#[test]
fn a_deformation_that_collapses_a_face_renders_and_reads_back() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = path_in(dir.path(), "grid.obj");
    let o = run(&["generate", "grid", "--vertices", "100", "-o", &mesh]);
    assert!(o.status.success(), "{}", stderr(&o));
    let first = lse_deform::mesh::read_mesh(
        Path::new(&mesh),
        lse_deform::limits::MemoryBudget::default(),
    )
    .unwrap()
    .mesh
    .faces()[0];
    let last = lse_deform::mesh::read_mesh(
        Path::new(&mesh),
        lse_deform::limits::MemoryBudget::default(),
    )
    .unwrap()
    .mesh
    .n_vertices()
        - 1;
    let mut constraints: Vec<String> = first
        .iter()
        .map(|v| format!(r#"{{"type": "position", "vertex": {v}, "target": [0.5, 0.5, 0]}}"#))
        .collect();
    constraints.push(format!(
        r#"{{"type": "position", "vertex": {last}, "target": [1, 1, 0]}}"#
    ));
    let scene = path_in(dir.path(), "collapse.json");
    std::fs::write(
        &scene,
        format!(r#"{{"constraints": [{}]}}"#, constraints.join(", ")),
    )
    .unwrap();
    let collapsed = path_in(dir.path(), "collapsed.obj");
    let o = run(&["deform", &mesh, "-c", &scene, "-o", &collapsed]);
    assert!(o.status.success(), "{}", stderr(&o));

    // Read back: a warning, not an error.
    let loaded = lse_deform::mesh::read_mesh(
        Path::new(&collapsed),
        lse_deform::limits::MemoryBudget::default(),
    )
    .unwrap();
    let warnings: Vec<String> = loaded
        .mesh
        .warnings()
        .iter()
        .map(|w| w.to_string())
        .collect();
    assert!(
        warnings
            .iter()
            .any(|w| w.contains("zero area") && w.contains("face 0")),
        "{warnings:?}"
    );

    // Rendered, alone and as a deformation of the original.
    for args in [
        vec!["render", collapsed.as_str()],
        vec!["render", mesh.as_str(), collapsed.as_str()],
    ] {
        let png = path_in(dir.path(), "c.png");
        let _ = std::fs::remove_file(&png);
        let o = run(&[args.as_slice(), &["-o", &png]].concat());
        assert!(o.status.success(), "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).contains("zero area"), "{}", stderr(&o));
        let (w, h, px) = read_png(&png);
        assert!(w > 0 && h > 0 && px.iter().any(|&c| c != WHITE));
    }

    // Deformed again: the uniform Laplacian takes it; the cotangent one
    // names the face.
    let again = path_in(dir.path(), "again.obj");
    let o = run(&[
        "deform",
        &collapsed,
        "-c",
        &scene,
        "--laplacian",
        "uniform",
        "-o",
        &again,
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = run(&["deform", &collapsed, "-c", &scene, "-o", &again]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let error = stderr(&o);
    assert!(
        error.contains("error: face 0 (vertices") && error.contains("cotangent"),
        "{error}"
    );
}
