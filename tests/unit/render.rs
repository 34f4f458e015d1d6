//! Tests of `src/render/mod.rs`.

use destair::mesh::Mesh;
use destair::render::*;

/// A unit square in the plane y = 0 facing the camera of `FRONT`.
fn square(size_mm: f32) -> Mesh {
    Mesh::new(
        vec![
            [0.0, 0.0, 0.0],
            [size_mm, 0.0, 0.0],
            [size_mm, 0.0, size_mm],
            [0.0, 0.0, size_mm],
        ],
        vec![[0, 1, 2], [0, 2, 3]],
    )
    .unwrap()
}

#[test]
fn a_square_seen_head_on_fills_the_middle_in_full_colour() {
    let m = square(10.0);
    let cam = Camera::fitted(&[&m], [0.0, 1.0, 0.0], 50);
    // right = +x, up = +z; 10 mm over 46 px.
    assert!((cam.pixels_per_mm - 4.6).abs() < 1e-9);
    let pic = render_surface(&m, Paint::Plain([200, 100, 50]), &cam);
    assert_eq!(pic.pixel(25, 25), Some([200, 100, 50]));
    assert_eq!(pic.pixel(1, 1), Some(BACKGROUND));
    // +x is on the right, +z at the top: a vertex colour placed at (10, 0, 10) shows top right.
    let colours = [[0, 0, 0], [0, 0, 0], [255, 0, 0], [0, 0, 0]];
    let pic = render_surface(&m, Paint::PerVertex(&colours), &cam);
    let top_right = pic.pixel(47, 3).unwrap();
    let bottom_left = pic.pixel(3, 47).unwrap();
    assert!(
        top_right[0] > 200 && bottom_left[0] < 20,
        "{top_right:?} {bottom_left:?}"
    );
}

#[test]
fn nearer_faces_hide_farther_ones_in_either_drawing_order() {
    // Two squares, one 5 mm behind the other; the near one is green, drawn first or last.
    for near_first in [true, false] {
        let ys = if near_first { [0.0, 5.0] } else { [5.0, 0.0] };
        let mut positions = Vec::new();
        for y in ys {
            positions.extend([
                [0.0, y, 0.0],
                [10.0, y, 0.0],
                [10.0, y, 10.0],
                [0.0, y, 10.0],
            ]);
        }
        let triangles = vec![[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]];
        let both = Mesh::new(positions, triangles).unwrap();
        let green = [10, 200, 10];
        let red = [200, 10, 10];
        let (a, b) = if near_first {
            (green, red)
        } else {
            (red, green)
        };
        let faces = [a, a, b, b];
        let cam = Camera::fitted(&[&both], [0.0, 1.0, 0.0], 40);
        let pic = render_surface(&both, Paint::PerFace(&faces), &cam);
        assert_eq!(pic.pixel(20, 20), Some(green));
    }
}

#[test]
fn wrong_length_paints_fall_back_to_grey_and_empty_extents_do_not_divide_by_zero() {
    let m = square(1.0);
    let cam = Camera::fitted(&[&m], FRONT_OBLIQUE, 32);
    let pic = render_surface(&m, Paint::PerVertex(&[[1, 2, 3]]), &cam);
    assert_eq!(pic.rgb.len(), 32 * 32);
    let point = Mesh::new(vec![[1.0, 1.0, 1.0]; 3], vec![[0, 1, 2]]).unwrap();
    let cam = Camera::fitted(&[&point], FRONT_OBLIQUE, 32);
    assert!(cam.pixels_per_mm.is_finite());
    let pic = render_surface(&point, Paint::Plain([0; 3]), &cam);
    assert!(pic.rgb.iter().all(|&c| c == BACKGROUND));
}
