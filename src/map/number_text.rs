//! How a number is written in a map message: plainly where that is short, in exponent
//! notation where it is not. Rust writes `1e300` as a 301-digit number; a message quoting a
//! nonsense value must still be readable.

use std::fmt;

/// Below this magnitude (and above 0) a number is written with an exponent.
const SMALLEST_PLAIN: f64 = 1e-4;
/// At or above this magnitude a number is written with an exponent: far beyond any sane map
/// value (coordinates are at most 1e7 m), and at most 10 digits written out.
const LARGEST_PLAIN: f64 = 1e10;

/// `f64` written by the one rule of map messages: `{}` for 0 and magnitudes in
/// [1e-4, 1e10), `{:e}` otherwise; a precision (`{:.2}`) is kept in both forms.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Num(pub f64);

impl fmt::Display for Num {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let v = self.0;
        let plain =
            v == 0.0 || !v.is_finite() || (SMALLEST_PLAIN..LARGEST_PLAIN).contains(&v.abs());
        match (plain, f.precision()) {
            (true, Some(p)) => write!(f, "{v:.p$}"),
            (true, None) => write!(f, "{v}"),
            (false, Some(p)) => write!(f, "{v:.p$e}"),
            (false, None) => write!(f, "{v:e}"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Num;

    #[test]
    fn huge_and_tiny_numbers_are_short() {
        assert_eq!(Num(1e300).to_string(), "1e300");
        assert_eq!(Num(-1e300).to_string(), "-1e300");
        assert_eq!(Num(3.5).to_string(), "3.5");
        assert_eq!(Num(-5.0).to_string(), "-5");
        assert_eq!(Num(0.0).to_string(), "0");
        assert_eq!(Num(2.5e-7).to_string(), "2.5e-7");
        assert_eq!(format!("{:.2}", Num(1.2345)), "1.23");
        assert_eq!(format!("{:.2}", Num(1.5e300)), "1.50e300");
        assert_eq!(Num(10_000_000.0).to_string(), "10000000");
        assert_eq!(Num(1e9).to_string(), "1000000000");
        assert_eq!(Num(1e10).to_string(), "1e10");
    }
}
