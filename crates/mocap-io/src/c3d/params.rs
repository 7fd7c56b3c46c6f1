//! The C3D parameter section: groups and parameters, walked by their `next` offsets.

use std::collections::BTreeMap;

use super::header::{BLOCK, Processor, take};

/// Element type of a parameter (the spec's type byte).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// -1: characters.
    Char,
    /// 1: bytes.
    Byte,
    /// 2: 16-bit integers.
    Int,
    /// 4: 32-bit floats in the processor's layout.
    Float,
}

impl Kind {
    fn from_byte(b: i8) -> Option<Self> {
        match b {
            -1 => Some(Kind::Char),
            1 => Some(Kind::Byte),
            2 => Some(Kind::Int),
            4 => Some(Kind::Float),
            _ => None,
        }
    }

    fn size(self) -> usize {
        match self {
            Kind::Char | Kind::Byte => 1,
            Kind::Int => 2,
            Kind::Float => 4,
        }
    }
}

/// One parameter: its type, dimensions and raw bytes (decoded on demand).
#[derive(Clone, Debug)]
pub struct Param {
    /// Element type.
    pub kind: Kind,
    /// Dimensions, first varying fastest (a char array [width, count]).
    pub dims: Vec<usize>,
    /// The elements' bytes, `dims` product × element size long.
    pub data: Vec<u8>,
}

/// All parameters of a file, keyed by upper-case "GROUP:NAME"; plus what went wrong walking them.
#[derive(Clone, Debug, Default)]
pub struct Params {
    processor: Option<Processor>,
    map: BTreeMap<String, Param>,
    beyond_declared: bool,
    /// Problems met while walking the section (the walk keeps what it parsed before them).
    pub warnings: Vec<String>,
}

/// A parameter entry before its group id is resolved to a name.
struct Entry {
    group_id: u8,
    name: String,
    param: Param,
}

impl Params {
    /// Walks the parameter section starting at byte `start`, `blocks` blocks long.
    ///
    /// The walk follows each entry's `next` offset. It ends at a zero name length or group
    /// id, at a `next` of 0, or (with a warning) at a negative `next`, a `next` leaving the
    /// declared section, an unknown type byte or an entry running past the section.
    pub fn walk(
        bytes: &[u8],
        start: usize,
        blocks: u8,
        data_offset: usize,
        processor: Processor,
    ) -> Self {
        let mut params = Params {
            processor: Some(processor),
            ..Params::default()
        };
        let declared_end = start.saturating_add(usize::from(blocks) * BLOCK);
        // Some writers (Dance.c3d) declare too few blocks: entries may run on up to where
        // the header says the data starts; others (MACsample.c3d) declare too many.
        let end = if data_offset > start {
            data_offset
        } else {
            declared_end
        }
        .min(bytes.len());
        if declared_end > bytes.len() {
            params.warnings.push(format!(
                "parameter section at byte {start} declares {blocks} blocks but the file ends at byte {}; read what is there",
                bytes.len()
            ));
        }
        let section = bytes.get(..end).unwrap_or(&[]);
        let mut groups: BTreeMap<u8, String> = BTreeMap::new();
        let mut entries: Vec<Entry> = Vec::new();
        let mut pos = start.saturating_add(4);
        // Each step moves forward by at least one byte (next > 0), so this loop ends.
        loop {
            let Some([name_len, id]) = take::<2>(section, pos) else {
                if pos < end {
                    params.warn_stop(pos, "entry header runs past the section end");
                }
                break;
            };
            let name_len = usize::from((name_len as i8).unsigned_abs());
            let id = id as i8;
            if name_len == 0 || id == 0 {
                break;
            }
            let name_at = pos + 2;
            let Some(name_bytes) = section.get(name_at..name_at + name_len) else {
                params.warn_stop(pos, "name runs past the section end");
                break;
            };
            let name = String::from_utf8_lossy(name_bytes)
                .trim()
                .to_ascii_uppercase();
            let next_at = name_at + name_len;
            let Some(next_bytes) = take::<2>(section, next_at) else {
                params.warn_stop(pos, "next offset runs past the section end");
                break;
            };
            let next = processor.i16(next_bytes);
            if id < 0 {
                groups.entry(id.unsigned_abs()).or_insert(name);
            } else {
                match read_param(section, next_at + 2) {
                    Ok(param) => entries.push(Entry {
                        group_id: id.unsigned_abs(),
                        name,
                        param,
                    }),
                    Err(problem) => {
                        params.warn_stop(pos, &format!("parameter {name}: {problem}"));
                        break;
                    }
                }
            }
            if next == 0 {
                break;
            }
            if next < 0 {
                params.warn_stop(pos, &format!("next offset is {next}"));
                break;
            }
            let target = next_at + usize::from(next.unsigned_abs());
            if target > declared_end && !params.beyond_declared {
                params.beyond_declared = true;
                params.warnings.push(format!(
                    "parameters run past the {blocks} blocks the section declares (byte {declared_end}): read on up to the data section"
                ));
            }
            if target >= end {
                // A last entry pointing just past the section is common and harmless.
                if target > end {
                    params.warn_stop(
                        pos,
                        &format!("next offset {next} points past the section end (byte {end})"),
                    );
                }
                break;
            }
            pos = target;
        }
        let mut duplicates = Vec::new();
        for e in entries {
            let group = match groups.get(&e.group_id) {
                Some(g) => g.clone(),
                None => format!("GROUP{}", e.group_id),
            };
            let key = format!("{group}:{}", e.name);
            match params.map.entry(key) {
                std::collections::btree_map::Entry::Occupied(o) => duplicates.push(o.key().clone()),
                std::collections::btree_map::Entry::Vacant(v) => {
                    v.insert(e.param);
                }
            }
        }
        if !duplicates.is_empty() {
            duplicates.sort();
            duplicates.dedup();
            let shown: Vec<&str> = duplicates.iter().take(5).map(String::as_str).collect();
            params.warnings.push(format!(
                "{} parameters defined more than once, first definition kept: {}{}",
                duplicates.len(),
                shown.join(", "),
                if duplicates.len() > shown.len() {
                    ", ..."
                } else {
                    ""
                }
            ));
        }
        params
    }

    fn warn_stop(&mut self, pos: usize, problem: &str) {
        self.warnings.push(format!(
            "parameter section, entry at byte {pos}: {problem}; parameters after it are ignored"
        ));
    }

    /// The parameter GROUP:NAME (upper case), if present.
    pub fn get(&self, key: &str) -> Option<&Param> {
        self.map.get(key)
    }

    /// Number of parameters read.
    pub fn len(&self) -> usize {
        self.map.len()
    }

    /// The first element of a numeric parameter as f64 (integers read as unsigned 16-bit).
    pub fn number(&self, key: &str) -> Option<f64> {
        self.numbers(key)?.first().copied()
    }

    /// Every element of a numeric parameter as f64 (integers read as unsigned 16-bit).
    pub fn numbers(&self, key: &str) -> Option<Vec<f64>> {
        let p = self.get(key)?;
        let processor = self.processor?;
        let values = match p.kind {
            Kind::Char => return None,
            Kind::Byte => p.data.iter().map(|&b| f64::from(b)).collect(),
            Kind::Int => p
                .data
                .chunks_exact(2)
                .filter_map(|c| take::<2>(c, 0))
                .map(|b| f64::from(processor.u16(b)))
                .collect(),
            Kind::Float => p
                .data
                .chunks_exact(4)
                .filter_map(|c| take::<4>(c, 0))
                .map(|b| f64::from(processor.f32(b)))
                .collect(),
        };
        Some(values)
    }

    /// The first element of a float parameter as f32 exactly as stored (e.g. POINT:RATE).
    pub fn float32(&self, key: &str) -> Option<f32> {
        let p = self.get(key)?;
        match p.kind {
            Kind::Float => take::<4>(&p.data, 0).map(|b| self.processor.map_or(0.0, |q| q.f32(b))),
            _ => self.number(key).map(|v| v as f32),
        }
    }

    /// A character parameter as strings: [width] is one string, [width, n, ...] is n·… strings.
    /// Each is trimmed of spaces and NULs.
    pub fn strings(&self, key: &str) -> Option<Vec<String>> {
        let p = self.get(key)?;
        if p.kind != Kind::Char {
            return None;
        }
        let width = p.dims.first().copied().unwrap_or(p.data.len());
        if width == 0 {
            let count: usize = p.dims.iter().skip(1).product();
            return Some(vec![String::new(); count]);
        }
        Some(
            p.data
                .chunks(width)
                .map(|c| {
                    String::from_utf8_lossy(c)
                        .trim_matches(|ch: char| ch == ' ' || ch == '\0')
                        .to_string()
                })
                .collect(),
        )
    }
}

/// Reads a parameter's type, dimensions and data starting at `at` (just after `next`).
fn read_param(section: &[u8], at: usize) -> Result<Param, String> {
    let [kind, ndims] = take::<2>(section, at).ok_or("type runs past the section end")?;
    let kind = Kind::from_byte(kind as i8).ok_or(format!("unknown type byte {}", kind as i8))?;
    let ndims = usize::from(ndims);
    let dims_at = at + 2;
    let dims: Vec<usize> = section
        .get(dims_at..dims_at + ndims)
        .ok_or("dimensions run past the section end")?
        .iter()
        .map(|&d| usize::from(d))
        .collect();
    // At most 255 dimensions of at most 255 each: bound the product before multiplying on.
    let mut count: usize = 1;
    for &d in &dims {
        count = count
            .checked_mul(d)
            .filter(|&c| c <= section.len())
            .ok_or("dimensions larger than the section")?;
    }
    let data_at = dims_at + ndims;
    let len = count * kind.size();
    let data = section
        .get(data_at..data_at + len)
        .ok_or("data runs past the section end")?
        .to_vec();
    Ok(Param { kind, dims, data })
}
