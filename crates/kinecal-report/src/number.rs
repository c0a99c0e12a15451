//! Numbers as a person reads them: the one formatter of every page, table and summary kinecal
//! shows (files kinecal writes for programs keep every digit: `kinecal::units::number`).

/// `v` to `digits` significant digits: plain decimals from 1e-4 to 1e9 in magnitude (`0.2102`,
/// `3478`, `12.50`), an exponent outside (`6.493e-5`, `2.5e12`), `0` for zero, `n/a` for a
/// number that is not finite.
pub fn sig(v: f64, digits: usize) -> String {
    let digits = digits.max(1);
    if v == 0.0 {
        return "0".into();
    }
    if !v.is_finite() {
        return "n/a".into();
    }
    let e = v.abs().log10().floor() as i32;
    if !(-4..9).contains(&e) {
        return format!("{v:.*e}", digits - 1);
    }
    let decimals = (digits as i32 - 1 - e).max(0) as usize;
    let s = format!("{v:.decimals$}");
    // Rounding up to the next power of ten (9.9996 to 4 digits) keeps `digits` digits.
    let shown = s.trim_start_matches('-').replace('.', "");
    if shown.trim_start_matches('0').len() > digits && decimals > 0 {
        return format!("{v:.*}", decimals - 1);
    }
    s
}

/// [`sig`] to four significant digits: a number in a page's tables and sentences.
pub fn num(v: f64) -> String {
    sig(v, 4)
}

/// [`sig`] with a sign: `+0.0120`, `-3.5`.
pub fn signed(v: f64, digits: usize) -> String {
    if v > 0.0 {
        format!("+{}", sig(v, digits))
    } else {
        sig(v, digits)
    }
}

/// `v` with `decimals` decimals for the columns of a table, or 4 significant digits with an
/// exponent when those decimals would show fewer than two of its digits (a small error is not
/// printed as `0.000000`).
pub fn fixed(v: f64, decimals: usize) -> String {
    if !v.is_finite() {
        return "n/a".into();
    }
    // No `-0.000000` for a negative zero.
    let v = if v == 0.0 { 0.0 } else { v };
    if v != 0.0 && v.abs() < 10f64.powi(1 - decimals as i32) {
        format!("{v:.3e}")
    } else {
        format!("{v:.decimals$}")
    }
}

/// [`fixed`] with a sign (a plus for zero too: a change).
pub fn fixed_signed(v: f64, decimals: usize) -> String {
    if v >= 0.0 {
        format!("+{}", fixed(v, decimals))
    } else {
        fixed(v, decimals)
    }
}

/// A dimensionless figure (a ratio, a variance factor): four decimals from 1 to 1e5, four
/// significant digits down to 1e-3, an exponent beyond (never `0.0000` for a small value).
pub fn ratio(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let e = v.abs().log10().floor() as i32;
    if (0..5).contains(&e) {
        format!("{v:.4}")
    } else if (-3..0).contains(&e) {
        format!("{v:.*}", (3 - e) as usize)
    } else {
        format!("{v:.3e}")
    }
}

/// [`sig`] to 4 digits of a number that may be absent: `n/a` then.
pub fn opt(v: Option<f64>) -> String {
    v.map_or_else(|| "n/a".into(), |v| sig(v, 4))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn significant_digits_plain_or_with_an_exponent() {
        assert_eq!(sig(0.210241, 4), "0.2102");
        assert_eq!(sig(3478.1, 4), "3478");
        assert_eq!(sig(12.5, 4), "12.50");
        assert_eq!(sig(0.0004394, 4), "0.0004394");
        assert_eq!(sig(0.000004394, 4), "4.394e-6");
        assert_eq!(sig(-2.5e12, 2), "-2.5e12");
        assert_eq!(sig(9.99996, 4), "10.00");
        assert_eq!(sig(0.0, 4), "0");
        assert_eq!(sig(f64::NAN, 4), "n/a");
        assert_eq!(signed(0.012, 3), "+0.0120");
        assert_eq!(signed(-3.5, 2), "-3.5");
    }

    #[test]
    fn numbers_in_tables_are_plain_with_four_significant_digits() {
        assert_eq!(num(8.04273e-2), "0.08043");
        assert_eq!(num(3478.053673), "3478");
        assert_eq!(num(0.000864), "0.0008640");
        assert_eq!(num(0.0), "0");
        assert_eq!(num(-0.4995), "-0.4995");
        assert_eq!(num(1e-12), "1.000e-12");
        assert_eq!(num(4.394e-6), "4.394e-6");
        assert_eq!(signed(0.05031, 4), "+0.05031");
    }

    #[test]
    fn table_columns_keep_their_decimals_unless_they_would_show_nothing() {
        assert_eq!(fixed(0.232016, 6), "0.232016");
        assert_eq!(fixed(0.0000012, 6), "1.200e-6");
        assert_eq!(fixed(20.9004461, 6), "20.900446");
        assert_eq!(fixed_signed(0.0, 6), "+0.000000");
        assert_eq!(ratio(1.0895), "1.0895");
        assert_eq!(ratio(0.009201), "0.009201");
        assert_eq!(ratio(1.5e-5), "1.500e-5");
    }
}
