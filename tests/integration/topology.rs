//! Topology against a brute-force reference on random triangle sets (non-manifold, flipped,
//! degenerate and unreferenced cases included), and identical results for 1 to 4 threads.

use destair::mesh::topology::BoundaryLoop;
use destair::{Mesh, Topology};
use std::collections::{BTreeMap, BTreeSet};

fn random_mesh(rng: &mut fastrand::Rng) -> Mesh {
    let n = rng.usize(1..12);
    let positions = (0..n).map(|_| [rng.f32(), rng.f32(), rng.f32()]).collect();
    let triangles = (0..rng.usize(0..20))
        .map(|_| {
            [
                rng.u32(..n as u32),
                rng.u32(..n as u32),
                rng.u32(..n as u32),
            ]
        })
        .collect();
    Mesh::new(positions, triangles).unwrap()
}

/// Fans at a vertex by flood fill over its faces that share an edge at that vertex.
fn brute_fans(faces: &[[u32; 3]], v: u32) -> usize {
    let mut seen = vec![false; faces.len()];
    let mut fans = 0;
    for s in 0..faces.len() {
        if seen[s] {
            continue;
        }
        fans += 1;
        let mut stack = vec![s];
        seen[s] = true;
        while let Some(f) = stack.pop() {
            for g in 0..faces.len() {
                let shared = faces[f]
                    .iter()
                    .filter(|&&u| u != v && faces[g].contains(&u))
                    .count();
                if !seen[g] && shared > 0 {
                    seen[g] = true;
                    stack.push(g);
                }
            }
        }
    }
    fans
}

/// Every finding of `Topology::build` against sets and maps built from the triangles directly.
fn assert_matches_brute_force(mesh: &Mesh) {
    let topo = Topology::build(mesh);
    let valid = |t: &[u32; 3]| t[0] != t[1] && t[1] != t[2] && t[0] != t[2];
    let tris: Vec<[u32; 3]> = mesh.triangles().iter().copied().filter(valid).collect();
    // Edge -> (faces walking lo->hi, faces walking hi->lo).
    let mut edges: BTreeMap<[u32; 2], (u32, u32)> = BTreeMap::new();
    for t in &tris {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            let e = edges.entry([a.min(b), a.max(b)]).or_default();
            if a < b {
                e.0 += 1
            } else {
                e.1 += 1
            }
        }
    }
    let keys: Vec<[u32; 2]> = edges.keys().copied().collect();
    assert_eq!(topo.n_edges(), keys.len());
    assert_eq!(topo.edges(), keys.as_slice());
    let counts: Vec<u32> = edges.values().map(|(a, b)| a + b).collect();
    assert_eq!(topo.edge_n_faces(), counts.as_slice());
    let inconsistent: Vec<u32> = edges
        .values()
        .enumerate()
        .filter(|(_, (a, b))| a + b == 2 && (*a == 2 || *b == 2))
        .map(|(i, _)| i as u32)
        .collect();
    assert_eq!(topo.inconsistent_edges(), inconsistent.as_slice());
    let non_manifold: Vec<u32> = counts
        .iter()
        .enumerate()
        .filter(|(_, &c)| c > 2)
        .map(|(i, _)| i as u32)
        .collect();
    assert_eq!(topo.non_manifold_edges(), non_manifold.as_slice());
    let mut irregular = vec![false; mesh.n_vertices()];
    for (&[a, b], &c) in keys.iter().zip(&counts) {
        if c != 2 {
            irregular[a as usize] = true;
            irregular[b as usize] = true;
        }
    }
    assert_eq!(topo.on_irregular_edge(), irregular);
    let n = mesh.n_vertices();
    let mut neighbours = vec![BTreeSet::new(); n];
    for &[a, b] in &keys {
        neighbours[a as usize].insert(b);
        neighbours[b as usize].insert(a);
    }
    let mut faces_at = vec![Vec::new(); n];
    for (f, t) in mesh
        .triangles()
        .iter()
        .enumerate()
        .filter(|(_, t)| valid(t))
    {
        for &v in t {
            faces_at[v as usize].push(f as u32);
        }
    }
    for v in 0..n {
        let expected: Vec<u32> = neighbours[v].iter().copied().collect();
        assert_eq!(topo.neighbors(v), expected.as_slice(), "vertex {v}");
        let larger: Vec<u32> = neighbours[v].range(v as u32 + 1..).copied().collect();
        assert_eq!(topo.larger_neighbors(v), larger.as_slice(), "vertex {v}");
        assert_eq!(topo.vertex_faces(v), faces_at[v].as_slice(), "vertex {v}");
        let faces: Vec<[u32; 3]> = faces_at[v]
            .iter()
            .map(|&f| mesh.triangles()[f as usize])
            .collect();
        let nm = topo.non_manifold_vertices().contains(&(v as u32));
        assert_eq!(nm, brute_fans(&faces, v as u32) > 1, "vertex {v}");
    }
    // Every boundary edge appears in exactly one loop step.
    let boundary: BTreeSet<[u32; 2]> = edges
        .iter()
        .filter(|(_, (a, b))| a + b == 1)
        .map(|(k, _)| *k)
        .collect();
    let mut walked = BTreeSet::new();
    for BoundaryLoop { vertices, closed } in topo.boundary_loops() {
        let steps = if *closed {
            vertices.len()
        } else {
            vertices.len() - 1
        };
        for i in 0..steps {
            let (a, b) = (vertices[i], vertices[(i + 1) % vertices.len()]);
            assert!(walked.insert([a.min(b), a.max(b)]), "edge walked twice");
        }
    }
    assert_eq!(walked, boundary);
    let v_ref = faces_at.iter().filter(|f| !f.is_empty()).count();
    assert_eq!(
        topo.euler_characteristic(),
        v_ref as i64 - keys.len() as i64 + tris.len() as i64
    );
    assert_eq!(topo.unreferenced_vertices().len(), n - v_ref);
}

#[test]
fn matches_brute_force_on_random_meshes() {
    let mut rng = fastrand::Rng::with_seed(42);
    for _ in 0..3000 {
        assert_matches_brute_force(&random_mesh(&mut rng));
    }
}

/// Vertex 0 as the apex of one to four cones, each a closed fan of fresh rim vertices: one
/// closed fan is manifold, several meet at a pinch although every edge has one face each way.
/// Now and then a face is flipped or dropped, or two cones share a rim vertex, so the closed
/// vertices' shortcut is checked beside the general path.
fn random_cones(rng: &mut fastrand::Rng) -> Mesh {
    let mut positions = vec![[0.0f32; 3]];
    let mut triangles = Vec::new();
    for _ in 0..rng.usize(1..5) {
        let first = positions.len() as u32;
        let rim = rng.usize(3..9) as u32;
        for _ in 0..rim {
            positions.push([rng.f32(), rng.f32(), rng.f32()]);
        }
        for i in 0..rim {
            let (a, mut b) = (first + i, first + (i + 1) % rim);
            if rng.usize(..40) == 0 && first > 1 {
                b = rng.u32(1..first);
            }
            match rng.usize(..30) {
                0 => {}
                1 => triangles.push([0, b, a]),
                _ => triangles.push([0, a, b]),
            }
        }
    }
    Mesh::new(positions, triangles).unwrap()
}

#[test]
fn matches_brute_force_on_random_cones_at_one_apex() {
    let mut rng = fastrand::Rng::with_seed(43);
    let mut pinched = 0;
    for _ in 0..2000 {
        let mesh = random_cones(&mut rng);
        assert_matches_brute_force(&mesh);
        pinched += Topology::build(&mesh).non_manifold_vertices().contains(&0) as usize;
    }
    assert!(pinched > 500, "pinches tested: {pinched}");
}

/// A torus of 144,000 vertices (many blocks of vertices, found and joined in several waves)
/// with faults scattered through it: holes, flipped faces, extra faces on edges, faces
/// meeting it at one vertex only, degenerate faces and unused vertices, numbered at random.
#[test]
fn matches_brute_force_on_a_large_damaged_mesh() {
    let torus = destair::bench::torus(600, 240);
    let mut positions = torus.positions().to_vec();
    let mut triangles = Vec::new();
    let fresh = |positions: &mut Vec<[f32; 3]>| {
        positions.push([0.0, 0.0, 0.0]);
        positions.len() as u32 - 1
    };
    for (f, &[a, b, c]) in torus.triangles().iter().enumerate() {
        match f % 1999 {
            // A hole.
            0 => {}
            // Flipped.
            1 => triangles.push([a, c, b]),
            // A third face on edge a-b.
            2 => {
                triangles.push([a, b, c]);
                let d = fresh(&mut positions);
                triangles.push([a, b, d]);
            }
            // A face touching the surface at vertex a only (a pinch).
            3 => {
                triangles.push([a, b, c]);
                let (d, e) = (fresh(&mut positions), fresh(&mut positions));
                triangles.push([a, d, e]);
            }
            // Degenerate beside the face.
            4 => {
                triangles.push([a, b, c]);
                triangles.push([a, a, b]);
            }
            _ => triangles.push([a, b, c]),
        }
    }
    for _ in 0..5 {
        fresh(&mut positions);
    }
    let mesh = Mesh::new(positions, triangles).unwrap();
    assert!(mesh.n_vertices() > 16 * 8192, "several waves of blocks");
    assert_matches_brute_force(&destair::bench::shuffled(&mesh, 11));
}

#[test]
fn identical_for_one_to_four_threads() {
    let mesh = destair::bench::shuffled(&destair::bench::torus(300, 120), 3);
    let build = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                let t = Topology::build(&mesh);
                let vertex_faces: Vec<Vec<u32>> = (0..mesh.n_vertices())
                    .map(|v| t.vertex_faces(v).to_vec())
                    .collect();
                (
                    vertex_faces,
                    t.neighbor_csr().0.to_vec(),
                    t.neighbor_csr().1.to_vec(),
                    t.edges().to_vec(),
                    t.boundary_loops().to_vec(),
                    destair::mesh::geometry::signed_volume(&mesh).to_bits(),
                    destair::metrics::average_normal_curvature(&mesh, &t).to_bits(),
                )
            })
    };
    let one = build(1);
    assert_eq!(one, build(2));
    // Three and four vertex ranges for the vertex->face lists.
    assert_eq!(one, build(3));
    assert_eq!(one, build(4));
}
