//! Whether a mesh is a closed, consistently oriented 2-manifold, without building its whole
//! topology: around every vertex, its faces must form one closed fan.

use super::Mesh;

/// The same answer as `Topology::build(mesh).is_closed_oriented_manifold()` (degenerate
/// triangles are left out by both; unreferenced vertices are allowed), at a fraction of the
/// cost: one vertex-to-face pass and a walk around each vertex. Each face at vertex v, rotated
/// to (v, x, y), maps x to y; the mesh is a closed oriented 2-manifold exactly when, at every
/// vertex, the x are distinct and following x -> y visits all of them in one cycle (then every
/// edge at v has one face on each side, both orienting it oppositely, and the faces form a
/// single fan).
pub fn is_closed_oriented_manifold(mesh: &Mesh) -> bool {
    let n = mesh.n_vertices();
    let valid = |t: &&[u32; 3]| t[0] != t[1] && t[1] != t[2] && t[0] != t[2];
    let mut start = vec![0u32; n + 1];
    for t in mesh.triangles().iter().filter(valid) {
        for &v in t {
            start[v as usize + 1] += 1;
        }
    }
    super::topology::prefix_sum(&mut start);
    // (x, y) of each face at each vertex.
    let mut fan = vec![[0u32; 2]; start[n] as usize];
    let mut cursor = start.clone();
    for t in mesh.triangles().iter().filter(valid) {
        for c in 0..3 {
            let v = t[c] as usize;
            fan[cursor[v] as usize] = [t[(c + 1) % 3], t[(c + 2) % 3]];
            cursor[v] += 1;
        }
    }
    drop(cursor);
    (0..n).all(|v| {
        let pairs = &mut fan[start[v] as usize..start[v + 1] as usize];
        one_cycle(pairs)
    })
}

/// Whether the map x -> y of `pairs` is defined once per x and is a single cycle through all
/// of them (an empty fan is an unreferenced vertex: fine). Sorts `pairs` by x.
fn one_cycle(pairs: &mut [[u32; 2]]) -> bool {
    let Some(&[first, mut y]) = pairs.first() else {
        return true;
    };
    pairs.sort_unstable_by_key(|p| p[0]);
    if pairs.windows(2).any(|w| w[0][0] == w[1][0]) {
        return false;
    }
    let mut steps = 1;
    while y != first {
        let Ok(at) = pairs.binary_search_by_key(&y, |p| p[0]) else {
            return false;
        };
        steps += 1;
        if steps > pairs.len() {
            return false;
        }
        y = pairs[at][1];
    }
    steps == pairs.len()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::Topology;

    fn both(positions: &[[f32; 3]], triangles: Vec<[u32; 3]>) -> (bool, bool) {
        let mesh = Mesh::new(positions.to_vec(), triangles).expect("valid mesh");
        (
            is_closed_oriented_manifold(&mesh),
            Topology::build(&mesh).is_closed_oriented_manifold(),
        )
    }

    fn octahedron() -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
        let p = vec![
            [1.0, 0.0, 0.0],
            [-1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, -1.0, 0.0],
            [0.0, 0.0, 1.0],
            [0.0, 0.0, -1.0],
        ];
        let t = vec![
            [0, 2, 4],
            [2, 1, 4],
            [1, 3, 4],
            [3, 0, 4],
            [2, 0, 5],
            [1, 2, 5],
            [3, 1, 5],
            [0, 3, 5],
        ];
        (p, t)
    }

    #[test]
    fn agrees_with_the_topology_on_closed_open_flipped_and_pinched_meshes() {
        let (p, t) = octahedron();
        assert_eq!(both(&p, t.clone()), (true, true));
        // One face removed: a boundary.
        assert_eq!(both(&p, t[1..].to_vec()), (false, false));
        // One face flipped: inconsistent orientation.
        let mut flipped = t.clone();
        flipped[3] = [flipped[3][0], flipped[3][2], flipped[3][1]];
        assert_eq!(both(&p, flipped), (false, false));
        // A face twice: an edge with three faces.
        let mut doubled = t.clone();
        doubled.push(t[0]);
        assert_eq!(both(&p, doubled), (false, false));
        // Two octahedra sharing vertex 0 (the second's vertex 0 is the first's): pinched.
        let mut p2 = p.clone();
        p2.extend(p[1..].iter().map(|q| [q[0] + 2.0, q[1], q[2]]));
        let shift = |v: u32| if v == 0 { 0 } else { v + 5 };
        let mut pinched = t.clone();
        pinched.extend(t.iter().map(|f| f.map(shift)));
        assert_eq!(both(&p2, pinched), (false, false));
        // Two separate octahedra and an unreferenced vertex: still closed and oriented.
        let mut p3 = p.clone();
        p3.extend(p.iter().map(|q| [q[0] + 5.0, q[1], q[2]]));
        p3.push([9.0, 9.0, 9.0]);
        let mut two = t.clone();
        two.extend(t.iter().map(|f| f.map(|v| v + 6)));
        assert_eq!(both(&p3, two.clone()), (true, true));
        // A degenerate triangle is left out by both.
        two.push([0, 0, 1]);
        assert_eq!(both(&p3, two), (true, true));
    }

    #[test]
    fn agrees_with_the_topology_on_random_edits_of_a_closed_surface() {
        let (_, surface) = crate::phantom::gaussian::gauss_sphere_surface(
            3,
            false,
            crate::phantom::BorderEnds::Capped,
        );
        let (p, t) = (surface.positions().to_vec(), surface.triangles().to_vec());
        let mut seed = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = |m: usize| {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed % m as u64) as usize
        };
        let mut seen = [0; 2];
        for case in 0..300 {
            let mut tris = t.clone();
            for _ in 0..1 + case % 3 {
                let f = next(tris.len());
                match next(5) {
                    0 => {
                        tris.swap_remove(f);
                    }
                    1 => tris[f] = [tris[f][0], tris[f][2], tris[f][1]],
                    2 => tris.push(tris[f]),
                    3 => tris[f][next(3)] = next(p.len()) as u32,
                    _ => {}
                }
            }
            let (fast, full) = both(&p, tris);
            assert_eq!(fast, full, "case {case}");
            seen[fast as usize] += 1;
        }
        // Both answers occur (an edit that does nothing keeps the surface closed).
        assert!(seen[0] > 50 && seen[1] > 20, "{seen:?}");
    }
}
