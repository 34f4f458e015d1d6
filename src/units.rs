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

#[cfg(test)]
mod tests {
    use super::readable;

    #[test]
    fn numbers_stay_short() {
        assert_eq!(readable(1e300), "1.000e300");
        assert_eq!(readable(0.5), "0.5");
        assert_eq!(readable(-0.53), "-0.53");
        assert_eq!(readable(3.0), "3");
        assert_eq!(readable(30.667575), "30.6676");
        assert_eq!(readable(0.0), "0");
        assert_eq!(readable(1e-7), "1.000e-7");
        assert_eq!(readable(f64::NAN), "NaN");
        assert_eq!(readable(f32::MAX as f64), "3.403e38");
    }
}
