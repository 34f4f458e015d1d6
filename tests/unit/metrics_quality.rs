//! Tests of `src/metrics/quality.rs`.

mod tests {
    use destair::mesh::Mesh;
    use destair::metrics::quality::*;

    #[test]
    fn angles_and_stats_by_hand() {
        let m = Mesh::new(
            vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            vec![[0, 1, 2]],
        )
        .unwrap();
        assert!((min_triangle_angle(&m) - 45.0).abs() < 1e-9);
        let s = displacement_stats(&[0.0, 1.0, 2.0, 3.0]);
        assert_eq!(s.max_mm, 3.0);
        assert_eq!(s.mean_mm, 1.5);
        assert!((s.rms_mm - 3.5f64.sqrt()).abs() < 1e-12);
        assert_eq!(s.n_unmoved, 1);
        assert_eq!(s.histogram.iter().sum::<u64>(), 4);
        assert_eq!(s.histogram[HISTOGRAM_BINS - 1], 1);
    }

    /// The statistics as a full sort gives them (the order statistics at their ranks, the zeros
    /// a sort puts first), for comparison with the selection.
    fn sorted_stats(lengths: &[f64]) -> (u64, u64, u64, usize) {
        let mut sorted = lengths.to_vec();
        sorted.sort_by(f64::total_cmp);
        let n = sorted.len();
        let at = |q: f64| sorted[((q * (n - 1) as f64).round() as usize).min(n - 1)].to_bits();
        let zeros = sorted.iter().take_while(|&&d| d == 0.0).count();
        (sorted[n - 1].to_bits(), at(0.5), at(0.95), zeros)
    }

    /// Selection gives the sort's order statistics to the bit on random lengths with ties,
    /// zeros of both signs, and now and then a NaN of either sign or a negative value.
    #[test]
    fn order_statistics_match_a_sort() {
        let mut rng = fastrand::Rng::with_seed(12);
        for round in 0..300 {
            let n = 1 + rng.usize(0..(if round % 10 == 0 { 5000 } else { 40 }));
            let lengths: Vec<f64> = (0..n)
                .map(|_| match rng.u32(0..20) {
                    0 => 0.0,
                    1 => -0.0,
                    2 => 1.25,
                    3 if round % 7 == 0 => f64::NAN,
                    4 if round % 11 == 0 => -f64::NAN,
                    5 if round % 13 == 0 => -0.5,
                    _ => rng.f64() * 3.0,
                })
                .collect();
            let s = displacement_stats(&lengths);
            let (max, median, p95, zeros) = sorted_stats(&lengths);
            let got = (
                s.max_mm.to_bits(),
                s.median_mm.to_bits(),
                s.p95_mm.to_bits(),
            );
            assert_eq!(got, (max, median, p95), "round {round}, n {n}");
            assert_eq!(s.n_unmoved, zeros, "round {round}, n {n}");
            assert_eq!(s.histogram.iter().sum::<u64>(), n as u64);
        }
    }
}

mod shape_tests {
    use destair::mesh::Mesh;
    use destair::metrics::quality::*;

    #[test]
    fn angles_aspect_ratios_and_edge_lengths_by_hand() {
        let h = 3f32.sqrt() / 2.0;
        // An equilateral triangle and a right isosceles one.
        let mesh = Mesh::new(
            vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.5, h, 0.0],
                [0.0, 0.0, 5.0],
                [1.0, 0.0, 5.0],
                [0.0, 1.0, 5.0],
            ],
            vec![[0, 1, 2], [3, 4, 5]],
        )
        .unwrap();
        let q = triangle_quality(&mesh);
        assert!((q.min_angle_deg - 45.0).abs() < 1e-4, "{q:?}");
        // Right isosceles: sqrt 2 x (2 + sqrt 2) / (2 sqrt 3) = (1 + sqrt 2) / sqrt 3.
        let right = (1.0 + 2f64.sqrt()) / 3f64.sqrt();
        assert!((q.max_aspect - right).abs() < 1e-6, "{q:?}");
        assert_eq!(q.aspect_histogram, [2, 0, 0, 0, 0, 0]);
        // Edges 0-1 (1 mm) against 1 mm, 3-5 (1 mm) against 0.5 mm.
        let targets = [1.0, 1.0, 1.0, 0.5, 0.5, 0.5];
        let e = edge_length_stats(&mesh, &[[0, 1], [3, 5]], &targets);
        assert_eq!((e.edges, e.min_mm, e.max_mm), (2, 1.0, 1.0));
        assert!((e.mean_ratio - 1.5).abs() < 1e-12);
        assert_eq!(e.within_20_percent, 0.5);
        // A degenerate triangle: angle 0, infinite aspect, last bin.
        let flat = Mesh::new(
            vec![[0.0; 3], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]],
            vec![[0, 1, 2]],
        )
        .unwrap();
        let q = triangle_quality(&flat);
        assert_eq!((q.min_angle_deg, q.aspect_histogram[5]), (0.0, 1));
        assert!(q.max_aspect.is_infinite());
    }

    /// The smallest angle picked by comparing sine and cosine pairs is the one the
    /// arctangent of every corner gives, triangle by triangle: on the phantom's marching-cubes
    /// triangles (many equal angles), jittered ones, and ones with a repeated corner or all
    /// corners on a line.
    #[test]
    fn smallest_angle_matches_every_corner() {
        let case = destair::phantom::big_case(20_000, &Default::default());
        let mesh = &case.meshes[0].1;
        let p = mesh.positions();
        let mut rng = fastrand::Rng::with_seed(3);
        let mut checked = 0;
        let mut all = Vec::new();
        for t in mesh.triangles().iter().step_by(3) {
            let mut q = t.map(|v| p[v as usize]);
            match rng.u8(..6) {
                0 => q[1] = q[0],
                1 => {
                    q[2] = [
                        2.0 * q[1][0] - q[0][0],
                        2.0 * q[1][1] - q[0][1],
                        2.0 * q[1][2] - q[0][2],
                    ]
                }
                2 | 3 => {
                    for x in q.iter_mut().flatten() {
                        *x += (rng.f32() - 0.5) * 0.4;
                    }
                }
                _ => {}
            }
            all.push(q);
            let one = Mesh::new(q.to_vec(), vec![[0, 1, 2]]).unwrap();
            assert_eq!(
                min_triangle_angle(&one).to_bits(),
                min_triangle_angle_of_every_corner(&one).to_bits(),
                "{q:?}"
            );
            checked += 1;
        }
        assert!(checked > 5000);
        // Whole meshes, each triangle with corners of its own: the pick across triangles
        // too, with and without the degenerate ones (whose zero angle is the smallest).
        let soup = |t: &[[[f32; 3]; 3]]| {
            let faces = (0..t.len() as u32).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]);
            Mesh::new(t.iter().flatten().copied().collect(), faces.collect()).unwrap()
        };
        let jittered = soup(&all);
        let sound: Vec<[[f32; 3]; 3]> = all
            .iter()
            .copied()
            .filter(|q| {
                let one = Mesh::new(q.to_vec(), vec![[0, 1, 2]]).unwrap();
                min_triangle_angle_of_every_corner(&one) > 0.0
            })
            .collect();
        let sound = soup(&sound);
        for m in [mesh, &jittered, &sound] {
            assert_eq!(
                min_triangle_angle(m).to_bits(),
                min_triangle_angle_of_every_corner(m).to_bits()
            );
        }
        assert!(min_triangle_angle(&sound) > 0.0);
    }

    /// `wider_angle` never orders two directions against their arctangents, ties and zero vectors
    /// included.
    #[test]
    fn wider_angle_orders_as_the_arctangent() {
        let mut rng = fastrand::Rng::with_seed(8);
        let special = [0.0, -0.0, 1.0, -1.0, 0.5, 1e-300, 3.0];
        let (mut both, mut ties) = ([0usize; 2], 0);
        for i in 0..200_000 {
            let pick = |rng: &mut fastrand::Rng, sign: bool| {
                let x = if i % 3 == 0 {
                    special[rng.usize(..special.len())]
                } else {
                    (rng.f64() - 0.5) * 10f64.powi(rng.i32(-3..3))
                };
                if sign {
                    x.abs()
                } else {
                    x
                }
            };
            let (sa, ca) = (pick(&mut rng, true), pick(&mut rng, false));
            let (sb, cb) = if i % 5 == 0 {
                // The same direction at another length or the same pair (a tie).
                let k = if i % 10 == 0 { 1.0 } else { rng.f64() * 4.0 };
                (sa * k, ca * k)
            } else {
                (pick(&mut rng, true), pick(&mut rng, false))
            };
            // Never the other way round from the arctangents (which may round equal where
            // the directions differ): a maximum or minimum picked with it has their value.
            let (a, b) = (sa.atan2(ca), sb.atan2(cb));
            let wider = destair::metrics::wider_angle(sa, ca, sb, cb);
            assert!(
                if wider { a >= b } else { a <= b },
                "({sa}, {ca}) vs ({sb}, {cb}): {wider}"
            );
            both[usize::from(wider)] += 1;
            ties += usize::from(a == b);
        }
        assert!(
            both[0] > 50_000 && both[1] > 50_000 && ties > 20_000,
            "{both:?} {ties}"
        );
    }
}
