//! Numbers as people read them in messages: short, with an exponent when very large or small
//! (Rust prints 1e300 with 300 digits otherwise).

/// A number for a message: up to 6 significant digits, scientific beyond 1e6 or below 1e-4.
pub fn readable(x: f64) -> String {
    if !x.is_finite() {
        return format!("{x}");
    }
    let a = x.abs();
    if a == 0.0 {
        return "0".into();
    }
    if !(1e-4..1e6).contains(&a) {
        format!("{x:.3e}")
    } else {
        // Six significant digits.
        let decimals = (5 - a.log10().floor() as i32).clamp(0, 9) as usize;
        let s = format!("{x:.decimals$}");
        let s = s.trim_end_matches('0').trim_end_matches('.');
        if s.is_empty() || s == "-" {
            "0".into()
        } else {
            s.into()
        }
    }
}
