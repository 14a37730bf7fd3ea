//! Typed identifiers of the HORT pipeline: job, task, split, partition (stages: [`crate::stage`]).
//!
//! Every id that reaches an object key or a state-machine payload goes through these types, so a
//! split index can never be passed where a partition index is expected. Ids serialize as plain
//! JSON strings (`JobId`) or numbers (the `u32` newtypes).

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

/// Why a string is not a valid [`JobId`] or [`crate::stage::Stage`].
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum IdError {
    /// The job id is empty or longer than [`JobId::MAX_LEN`] characters.
    #[error("invalid job id {id:?}: must be 1 to 64 characters long, found {len}")]
    JobIdLength {
        /// The rejected id.
        id: String,
        /// Its length in bytes.
        len: usize,
    },
    /// The job id contains a character outside `[a-z0-9-]`.
    #[error("invalid job id {id:?}: character {found:?} is not one of a-z, 0-9, '-'")]
    JobIdChar {
        /// The rejected id.
        id: String,
        /// The first offending character.
        found: char,
    },
    /// The string names no stage.
    #[error(
        "unknown stage {found:?}: expected one of plan, partition, build, render, cast-map, cast-reduce, expand, trace-map, trace-reduce, combine"
    )]
    UnknownStage {
        /// The rejected stage name.
        found: String,
    },
}

/// A job identifier: 1 to 64 characters, each one of `a-z`, `0-9` or `-`.
///
/// Guarantee: every value of this type satisfies that rule (construction validates it, and so does
/// deserialization), so a job id is always safe as one object-key segment and as a Step Functions
/// execution name.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub struct JobId(String);

impl JobId {
    /// The longest accepted job id, in characters.
    pub const MAX_LEN: usize = 64;

    /// Validates `id`; returns an [`IdError`] naming the id and the rule it breaks.
    pub fn new(id: impl Into<String>) -> Result<Self, IdError> {
        let id = id.into();
        if id.is_empty() || id.len() > Self::MAX_LEN {
            let len = id.len();
            return Err(IdError::JobIdLength { id, len });
        }
        let bad = id
            .chars()
            .find(|c| !(c.is_ascii_lowercase() || c.is_ascii_digit() || *c == '-'));
        match bad {
            Some(found) => Err(IdError::JobIdChar { id, found }),
            None => Ok(Self(id)),
        }
    }

    /// The id as validated text.
    pub fn as_str(&self) -> &str {
        &self.0
    }
}

impl fmt::Display for JobId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl FromStr for JobId {
    type Err = IdError;
    fn from_str(s: &str) -> Result<Self, IdError> {
        Self::new(s)
    }
}

impl TryFrom<String> for JobId {
    type Error = IdError;
    fn try_from(s: String) -> Result<Self, IdError> {
        Self::new(s)
    }
}

impl From<JobId> for String {
    fn from(id: JobId) -> String {
        id.0
    }
}

macro_rules! index_id {
    ($(#[$doc:meta])* $name:ident) => {
        $(#[$doc])*
        #[derive(
            Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default, Serialize, Deserialize,
        )]
        #[serde(transparent)]
        pub struct $name(pub u32);

        impl fmt::Display for $name {
            /// The plain decimal index (object keys zero-pad it themselves).
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                write!(f, "{}", self.0)
            }
        }

        impl From<u32> for $name {
            fn from(index: u32) -> Self {
                Self(index)
            }
        }
    };
}

index_id!(
    /// Index of a task within one stage, 0-based; serializes as a JSON number.
    TaskId
);
index_id!(
    /// Index of a scene split, 0-based, `< k`; serializes as a JSON number.
    SplitId
);
index_id!(
    /// Index of a shuffle partition, 0-based; for reduce stages the span index. Serializes as a
    /// JSON number.
    PartitionId
);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn job_id_accepts_the_documented_alphabet_and_lengths() {
        for ok in [
            "a",
            "job-1",
            "0123456789-abcdefghijklmnopqrstuvwxyz",
            &"x".repeat(64),
        ] {
            assert_eq!(JobId::new(ok).map(|j| j.to_string()), Ok(ok.to_owned()));
        }
    }

    #[test]
    fn job_id_rejects_bad_length_and_characters() {
        assert!(matches!(
            JobId::new(""),
            Err(IdError::JobIdLength { len: 0, .. })
        ));
        assert!(matches!(
            JobId::new("x".repeat(65)),
            Err(IdError::JobIdLength { len: 65, .. })
        ));
        for (bad, c) in [
            ("Job", 'J'),
            ("a/b", '/'),
            ("a_b", '_'),
            ("a b", ' '),
            ("é", 'é'),
        ] {
            assert_eq!(
                JobId::new(bad),
                Err(IdError::JobIdChar {
                    id: bad.to_owned(),
                    found: c
                })
            );
        }
        let msg = JobId::new("a/b").unwrap_err().to_string();
        assert!(msg.contains("\"a/b\"") && msg.contains("'/'"), "{msg}");
    }

    #[test]
    fn serde_uses_strings_and_numbers_and_validates() {
        let job = JobId::new("job-7").unwrap();
        assert_eq!(serde_json::to_string(&job).unwrap(), "\"job-7\"");
        assert_eq!(serde_json::from_str::<JobId>("\"job-7\"").unwrap(), job);
        assert!(serde_json::from_str::<JobId>("\"Job 7\"").is_err());
        assert_eq!(serde_json::to_string(&TaskId(12)).unwrap(), "12");
        assert_eq!(
            serde_json::from_str::<PartitionId>("3").unwrap(),
            PartitionId(3)
        );
        assert_eq!(serde_json::from_str::<SplitId>("4").unwrap(), SplitId(4));
        assert_eq!(TaskId(5).to_string(), "5");
    }
}
