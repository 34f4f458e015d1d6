//! Pictures show what they claim, and are the same bytes for any thread count.

use crate::common;

use destair::render::colour::viridis;
use destair::render::{sheet::panel_origin, Camera, FRONT_OBLIQUE};
use destair::report::pictures::{structure_picture, structure_sheet, StructureViews, PANEL_PX};
use destair::Mesh;

/// A 10 mm sphere whose upper half (z > 0) moved 0.8 mm outwards; the lower half stayed.
fn sphere_with_known_field() -> (Mesh, Mesh, Vec<f32>) {
    let before = common::icosphere(4, 10.0);
    let mut after = before.clone();
    for p in after.positions_mut() {
        if p[2] > 0.0 {
            let r = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
            *p = p.map(|x| x * (r + 0.8) / r);
        }
    }
    let d: Vec<f32> = destair::metrics::displacements(before.positions(), after.positions())
        .into_iter()
        .map(|x| x as f32)
        .collect();
    (before, after, d)
}

fn unit(v: [f64; 3]) -> [f64; 3] {
    let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    v.map(|x| x / l)
}

/// Cosine between two colours as RGB vectors: 1 when one is the other, shaded.
fn same_hue(a: [u8; 3], b: [u8; 3]) -> f64 {
    let (a, b) = (a.map(f64::from), b.map(f64::from));
    let dot = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    dot / ((a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
        * (b[0] * b[0] + b[1] * b[1] + b[2] * b[2]).sqrt())
}

#[test]
fn the_displacement_panel_shows_the_known_field_at_known_places() {
    let (before, after, d) = sphere_with_known_field();
    let arrays: [(&str, &[f32]); 1] = [("displacement", &d)];
    let views = StructureViews {
        heading: "sphere".into(),
        before: &before,
        after: &after,
        arrays: &arrays,
        patches: None,
    };
    let (sheet, titles) = structure_sheet(&views);
    assert_eq!(titles, ["input", "smoothed", "displacement"]);
    let camera = Camera::fitted(&[&before, &after], FRONT_OBLIQUE, PANEL_PX);
    // Where a point on a surface shows on the sheet, in panel `index`.
    let pixel = |index: usize, p: [f64; 3]| -> [u8; 3] {
        let s = camera.project(p);
        let (x0, y0) = panel_origin(index, PANEL_PX);
        sheet
            .pixel(x0 + s[0] as u32, y0 + s[1] as u32)
            .expect("inside the sheet")
    };
    let f = camera.forward;
    let up = camera.up;
    // A point of the moved upper half facing the viewer, and one of the resting lower half.
    let upper = unit([0, 1, 2].map(|k| -f[k] + 0.5 * up[k]));
    let lower = unit([0, 1, 2].map(|k| -f[k] - 0.9 * up[k]));
    assert!(upper[2] > 0.3 && lower[2] < -0.3, "{upper:?} {lower:?}");
    let moved = pixel(2, upper.map(|x| x * 10.8));
    let rest = pixel(2, lower.map(|x| x * 10.0));
    // The scale runs 0..1 mm: 0.8 mm is viridis(0.8), 0 is viridis(0); shading only darkens.
    let (want_moved, want_rest) = (viridis(0.8), viridis(0.0));
    assert!(
        same_hue(moved, want_moved) > 0.995,
        "{moved:?} vs {want_moved:?}"
    );
    assert!(
        same_hue(rest, want_rest) > 0.995,
        "{rest:?} vs {want_rest:?}"
    );
    assert!(moved[1] <= want_moved[1] && moved[1] as f64 > 0.5 * want_moved[1] as f64);
    // The plain panels show the grey surface, outside the sphere the background.
    let grey = destair::render::colour::SURFACE;
    assert!(same_hue(pixel(0, lower.map(|x| x * 10.0)), grey) > 0.999);
    assert_eq!(
        sheet.pixel(
            panel_origin(0, PANEL_PX).0 + 3,
            panel_origin(0, PANEL_PX).1 + 3
        ),
        Some([255; 3])
    );
    // The moved half stands out on the smoothed panel beyond the input's silhouette: a point
    // 10.4 mm out along the upper direction is surface after, background before.
    assert_eq!(
        pixel(
            0,
            unit([0, 1, 2].map(|k| 0.8 * up[k] - 0.2 * f[k])).map(|x| x * 10.5)
        ),
        [255; 3]
    );
    assert_ne!(
        pixel(
            1,
            unit([0, 1, 2].map(|k| 0.8 * up[k] - 0.2 * f[k])).map(|x| x * 10.5)
        ),
        [255; 3]
    );
}

#[test]
fn pictures_are_the_same_bytes_for_any_thread_count() {
    let (before, after, d) = sphere_with_known_field();
    let w: Vec<f32> = d.iter().map(|x| 1.0 - x).collect();
    let stairs: Vec<f32> = (0..d.len()).map(|v| (v % 3 == 0) as u8 as f32).collect();
    let caps: Vec<f32> = (0..d.len()).map(|v| (v % 7 == 0) as u8 as f32).collect();
    let arrays: [(&str, &[f32]); 4] = [
        ("displacement", &d),
        ("weight", &w),
        ("staircase", &stairs),
        ("cap", &caps),
    ];
    let views = StructureViews {
        heading: "sphere".into(),
        before: &before,
        after: &after,
        arrays: &arrays,
        patches: None,
    };
    let render = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| structure_picture(&views, "s_views.png".into()))
    };
    let (info, one) = render(1);
    assert_eq!(info.panels.len(), 5);
    for threads in [2, 3] {
        assert_eq!(render(threads).1, one, "{threads} threads");
    }
    // And the PNG decodes to the sheet's size.
    let decoder = png::Decoder::new(std::io::Cursor::new(&one));
    let reader = decoder.read_info().unwrap();
    assert_eq!(
        (reader.info().width, reader.info().height),
        (info.width, info.height)
    );
}
