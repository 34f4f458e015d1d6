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
