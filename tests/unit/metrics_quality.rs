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
}
