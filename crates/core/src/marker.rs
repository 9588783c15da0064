//! Marker names with their subject prefix kept apart.
//!
//! Vicon Nexus and Shogun write `Subject:Marker` (`Male:LFWT`, `TakeoMonday:RKNE`); labeling
//! and layouts match on the marker part only, while writers must give the prefix back.
//! Unlabeled points are conventionally called `*N`.

use serde::{Deserialize, Serialize};

/// A marker's name, split into an optional subject prefix and the marker's own label.
#[derive(Debug, Clone, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct MarkerName {
    /// The subject prefix without its colon (`Male` in `Male:LFWT`), if any.
    pub subject: Option<String>,
    /// The marker's own label (`LFWT`).
    pub label: String,
}

impl MarkerName {
    /// Splits `full` at its first colon into subject and label. Surrounding blanks (C3D labels
    /// are blank-padded) are trimmed.
    pub fn parse(full: &str) -> MarkerName {
        let full = full.trim();
        match full.split_once(':') {
            Some((subject, label)) if !subject.is_empty() && !label.is_empty() => {
                MarkerName { subject: Some(subject.to_string()), label: label.to_string() }
            }
            _ => MarkerName { subject: None, label: full.to_string() },
        }
    }

    /// The name as files store it: `Subject:Label`, or the label alone.
    pub fn full(&self) -> String {
        match &self.subject {
            Some(subject) => format!("{subject}:{}", self.label),
            None => self.label.clone(),
        }
    }

    /// True if and only if this is an unlabeled point (`*N`, the vendors' convention).
    pub fn is_unlabeled(&self) -> bool {
        self.label.starts_with('*')
    }
}

impl std::fmt::Display for MarkerName {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.full())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn splits_subject_prefix() {
        let name = MarkerName::parse("Male:LFWT  ");
        assert_eq!(name.subject.as_deref(), Some("Male"));
        assert_eq!(name.label, "LFWT");
        assert_eq!(name.full(), "Male:LFWT");
        assert_eq!(MarkerName::parse("RBAC").subject, None);
        assert_eq!(MarkerName::parse(":odd").label, ":odd");
        assert!(MarkerName::parse("*12").is_unlabeled());
    }
}
