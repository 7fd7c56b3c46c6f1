//! Marker tables as capture systems' own software exports them: OptiTrack Motive CSV,
//! Vicon Nexus CSV and Qualisys QTM TSV.
//!
//! Each layout has its own header (one module each); what they share is read here: a
//! header row split into cells, and the data rows, in which each marker's x, y and z sit
//! in known fields among others (rigid bodies, sub frames, times) that are not read.
//! Missing samples are empty fields, `null`, NaN spellings or exactly (0, 0, 0), as in
//! ossify's own CSV.

pub(crate) mod motive;
pub(crate) mod nexus;
pub(crate) mod qtm;

use crate::csv::unquote;
use crate::trc::{FrameColumn, GapCounts, parse_number, sample_limit, show, warn_frame_jumps};
use crate::{Format, FormatError, LengthUnit};

/// Which vendor layout a `.csv` file holds, by its first line with content; `None` when
/// it is none of them (ossify's own layout).
pub(crate) fn sniff_csv(bytes: &[u8]) -> Option<Format> {
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    let first = bytes
        .split(|&b| b == b'\n')
        .find(|line| !is_blank(line, b','))?;
    let cells = cells(first, b',');
    let head = cells.first().map(|c| c.as_str())?;
    if head.eq_ignore_ascii_case("Format Version") {
        Some(Format::MotiveCsv)
    } else if nexus::SECTIONS.iter().any(|s| head.eq_ignore_ascii_case(s)) {
        Some(Format::NexusCsv)
    } else {
        None
    }
}

/// Whether a line holds nothing but separators and whitespace (Nexus pads its blank rows
/// with commas to the table's width).
pub(crate) fn is_blank(line: &[u8], sep: u8) -> bool {
    line.iter().all(|&b| b == sep || b.is_ascii_whitespace())
}

/// A header line's cells, trimmed; a cell in double quotes may hold the separator, and
/// `""` inside one is a quote.
pub(crate) fn cells(line: &[u8], sep: u8) -> Vec<String> {
    let text = String::from_utf8_lossy(line);
    let mut out = Vec::new();
    let mut cell = String::new();
    let mut quoted = false;
    let mut chars = text.chars().peekable();
    while let Some(c) = chars.next() {
        match c {
            '"' if quoted && chars.peek() == Some(&'"') => {
                cell.push('"');
                chars.next();
            }
            '"' => quoted = !quoted,
            c if !quoted && c as u32 == u32::from(sep) => {
                out.push(cell.trim().to_owned());
                cell.clear();
            }
            c => cell.push(c),
        }
    }
    out.push(cell.trim().to_owned());
    out
}

/// Cell `i` of a row, empty past its end.
pub(crate) fn cell(row: &[String], i: usize) -> &str {
    row.get(i).map_or("", String::as_str)
}

/// A rate in Hz read from a header, or why it is not one.
pub(crate) fn frame_rate(text: &str, at: &str, what: &str) -> Result<f64, FormatError> {
    // Outside 0.001 Hz – 1 MHz no capture system records; such a value is a misreading.
    parse_number(text.as_bytes())
        .filter(|r| (1e-3..=1e6).contains(r))
        .ok_or_else(|| {
            FormatError::new(
                at,
                format!(
                    "{what} `{}` is not a rate between 0.001 and 1000000 Hz",
                    show(text.as_bytes())
                ),
            )
        })
}

/// Millimetres per unit of the file's coordinates: `options.units` over the file's word
/// (`declared`, `None` when it has none, then `default`); warnings say where they differ.
pub(crate) fn scale(
    override_unit: Option<LengthUnit>,
    declared: Option<&str>,
    default: (f64, &str),
    at: &str,
    warnings: &mut Vec<String>,
) -> Result<f64, FormatError> {
    let known = declared.map(|d| (d, crate::mm_per_unit(d)));
    if let Some(unit) = override_unit {
        warnings.extend(unit.overriding(known).map(|w| format!("{at}: {w}")));
        return Ok(unit.mm());
    }
    match known {
        Some((_, Some(mm))) => Ok(mm),
        Some((word, None)) => Err(FormatError::new(
            at,
            format!(
                "unknown length unit `{}` (expected {}; mocap-io.units sets one)",
                show(word.as_bytes()),
                crate::KNOWN_UNITS
            ),
        )),
        None => {
            warnings.push(format!(
                "{at}: the file names no length unit; read as {} ({}; mocap-io.units sets \
                 another)",
                default.1,
                if default.0 == 1.0 {
                    "what this software writes"
                } else {
                    "this software's default"
                }
            ));
            Ok(default.0)
        }
    }
}

/// Where a table's markers and frame numbers sit in each data row (fields from 0).
pub(crate) struct Layout {
    /// Marker labels, in column order.
    pub labels: Vec<String>,
    /// Each marker's x, y and z fields.
    pub fields: Vec<[usize; 3]>,
    /// The frame-number field, if the rows carry one.
    pub frame_field: Option<usize>,
    /// The time field (seconds), if the rows carry one.
    pub time_field: Option<usize>,
    /// Field separator.
    pub sep: u8,
    /// Accept a decimal comma (`12,5`) where the separator is not a comma.
    pub decimal_comma: bool,
}

/// The data rows of a table, read.
pub(crate) struct Table {
    /// Row-major samples in millimetres, `MISSING` where absent.
    pub positions: Vec<[f64; 3]>,
    /// Number of rows read.
    pub rows: usize,
    /// The first row's frame number, if the rows carry them.
    pub first_frame: Option<i64>,
    /// Rows whose frame number is not the previous one's plus one.
    pub frame_jumps: usize,
    /// The first and last rows' times, if the rows carry them.
    pub times: Option<(f64, f64)>,
    /// Gap conventions met.
    pub counts: GapCounts,
}

/// Reads data rows until the lines end or `ends` says a line ends the table; blank lines
/// are skipped. `len` is the file's size (a bound on what it can hold).
pub(crate) fn read_rows<'a>(
    lines: impl Iterator<Item = (usize, &'a [u8])>,
    layout: &Layout,
    scale: f64,
    len: usize,
    ends: impl Fn(&[u8]) -> bool,
) -> Result<Table, FormatError> {
    let markers = layout.labels.len();
    // What each field holds: (marker, axis) or nothing this reader keeps.
    let width = layout.fields.iter().flatten().max().map_or(0, |&f| f + 1);
    let mut slot: Vec<Option<(usize, usize)>> = vec![None; width];
    for (m, fields) in layout.fields.iter().enumerate() {
        for (axis, &f) in fields.iter().enumerate() {
            slot[f] = Some((m, axis));
        }
    }
    let limit = sample_limit(len);
    let mut table = Table {
        positions: Vec::new(),
        rows: 0,
        first_frame: None,
        frame_jumps: 0,
        times: None,
        counts: GapCounts::default(),
    };
    let mut frame_column = FrameColumn::default();
    let mut row = vec![[f64::NAN; 3]; markers];
    for (no, line) in lines {
        if ends(line) {
            break;
        }
        if is_blank(line, layout.sep) {
            continue;
        }
        if (table.rows + 1).saturating_mul(markers) > limit {
            return Err(FormatError::new(
                format!("line {no}"),
                format!(
                    "{} rows of {markers} markers is more data than a {len}-byte file can \
                     hold; refusing to allocate",
                    table.rows + 1
                ),
            ));
        }
        row.fill([f64::NAN; 3]);
        let mut seen = 0;
        for (index, field) in line.split(|&b| b == layout.sep).enumerate() {
            seen = index + 1;
            let field = field.trim_ascii();
            let at = || format!("line {no}, field {}", index + 1);
            if Some(index) == layout.frame_field {
                frame_column.record(unquote(field), at)?;
                continue;
            }
            if Some(index) == layout.time_field {
                if let Some(t) = number(field, layout.decimal_comma).filter(|t| t.is_finite()) {
                    let first = table.times.map_or(t, |(first, _)| first);
                    table.times = Some((first, t));
                }
                continue;
            }
            let Some(&Some((m, axis))) = slot.get(index) else {
                continue;
            };
            if field.is_empty() || field.eq_ignore_ascii_case(b"null") {
                continue;
            }
            let v = number(field, layout.decimal_comma).ok_or_else(|| {
                FormatError::new(
                    at(),
                    format!(
                        "`{}` is not a number (marker {}, {})",
                        show(field),
                        layout.labels[m],
                        ["x", "y", "z"][axis]
                    ),
                )
            })?;
            row[m][axis] = v * scale;
        }
        if seen < width {
            table.counts.short_rows += 1;
        }
        table.counts.settle(&mut row);
        table.positions.extend_from_slice(&row);
        table.rows += 1;
    }
    table.first_frame = frame_column.first;
    table.frame_jumps = frame_column.jumps;
    Ok(table)
}

/// A number, with a decimal comma where `decimal_comma` allows it.
fn number(field: &[u8], decimal_comma: bool) -> Option<f64> {
    parse_number(field).or_else(|| {
        if !decimal_comma || field.iter().filter(|&&b| b == b',').count() != 1 {
            return None;
        }
        let dotted: Vec<u8> = field
            .iter()
            .map(|&b| if b == b',' { b'.' } else { b })
            .collect();
        parse_number(&dotted)
    })
}

/// The frame rate from the rows' times, where the header gives none: rows − 1 intervals
/// over the time they span.
pub(crate) fn rate_from_times(table: &Table) -> Option<f64> {
    let (first, last) = table.times?;
    let span = last - first;
    (table.rows >= 2 && span > 0.0).then(|| (table.rows - 1) as f64 / span)
}

/// The warnings every table reader gives alike: frame-number jumps and gap conventions.
pub(crate) fn table_warnings(table: &Table, warnings: &mut Vec<String>) {
    warn_frame_jumps("frame numbers are", table.frame_jumps, warnings);
    table.counts.warn(warnings);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quoted_cells_keep_their_separators_and_lose_their_quotes() {
        assert_eq!(
            cells(br#",ID,"8908D5","a,b", "say ""hi"""  "#, b','),
            ["", "ID", "8908D5", "a,b", r#"say "hi""#]
        );
        assert_eq!(
            cells(b"Frame\tTime\tNew 0000 X", b'\t'),
            ["Frame", "Time", "New 0000 X"]
        );
    }

    #[test]
    fn vendor_csv_layouts_are_told_by_their_first_line() {
        let motive = b"\xEF\xBB\xBFFormat Version,1.23,Take Name,t\r\n\r\n,Type,Marker";
        assert_eq!(sniff_csv(motive), Some(Format::MotiveCsv));
        assert_eq!(
            sniff_csv(b",,,,\n,,,,\nTrajectories,,,\n100,,,\n"),
            Some(Format::NexusCsv)
        );
        assert_eq!(sniff_csv(b"Devices,,\n1000\n"), Some(Format::NexusCsv));
        assert_eq!(sniff_csv(b"# frame_rate: 100\nframe,A_x,A_y,A_z\n"), None);
        assert_eq!(sniff_csv(b""), None);
    }

    #[test]
    fn a_decimal_comma_is_read_only_where_allowed() {
        assert_eq!(number(b"12,5", true), Some(12.5));
        assert_eq!(number(b"12,5", false), None);
        assert_eq!(number(b"1,2,5", true), None);
    }
}
