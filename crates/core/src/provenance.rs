//! What locap changed in a take: the filled samples, the outlier windows it replaced, the label
//! swaps it undid and the method it filled with, as stored in the C3D group `LOCAP`.
//!
//! The stored form is text, one line per range, in C3D frame numbers (the take's
//! `first_frame` is the first frame; ranges are inclusive):
//!
//! | parameter | line | meaning |
//! |---|---|---|
//! | `LOCAP:FILLED` | `LABEL first-last` | samples locap computed (gaps and replaced outliers) |
//! | `LOCAP:OUTLIERS` | `LABEL first-last Kind` | samples removed as outliers (`Spike`, `Stuck`), then refilled |
//! | `LOCAP:SWAPS` | `LABEL_A LABEL_B first-last` | two markers whose samples were exchanged back |
//! | `LOCAP:FILLS` | `LABEL first-last method` | per gap, what filled it when the fill chooses per gap (`auto`: `pca`, `edm 0.62 + rigid 0.38`) |
//! | `LOCAP:METHOD` | free text | the fill, e.g. `Edm K=6` |
//!
//! The three lists are stored in the compact form of [`crate::range_list`] (files written by
//! earlier versions hold the lines themselves; both are read). Labels may contain spaces, so
//! a line is read from its end, and a swap's two labels are told apart with the take's labels.
//!
//! [`Provenance`] holds marker indices and 0-based frame ranges of one take, so the stage
//! that produced it and the viewer that shows it need no text; [`Provenance::to_parameters`]
//! and [`Provenance::from_parameters`] convert with the take's labels and first frame. The
//! C3D reader and writer (`locap_io::c3d`) move the strings in and out of files.

use crate::Take;
use crate::range_list::{self, RangeListError};
use std::ops::Range;

/// The C3D group the parameters live in.
pub const GROUP: &str = "LOCAP";

/// One run of frames of one marker (0-based, end excluded).
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct MarkerFrames {
    /// Marker index in the take.
    pub marker: usize,
    /// Frames of the take (0-based, end excluded).
    pub frames: Range<usize>,
}

/// One replaced outlier window.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct OutlierRecord {
    /// The marker and frames removed.
    pub at: MarkerFrames,
    /// Why, as the detector names it (`Spike`, `Stuck`).
    pub kind: String,
}

/// Two markers whose samples were exchanged back over some frames.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct SwapRecord {
    /// First marker index.
    pub a: usize,
    /// Second marker index.
    pub b: usize,
    /// Frames (0-based, end excluded).
    pub frames: Range<usize>,
}

/// What filled one gap, for a fill that chooses per gap.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct FillRecord {
    /// The gap.
    pub at: MarkerFrames,
    /// The method or blend, as the filler names it (no word of the form `first-last`).
    pub method: String,
}

/// What locap changed in one take (see the module docs for the stored form).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Provenance {
    /// The fill, as text (`LOCAP:METHOD`); `None` for a take locap did not fill.
    pub method: Option<String>,
    /// Runs of computed samples.
    pub filled: Vec<MarkerFrames>,
    /// Outlier windows removed and refilled.
    pub outliers: Vec<OutlierRecord>,
    /// Label swaps undone.
    pub swaps: Vec<SwapRecord>,
    /// Per gap, the method that filled it (empty when one method filled every gap).
    pub fills: Vec<FillRecord>,
}

/// A `LOCAP` parameter that does not describe the take it is read with.
#[derive(Debug, thiserror::Error)]
pub enum ProvenanceError {
    /// The compact list is corrupt.
    #[error("LOCAP:{parameter}: {source}")]
    List {
        /// The parameter.
        parameter: &'static str,
        /// What is wrong.
        #[source]
        source: RangeListError,
    },
    /// A line that does not parse or does not fit the take.
    #[error("LOCAP:{parameter}: `{line}`: {reason}")]
    Line {
        /// The parameter.
        parameter: &'static str,
        /// The line.
        line: String,
        /// What is wrong with it.
        reason: String,
    },
}

impl Provenance {
    /// The runs of `filled` (`[frame * markers + marker]`, as `Filled::filled` in the clean
    /// stage), marker by marker.
    ///
    /// # Panics
    /// If `filled` does not have one entry per sample of `take` (a programming error).
    pub fn runs_of(take: &Take, filled: &[bool]) -> Vec<MarkerFrames> {
        let m = take.marker_count();
        assert_eq!(filled.len(), m * take.frame_count(), "one mask entry per sample");
        let mut out = Vec::new();
        for marker in 0..m {
            let mask = (0..take.frame_count()).map(|f| !filled[f * m + marker]);
            for gap in crate::gaps::gaps_of(mask) {
                out.push(MarkerFrames { marker, frames: gap.start..gap.end() });
            }
        }
        out
    }

    /// The parameters to store, `(name, strings)`: `FILLED`, `OUTLIERS` and `SWAPS` in the
    /// compact form, then `METHOD` when there is one. Every list is written, empty or not, so
    /// a cleaned take says it has no outliers rather than leaving an older list in place.
    ///
    /// # Errors
    /// A list past the compact form's ceiling (see [`range_list::encode`]).
    ///
    /// # Panics
    /// If a record names a marker the take does not have (a programming error).
    pub fn to_parameters(&self, take: &Take) -> Result<Vec<(&'static str, Vec<String>)>, ProvenanceError> {
        let labels: Vec<String> = take.markers().iter().map(|m| m.full()).collect();
        let base = take.first_frame as usize;
        let range = |r: &Range<usize>| format!("{}-{}", base + r.start, base + r.end - 1);
        let filled: Vec<String> =
            self.filled.iter().map(|r| format!("{} {}", labels[r.marker], range(&r.frames))).collect();
        let outliers: Vec<String> = self
            .outliers
            .iter()
            .map(|o| format!("{} {} {}", labels[o.at.marker], range(&o.at.frames), o.kind))
            .collect();
        let swaps: Vec<String> =
            self.swaps.iter().map(|s| format!("{} {} {}", labels[s.a], labels[s.b], range(&s.frames))).collect();
        let encode = |parameter: &'static str, lines: &[String]| {
            range_list::encode(lines)
                .map(|s| (parameter, s))
                .map_err(|source| ProvenanceError::List { parameter, source })
        };
        let fills: Vec<String> = self
            .fills
            .iter()
            .map(|r| format!("{} {} {}", labels[r.at.marker], range(&r.at.frames), r.method))
            .collect();
        let mut out = vec![
            encode("FILLED", &filled)?,
            encode("OUTLIERS", &outliers)?,
            encode("SWAPS", &swaps)?,
            encode("FILLS", &fills)?,
        ];
        if let Some(method) = &self.method {
            out.push(("METHOD", vec![method.clone()]));
        }
        Ok(out)
    }

    /// Reads the parameters `get` returns (empty for an absent one) for `take`.
    ///
    /// # Errors
    /// A corrupt compact list, a line that does not parse, a label the take does not have, or
    /// a range outside the take's frames.
    pub fn from_parameters(take: &Take, get: impl Fn(&str) -> Vec<String>) -> Result<Provenance, ProvenanceError> {
        let labels: Vec<String> = take.markers().iter().map(|m| m.full()).collect();
        let reader = LineReader { labels: &labels, base: take.first_frame as usize, frames: take.frame_count() };
        let decode = |parameter: &'static str| {
            range_list::decode(&get(parameter)).map_err(|source| ProvenanceError::List { parameter, source })
        };
        let mut out = Provenance { method: get("METHOD").into_iter().next(), ..Provenance::default() };
        for line in decode("FILLED")? {
            let (head, frames) = reader.range_at_end(&line, "FILLED", &line)?;
            out.filled.push(MarkerFrames { marker: reader.marker(head, "FILLED", &line)?, frames });
        }
        for line in decode("OUTLIERS")? {
            // The kind follows the range.
            let (head, kind) = line.trim_end().rsplit_once(' ').ok_or_else(|| reader.bad(&line, "OUTLIERS"))?;
            let (label, frames) = reader.range_at_end(head, "OUTLIERS", &line)?;
            let at = MarkerFrames { marker: reader.marker(label, "OUTLIERS", &line)?, frames };
            out.outliers.push(OutlierRecord { at, kind: kind.to_string() });
        }
        for line in decode("SWAPS")? {
            let (pair, frames) = reader.range_at_end(&line, "SWAPS", &line)?;
            let (a, b) = reader.pair(pair, &line)?;
            out.swaps.push(SwapRecord { a, b, frames });
        }
        for line in decode("FILLS")? {
            // The method follows the range and may have several words: the range is the last
            // word of the form `first-last`.
            let words: Vec<&str> = line.split(' ').collect();
            let at = words.iter().rposition(|w| is_range(w)).ok_or_else(|| reader.bad(&line, "FILLS"))?;
            let head = words[..=at].join(" ");
            let (label, frames) = reader.range_at_end(&head, "FILLS", &line)?;
            let at_marker = MarkerFrames { marker: reader.marker(label, "FILLS", &line)?, frames };
            out.fills.push(FillRecord { at: at_marker, method: words[at + 1..].join(" ") });
        }
        Ok(out)
    }

    /// True when locap recorded nothing.
    pub fn is_empty(&self) -> bool {
        self.method.is_none()
            && self.filled.is_empty()
            && self.outliers.is_empty()
            && self.swaps.is_empty()
            && self.fills.is_empty()
    }
}

/// `first-last` with two numbers.
fn is_range(word: &str) -> bool {
    word.split_once('-').is_some_and(|(a, b)| {
        !a.is_empty() && !b.is_empty() && a.bytes().all(|c| c.is_ascii_digit()) && b.bytes().all(|c| c.is_ascii_digit())
    })
}

/// Parses the lines of one take's lists.
struct LineReader<'a> {
    labels: &'a [String],
    base: usize,
    frames: usize,
}

impl LineReader<'_> {
    fn bad(&self, line: &str, parameter: &'static str) -> ProvenanceError {
        let form = match parameter {
            "OUTLIERS" => "LABEL first-last Kind",
            "SWAPS" => "LABEL LABEL first-last",
            "FILLS" => "LABEL first-last method",
            _ => "LABEL first-last",
        };
        ProvenanceError::Line { parameter, line: line.to_string(), reason: format!("expected `{form}`") }
    }

    /// Splits `text` into what precedes its last word and that word read as a C3D frame range.
    fn range_at_end<'t>(
        &self,
        text: &'t str,
        parameter: &'static str,
        line: &str,
    ) -> Result<(&'t str, Range<usize>), ProvenanceError> {
        let (head, range) = text.trim_end().rsplit_once(' ').ok_or_else(|| self.bad(line, parameter))?;
        let (first, last) = range.split_once('-').ok_or_else(|| self.bad(line, parameter))?;
        let (Ok(first), Ok(last)) = (first.parse::<usize>(), last.parse::<usize>()) else {
            return Err(self.bad(line, parameter));
        };
        if first > last || first < self.base || last - self.base >= self.frames {
            let reason = format!(
                "frames {first}-{last} are outside the take's frames {}-{}",
                self.base,
                (self.base + self.frames).saturating_sub(1)
            );
            return Err(ProvenanceError::Line { parameter, line: line.to_string(), reason });
        }
        Ok((head, first - self.base..last - self.base + 1))
    }

    fn marker(&self, label: &str, parameter: &'static str, line: &str) -> Result<usize, ProvenanceError> {
        let label = label.trim();
        self.labels.iter().position(|l| l == label).ok_or_else(|| ProvenanceError::Line {
            parameter,
            line: line.to_string(),
            reason: format!("the take has no marker `{label}`"),
        })
    }

    /// Two labels separated by a space, either of which may contain spaces: the split point
    /// where both halves are labels of the take.
    fn pair(&self, text: &str, line: &str) -> Result<(usize, usize), ProvenanceError> {
        let text = text.trim();
        let found = text.match_indices(' ').find_map(|(i, _)| {
            let a = self.labels.iter().position(|l| l == &text[..i])?;
            let b = self.labels.iter().position(|l| l == &text[i + 1..])?;
            Some((a, b))
        });
        found.ok_or_else(|| ProvenanceError::Line {
            parameter: "SWAPS",
            line: line.to_string(),
            reason: "not two labels of the take".into(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{MarkerName, Vec3};
    use std::collections::HashMap;

    fn take() -> Take {
        let markers = vec![MarkerName::parse("A"), MarkerName::parse("Sub:B C"), MarkerName::parse("D")];
        let samples = vec![Some(Vec3::new(1.0, 2.0, 3.0)); 10 * 3];
        let mut t = Take::from_samples(markers, &samples, 100.0).unwrap();
        t.first_frame = 11;
        t
    }

    fn provenance() -> Provenance {
        Provenance {
            method: Some("Edm K=6".into()),
            filled: vec![
                MarkerFrames { marker: 0, frames: 1..4 },
                MarkerFrames { marker: 1, frames: 2..6 },
                MarkerFrames { marker: 1, frames: 9..10 },
            ],
            outliers: vec![OutlierRecord { at: MarkerFrames { marker: 1, frames: 5..7 }, kind: "Spike".into() }],
            swaps: vec![SwapRecord { a: 1, b: 2, frames: 0..10 }],
            fills: vec![
                FillRecord { at: MarkerFrames { marker: 1, frames: 2..6 }, method: "edm 0.62 + pca 0.38".into() },
                FillRecord { at: MarkerFrames { marker: 0, frames: 1..4 }, method: "default: rigid".into() },
            ],
        }
    }

    fn stored(p: &Provenance, t: &Take) -> HashMap<&'static str, Vec<String>> {
        p.to_parameters(t).unwrap().into_iter().collect()
    }

    #[test]
    fn parameters_round_trip_with_labels_that_contain_spaces() {
        let (t, p) = (take(), provenance());
        let params = stored(&p, &t);
        assert_eq!(params["METHOD"], ["Edm K=6"]);
        assert_eq!(params["FILLED"][0], range_list::MAGIC);
        let lines = range_list::decode(&params["FILLED"]).unwrap();
        assert_eq!(lines, ["A 12-14", "Sub:B C 13-16", "Sub:B C 20-20"]);
        assert_eq!(range_list::decode(&params["OUTLIERS"]).unwrap(), ["Sub:B C 16-17 Spike"]);
        assert_eq!(range_list::decode(&params["SWAPS"]).unwrap(), ["Sub:B C D 11-20"]);
        assert_eq!(
            range_list::decode(&params["FILLS"]).unwrap(),
            ["Sub:B C 13-16 edm 0.62 + pca 0.38", "A 12-14 default: rigid"]
        );
        let back = Provenance::from_parameters(&t, |name| params.get(name).cloned().unwrap_or_default()).unwrap();
        assert_eq!(back, p);
    }

    #[test]
    fn plain_lines_of_earlier_versions_are_read() {
        let t = take();
        let params: HashMap<&str, Vec<String>> =
            [("FILLED", vec!["A 12-14".to_string()]), ("OUTLIERS", vec!["Sub:B C 16-17 Stuck".to_string()])]
                .into_iter()
                .collect();
        let p = Provenance::from_parameters(&t, |n| params.get(n).cloned().unwrap_or_default()).unwrap();
        assert_eq!(p.filled, [MarkerFrames { marker: 0, frames: 1..4 }]);
        assert_eq!(p.outliers[0].kind, "Stuck");
        assert!(p.method.is_none() && p.swaps.is_empty() && p.fills.is_empty());
    }

    #[test]
    fn bad_lines_are_clear_errors_naming_the_parameter() {
        let t = take();
        let err = |name: &'static str, line: &str| {
            let line = line.to_string();
            Provenance::from_parameters(&t, |n| if n == name { vec![line.clone()] } else { Vec::new() })
                .unwrap_err()
                .to_string()
        };
        assert!(err("FILLED", "A 12").contains("expected `LABEL first-last`"));
        assert!(err("FILLED", "Z 12-13").contains("no marker `Z`"));
        assert!(err("FILLED", "A 5-13").contains("outside the take's frames 11-20"));
        assert!(err("FILLED", "A 14-12").contains("outside"));
        assert!(err("OUTLIERS", "A 12-13").contains("LOCAP:OUTLIERS"));
        assert!(err("SWAPS", "A Z 12-13").contains("not two labels"));
        assert!(err("FILLS", "A pca").contains("expected `LABEL first-last method`"));
        let corrupt = Provenance::from_parameters(&t, |n| {
            if n == "FILLED" { vec![range_list::MAGIC.to_string(), "g".to_string()] } else { Vec::new() }
        });
        assert!(corrupt.unwrap_err().to_string().contains("LOCAP:FILLED"));
    }

    #[test]
    fn runs_of_a_mask_are_per_marker_runs() {
        let t = take();
        let mut mask = vec![false; 30];
        for f in [1, 2, 3, 7] {
            mask[f * 3] = true;
        }
        mask[9 * 3 + 2] = true;
        let runs = Provenance::runs_of(&t, &mask);
        assert_eq!(
            runs,
            [
                MarkerFrames { marker: 0, frames: 1..4 },
                MarkerFrames { marker: 0, frames: 7..8 },
                MarkerFrames { marker: 2, frames: 9..10 }
            ]
        );
    }
}
