//! Tests of `src/mesh/face_neighbours.rs`.

use destair::mesh::face_neighbours::*;
use destair::mesh::{Mesh, Topology};

/// Faces sharing each edge of `f`, edge by edge, found by comparing every face.
fn brute_force_neighbours(mesh: &Mesh, f: u32) -> Vec<u32> {
    let t = mesh.triangles()[f as usize];
    let mut out = Vec::new();
    for k in 0..3 {
        let (a, b) = (t[k], t[(k + 1) % 3]);
        for (g, u) in mesh.triangles().iter().enumerate() {
            if g as u32 != f && u.contains(&a) && u.contains(&b) {
                out.push(g as u32);
            }
        }
    }
    out
}

#[test]
fn edge_neighbours_match_brute_force_with_rims_and_fins() {
    for seed in 0..20 {
        let mut rng = fastrand::Rng::with_seed(seed);
        // A 6 x 6 grid of vertices, some cells left out (rims), plus random triangles over
        // its vertices (fins on non-manifold edges), in shuffled face order.
        let n = 6u32;
        let positions: Vec<[f32; 3]> = (0..n * n)
            .map(|i| [(i % n) as f32, (i / n) as f32, rng.f32()])
            .collect();
        let mut triangles = Vec::new();
        for y in 0..n - 1 {
            for x in 0..n - 1 {
                if rng.u32(0..5) == 0 {
                    continue;
                }
                let v = y * n + x;
                triangles.push([v, v + 1, v + n + 1]);
                triangles.push([v, v + n + 1, v + n]);
            }
        }
        for _ in 0..8 {
            let mut t = [0; 3];
            while t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
                t = std::array::from_fn(|_| rng.u32(0..n * n));
            }
            triangles.push(t);
        }
        // A fan of six faces on the edge (0, 1), which is each one's last edge.
        for k in 10..16 {
            triangles.push([1, k, 0]);
        }
        rng.shuffle(&mut triangles);
        let mesh = Mesh::new(positions, triangles).unwrap();
        let topology = Topology::build(&mesh);
        let mut out = Vec::new();
        for f in 0..mesh.n_triangles() as u32 {
            edge_neighbours(&mesh, &topology, f, &mut out);
            assert_eq!(
                out,
                brute_force_neighbours(&mesh, f),
                "seed {seed}, face {f}"
            );
        }
    }
}
