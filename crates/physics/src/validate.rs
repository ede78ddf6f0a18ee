//! Parameter validation shared by every param struct in grip (physics here,
//! controllers in `grip-tcs`): one error type naming the field and the reason.
//!
//! Every check is written so that NaN fails (`!(x > 0.0)` rather than `x <= 0.0`).

use std::fmt;

/// A parameter that failed validation: which field, and why.
///
/// `field` is a dotted path relative to the struct that was validated
/// (e.g. `mass`, `c2`, `segment[2].duration`); loaders prefix it with the
/// TOML table it came from (see [`InvalidField::prefixed`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct InvalidField {
    /// Dotted path of the offending field.
    pub field: String,
    /// Human-readable reason, including the offending value, e.g. `must be > 0 (got -5)`.
    pub reason: String,
}

impl InvalidField {
    /// A new error for `field` with `reason`.
    pub fn new(field: impl Into<String>, reason: impl Into<String>) -> Self {
        Self {
            field: field.into(),
            reason: reason.into(),
        }
    }

    /// The same error with `prefix.` in front of the field (no dot added when
    /// `prefix` is empty or the field is empty).
    pub fn prefixed(mut self, prefix: &str) -> Self {
        if !prefix.is_empty() {
            self.field = if self.field.is_empty() {
                prefix.to_owned()
            } else {
                format!("{prefix}.{}", self.field)
            };
        }
        self
    }
}

impl fmt::Display for InvalidField {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "field `{}`: {}", self.field, self.reason)
    }
}

impl std::error::Error for InvalidField {}

/// `value` must be finite.
pub fn finite(field: &str, value: f64) -> Result<(), InvalidField> {
    if value.is_finite() {
        Ok(())
    } else {
        Err(InvalidField::new(
            field,
            format!("must be a finite number (got {value})"),
        ))
    }
}

/// `value` must be finite and > 0.
pub fn positive(field: &str, value: f64) -> Result<(), InvalidField> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(InvalidField::new(
            field,
            format!("must be > 0 (got {value})"),
        ))
    }
}

/// `value` must be finite and >= 0.
pub fn non_negative(field: &str, value: f64) -> Result<(), InvalidField> {
    if value.is_finite() && value >= 0.0 {
        Ok(())
    } else {
        Err(InvalidField::new(
            field,
            format!("must be >= 0 (got {value})"),
        ))
    }
}

/// `value` must be finite and within `[lo, hi]` (inclusive).
pub fn in_range(field: &str, value: f64, lo: f64, hi: f64) -> Result<(), InvalidField> {
    if value.is_finite() && value >= lo && value <= hi {
        Ok(())
    } else {
        Err(InvalidField::new(
            field,
            format!("must be in [{lo}, {hi}] (got {value})"),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nan_fails_every_check() {
        assert!(finite("x", f64::NAN).is_err());
        assert!(positive("x", f64::NAN).is_err());
        assert!(non_negative("x", f64::NAN).is_err());
        assert!(in_range("x", f64::NAN, 0.0, 1.0).is_err());
        assert!(positive("x", f64::INFINITY).is_err());
    }

    #[test]
    fn bounds() {
        assert!(positive("x", 0.0).is_err());
        assert!(positive("x", 1e-9).is_ok());
        assert!(non_negative("x", 0.0).is_ok());
        assert!(non_negative("x", -1e-9).is_err());
        assert!(in_range("x", 1.0, 0.0, 1.0).is_ok());
        assert!(in_range("x", 1.1, 0.0, 1.0).is_err());
    }

    #[test]
    fn message_and_prefix() {
        let e = positive("mass", -5.0).unwrap_err().prefixed("vehicle");
        assert_eq!(e.field, "vehicle.mass");
        assert_eq!(e.to_string(), "field `vehicle.mass`: must be > 0 (got -5)");
        assert_eq!(InvalidField::new("", "r").prefixed("a").field, "a");
        assert_eq!(InvalidField::new("b", "r").prefixed("").field, "b");
    }
}
