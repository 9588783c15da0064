//! Compact text storage of frame-range lists (`locap clean`'s `LOCAP:FILLED`, `OUTLIERS`,
//! `SWAPS`), so that tens of thousands of ranges fit a C3D parameter section.
//!
//! A range list is a list of lines, each holding one inclusive frame range written
//! `first-last` (the last word of that form), with text around it: `LFHD 120-135`,
//! `LFHD 120-135 Spike`, `LFHD RFHD 9-40`. Written one line per string (the *plain form*, what
//! locap wrote before this module), 20,000 ranges take ~320 KB, more than a C3D parameter
//! section holds for every reader (255 blocks of 512 bytes: py-c3d reads only the blocks the
//! section header declares, and that count is one byte).
//!
//! # The compact form
//! [`encode`] returns strings whose first is [`MAGIC`]; the others, concatenated, are one
//! stream of base64 VLQ digits (the variable-length quantities of JavaScript source maps,
//! "Source Map Revision 3 Proposal", section "Base64 VLQ"): each character carries 5 bits of a
//! number, least significant first, plus a continuation bit. The alphabet has no blanks, so
//! C3D readers that trim strings cannot change it, and it is plain ASCII. The stream holds:
//!
//! 1. the number of *templates*, then each template: the text before the range and the text
//!    after it, each as a byte count followed by the bytes;
//! 2. *groups* until the stream ends: a template index, a range count, then per range the gap
//!    since the previous range of the group (`first - previous_last - 1`; the first range of a
//!    group counts from frame 0) and the length (`last - first`).
//!
//! A group is a maximal run of consecutive lines with the same template and increasing,
//! non-overlapping ranges, so any list (any order) decodes to exactly the lines given. Per
//! range that costs about three characters on real gap patterns (a gap under 1024 frames and a
//! length under 32 are two characters and one), so ~40,000 ranges fit in the 255 blocks next to
//! a take's other parameters; the worst case is 14 characters (two 32-bit numbers). Past 255
//! blocks the C3D writer still writes the file (see `locap_io::c3d`): the hard ceiling is the
//! whole parameter section, 65,533 blocks (~33.5 MB, about ten million ranges), because the
//! data section's 16-bit start block must follow it.
//!
//! [`decode`] reads both forms: strings that do not start with [`MAGIC`] are the plain form
//! and are returned as they are.

/// First string of a compact range list.
pub const MAGIC: &str = "locap-ranges/1";

/// Width of the stream strings: the longest string a C3D character parameter holds.
pub const STRING_WIDTH: usize = 255;

/// Decoded lists larger than this are refused (a small corrupt stream could otherwise name a
/// long template a billion times).
pub const MAX_DECODED_BYTES: usize = 1 << 30;

const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

/// Why a range list could not be encoded or decoded.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum RangeListError {
    /// A line to encode has no `first-last` word (frame numbers up to 2^32 - 1, first <= last).
    #[error("range list line {0:?} has no `first-last` word")]
    NoRange(String),
    /// The compact stream is malformed: what was wrong and at which character.
    #[error("compact range list ({MAGIC}) is corrupt at character {at}: {reason}")]
    Corrupt {
        /// Character offset in the concatenated stream.
        at: usize,
        /// What was wrong.
        reason: String,
    },
}

/// Splits a line into (text before, first, last, text after) at its last `first-last` word.
fn split(line: &str) -> Option<(&str, u32, u32, &str)> {
    let mut end = line.len();
    // Words are separated by spaces; walk them from the end.
    loop {
        let start = line[..end].rfind(' ').map_or(0, |i| i + 1);
        let word = &line[start..end];
        if let Some((a, b)) = word.split_once('-')
            && let (Ok(first), Ok(last)) = (a.parse::<u32>(), b.parse::<u32>())
            && first <= last
            && a.bytes().all(|c| c.is_ascii_digit())
            && b.bytes().all(|c| c.is_ascii_digit())
        {
            return Some((&line[..start], first, last, &line[end..]));
        }
        if start == 0 {
            return None;
        }
        end = start - 1;
    }
}

fn push_vlq(out: &mut Vec<u8>, mut n: u64) {
    loop {
        let digit = (n & 31) as usize;
        n >>= 5;
        if n == 0 {
            out.push(ALPHABET[digit]);
            return;
        }
        out.push(ALPHABET[digit | 32]);
    }
}

fn push_bytes(out: &mut Vec<u8>, bytes: &[u8]) {
    push_vlq(out, bytes.len() as u64);
    bytes.iter().for_each(|b| push_vlq(out, *b as u64));
}

/// Encodes `lines` in the compact form (see the module doc).
///
/// # Errors
/// [`RangeListError::NoRange`] for a line without a `first-last` word.
pub fn encode(lines: &[String]) -> Result<Vec<String>, RangeListError> {
    let mut templates: Vec<(&str, &str)> = Vec::new();
    let mut records = Vec::with_capacity(lines.len());
    for line in lines {
        let (before, first, last, after) = split(line).ok_or_else(|| RangeListError::NoRange(line.clone()))?;
        let t = match templates.iter().position(|t| *t == (before, after)) {
            Some(t) => t,
            None => {
                templates.push((before, after));
                templates.len() - 1
            }
        };
        records.push((t, first, last));
    }
    let mut stream = Vec::new();
    push_vlq(&mut stream, templates.len() as u64);
    for (before, after) in &templates {
        push_bytes(&mut stream, before.as_bytes());
        push_bytes(&mut stream, after.as_bytes());
    }
    let mut i = 0;
    while i < records.len() {
        let t = records[i].0;
        let mut j = i + 1;
        while j < records.len() && records[j].0 == t && records[j].1 > records[j - 1].2 {
            j += 1;
        }
        push_vlq(&mut stream, t as u64);
        push_vlq(&mut stream, (j - i) as u64);
        let mut next = 0u64;
        for &(_, first, last) in &records[i..j] {
            push_vlq(&mut stream, first as u64 - next);
            push_vlq(&mut stream, (last - first) as u64);
            next = last as u64 + 1;
        }
        i = j;
    }
    let mut out = vec![MAGIC.to_string()];
    // The alphabet is ASCII, so every chunk is valid UTF-8.
    out.extend(stream.chunks(STRING_WIDTH).map(|c| String::from_utf8_lossy(c).into_owned()));
    Ok(out)
}

struct Reader<'a> {
    stream: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn corrupt(&self, reason: impl Into<String>) -> RangeListError {
        RangeListError::Corrupt { at: self.at, reason: reason.into() }
    }

    fn done(&self) -> bool {
        self.at >= self.stream.len()
    }

    /// One VLQ number of at most 32 bits.
    fn number(&mut self) -> Result<u64, RangeListError> {
        let mut n = 0u64;
        for shift in (0..35).step_by(5) {
            let Some(&c) = self.stream.get(self.at) else {
                return Err(self.corrupt("the stream ends inside a number"));
            };
            let digit = ALPHABET
                .iter()
                .position(|a| *a == c)
                .ok_or_else(|| self.corrupt(format!("{:?} is not a base64 digit", c as char)))?
                as u64;
            self.at += 1;
            n |= (digit & 31) << shift;
            if digit & 32 == 0 {
                return if n <= u32::MAX as u64 { Ok(n) } else { Err(self.corrupt("number above 2^32 - 1")) };
            }
        }
        Err(self.corrupt("number longer than 7 digits"))
    }

    /// A count of items that take at least `min_chars` characters each: checked against what
    /// is left of the stream before anything is allocated for them.
    fn count(&mut self, min_chars: usize, what: &str) -> Result<usize, RangeListError> {
        let n = self.number()? as usize;
        let left = self.stream.len() - self.at;
        if n.saturating_mul(min_chars) > left {
            return Err(self.corrupt(format!("{n} {what} cannot fit in the {left} characters left")));
        }
        Ok(n)
    }

    fn text(&mut self) -> Result<String, RangeListError> {
        let n = self.count(1, "bytes")?;
        let mut bytes = Vec::with_capacity(n);
        for _ in 0..n {
            let b = self.number()?;
            bytes.push(u8::try_from(b).map_err(|_| self.corrupt(format!("byte value {b}")))?);
        }
        String::from_utf8(bytes).map_err(|_| self.corrupt("template text is not UTF-8"))
    }
}

/// The lines of a range list stored as `strings` in either form (see the module doc).
///
/// # Errors
/// [`RangeListError::Corrupt`] for a malformed compact stream, or one that decodes to more
/// than [`MAX_DECODED_BYTES`].
pub fn decode(strings: &[String]) -> Result<Vec<String>, RangeListError> {
    if strings.first().map(|s| s.as_str()) != Some(MAGIC) {
        return Ok(strings.to_vec());
    }
    let stream: Vec<u8> = strings[1..].iter().flat_map(|s| s.bytes()).collect();
    let mut r = Reader { stream: &stream, at: 0 };
    let n = r.count(2, "templates")?;
    let mut templates = Vec::with_capacity(n);
    for _ in 0..n {
        templates.push((r.text()?, r.text()?));
    }
    let mut records: Vec<(usize, u32, u32)> = Vec::new();
    let mut size = 0usize;
    while !r.done() {
        let t = r.number()? as usize;
        let (before, after) = templates.get(t).ok_or_else(|| r.corrupt(format!("template {t} of {n}")))?;
        let count = r.count(2, "ranges")?;
        let line_len = before.len() + after.len() + 21;
        size = size.saturating_add(count.saturating_mul(line_len));
        if size > MAX_DECODED_BYTES {
            return Err(r.corrupt(format!("the list decodes to more than {MAX_DECODED_BYTES} bytes")));
        }
        records.reserve(count);
        let mut next = 0u64;
        for _ in 0..count {
            let first = next + r.number()?;
            let last = first + r.number()?;
            if last > u32::MAX as u64 {
                return Err(r.corrupt(format!("frame {last} is above 2^32 - 1")));
            }
            records.push((t, first as u32, last as u32));
            next = last + 1;
        }
    }
    Ok(records
        .into_iter()
        .map(|(t, first, last)| format!("{}{first}-{last}{}", templates[t].0, templates[t].1))
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lines(v: &[&str]) -> Vec<String> {
        v.iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn every_line_shape_round_trips_in_order() {
        let l = lines(&[
            "LFHD 1-1",
            "LFHD 5-9",
            "Sub:B C 3-4",
            "LFHD 2-3",
            "RBAC-1 100-4294967295",
            "LFHD 12-14 Spike",
            "LFHD RFHD 9-40",
            "LFHD 5-9",
            "Überlänge 0-0",
        ]);
        let enc = encode(&l).unwrap();
        assert_eq!(enc[0], MAGIC);
        assert!(enc[1..].iter().all(|s| s.len() <= STRING_WIDTH && !s.contains(' ')));
        assert_eq!(decode(&enc).unwrap(), l);
    }

    #[test]
    fn the_plain_form_reads_as_it_is() {
        let l = lines(&["A 12-14", "junk"]);
        assert_eq!(decode(&l).unwrap(), l);
        assert_eq!(decode(&[]).unwrap(), Vec::<String>::new());
        assert_eq!(decode(&encode(&[]).unwrap()).unwrap(), Vec::<String>::new());
    }

    #[test]
    fn sorted_gaps_cost_about_three_characters() {
        // 41 markers x 500 ranges, gaps under 1024 frames, lengths under 32.
        let mut l = Vec::new();
        for m in 0..41 {
            for k in 0..500u32 {
                let first = k * 997 + (m * 13) as u32 % 500;
                l.push(format!("M{m:02} {first}-{}", first + k % 31));
            }
        }
        let chars: usize = encode(&l).unwrap()[1..].iter().map(|s| s.len()).sum();
        assert!(chars < 3 * l.len() + 2000, "{chars} characters for {} ranges", l.len());
    }

    #[test]
    fn lines_without_a_range_are_refused() {
        assert_eq!(encode(&lines(&["A 12"])), Err(RangeListError::NoRange("A 12".into())));
        assert!(encode(&lines(&["A 14-12"])).is_err());
    }

    #[test]
    fn corrupt_streams_are_errors_not_allocations() {
        let bad = |s: &str| decode(&[MAGIC.to_string(), s.to_string()]).unwrap_err().to_string();
        assert!(bad("g").contains("ends inside"), "{}", bad("g"));
        assert!(bad("B").contains("cannot fit"), "{}", bad("B"));
        assert!(bad("A!").contains("not a base64 digit"));
        // One template "x" then a group claiming 2^30 ranges.
        let mut s = Vec::new();
        push_vlq(&mut s, 1);
        push_bytes(&mut s, b"x ");
        push_bytes(&mut s, b"");
        push_vlq(&mut s, 0);
        push_vlq(&mut s, 1 << 30);
        let e = bad(std::str::from_utf8(&s).unwrap());
        assert!(e.contains("cannot fit"), "{e}");
        assert!(bad("////////").contains("longer than 7"), "{}", bad("////////"));
        assert!(bad("BAAAAB").contains("template 1 of 1"), "{}", bad("BAAAAB"));
    }

    proptest::proptest! {
        #[test]
        fn any_list_of_range_lines_round_trips(
            lines in proptest::collection::vec(("[A-Za-z:* -]{0,12}", 0u32..5_000_000, 0u32..2000, "( [A-Z][a-z]{0,6})?"), 0..60)
        ) {
            let lines: Vec<String> =
                lines.iter().map(|(label, first, len, kind)| format!("{label} {first}-{}{kind}", first + len)).collect();
            let enc = encode(&lines).unwrap();
            proptest::prop_assert_eq!(decode(&enc).unwrap(), lines);
        }

        #[test]
        fn any_stream_decodes_or_fails_cleanly(stream in "[A-Za-z0-9+/!]{0,80}") {
            let _ = decode(&[MAGIC.to_string(), stream]);
        }
    }
}
