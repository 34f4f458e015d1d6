//! Tests of `src/mesh/order.rs`.

use destair::mesh::order::*;
use destair::mesh::Mesh;

#[test]
fn spread_puts_two_zero_bits_after_each_bit() {
    assert_eq!(spread(0b1), 0b1);
    assert_eq!(spread(0b11), 0b1001);
    assert_eq!(spread(0b101), 0b1_000_001);
    // Bit 20 goes to bit 60; higher bits are dropped.
    assert_eq!(spread(1 << 20), 1 << 60);
    assert_eq!(spread(1 << 21), 0);
}

#[test]
fn reordering_keeps_every_face_and_follows_the_curve() {
    // A 2 x 2 grid of quads written in a scattered vertex order.
    let positions = vec![
        [2.0, 2.0, 0.0],
        [0.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [2.0, 0.0, 0.0],
        [0.0, 2.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [2.0, 1.0, 0.0],
        [1.0, 2.0, 0.0],
    ];
    let at = |x: f32, y: f32| {
        positions
            .iter()
            .position(|p| p[0] == x && p[1] == y)
            .unwrap() as u32
    };
    let mut triangles = Vec::new();
    for (x, y) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)] {
        triangles.push([at(x, y), at(x + 1.0, y), at(x + 1.0, y + 1.0)]);
        triangles.push([at(x, y), at(x + 1.0, y + 1.0), at(x, y + 1.0)]);
    }
    let mesh = Mesh::new(positions.clone(), triangles.clone()).unwrap();
    let (ordered, face_order) = locality_ordered(&mesh);
    // Z-order over the 3 x 3 grid: (0,0) (1,0) (0,1) (1,1) first.
    let q = ordered.positions();
    assert_eq!(
        &q[..4],
        &[
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [1.0, 1.0, 0.0]
        ]
    );
    // Every new face is the old face it says it was, corner for corner.
    let mut seen = vec![false; triangles.len()];
    for (t, &f) in ordered.triangles().iter().zip(&face_order) {
        let old = triangles[f as usize].map(|v| positions[v as usize]);
        assert_eq!(t.map(|v| q[v as usize]), old);
        seen[f as usize] = true;
    }
    assert!(seen.iter().all(|&s| s));
    // Faces come in order of their smallest vertex.
    let firsts: Vec<u32> = ordered
        .triangles()
        .iter()
        .map(|t| *t.iter().min().unwrap())
        .collect();
    assert!(firsts.windows(2).all(|w| w[0] <= w[1]));
}

#[test]
fn scanline_renumbers_a_scattered_torus_and_keeps_every_neighbour_list() {
    let torus = destair::bench::torus(300, 200);
    let t = destair::mesh::Topology::build(&torus);
    assert!(!is_scattered(t.neighbor_csr().0, t.neighbor_csr().1));
    let mesh = destair::bench::shuffled(&torus, 9);
    let topology = destair::mesh::Topology::build(&mesh);
    let (offsets, neighbors) = topology.neighbor_csr();
    assert!(is_scattered(offsets, neighbors));
    let r = scanline(mesh.positions(), offsets, neighbors);
    // A permutation, and `new` is its inverse.
    let mut seen = vec![false; mesh.n_vertices()];
    for (i, &v) in r.old.iter().enumerate() {
        assert!(!seen[v as usize]);
        seen[v as usize] = true;
        assert_eq!(r.new[v as usize], i as u32);
    }
    assert_eq!(r.old.len(), mesh.n_vertices());
    // The adjacency in the new numbering is no longer scattered.
    let (mut o2, mut n2) = (vec![0u32], Vec::new());
    for &v in &r.old {
        let list = &neighbors[offsets[v as usize] as usize..offsets[v as usize + 1] as usize];
        n2.extend(list.iter().map(|&w| r.new[w as usize]));
        o2.push(n2.len() as u32);
    }
    assert!(!is_scattered(&o2, &n2));
    // Gathering then scattering gives the values back.
    let values: Vec<u32> = (0..mesh.n_vertices() as u32).map(|v| v * 7).collect();
    assert_eq!(r.scatter(&r.gather(&values)), values);
}

#[test]
fn working_numbering_is_read_from_the_faces_and_restores_to_the_bit() {
    let torus = destair::bench::torus(300, 200);
    assert!(!faces_scattered(torus.triangles()));
    assert!(working_numbering(&torus).is_none());
    for seed in [1, 9] {
        let mesh = destair::bench::shuffled(&torus, seed);
        let topology = destair::mesh::Topology::build(&mesh);
        let (offsets, neighbors) = topology.neighbor_csr();
        // The faces tell what the adjacency tells.
        assert_eq!(
            faces_scattered(mesh.triangles()),
            is_scattered(offsets, neighbors)
        );
        let r = working_numbering(&mesh).expect("a shuffled torus is scattered");
        assert!(face_order_scattered(mesh.triangles(), Some(&r.new)));
        let worked = r.mesh(&mesh);
        assert!(!faces_scattered(worked.triangles()));
        assert!(!face_order_scattered(worked.triangles(), None));
        // Working face i is the file's face file_index[i] renumbered, turned to start at its
        // smallest vertex, each vertex where it was.
        let faces = r.faces.as_ref().expect("shuffled faces are sorted");
        assert_eq!(faces.working(), worked.triangles());
        for (&f, u) in faces.file_index.iter().zip(worked.triangles()) {
            let t = mesh.triangles()[f as usize];
            assert!(u[0] < u[1] && u[0] < u[2]);
            let turn = (0..3).find(|&k| r.old[u[0] as usize] == t[k]).unwrap();
            for k in 0..3 {
                let file_vertex = t[(turn + k) % 3];
                assert_eq!(r.old[u[k] as usize], file_vertex);
                assert_eq!(
                    worked.positions()[u[k] as usize],
                    mesh.positions()[file_vertex as usize]
                );
            }
        }
        let back = r.restore(&worked);
        assert_eq!(back.positions(), mesh.positions());
        assert_eq!(back.triangles(), mesh.triangles());
    }
    // Degenerate inputs do not panic.
    assert!(working_numbering(&Mesh::default()).is_none());
}

/// A file whose vertices are numbered locally but whose faces are listed in a random order
/// keeps its numbering and has its faces sorted by their smallest vertex, each face turning
/// the way it did; the working faces do not depend on the order the faces came in nor on the
/// corner each starts at, and restoring gives the file's faces back to the bit.
#[test]
fn shuffled_faces_are_sorted_by_vertex_whatever_their_order() {
    // 180 K vertices: two random faces' smallest vertices are mostly over 32,768 apart.
    let torus = destair::bench::torus(600, 300);
    let listed = |seed| {
        destair::bench::relisted(
            &torus,
            &destair::bench::permutation(torus.n_triangles(), seed),
        )
    };
    let mut worked_once: Option<Mesh> = None;
    for seed in [4, 5] {
        let mut mesh = listed(seed);
        if seed == 5 {
            // Each face starting at another corner.
            let turned = mesh.triangles().iter().enumerate().map(|(f, t)| {
                let k = f % 3;
                [t[k], t[(k + 1) % 3], t[(k + 2) % 3]]
            });
            mesh = Mesh::new(mesh.positions().to_vec(), turned.collect()).unwrap();
        }
        assert!(!faces_scattered(mesh.triangles()));
        assert!(face_order_scattered(mesh.triangles(), None));
        let r = working_numbering(&mesh).expect("scattered faces");
        assert!(r.old.iter().enumerate().all(|(i, &v)| v == i as u32));
        let worked = r.mesh(&mesh);
        assert_eq!(worked.positions(), mesh.positions());
        let smallest: Vec<u32> = (worked.triangles().iter())
            .map(|t| *t.iter().min().unwrap())
            .collect();
        assert!(smallest.windows(2).all(|w| w[0] <= w[1]));
        // The same faces, the same way round: each the file's, turned to start at its smallest
        // vertex.
        let faces = r.faces.as_ref().unwrap();
        for (&f, u) in faces.file_index.iter().zip(worked.triangles()) {
            let t = mesh.triangles()[f as usize];
            assert!(u[0] < u[1] && u[0] < u[2]);
            assert!((0..3).any(|k| [t[k], t[(k + 1) % 3], t[(k + 2) % 3]] == *u));
        }
        if let Some(first) = &worked_once {
            assert!(first == &worked, "the working order depends on the file's");
        }
        let back = r.restore(&worked);
        assert!(back.triangles() == mesh.triangles());
        worked_once = Some(worked);
    }
    // The torus as generated lists neighbouring faces together.
    assert!(!face_order_scattered(torus.triangles(), None));
    assert!(working_numbering(&torus).is_none());
}
