//! Headless pictures of surfaces: an orthographic camera fitted to the structure, z-buffered
//! triangles with flat (per-face) shading and Gouraud-interpolated colours, 2 x 2 supersampled.
//! Pure CPU and serial per picture, so the pixels are the same for any thread count; callers
//! render several pictures in parallel. Sheets of labelled panels and PNG encoding are in
//! [`sheet`], colour scales in [`colour`], the bitmap font in [`text`].

pub mod colour;
pub mod sheet;
pub mod text;

use crate::mesh::geometry::{
    cross as cross32, cross64 as cross, dot as dot32, dot64 as dot, sub as sub32,
};
use crate::mesh::Mesh;

/// Supersampling factor per axis: each output pixel averages `SUPERSAMPLE^2` samples.
const SUPERSAMPLE: usize = 2;
/// Share of the light that does not depend on the face's angle to the viewer.
const AMBIENT: f32 = 0.3;

/// An orthographic camera: screen axes `right` and `up`, viewing direction `forward` (unit
/// vectors, world coordinates), and the map from world millimetres to pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    pub right: [f64; 3],
    pub up: [f64; 3],
    pub forward: [f64; 3],
    /// World point shown at the picture's centre (mm).
    pub centre: [f64; 3],
    /// Pixels per millimetre.
    pub pixels_per_mm: f64,
    /// Width and height of the square picture (pixels).
    pub size: u32,
}

/// The default view direction: from the front (anterior, -y in LPS), a little from the
/// patient's right and from above, so terraces across z and y show as bands.
pub const FRONT_OBLIQUE: [f64; 3] = [0.35, 1.0, -0.3];

impl Camera {
    /// A camera looking along `forward` with world `+z` (or `+y` when looking along z) up, zoomed
    /// so every vertex of every mesh fits with a 4 % margin. `size` is clamped to 16..=4096 px.
    pub fn fitted(meshes: &[&Mesh], forward: [f64; 3], size: u32) -> Camera {
        let size = size.clamp(16, 4096);
        let f = normalise(forward).unwrap_or([0.0, 1.0, 0.0]);
        let world_up = if f[2].abs() > 0.9 {
            [0.0, 1.0, 0.0]
        } else {
            [0.0, 0.0, 1.0]
        };
        // right = forward x up, then up re-orthogonalised: a right-handed screen frame.
        let right = normalise(cross(f, world_up)).unwrap_or([1.0, 0.0, 0.0]);
        let up = cross(right, f);
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for m in meshes {
            for p in m.positions() {
                let p = p.map(f64::from);
                let s = [dot(p, right), dot(p, up), dot(p, f)];
                for k in 0..3 {
                    lo[k] = lo[k].min(s[k]);
                    hi[k] = hi[k].max(s[k]);
                }
            }
        }
        if !lo.iter().chain(&hi).all(|x| x.is_finite()) {
            lo = [0.0; 3];
            hi = [0.0; 3];
        }
        let mid = [0, 1, 2].map(|k| 0.5 * (lo[k] + hi[k]));
        let centre = [0, 1, 2].map(|k| mid[0] * right[k] + mid[1] * up[k] + mid[2] * f[k]);
        let extent = (hi[0] - lo[0]).max(hi[1] - lo[1]).max(1e-6);
        Camera {
            right,
            up,
            forward: f,
            centre,
            pixels_per_mm: 0.92 * f64::from(size) / extent,
            size,
        }
    }

    /// Picture coordinates of a world point: x to the right, y downwards (pixels), and the depth
    /// along the viewing direction (mm, larger is farther).
    pub fn project(&self, p: [f64; 3]) -> [f64; 3] {
        let d = [
            p[0] - self.centre[0],
            p[1] - self.centre[1],
            p[2] - self.centre[2],
        ];
        let half = 0.5 * f64::from(self.size);
        [
            half + dot(d, self.right) * self.pixels_per_mm,
            half - dot(d, self.up) * self.pixels_per_mm,
            dot(d, self.forward),
        ]
    }
}

/// How the triangles of a picture are coloured (sRGB); flat shading is applied on top.
#[derive(Debug, Clone, Copy)]
pub enum Paint<'a> {
    /// One colour for the whole surface.
    Plain([u8; 3]),
    /// A colour per vertex, interpolated across each triangle.
    PerVertex(&'a [[u8; 3]]),
    /// A colour per triangle.
    PerFace(&'a [[u8; 3]]),
}

/// An RGB picture, row by row from the top.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Picture {
    pub width: u32,
    pub height: u32,
    pub rgb: Vec<[u8; 3]>,
}

impl Picture {
    /// The colour at (x, y), x to the right and y downwards from the top-left corner.
    pub fn pixel(&self, x: u32, y: u32) -> Option<[u8; 3]> {
        (x < self.width && y < self.height)
            .then(|| self.rgb[y as usize * self.width as usize + x as usize])
    }
}

/// Picture background (sRGB).
pub const BACKGROUND: [u8; 3] = [255, 255, 255];

/// Renders `mesh` seen by `camera` on a white background. A paint whose length does not match
/// the mesh falls back to plain grey rather than failing: a picture is never worth an error.
pub fn render_surface(mesh: &Mesh, paint: Paint, camera: &Camera) -> Picture {
    rasterise(mesh, camera).shade(mesh, paint)
}

/// Which triangle each sample of a picture sees, and where on it: rasterised once, shaded
/// with as many paints as wanted (the input panels of a sheet share one).
#[derive(Debug, Clone)]
pub struct Coverage {
    /// Output picture size (px); samples are `size * SUPERSAMPLE` per side.
    size: usize,
    /// Per sample: the nearest triangle, or `u32::MAX` for background.
    triangle: Vec<u32>,
    /// Per vertex: its place in samples (x, y) and depth; the shading recomputes barycentric
    /// weights from these rather than storing them per sample.
    screen: Vec<[f32; 3]>,
    /// Per triangle: the light it reflects towards the viewer (flat shading), 0..1.
    shade: Vec<f32>,
}

/// Slack on the inside test, so that samples on an edge shared by two triangles are never
/// missed by both through rounding (the depth test settles which one shows).
const EDGE_SLACK: f32 = 1e-5;

thread_local! {
    /// The depth buffer, kept per thread between pictures: a fresh one per picture cost more
    /// in page faults than drawing a small mesh.
    static DEPTH: std::cell::RefCell<Vec<f32>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// Rasterises `mesh` with a depth buffer: for every sample the nearest triangle.
pub fn rasterise(mesh: &Mesh, camera: &Camera) -> Coverage {
    DEPTH.with(|d| rasterise_into(mesh, camera, &mut d.borrow_mut()))
}

fn rasterise_into(mesh: &Mesh, camera: &Camera, depth: &mut Vec<f32>) -> Coverage {
    let n = camera.size as usize * SUPERSAMPLE;
    depth.clear();
    depth.resize(n * n, f32::INFINITY);
    let mut triangle = vec![u32::MAX; n * n];
    let scale = SUPERSAMPLE as f64;
    let screen: Vec<[f32; 3]> = mesh
        .positions()
        .iter()
        .map(|p| {
            let s = camera.project(p.map(f64::from));
            [(s[0] * scale) as f32, (s[1] * scale) as f32, s[2] as f32]
        })
        .collect();
    let forward = camera.forward.map(|x| x as f32);
    let mut shade = Vec::with_capacity(mesh.n_triangles());
    for (t, tri) in mesh.triangles().iter().enumerate() {
        let [pa, pb, pc] = tri.map(|v| mesh.positions()[v as usize]);
        let normal = cross32(sub32(pb, pa), sub32(pc, pa));
        let len = dot32(normal, normal).sqrt();
        let facing = if len > 0.0 {
            (dot32(normal, forward) / len).abs()
        } else {
            0.0
        };
        shade.push(AMBIENT + (1.0 - AMBIENT) * facing);
        let [a, b, c] = tri.map(|v| screen[v as usize]);
        let area = edge(a, b, c);
        if area == 0.0 || !area.is_finite() {
            continue;
        }
        let inv = 1.0 / area;
        let x0 = floor_index(a[0].min(b[0]).min(c[0]));
        let y0 = floor_index(a[1].min(b[1]).min(c[1]));
        let x1 = ceil_index(a[0].max(b[0]).max(c[0])).min(n);
        let y1 = ceil_index(a[1].max(b[1]).max(c[1])).min(n);
        if x0 >= x1 || y0 >= y1 {
            continue;
        }
        // Barycentric weights are linear in the sample position: step them along each row.
        let (wa_dx, wb_dx) = ((b[1] - c[1]) * inv, (c[1] - a[1]) * inv);
        let (za, zb, zc) = (a[2], b[2], c[2]);
        let wc_dx = -(wa_dx + wb_dx);
        for y in y0..y1 {
            let p = [x0 as f32 + 0.5, y as f32 + 0.5, 0.0];
            let wa0 = edge(b, c, p) * inv;
            let wb0 = edge(c, a, p) * inv;
            // The samples of this row inside all three edges (widened by one for rounding;
            // the inside test below decides).
            let mut lo = x0 as f32;
            let mut hi = x1 as f32;
            // Worth it for wide triangles only; narrow ones test their few samples.
            let wide = x1 - x0 > 8;
            for (w, d) in [(wa0, wa_dx), (wb0, wb_dx), (1.0 - wa0 - wb0, wc_dx)] {
                if !wide {
                    break;
                }
                if d > 0.0 {
                    lo = lo.max(x0 as f32 + (-EDGE_SLACK - w) / d - 1.0);
                } else if d < 0.0 {
                    hi = hi.min(x0 as f32 + (-EDGE_SLACK - w) / d + 2.0);
                } else if w < -EDGE_SLACK {
                    hi = lo;
                }
            }
            if lo.partial_cmp(&hi) != Some(std::cmp::Ordering::Less) {
                continue;
            }
            let xs = floor_index(lo).clamp(x0, x1);
            let xe = ceil_index(hi).clamp(x0, x1);
            let skip = (xs - x0) as f32;
            let mut wa = wa0 + wa_dx * skip;
            let mut wb = wb0 + wb_dx * skip;
            let row = y * n;
            for x in xs..xe {
                let wc = 1.0 - wa - wb;
                if wa >= -EDGE_SLACK && wb >= -EDGE_SLACK && wc >= -EDGE_SLACK {
                    let z = wa * za + wb * zb + wc * zc;
                    let i = row + x;
                    // Branch-free: which of two overlapping layers is nearer is not
                    // predictable, and mispredictions cost more than the stores.
                    let nearer = z < depth[i];
                    depth[i] = if nearer { z } else { depth[i] };
                    triangle[i] = if nearer { t as u32 } else { triangle[i] };
                }
                wa += wa_dx;
                wb += wb_dx;
            }
        }
    }
    Coverage {
        size: camera.size as usize,
        triangle,
        screen,
        shade,
    }
}

impl Coverage {
    /// The picture with the surface coloured by `paint` (see [`render_surface`]), each output
    /// pixel the mean of its samples.
    pub fn shade(&self, mesh: &Mesh, paint: Paint) -> Picture {
        let paint = match paint {
            Paint::PerVertex(c) if c.len() != mesh.n_vertices() => Paint::Plain([190; 3]),
            Paint::PerFace(c) if c.len() != mesh.n_triangles() => Paint::Plain([190; 3]),
            p => p,
        };
        let k = SUPERSAMPLE;
        let n = self.size * k;
        let norm = 1.0 / (k * k) as f32;
        let background = BACKGROUND.map(f32::from);
        let tris = mesh.triangles();
        // The colour of triangle `t` at sample-grid position (px, py).
        let colour_at = |t: u32, px: f32, py: f32| -> [f32; 3] {
            let Some(tri) = tris.get(t as usize) else {
                return background;
            };
            let s = self.shade[t as usize];
            let flat = |c: [u8; 3]| {
                [
                    f32::from(c[0]) * s,
                    f32::from(c[1]) * s,
                    f32::from(c[2]) * s,
                ]
            };
            match paint {
                Paint::Plain(c) => flat(c),
                Paint::PerFace(cs) => flat(cs[t as usize]),
                Paint::PerVertex(cs) => {
                    let [ia, ib, ic] = [tri[0] as usize, tri[1] as usize, tri[2] as usize];
                    let (a, b, c) = (self.screen[ia], self.screen[ib], self.screen[ic]);
                    let p = [px, py, 0.0];
                    let inv = 1.0 / edge(a, b, c);
                    let wa = (edge(b, c, p) * inv).clamp(0.0, 1.0);
                    let wb = (edge(c, a, p) * inv).clamp(0.0, 1.0 - wa);
                    let wc = 1.0 - wa - wb;
                    let (ca, cb, cc) = (cs[ia], cs[ib], cs[ic]);
                    let mix = |j: usize| {
                        s * (wa * f32::from(ca[j]) + wb * f32::from(cb[j]) + wc * f32::from(cc[j]))
                    };
                    [mix(0), mix(1), mix(2)]
                }
            }
        };
        let mut rgb = Vec::with_capacity(self.size * self.size);
        for y in 0..self.size {
            let top = y * k * n;
            for x in 0..self.size {
                let first = self.triangle[top + x * k];
                let mut same = true;
                for dy in 0..k {
                    let row = top + dy * n + x * k;
                    for &t in &self.triangle[row..row + k] {
                        same &= t == first;
                    }
                }
                // One triangle under the whole pixel: colours are linear across it, so the
                // mean of the samples is the colour at their mean position.
                let mean = if same {
                    let centre = |v: usize| (v * k) as f32 + 0.5 * k as f32;
                    colour_at(first, centre(x), centre(y))
                } else {
                    let mut sum = [0.0f32; 3];
                    for dy in 0..k {
                        for dx in 0..k {
                            let (sx, sy) = (x * k + dx, y * k + dy);
                            let c = colour_at(
                                self.triangle[sy * n + sx],
                                sx as f32 + 0.5,
                                sy as f32 + 0.5,
                            );
                            for j in 0..3 {
                                sum[j] += c[j] * norm;
                            }
                        }
                    }
                    sum
                };
                // Non-negative: adding a half and truncating rounds.
                let byte = |v: f32| (v + 0.5).min(255.0) as u8;
                rgb.push([byte(mean[0]), byte(mean[1]), byte(mean[2])]);
            }
        }
        Picture {
            width: self.size as u32,
            height: self.size as u32,
            rgb,
        }
    }
}

/// `v` rounded down to a sample index (0 for negative values and NaN); casts, not `floor`,
/// which is a library call on x86-64 without SSE 4.1.
fn floor_index(v: f32) -> usize {
    if v > 0.0 {
        v as usize
    } else {
        0
    }
}

/// `v` rounded up to a sample index (0 for negative values and NaN, saturating).
fn ceil_index(v: f32) -> usize {
    if v > 0.0 {
        let t = v as usize;
        if (t as f32) < v {
            t.saturating_add(1)
        } else {
            t
        }
    } else {
        0
    }
}

/// Twice the signed area of (a, b, p) in the picture plane.
fn edge(a: [f32; 3], b: [f32; 3], p: [f32; 3]) -> f32 {
    (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])
}

fn normalise(a: [f64; 3]) -> Option<[f64; 3]> {
    let l = dot(a, a).sqrt();
    (l > 0.0 && l.is_finite()).then(|| a.map(|x| x / l))
}
