use lse_deform::constraints::*;
use lse_deform::*;
fn grid(nx: usize, ny: usize) -> Mesh {
    let mut p = vec![];
    let mut f = vec![];
    for j in 0..=ny {
        for i in 0..=nx {
            p.push([i as f64 / nx as f64, j as f64 / ny as f64, 0.0]);
        }
    }
    let id = |i: usize, j: usize| j * (nx + 1) + i;
    for j in 0..ny {
        for i in 0..nx {
            f.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            f.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    Mesh::new(p, f).unwrap()
}
fn main() {
    let mesh = grid(20, 20);
    let n = mesh.n_vertices();
    let mut cs = ConstraintSet::new();
    for v in 0..21 {
        let p = mesh.positions()[v];
        cs.push(Constraint::hard(ConstraintKind::Position {
            vertex: v,
            target: p,
        }))
        .unwrap();
    }
    for v in n - 21..n {
        let p = mesh.positions()[v];
        cs.push(Constraint::hard(ConstraintKind::Position {
            vertex: v,
            target: [p[0], p[1], 0.3],
        }))
        .unwrap();
    }
    // duplicate and conflict, relative, edge, face
    cs.push(Constraint::hard(ConstraintKind::Position {
        vertex: 3,
        target: mesh.positions()[3],
    }))
    .unwrap();
    cs.push(Constraint::hard(ConstraintKind::Position {
        vertex: 4,
        target: [9.0, 9.0, 9.0],
    }))
    .unwrap();
    cs.push(Constraint::hard(ConstraintKind::Relative {
        vertices: [200, 201],
        vector: [-0.05, 0.0, 0.0],
    }))
    .unwrap();
    cs.push(Constraint::hard(ConstraintKind::Edge {
        vertices: [150, 151],
        t: 0.3,
        target: [0.5, 0.4, 0.1],
    }))
    .unwrap();
    cs.push(Constraint::hard(ConstraintKind::Face {
        vertices: [100, 101, 122],
        barycentric: [0.2, 0.3],
        target: [0.3, 0.3, 0.05],
    }))
    .unwrap();
    cs.push(Constraint::soft(
        ConstraintKind::Position {
            vertex: 300,
            target: [0.6, 0.6, 0.2],
        },
        10.0,
    ))
    .unwrap();
    for kind in [
        LaplacianKind::Uniform,
        LaplacianKind::Cotangent,
        LaplacianKind::CotangentSymmetric,
    ] {
        let mut d = Deformer::new(mesh.clone(), kind, cs.clone()).unwrap();
        d.precompute(&NullSpaceQr::default()).unwrap();
        let s = d.solve().unwrap();
        println!("{kind}: {}", serde_json::to_string(&s.report).unwrap());
        println!("p220 = {:?}", s.positions[220]);
    }
}
