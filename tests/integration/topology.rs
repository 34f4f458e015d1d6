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

/// Fans at a vertex by flood fill over faces sharing an edge at that vertex.
fn brute_fans(tris: &[[u32; 3]], v: u32) -> usize {
    let faces: Vec<[u32; 3]> = tris.iter().copied().filter(|t| t.contains(&v)).collect();
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

#[test]
fn matches_brute_force_on_random_meshes() {
    let mut rng = fastrand::Rng::with_seed(42);
    for _ in 0..3000 {
        let mesh = random_mesh(&mut rng);
        let topo = Topology::build(&mesh);
        let tris: Vec<[u32; 3]> = mesh
            .triangles()
            .iter()
            .copied()
            .filter(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2])
            .collect();
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
        for v in 0..mesh.n_vertices() as u32 {
            let neighbours: BTreeSet<u32> = keys
                .iter()
                .filter(|e| e.contains(&v))
                .map(|e| if e[0] == v { e[1] } else { e[0] })
                .collect();
            let got: Vec<u32> = topo.neighbors(v as usize).to_vec();
            assert_eq!(got, neighbours.into_iter().collect::<Vec<_>>());
            let faces: Vec<u32> = mesh
                .triangles()
                .iter()
                .enumerate()
                .filter(|(_, t)| tris.contains(t) && t.contains(&v))
                .map(|(i, _)| i as u32)
                .collect();
            assert_eq!(topo.vertex_faces(v as usize), faces.as_slice());
            let nm = topo.non_manifold_vertices().contains(&v);
            assert_eq!(nm, brute_fans(&tris, v) > 1, "vertex {v} of {mesh:?}");
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
        let v_ref = (0..mesh.n_vertices() as u32)
            .filter(|v| tris.iter().any(|t| t.contains(v)))
            .count();
        assert_eq!(
            topo.euler_characteristic(),
            v_ref as i64 - keys.len() as i64 + tris.len() as i64
        );
        assert_eq!(
            topo.unreferenced_vertices().len(),
            mesh.n_vertices() - v_ref
        );
    }
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
