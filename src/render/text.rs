//! Labels on pictures, drawn with the public-domain 8 x 8 bitmap font of the `font8x8` crate
//! (printable ASCII; anything else shows as `?`), scaled by whole pixels.

use super::Picture;

/// Width in pixels of `text` drawn at `scale`.
pub fn text_width(text: &str, scale: u32) -> u32 {
    text.chars().count() as u32 * 8 * scale
}

/// Draws `text` with its top-left corner at (x, y); pixels outside the picture are skipped.
pub fn draw_text(pic: &mut Picture, x: u32, y: u32, text: &str, scale: u32, colour: [u8; 3]) {
    let scale = scale.max(1);
    for (i, ch) in text.chars().enumerate() {
        let code = if ch.is_ascii() && !ch.is_ascii_control() {
            ch as usize
        } else {
            b'?' as usize
        };
        let glyph = font8x8::legacy::BASIC_LEGACY[code];
        let left = x + i as u32 * 8 * scale;
        for (row, bits) in glyph.iter().enumerate() {
            for col in 0..8u32 {
                if bits & (1 << col) == 0 {
                    continue;
                }
                for dy in 0..scale {
                    for dx in 0..scale {
                        pic.set(left + col * scale + dx, y + row as u32 * scale + dy, colour);
                    }
                }
            }
        }
    }
}
