//! Checks of configuration values, shared by every crate that reads a machine file: a
//! refused value is a [`FieldError`] naming its field (a dotted path) and the reason.

/// A configuration value was refused: `field` names it (dotted path, e.g.
/// `joints[1].motor.inertia`), `reason` says why.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{field}: {reason}")]
pub struct FieldError {
    /// Dotted path of the refused field.
    pub field: String,
    /// Why it was refused.
    pub reason: String,
}

impl FieldError {
    /// A refusal of `field` for `reason`.
    ///
    /// Real-time: no (set-up: allocates).
    pub fn new(field: impl Into<String>, reason: impl Into<String>) -> Self {
        Self {
            field: field.into(),
            reason: reason.into(),
        }
    }

    /// The same error with `prefix.` in front of the field, for a caller that nests the
    /// configuration (e.g. `joints[2].servo`).
    ///
    /// Real-time: no (set-up: allocates).
    pub fn within(mut self, prefix: &str) -> Self {
        self.field = format!("{prefix}.{}", self.field);
        self
    }

    /// Stable code of every refused configuration value.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn code(&self) -> &'static str {
        "config.invalid"
    }
}

/// A finite number.
///
/// Real-time: no (set-up: a refusal allocates its message).
pub fn finite(field: &str, value: f64) -> Result<(), FieldError> {
    if value.is_finite() {
        Ok(())
    } else {
        Err(FieldError::new(field, "must be a finite number"))
    }
}

/// A finite number, zero or more.
///
/// Real-time: no (set-up: a refusal allocates its message).
pub fn non_negative(field: &str, value: f64) -> Result<(), FieldError> {
    finite(field, value)?;
    if value >= 0.0 {
        Ok(())
    } else {
        Err(FieldError::new(field, "must not be negative"))
    }
}

/// A finite number greater than zero.
///
/// Real-time: no (set-up: a refusal allocates its message).
pub fn positive(field: &str, value: f64) -> Result<(), FieldError> {
    finite(field, value)?;
    if value > 0.0 {
        Ok(())
    } else {
        Err(FieldError::new(field, "must be greater than zero"))
    }
}

/// A finite number within `low..=high`; the reason gives the range and its unit.
///
/// Real-time: no (set-up: a refusal allocates its message).
pub fn within(field: &str, value: f64, low: f64, high: f64, unit: &str) -> Result<(), FieldError> {
    finite(field, value)?;
    if (low..=high).contains(&value) {
        Ok(())
    } else {
        Err(FieldError::new(
            field,
            format!("must be between {low} and {high}{unit}"),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refusals_name_the_field_and_the_reason() {
        assert_eq!(
            positive("a.b", 0.0).unwrap_err().to_string(),
            "a.b: must be greater than zero"
        );
        assert_eq!(
            finite("x", f64::NAN)
                .unwrap_err()
                .within("joints[1]")
                .to_string(),
            "joints[1].x: must be a finite number"
        );
        assert!(non_negative("x", 0.0).is_ok());
        assert_eq!(
            within("p", 2e-6, 5e-5, 0.1, " s").unwrap_err().reason,
            "must be between 0.00005 and 0.1 s"
        );
    }
}
