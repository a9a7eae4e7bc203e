//! Status and errors: the FMI status codes ([`Status`]), why a call failed ([`FmiError`]), the
//! one place where errors become status codes ([`FmiError::status`]), and the message of a
//! caught panic.

/// fmi2Status values.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Status {
    Ok = 0,
    Warning = 1,
    Discard = 2,
    Error = 3,
    Fatal = 4,
    Pending = 5,
}

/// Why a call failed.
#[derive(Clone, Debug, PartialEq)]
pub enum FmiError {
    /// The call is not allowed in the instance's current state.
    IllegalCall(String),
    /// A bad argument: unknown value reference, wrong type, NaN, out of range, bad state data...
    Invalid(String),
    /// The solver failed (blow-up, material collapse, overlap) or the model could not be built.
    Solver(String),
    /// A status that is not provided (fmi2Discard by the standard).
    NotProvided(String),
    /// The instance can no longer be used.
    Fatal(String),
}

impl FmiError {
    /// The FMI status of an error: the one place where errors become status codes.
    pub fn status(&self) -> Status {
        match self {
            FmiError::IllegalCall(_) | FmiError::Invalid(_) | FmiError::Solver(_) => Status::Error,
            FmiError::NotProvided(_) => Status::Discard,
            FmiError::Fatal(_) => Status::Fatal,
        }
    }
    pub fn message(&self) -> &str {
        match self {
            FmiError::IllegalCall(m)
            | FmiError::Invalid(m)
            | FmiError::Solver(m)
            | FmiError::NotProvided(m)
            | FmiError::Fatal(m) => m,
        }
    }
}

pub type FmiResult<T> = Result<T, FmiError>;

/// The message of a caught panic (for the error that reports it).
pub(crate) fn panic_message(p: &(dyn std::any::Any + Send)) -> String {
    p.downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| p.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown panic".into())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn error_statuses() {
        assert_eq!(FmiError::IllegalCall("x".into()).status(), Status::Error);
        assert_eq!(FmiError::NotProvided("x".into()).status(), Status::Discard);
        assert_eq!(FmiError::Fatal("x".into()).status(), Status::Fatal);
    }
}
