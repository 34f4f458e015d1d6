//! Colour scales for pictures: viridis for magnitudes (perceptually uniform, readable in grey
//! and by most colour-blind readers) and fixed colours for classes.

/// Viridis at nine evenly spaced stops (matplotlib's table, sRGB).
pub const VIRIDIS: [[u8; 3]; 9] = [
    [68, 1, 84],
    [71, 45, 123],
    [59, 82, 139],
    [44, 114, 142],
    [33, 145, 140],
    [39, 173, 129],
    [92, 200, 99],
    [170, 220, 50],
    [253, 231, 37],
];

/// Colour of values that are not numbers (no reference within reach, say).
pub const MISSING: [u8; 3] = [150, 150, 150];
/// Surface colour of plain pictures (input, smoothed).
pub const SURFACE: [u8; 3] = [205, 200, 190];
/// Class colours: vertices in no class, on a staircase, on a cap.
pub const CLASS_OTHER: [u8; 3] = [200, 200, 200];
pub const CLASS_STAIRCASE: [u8; 3] = [230, 120, 30];
pub const CLASS_CAP: [u8; 3] = [40, 110, 220];

/// Viridis at `t` in 0..=1 (clamped), linear between the stops.
pub fn viridis(t: f32) -> [u8; 3] {
    if !t.is_finite() {
        return MISSING;
    }
    let x = t.clamp(0.0, 1.0) * (VIRIDIS.len() - 1) as f32;
    let i = (x.floor() as usize).min(VIRIDIS.len() - 2);
    let f = x - i as f32;
    let (a, b) = (VIRIDIS[i], VIRIDIS[i + 1]);
    [0, 1, 2].map(|k| (f32::from(a[k]) + f * (f32::from(b[k]) - f32::from(a[k]))).round() as u8)
}

/// A linear map from values (`lo`..`hi`, in `unit`) to viridis.
#[derive(Debug, Clone, PartialEq)]
pub struct Scale {
    pub lo: f32,
    pub hi: f32,
    pub unit: String,
}

impl Scale {
    /// A scale from 0 to the largest finite value, rounded up to a round number (1, 2 or 5
    /// times a power of ten) so the legend reads well; at least `floor`.
    pub fn zero_to_max(values: &[f32], floor: f32, unit: &str) -> Scale {
        let max = values
            .iter()
            .copied()
            .filter(|v| v.is_finite())
            .fold(floor, f32::max);
        Scale {
            lo: 0.0,
            hi: round_up(max),
            unit: unit.to_string(),
        }
    }

    /// The colour of `value`; NaN and infinities are [`MISSING`].
    pub fn colour(&self, value: f32) -> [u8; 3] {
        if !value.is_finite() {
            return MISSING;
        }
        let span = self.hi - self.lo;
        let t = if span > 0.0 {
            (value - self.lo) / span
        } else {
            0.0
        };
        viridis(t)
    }

    /// The colours of many values.
    pub fn colours(&self, values: &[f32]) -> Vec<[u8; 3]> {
        values.iter().map(|&v| self.colour(v)).collect()
    }
}

/// The smallest of 1, 2, 5 x 10^k that is >= x (x > 0).
pub fn round_up(x: f32) -> f32 {
    if !(x > 0.0 && x.is_finite()) {
        return 1.0;
    }
    let p = 10f32.powf(x.log10().floor());
    for m in [1.0, 2.0, 5.0, 10.0] {
        if m * p >= x * (1.0 - 1e-6) {
            return m * p;
        }
    }
    10.0 * p
}
