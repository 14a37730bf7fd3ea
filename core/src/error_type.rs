//! The two kinds of task failure the orchestrator tells apart, and their names on the wire.
//!
//! A function that fails reports one of these as its error type (the Lambda `errorType`, which
//! Step Functions matches in `Retry` and `Catch`). `infra/statemachine.asl.json` retries
//! [`ErrorType::Retryable`] with backoff and never retries [`ErrorType::BadInput`].

use std::fmt;

/// Whether running the same task again may succeed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ErrorType {
    /// Storage trouble (throttling, timeouts, 5xx) or a corrupt object that a retry may find
    /// rewritten: `Hort.Retryable`.
    Retryable,
    /// A bad scene, request or event, or an object that does not exist (S3 is strongly
    /// consistent, so it will not appear on a retry): `Hort.BadInput`. No retry can fix it.
    BadInput,
}

impl ErrorType {
    /// Both error types.
    pub const ALL: [ErrorType; 2] = [ErrorType::Retryable, ErrorType::BadInput];

    /// The error name the state machine matches: `Hort.Retryable` or `Hort.BadInput`.
    pub const fn as_str(self) -> &'static str {
        match self {
            ErrorType::Retryable => "Hort.Retryable",
            ErrorType::BadInput => "Hort.BadInput",
        }
    }

    /// The error type named `name`, if it is one of [`ErrorType::ALL`].
    pub fn from_name(name: &str) -> Option<ErrorType> {
        Self::ALL.into_iter().find(|t| t.as_str() == name)
    }
}

impl fmt::Display for ErrorType {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

#[cfg(test)]
mod tests {
    use super::ErrorType;

    #[test]
    fn names_are_the_documented_ones_and_round_trip() {
        assert_eq!(ErrorType::Retryable.as_str(), "Hort.Retryable");
        assert_eq!(ErrorType::BadInput.to_string(), "Hort.BadInput");
        assert_eq!(
            ErrorType::from_name("Hort.Retryable"),
            Some(ErrorType::Retryable)
        );
        assert_eq!(
            ErrorType::from_name("Hort.BadInput"),
            Some(ErrorType::BadInput)
        );
        assert_eq!(ErrorType::from_name("States.Timeout"), None);
    }
}
