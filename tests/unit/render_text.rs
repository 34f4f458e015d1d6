//! Tests of `src/render/text.rs`.

use destair::render::text::*;
use destair::render::Picture;

#[test]
fn a_glyph_marks_pixels_inside_its_box_only() {
    let mut pic = Picture::blank(40, 20, [255; 3]);
    draw_text(&mut pic, 2, 2, "I1", 1, [0; 3]);
    let dark: Vec<(u32, u32)> = (0..20)
        .flat_map(|y| (0..40).map(move |x| (x, y)))
        .filter(|&(x, y)| pic.pixel(x, y) == Some([0; 3]))
        .collect();
    assert!(!dark.is_empty());
    assert!(dark
        .iter()
        .all(|&(x, y)| (2..18).contains(&x) && (2..10).contains(&y)));
    assert_eq!(text_width("I1", 2), 32);
    // Off the edge: no panic.
    draw_text(&mut pic, 35, 15, "WW\u{e9}", 3, [0; 3]);
}
