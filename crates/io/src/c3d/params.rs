//! The C3D parameter section: groups and parameters, kept in file order.
//!
//! Layout (C3D manual, "The parameter section"): a 4-byte section header (two ignored bytes,
//! the number of 512-byte parameter blocks, the processor type), then records of the form
//! `name length (i8, negative = locked) | id (i8, negative = group, positive = parameter of
//! group id) | name | offset to next record (i16) | payload`. A group's payload is its
//! description; a parameter's is `type (i8: -1 char, 1 byte, 2 int16, 4 float) | number of
//! dimensions | dimensions | data | description`.
//!
//! locap keeps every record, decoded to native numbers but otherwise untouched, so that a
//! written file carries every parameter it does not understand through unchanged (only
//! Intel encoding is written, see [`super::processor`]).

/// The values of one parameter, decoded from the file's processor format.
#[derive(Debug, Clone, PartialEq)]
pub enum ParamData {
    /// Type -1: characters (bytes kept as-is; C3D text is ASCII in practice).
    Char(Vec<u8>),
    /// Type 1: bytes.
    Byte(Vec<u8>),
    /// Type 2: 16-bit integers.
    Int(Vec<i16>),
    /// Type 4: 32-bit floats.
    Float(Vec<f32>),
}

impl ParamData {
    /// The C3D type code.
    pub fn type_code(&self) -> i8 {
        match self {
            ParamData::Char(_) => -1,
            ParamData::Byte(_) => 1,
            ParamData::Int(_) => 2,
            ParamData::Float(_) => 4,
        }
    }

    /// Size in bytes of the data.
    pub fn byte_len(&self) -> usize {
        match self {
            ParamData::Char(v) | ParamData::Byte(v) => v.len(),
            ParamData::Int(v) => v.len() * 2,
            ParamData::Float(v) => v.len() * 4,
        }
    }
}

/// A parameter group.
#[derive(Debug, Clone, PartialEq)]
pub struct Group {
    /// Group id (positive; files store it negated).
    pub id: u8,
    /// Group name (`POINT`, `ANALOG`, ...), upper case by convention.
    pub name: String,
    /// Locked flag (negative name length in the file).
    pub locked: bool,
    /// Description bytes.
    pub description: Vec<u8>,
}

/// A parameter.
#[derive(Debug, Clone, PartialEq)]
pub struct Parameter {
    /// Id of the group it belongs to.
    pub group_id: u8,
    /// Parameter name.
    pub name: String,
    /// Locked flag.
    pub locked: bool,
    /// Dimensions, first varying fastest (for text: `[characters, strings]`).
    pub dims: Vec<u8>,
    /// Values.
    pub data: ParamData,
    /// Description bytes.
    pub description: Vec<u8>,
}

impl Parameter {
    /// The first value as an integer (ints, bytes, floats rounded), if numeric and non-empty.
    pub fn as_i64(&self) -> Option<i64> {
        match &self.data {
            ParamData::Int(v) => v.first().map(|x| *x as i64),
            ParamData::Byte(v) => v.first().map(|x| *x as i64),
            ParamData::Float(v) => v.first().filter(|x| x.is_finite()).map(|x| x.round() as i64),
            ParamData::Char(_) => None,
        }
    }

    /// The first value as a float, if numeric and non-empty.
    pub fn as_f64(&self) -> Option<f64> {
        match &self.data {
            ParamData::Int(v) => v.first().map(|x| *x as f64),
            ParamData::Byte(v) => v.first().map(|x| *x as f64),
            ParamData::Float(v) => v.first().map(|x| *x as f64),
            ParamData::Char(_) => None,
        }
    }

    /// All values as floats (empty for text).
    pub fn floats(&self) -> Vec<f64> {
        match &self.data {
            ParamData::Int(v) => v.iter().map(|x| *x as f64).collect(),
            ParamData::Byte(v) => v.iter().map(|x| *x as f64).collect(),
            ParamData::Float(v) => v.iter().map(|x| *x as f64).collect(),
            ParamData::Char(_) => Vec::new(),
        }
    }

    /// The values as strings: a text parameter of dims `[n, k, ...]` is `k * ...` strings of
    /// `n` characters, trailing blanks and NULs trimmed.
    pub fn strings(&self) -> Vec<String> {
        let ParamData::Char(bytes) = &self.data else {
            return Vec::new();
        };
        let width = match self.dims.first() {
            Some(&w) if w > 0 => w as usize,
            _ => bytes.len().max(1),
        };
        bytes
            .chunks(width)
            .map(|c| String::from_utf8_lossy(c).trim_end_matches([' ', '\0']).trim_start().to_string())
            .collect()
    }

    /// A text parameter holding `strings`, each padded to the longest (at least 1 char).
    pub fn text_array(group_id: u8, name: &str, strings: &[String]) -> Parameter {
        let width = strings.iter().map(|s| s.len()).max().unwrap_or(0).clamp(1, 255);
        let mut bytes = Vec::with_capacity(width * strings.len());
        for s in strings {
            let mut b: Vec<u8> = s.bytes().take(width).collect();
            b.resize(width, b' ');
            bytes.extend(b);
        }
        Parameter {
            group_id,
            name: name.to_string(),
            locked: false,
            dims: vec![width as u8, strings.len().min(255) as u8],
            data: ParamData::Char(bytes),
            description: Vec::new(),
        }
    }
}

/// One record of the parameter section.
#[derive(Debug, Clone, PartialEq)]
pub enum Record {
    /// A group.
    Group(Group),
    /// A parameter.
    Parameter(Parameter),
}

/// The whole parameter section, in file order.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Parameters {
    /// Groups and parameters as they appeared.
    pub records: Vec<Record>,
}

impl Parameters {
    /// The id of group `name` (case-insensitive).
    pub fn group_id(&self, name: &str) -> Option<u8> {
        self.records.iter().find_map(|r| match r {
            Record::Group(g) if g.name.eq_ignore_ascii_case(name) => Some(g.id),
            _ => None,
        })
    }

    /// The groups, in file order.
    pub fn groups(&self) -> impl Iterator<Item = &Group> {
        self.records.iter().filter_map(|r| match r {
            Record::Group(g) => Some(g),
            _ => None,
        })
    }

    /// The parameters of group id `id`.
    pub fn parameters_of(&self, id: u8) -> impl Iterator<Item = &Parameter> {
        self.records.iter().filter_map(move |r| match r {
            Record::Parameter(p) if p.group_id == id => Some(p),
            _ => None,
        })
    }

    /// Parameter `group:name` (both case-insensitive).
    pub fn get(&self, group: &str, name: &str) -> Option<&Parameter> {
        let id = self.group_id(group)?;
        self.records.iter().find_map(|r| match r {
            Record::Parameter(p) if p.group_id == id && p.name.eq_ignore_ascii_case(name) => Some(p),
            _ => None,
        })
    }

    /// Mutable parameter `group:name`.
    pub fn get_mut(&mut self, group: &str, name: &str) -> Option<&mut Parameter> {
        let id = self.group_id(group)?;
        self.records.iter_mut().find_map(|r| match r {
            Record::Parameter(p) if p.group_id == id && p.name.eq_ignore_ascii_case(name) => Some(p),
            _ => None,
        })
    }

    /// Sets parameter `group:name`, replacing it in place if it exists (keeping its position,
    /// lock flag and description) or appending it after the group's last parameter. The
    /// group is created if needed.
    pub fn set(&mut self, group: &str, name: &str, dims: Vec<u8>, data: ParamData) {
        if let Some(p) = self.get_mut(group, name) {
            p.dims = dims;
            p.data = data;
            return;
        }
        let id = match self.group_id(group) {
            Some(id) => id,
            None => {
                // Not the id of a group, nor of parameters whose group the file never declared
                // (they would join the new group).
                let used = |i: u8| {
                    self.records.iter().any(|r| match r {
                        Record::Group(g) => g.id == i,
                        Record::Parameter(p) => p.group_id == i,
                    })
                };
                let id = (1..=127u8).find(|i| !used(*i)).unwrap_or(127);
                self.records.push(Record::Group(Group {
                    id,
                    name: group.to_ascii_uppercase(),
                    locked: false,
                    description: Vec::new(),
                }));
                id
            }
        };
        let at = self
            .records
            .iter()
            .rposition(|r| match r {
                Record::Group(g) => g.id == id,
                Record::Parameter(p) => p.group_id == id,
            })
            .map(|i| i + 1)
            .unwrap_or(self.records.len());
        self.records.insert(
            at,
            Record::Parameter(Parameter {
                group_id: id,
                name: name.to_ascii_uppercase(),
                locked: false,
                dims,
                data,
                description: Vec::new(),
            }),
        );
    }

    /// Sets a text-array parameter (see [`Parameter::text_array`]), in place if it exists.
    pub fn set_strings(&mut self, group: &str, name: &str, strings: &[String]) {
        let p = Parameter::text_array(0, name, strings);
        self.set(group, name, p.dims, p.data);
    }

    /// Removes parameter `group:name` if present.
    pub fn remove(&mut self, group: &str, name: &str) {
        if let Some(id) = self.group_id(group) {
            self.records.retain(|r| match r {
                Record::Parameter(p) => !(p.group_id == id && p.name.eq_ignore_ascii_case(name)),
                _ => true,
            });
        }
    }

    /// Strings of `group:name`, followed by those of `name2`, `name3`, ... (the C3D
    /// convention for more than 255 labels: `LABELS`, `LABELS2`, ...).
    pub fn continued_strings(&self, group: &str, name: &str) -> Vec<String> {
        let mut out = Vec::new();
        if let Some(p) = self.get(group, name) {
            out.extend(p.strings());
        }
        for n in 2.. {
            match self.get(group, &format!("{name}{n}")) {
                Some(p) => out.extend(p.strings()),
                None => break,
            }
        }
        out
    }

    /// Writes `strings` as `name`, `name2`, ... with at most 255 strings and
    /// [`MAX_RECORD_DATA`] bytes each (a record's offset to the next is an int16), removing
    /// any stale continuation parameters.
    pub fn set_continued_strings(&mut self, group: &str, name: &str, strings: &[String]) {
        for n in 2.. {
            if self.get(group, &format!("{name}{n}")).is_none() {
                break;
            }
            self.remove(group, &format!("{name}{n}"));
        }
        let mut chunks: Vec<&[String]> = Vec::new();
        let mut start = 0;
        while start < strings.len() {
            let mut end = start;
            let mut width = 1;
            while end < strings.len() && end - start < 255 {
                let w = width.max(strings[end].len().min(255));
                if (end - start + 1) * w > MAX_RECORD_DATA {
                    break;
                }
                width = w;
                end += 1;
            }
            chunks.push(&strings[start..end]);
            start = end;
        }
        if chunks.is_empty() {
            chunks.push(&[]);
        }
        for (i, chunk) in chunks.iter().enumerate() {
            let param_name = if i == 0 { name.to_string() } else { format!("{name}{}", i + 1) };
            self.set_strings(group, &param_name, chunk);
        }
    }
}

/// The most data bytes locap puts in one parameter record: a record (name, type, dimensions,
/// data, a description of up to 255 bytes) must stay under 32 KiB.
pub const MAX_RECORD_DATA: usize = 32_000;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn continued_strings_keep_each_record_under_32_kib() {
        let mut p = Parameters::default();
        let long: Vec<String> = (0..1000).map(|i| format!("{i:0>255}")).collect();
        p.set_continued_strings("LOCAP", "FILLED", &long);
        let sizes: Vec<usize> = p
            .records
            .iter()
            .filter_map(|r| if let Record::Parameter(q) = r { Some(q.data.byte_len()) } else { None })
            .collect();
        assert!(sizes.iter().all(|s| *s <= MAX_RECORD_DATA), "{sizes:?}");
        assert_eq!(sizes.len(), 1000usize.div_ceil(MAX_RECORD_DATA / 255));
        assert_eq!(p.continued_strings("LOCAP", "FILLED"), long);
        // Shorter lists replace the continuation parameters; short strings pack 255 a record.
        let short: Vec<String> = (0..300).map(|i| i.to_string()).collect();
        p.set_continued_strings("LOCAP", "FILLED", &short);
        assert_eq!(p.continued_strings("LOCAP", "FILLED"), short);
        assert!(p.get("LOCAP", "FILLED2").is_some() && p.get("LOCAP", "FILLED3").is_none());
    }

    #[test]
    fn new_groups_do_not_adopt_undeclared_parameters() {
        // Parameters of group 1, which the file never declared.
        let mut p = Parameters { records: vec![Record::Parameter(Parameter::text_array(1, "X", &["x".into()]))] };
        p.set_strings("LOCAP", "METHOD", &["m".to_string()]);
        assert_ne!(p.group_id("LOCAP"), Some(1));
        assert_eq!(p.parameters_of(p.group_id("LOCAP").unwrap()).count(), 1);
    }
}
