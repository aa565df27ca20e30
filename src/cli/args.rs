//! Checked number parsers for clap's `value_parser`: every floating-point flag goes through
//! one of these, so NaN, infinities and out-of-range values are refused when the command line
//! is parsed, with clap's error naming the flag (`invalid value 'nan' for '--fps <FPS>': ...`).
//!
//! ```ignore
//! #[arg(long, value_parser = Finite::positive(1000.0).f64())]
//! fps: f64,
//! ```

use std::ops::Bound;

/// A range of finite `f64` values a flag accepts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Finite {
    low: Bound<f64>,
    high: Bound<f64>,
}

impl Finite {
    /// `[0, max]`: a finite non-negative value no larger than `max`.
    pub const fn non_negative(max: f64) -> Self {
        Self {
            low: Bound::Included(0.0),
            high: Bound::Included(max),
        }
    }

    /// `(0, max]`: a finite positive value no larger than `max`.
    pub const fn positive(max: f64) -> Self {
        Self {
            low: Bound::Excluded(0.0),
            high: Bound::Included(max),
        }
    }

    /// `[min, max]`: a finite value in a closed range.
    pub const fn in_range(min: f64, max: f64) -> Self {
        Self {
            low: Bound::Included(min),
            high: Bound::Included(max),
        }
    }

    /// `(min, max)`: a finite value strictly between two bounds.
    pub const fn between(min: f64, max: f64) -> Self {
        Self {
            low: Bound::Excluded(min),
            high: Bound::Excluded(max),
        }
    }

    /// Whether `v` is finite and inside the range.
    pub fn contains(&self, v: f64) -> bool {
        let above = match self.low {
            Bound::Included(l) => v >= l,
            Bound::Excluded(l) => v > l,
            Bound::Unbounded => true,
        };
        let below = match self.high {
            Bound::Included(h) => v <= h,
            Bound::Excluded(h) => v < h,
            Bound::Unbounded => true,
        };
        v.is_finite() && above && below
    }

    /// The range in interval notation, `[0, 45]`, `(0, 180)`.
    fn describe(&self) -> String {
        let low = match self.low {
            Bound::Included(l) => format!("[{l}"),
            Bound::Excluded(l) => format!("({l}"),
            Bound::Unbounded => "(-inf".to_owned(),
        };
        let high = match self.high {
            Bound::Included(h) => format!("{h}]"),
            Bound::Excluded(h) => format!("{h})"),
            Bound::Unbounded => "inf)".to_owned(),
        };
        format!("{low}, {high}")
    }

    /// Parses `s` as a finite number inside the range; the error says what was expected.
    pub fn parse(&self, s: &str) -> Result<f64, String> {
        let v: f64 = s
            .trim()
            .parse()
            .map_err(|_| format!("{s:?} is not a number"))?;
        if !v.is_finite() {
            return Err(format!("{s} is not a finite number"));
        }
        if !self.contains(v) {
            return Err(format!("{v} is outside {}", self.describe()));
        }
        Ok(v)
    }

    /// A clap value parser for an `f64` flag.
    pub fn f64(self) -> impl Fn(&str) -> Result<f64, String> + Clone + Send + Sync + 'static {
        move |s| self.parse(s)
    }

    /// A clap value parser for an `f32` flag (the range is checked on the `f64` value).
    pub fn f32(self) -> impl Fn(&str) -> Result<f32, String> + Clone + Send + Sync + 'static {
        // In range and finite as f64; the bounds used for f32 flags are small, so the
        // conversion cannot overflow.
        move |s| self.parse(s).map(|v| v as f32)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refuses_non_finite_and_out_of_range() {
        let p = Finite::non_negative(45.0);
        assert_eq!(p.parse("1.5"), Ok(1.5));
        assert_eq!(p.parse("0"), Ok(0.0));
        assert_eq!(p.parse("45"), Ok(45.0));
        for bad in [
            "nan", "NaN", "inf", "-inf", "infinity", "-1", "45.01", "1e308", "x", "",
        ] {
            assert!(p.parse(bad).is_err(), "{bad} accepted");
        }
        let e = p.parse("-1").unwrap_err();
        assert!(e.contains("[0, 45]"), "{e}");
        let e = p.parse("nan").unwrap_err();
        assert!(e.contains("finite"), "{e}");
    }

    #[test]
    fn open_and_half_open_bounds() {
        let fps = Finite::positive(1000.0);
        assert!(fps.parse("0").is_err());
        assert_eq!(fps.parse("1000"), Ok(1000.0));
        let fov = Finite::between(0.0, 180.0);
        assert!(fov.parse("180").is_err());
        assert!(fov.parse("0").is_err());
        assert_eq!(fov.parse("179.5"), Ok(179.5));
        let e = fov.parse("180").unwrap_err();
        assert!(e.contains("(0, 180)"), "{e}");
        let lag = Finite::in_range(-60.0, 60.0);
        assert_eq!(lag.parse("-0.5"), Ok(-0.5));
        assert!(lag.parse("-61").is_err());
    }

    #[test]
    fn f32_parser_keeps_the_value() {
        assert_eq!((Finite::non_negative(1.0).f32())("0.25"), Ok(0.25f32));
        assert!((Finite::non_negative(1.0).f32())("nan").is_err());
    }
}
