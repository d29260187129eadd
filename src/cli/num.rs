//! Numbers for people: plain decimals where they read better, scientific notation only for very
//! large or small magnitudes (never `8.223586e0`).

/// `x` to `digits` significant digits: a plain decimal for 1e-3 <= |x| < 1e6 (`0.03846`,
/// `2.308`, `37.72`), otherwise scientific (`3.846e-5`); 0 as `0`; NaN and infinities as Rust
/// prints them.
pub fn sig(x: f64, digits: usize) -> String {
    let digits = digits.max(1);
    if !x.is_finite() {
        return x.to_string();
    }
    if x == 0.0 {
        return "0".into();
    }
    let mag = x.abs();
    if (1e-3..1e6).contains(&mag) {
        let exponent = mag.log10().floor() as i64;
        let decimals = (digits as i64 - 1 - exponent).max(0) as usize;
        let plain = format!("{x:.decimals$}");
        // Rounding can carry into one more digit (9.9996 -> 10.000): drop the extra decimal.
        let carried = plain
            .parse::<f64>()
            .is_ok_and(|r| r.abs() >= 10f64.powi(exponent as i32 + 1));
        if decimals > 0 && carried {
            return format!("{x:.prec$}", prec = decimals - 1);
        }
        plain
    } else {
        format!("{x:.prec$e}", prec = digits - 1)
    }
}

#[cfg(test)]
mod tests {
    use super::sig;

    #[test]
    fn plain_in_the_readable_range_scientific_outside() {
        assert_eq!(sig(0.038460, 4), "0.03846");
        assert_eq!(sig(2.3076, 4), "2.308");
        assert_eq!(sig(37.72, 4), "37.72");
        assert_eq!(sig(-8.223586, 4), "-8.224");
        assert_eq!(sig(123456.0, 4), "123456");
        assert_eq!(sig(0.001, 3), "0.00100");
        assert_eq!(sig(3.8460e-5, 4), "3.846e-5");
        assert_eq!(sig(2.5e7, 3), "2.50e7");
        assert_eq!(sig(0.0, 4), "0");
        assert_eq!(sig(f64::NAN, 4), "NaN");
        assert_eq!(sig(9.9996, 4), "10.00");
        assert_eq!(sig(0.99996, 4), "1.000");
    }
}
