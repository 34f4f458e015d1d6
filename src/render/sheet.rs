//! Sheets: a heading over a row of titled panels, each with its legend (a colour bar with its
//! ends in the scale's unit, or class swatches), encoded as PNG with the `png` crate.

use super::colour::Scale;
use super::text::{draw_text, text_width};
use super::Picture;

/// Text colour on sheets.
const INK: [u8; 3] = [30, 30, 30];
/// Space between panels and around the sheet (px).
pub const GAP: u32 = 8;
/// Height of the heading and of each panel title (px).
const HEADING: u32 = 24;
const TITLE: u32 = 20;
/// Height of the legend band under the panels (px).
const LEGEND: u32 = 40;

/// What a panel's legend shows.
#[derive(Debug, Clone, PartialEq)]
pub enum Legend {
    None,
    /// A colour bar from `lo` to `hi`.
    Scale(Scale),
    /// Named colours.
    Classes(Vec<(String, [u8; 3])>),
}

/// One picture of a sheet with its title and legend.
#[derive(Debug, Clone)]
pub struct Panel {
    pub title: String,
    pub picture: Picture,
    pub legend: Legend,
}

impl Picture {
    /// A picture of one colour.
    pub fn blank(width: u32, height: u32, colour: [u8; 3]) -> Picture {
        Picture {
            width,
            height,
            rgb: vec![colour; width as usize * height as usize],
        }
    }

    /// Sets one pixel; outside the picture nothing happens.
    pub fn set(&mut self, x: u32, y: u32, colour: [u8; 3]) {
        if x < self.width && y < self.height {
            self.rgb[y as usize * self.width as usize + x as usize] = colour;
        }
    }

    /// Fills the rectangle with top-left (x, y), clipped to the picture.
    pub fn fill_rect(&mut self, x: u32, y: u32, w: u32, h: u32, colour: [u8; 3]) {
        for yy in y..y.saturating_add(h).min(self.height) {
            for xx in x..x.saturating_add(w).min(self.width) {
                self.set(xx, yy, colour);
            }
        }
    }

    /// Copies `other` with its top-left corner at (x, y), clipped.
    pub fn blit(&mut self, other: &Picture, x: u32, y: u32) {
        for yy in 0..other.height {
            for xx in 0..other.width {
                let c = other.rgb[yy as usize * other.width as usize + xx as usize];
                self.set(x + xx, y + yy, c);
            }
        }
    }

    /// The picture as an 8-bit RGB PNG (same bytes for the same pixels).
    pub fn encode_png(&self) -> Vec<u8> {
        let mut out = Vec::new();
        let mut encoder = png::Encoder::new(&mut out, self.width.max(1), self.height.max(1));
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        encoder.set_compression(png::Compression::Fast);
        let data: Vec<u8> = if self.rgb.is_empty() {
            vec![255; 3 * self.width.max(1) as usize * self.height.max(1) as usize]
        } else {
            self.rgb.iter().flatten().copied().collect()
        };
        // Writing into a Vec with matching dimensions cannot fail.
        let mut writer = encoder.write_header().expect("PNG header into memory");
        writer
            .write_image_data(&data)
            .expect("PNG data of the declared size into memory");
        writer.finish().expect("PNG end into memory");
        out
    }
}

/// Top-left corner (px) of the picture of panel `index` on a sheet of panels `size` px wide.
pub fn panel_origin(index: usize, size: u32) -> (u32, u32) {
    (GAP + index as u32 * (size + GAP), GAP + HEADING + TITLE)
}

/// Lays panels (all of the same size) out in a row under `heading`.
pub fn compose_sheet(heading: &str, panels: &[Panel]) -> Picture {
    let size = panels.first().map_or(64, |p| p.picture.width);
    let n = panels.len().max(1) as u32;
    let width = n * size + (n + 1) * GAP;
    let height = GAP + HEADING + TITLE + size + LEGEND + GAP;
    let mut sheet = Picture::blank(width, height, [255; 3]);
    draw_text(
        &mut sheet,
        GAP,
        GAP + 4,
        &fit(heading, width - 2 * GAP, 2),
        2,
        INK,
    );
    for (i, panel) in panels.iter().enumerate() {
        let (x, picture_y) = panel_origin(i, size);
        let y = picture_y - TITLE;
        draw_text(&mut sheet, x, y + 6, &fit(&panel.title, size, 1), 1, INK);
        sheet.blit(&panel.picture, x, y + TITLE);
        // A thin frame shows where the panel ends on white.
        let frame = [225; 3];
        sheet.fill_rect(x, y + TITLE, size, 1, frame);
        sheet.fill_rect(x, y + TITLE + size - 1, size, 1, frame);
        sheet.fill_rect(x, y + TITLE, 1, size, frame);
        sheet.fill_rect(x + size - 1, y + TITLE, 1, size, frame);
        draw_legend(&mut sheet, &panel.legend, x, y + TITLE + size + 6, size);
    }
    sheet
}

/// The legend of one panel in the band below it.
fn draw_legend(sheet: &mut Picture, legend: &Legend, x: u32, y: u32, width: u32) {
    match legend {
        Legend::None => {}
        Legend::Scale(scale) => {
            let bar = width.saturating_sub(16).max(2);
            for i in 0..bar {
                let t = i as f32 / (bar - 1) as f32;
                let v = scale.lo + t * (scale.hi - scale.lo);
                sheet.fill_rect(x + 8 + i, y, 1, 12, scale.colour(v));
            }
            let lo = number(scale.lo);
            let hi = format!("{} {}", number(scale.hi), scale.unit);
            draw_text(sheet, x + 8, y + 16, &lo, 1, INK);
            let w = text_width(&hi, 1);
            draw_text(sheet, (x + 8 + bar).saturating_sub(w), y + 16, &hi, 1, INK);
        }
        Legend::Classes(classes) => {
            // Left to right, on a second line when the first is full.
            let (mut cx, mut cy) = (x + 8, y + 2);
            for (name, colour) in classes {
                let w = 14 + text_width(name, 1);
                if cx + w > x + width && cx > x + 8 {
                    (cx, cy) = (x + 8, cy + 16);
                }
                sheet.fill_rect(cx, cy, 10, 10, *colour);
                draw_text(sheet, cx + 14, cy + 2, name, 1, INK);
                cx += w + 12;
            }
        }
    }
}

/// A legend number: few digits, no trailing zeros.
pub fn number(v: f32) -> String {
    let s = format!("{v:.3}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" {
        "0".into()
    } else {
        s.to_string()
    }
}

/// `text` cut (with "..") to fit `width` pixels at `scale`.
pub fn fit(text: &str, width: u32, scale: u32) -> String {
    let max = (width / (8 * scale.max(1))) as usize;
    if text.chars().count() <= max {
        return text.to_string();
    }
    let keep = max.saturating_sub(2);
    text.chars().take(keep).chain("..".chars()).collect()
}
