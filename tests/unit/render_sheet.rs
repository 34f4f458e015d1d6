//! Tests of `src/render/sheet.rs`.

use destair::render::colour::Scale;
use destair::render::sheet::*;
use destair::render::Picture;

#[test]
fn sheets_hold_their_panels_and_encode_to_the_same_png_bytes() {
    let panel = |c: [u8; 3]| Panel {
        title: "a title".into(),
        picture: Picture::blank(40, 40, c),
        legend: Legend::Scale(Scale {
            lo: 0.0,
            hi: 0.5,
            unit: "mm".into(),
        }),
    };
    let sheet = compose_sheet("case / structure", &[panel([10, 20, 30]), panel([1, 2, 3])]);
    assert_eq!(sheet.width, 2 * 40 + 3 * GAP);
    let (x0, y0) = panel_origin(0, 40);
    let (x1, y1) = panel_origin(1, 40);
    assert_eq!(sheet.pixel(x0 + 20, y0 + 20), Some([10, 20, 30]));
    assert_eq!(sheet.pixel(x1 + 20, y1 + 20), Some([1, 2, 3]));
    assert_eq!(sheet.pixel(x1 - 1, y1 + 20), Some([255; 3]));
    let png = sheet.encode_png();
    assert_eq!(&png[1..4], b"PNG");
    assert_eq!(png, sheet.encode_png());
    assert_eq!(number(0.5), "0.5");
    assert_eq!(number(2.0), "2");
    assert_eq!(fit("abcdefgh", 48, 1), "abcd..");
}
