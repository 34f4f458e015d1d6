//! Tests of `src/mesh/manifold.rs`.

use destair::mesh::manifold::*;
use destair::mesh::Mesh;
use destair::mesh::Topology;

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
    let (_, surface) = destair::phantom::gaussian::gauss_sphere_surface(
        3,
        false,
        destair::phantom::BorderEnds::Capped,
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
