//! ossify's CSV layout for marker data from anywhere else: reading and writing.
//!
//! # Layout
//!
//! ```text
//! # frame_rate: 120
//! # units: mm
//! frame,LASI_x,LASI_y,LASI_z,left_knee_x,left_knee_y,left_knee_z
//! 1,512.25,-80.5,1001.0,480.0,-95.25,512.5
//! 2,513.00,-80.25,1001.5,,,
//! ```
//!
//! - Comma separated, one row per frame, UTF-8; CRLF or LF line endings; spaces around
//!   a field are ignored; no quoting (a header cell wrapped in `"` has them removed).
//! - Lines starting with `#` are comments. Before the header row two of them are read:
//!   `# frame_rate: <Hz>` (**required**: without it the file is refused, naming the line
//!   to add) and `# units: mm|cm|dm|m|in` (optional, default millimetres; spelled-out
//!   names too; values are converted to millimetres). Other comments are ignored, as are
//!   blank lines anywhere.
//! - Header row: `frame`, an optional `time` column (seconds; ignored, the rate comes from
//!   the comment), then three columns per marker named `<label>_x`, `<label>_y`,
//!   `<label>_z` in that order. Labels may contain underscores: the suffix after the
//!   *last* `_` names the axis. An incomplete or out-of-order triple is an error naming
//!   the column.
//! - `frame` is an integer: the first row's value is the first frame; rows are read in
//!   file order as consecutive frames (a warning says when the numbers jump).
//! - A sample is missing when any of its three fields is empty, reads `nan`, or the row
//!   ends before it, or when it is exactly (0, 0, 0) (the gap convention of the other
//!   formats, applied here so every format reads alike). A row with more fields than the
//!   header, or a field that is not a number, is an error naming the line and field.
//!
//! The writer emits exactly this layout, with `# frame_rate:` and `# units: mm`, empty
//! fields for missing samples and positions with five decimals.

use std::fmt::Write as _;

use crate::trc::{
    FrameColumn, GapCounts, Lines, clean_label, parse_number, sample_limit, show, unique_labels,
    warn_frame_jumps,
};
use crate::{Capture, CaptureInfo, Format, FormatError, ReadOptions, Trajectories};

/// Parses CSV bytes in ossify's layout (see the module docs) into a capture in millimetres.
pub fn parse(bytes: &[u8], options: &ReadOptions) -> Result<Capture, FormatError> {
    let mut lines = Lines::new(bytes);
    let mut warnings = Vec::new();
    let mut frame_rate: Option<f64> = None;
    let mut units: Option<(String, f64)> = None;

    // Leading comments, then the header row.
    let (header_no, header_line) = loop {
        let Some((no, line)) = lines.next_nonblank() else {
            let at = lines.line_count().max(1);
            return Err(FormatError::new(
                format!("line {at}"),
                if bytes.iter().all(u8::is_ascii_whitespace) {
                    "empty file: expected `# frame_rate: <Hz>` and a `frame,<label>_x,...` header row"
                } else {
                    "file ends before the header row `frame,<label>_x,<label>_y,<label>_z,...`"
                },
            ));
        };
        let line = if no == 1 {
            line.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(line)
        } else {
            line
        };
        let Some(comment) = line.trim_ascii().strip_prefix(b"#") else {
            break (no, line);
        };
        let Some(colon) = comment.iter().position(|&b| b == b':') else {
            continue;
        };
        let key = comment[..colon].trim_ascii();
        let value = comment[colon + 1..].trim_ascii();
        if key.eq_ignore_ascii_case(b"frame_rate") {
            // Outside 0.001 Hz – 1 MHz no capture system records; such a value is a typo.
            let rate = parse_number(value)
                .filter(|r| (1e-3..=1e6).contains(r))
                .ok_or_else(|| {
                    FormatError::new(
                        format!("line {no}"),
                        format!(
                            "frame_rate `{}` is not a rate between 0.001 and 1000000 Hz",
                            show(value)
                        ),
                    )
                })?;
            frame_rate = Some(rate);
        } else if key.eq_ignore_ascii_case(b"units") {
            let text = String::from_utf8_lossy(value).into_owned();
            if let Some(unit) = options.units {
                let declared = Some((text.as_str(), crate::mm_per_unit(&text)));
                warnings.extend(unit.overriding(declared).map(|w| format!("line {no}: {w}")));
                units = Some((text, unit.mm()));
                continue;
            }
            let scale = crate::mm_per_unit(&text).ok_or_else(|| {
                FormatError::new(
                    format!("line {no}"),
                    format!(
                        "unknown units `{}` (expected {})",
                        show(value),
                        crate::KNOWN_UNITS
                    ),
                )
            })?;
            units = Some((text, scale));
        }
    };
    let Some(frame_rate) = frame_rate else {
        return Err(FormatError::new(
            format!("line {header_no}"),
            "no `# frame_rate: <Hz>` comment before the header row; add one, e.g. `# frame_rate: 120`",
        ));
    };
    let scale = match (options.units, &units) {
        (Some(unit), None) => {
            warnings.extend(unit.overriding(None));
            unit.mm()
        }
        _ => units.as_ref().map_or(1.0, |u| u.1),
    };

    // Header row.
    let cells: Vec<&[u8]> = header_line.split(|&b| b == b',').map(unquote).collect();
    let at_column = |i: usize| format!("line {header_no}, column {}", i + 1);
    if !cells
        .first()
        .is_some_and(|c| c.eq_ignore_ascii_case(b"frame"))
    {
        return Err(FormatError::new(
            at_column(0),
            format!(
                "the header row must start with `frame`, found `{}`",
                show(cells.first().copied().unwrap_or(b""))
            ),
        ));
    }
    let skip = if cells
        .get(1)
        .is_some_and(|c| c.eq_ignore_ascii_case(b"time"))
    {
        2
    } else {
        1
    };
    let marker_cells = cells.get(skip..).unwrap_or(&[]);
    if marker_cells.is_empty() {
        return Err(FormatError::new(
            format!("line {header_no}"),
            "no marker columns after `frame`: a capture needs at least one marker",
        ));
    }
    let mut labels = Vec::with_capacity(marker_cells.len() / 3);
    for (t, triple) in marker_cells.chunks(3).enumerate() {
        let mut label: Option<&[u8]> = None;
        for (k, axis) in [b'x', b'y', b'z'].into_iter().enumerate() {
            let column = skip + 3 * t + k;
            let Some(cell) = triple.get(k) else {
                return Err(FormatError::new(
                    at_column(column),
                    format!(
                        "header ends inside a marker: `{}` needs `_{}` (columns come as <label>_x, <label>_y, <label>_z)",
                        show(label.unwrap_or(b"?")),
                        axis as char
                    ),
                ));
            };
            let split = cell.iter().rposition(|&b| b == b'_');
            let (name, suffix) = match split {
                Some(i) => (&cell[..i], &cell[i + 1..]),
                None => (&cell[..0], &cell[..]),
            };
            let ok_axis = suffix.len() == 1 && suffix[0].eq_ignore_ascii_case(&axis);
            let same_label = label.is_none_or(|l| l == name);
            if name.is_empty() || !ok_axis || !same_label {
                return Err(FormatError::new(
                    at_column(column),
                    format!(
                        "expected `{}_{}`, found `{}` (columns come as <label>_x, <label>_y, <label>_z)",
                        show(label.unwrap_or(if name.is_empty() { b"<label>" } else { name })),
                        axis as char,
                        show(cell)
                    ),
                ));
            }
            label = Some(name);
        }
        labels.push(String::from_utf8_lossy(label.unwrap_or(b"")).into_owned());
    }
    unique_labels(&mut labels, &format!("line {header_no}"), &mut warnings);

    // Data rows.
    let markers = labels.len();
    let columns = cells.len();
    let limit = sample_limit(bytes.len());
    let mut positions: Vec<[f64; 3]> = Vec::new();
    let mut frame_column = FrameColumn::default();
    let mut rows = 0usize;
    let mut counts = GapCounts::default();
    let mut row = vec![[f64::NAN; 3]; markers];
    while let Some((no, line)) = lines.next_nonblank() {
        if line.trim_ascii_start().starts_with(b"#") {
            continue;
        }
        if (rows + 1).saturating_mul(markers) > limit {
            return Err(FormatError::new(
                format!("line {no}"),
                format!(
                    "{} rows of {markers} markers is more data than a {}-byte file can hold; refusing to allocate",
                    rows + 1,
                    bytes.len()
                ),
            ));
        }
        row.fill([f64::NAN; 3]);
        let mut seen = 0usize;
        for (index, field) in line.split(|&b| b == b',').enumerate() {
            seen = index + 1;
            let field = field.trim_ascii();
            let at = || format!("line {no}, field {}", index + 1);
            if index >= columns {
                return Err(FormatError::new(
                    at(),
                    format!("row has more fields than the header's {columns} columns"),
                ));
            }
            if index == 0 {
                frame_column.record(field, at)?;
                continue;
            }
            if field.is_empty() {
                continue;
            }
            let v = parse_number(field).ok_or_else(|| {
                let what = match index.checked_sub(skip) {
                    Some(i) => format!(
                        "marker {}, {}",
                        labels.get(i / 3).map(String::as_str).unwrap_or("?"),
                        ["x", "y", "z"][i % 3]
                    ),
                    None => "time".to_string(),
                };
                FormatError::new(at(), format!("`{}` is not a number ({what})", show(field)))
            })?;
            let sample = index
                .checked_sub(skip)
                .and_then(|i| Some((row.get_mut(i / 3)?, i % 3)));
            if let Some((sample, axis)) = sample {
                sample[axis] = v * scale;
            }
        }
        if seen < columns {
            counts.short_rows += 1;
        }
        counts.settle(&mut row);
        positions.extend_from_slice(&row);
        rows += 1;
    }
    let Some(first_frame) = frame_column.first else {
        return Err(FormatError::new(
            format!("line {}", lines.line_count() + 1),
            "no data rows after the header row",
        ));
    };
    warn_frame_jumps("frame numbers are", frame_column.jumps, &mut warnings);
    counts.warn(&mut warnings);

    let trajectories = Trajectories::new(labels, frame_rate, first_frame, rows, positions)
        .map_err(|e| FormatError::new(format!("line {header_no}"), e.to_string()))?;
    Ok(Capture {
        format: Format::Csv,
        trajectories,
        info: CaptureInfo {
            declared_units: units.map(|u| u.0),
            warnings,
            ..CaptureInfo::default()
        },
    })
}

/// Encodes trajectories in ossify's CSV layout, in millimetres (see the module docs).
///
/// Labels are written with commas, quotes and control characters replaced by `_`, and an
/// empty label as `M<n>`, so the file always parses back to the same markers. A present
/// sample at exactly (0, 0, 0) reads back as missing. An unknown frame rate (0) is
/// written as `# frame_rate: 0`, which the reader refuses.
pub fn write(t: &Trajectories) -> String {
    let markers = t.markers();
    let mut out = String::with_capacity(128 + markers * 32 + t.frames() * (8 + markers * 36));
    let _ = writeln!(out, "# frame_rate: {}", t.frame_rate());
    out.push_str("# units: mm\nframe");
    for (i, label) in t.labels().iter().enumerate() {
        let label: String = clean_label(label, i)
            .chars()
            .map(|c| if c == ',' || c == '"' { '_' } else { c })
            .collect();
        let _ = write!(out, ",{label}_x,{label}_y,{label}_z");
    }
    out.push('\n');
    for f in 0..t.frames() {
        let _ = write!(out, "{}", t.first_frame().saturating_add(f as i64));
        crate::trc::push_samples(&mut out, t.frame(f), ',');
        out.push('\n');
    }
    out
}

/// A header cell without surrounding spaces and double quotes.
pub(crate) fn unquote(cell: &[u8]) -> &[u8] {
    let cell = cell.trim_ascii();
    cell.strip_prefix(b"\"")
        .and_then(|c| c.strip_suffix(b"\""))
        .unwrap_or(cell)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(text: &str) -> Result<Capture, FormatError> {
        parse(text.as_bytes(), &ReadOptions::default())
    }

    #[test]
    fn reads_the_documented_example() {
        let text = "# frame_rate: 120\r\n# units: cm\r\n# made by hand\r\n\
            frame,LASI_x,LASI_y,LASI_z,left_knee_x,left_knee_y,left_knee_z\r\n\
            10,1,2,3,4,5,6\r\n11,1.5,2,3,,,\r\n\r\n";
        let c = read(text).unwrap();
        let t = &c.trajectories;
        assert_eq!(t.labels(), ["LASI", "left_knee"]);
        assert_eq!(
            (t.frames(), t.first_frame(), t.frame_rate()),
            (2, 10, 120.0)
        );
        assert_eq!(t.get(0, 1), Some([40.0, 50.0, 60.0]));
        assert_eq!(t.get(1, 0), Some([15.0, 20.0, 30.0]));
        assert_eq!(t.get(1, 1), None);
        assert_eq!(c.info.declared_units.as_deref(), Some("cm"));
        assert!(c.info.warnings.is_empty(), "{:?}", c.info.warnings);
    }

    #[test]
    fn optional_time_column_and_short_rows() {
        let text = "# frame_rate: 50\nframe,time,A_x,A_y,A_z,B_x,B_y,B_z\n1,0.0,1,2,3\n2,0.02,0,0,0,4,5,6\n";
        let c = read(text).unwrap();
        let t = &c.trajectories;
        assert_eq!(t.get(0, 0), Some([1.0, 2.0, 3.0]));
        assert_eq!(t.get(0, 1), None);
        assert_eq!(t.get(1, 0), None);
        assert_eq!(t.get(1, 1), Some([4.0, 5.0, 6.0]));
        assert_eq!(c.info.declared_units, None);
        assert_eq!(c.info.warnings.len(), 2, "{:?}", c.info.warnings);
    }

    #[test]
    fn header_errors_name_the_column() {
        let e = read("# frame_rate: 100\nframe,A_x,A_y\n").unwrap_err();
        assert_eq!(e.location, "line 2, column 4");
        let e = read("# frame_rate: 100\nframe,A_x,A_z,A_y\n").unwrap_err();
        assert_eq!(e.location, "line 2, column 3");
        assert!(e.problem.contains("expected `A_y`"), "{e}");
        let e = read("# frame_rate: 100\nframe,A_x,B_y,A_z\n").unwrap_err();
        assert_eq!(e.location, "line 2, column 3");
        let e = read("# frame_rate: 100\nframe,Ax,Ay,Az\n").unwrap_err();
        assert_eq!(e.location, "line 2, column 2");
        let e = read("# frame_rate: 100\ntime,A_x,A_y,A_z\n").unwrap_err();
        assert_eq!(e.location, "line 2, column 1");
        let e = read("# frame_rate: 100\nframe\n1\n").unwrap_err();
        assert!(e.problem.contains("no marker columns"), "{e}");
    }

    #[test]
    fn missing_rate_units_and_bad_values_are_errors() {
        let e = read("frame,A_x,A_y,A_z\n1,1,2,3\n").unwrap_err();
        assert_eq!(e.location, "line 1");
        assert!(e.problem.contains("# frame_rate:"), "{e}");
        let e = read("# frame_rate: fast\n").unwrap_err();
        assert_eq!(e.location, "line 1");
        let e = read("# frame_rate: 60\n# units: inch\n").unwrap_err();
        assert_eq!(e.location, "line 2");
        let e = read("# frame_rate: 60\nframe,A_x,A_y,A_z\n1,1,2,three\n").unwrap_err();
        assert_eq!(e.location, "line 3, field 4");
        assert!(e.problem.contains("marker A, z"), "{e}");
        let e = read("# frame_rate: 60\nframe,A_x,A_y,A_z\n1,1,2,3,4\n").unwrap_err();
        assert_eq!(e.location, "line 3, field 5");
        let e = read("# frame_rate: 60\nframe,A_x,A_y,A_z\n").unwrap_err();
        assert!(e.problem.contains("no data rows"), "{e}");
        let e = read("").unwrap_err();
        assert!(e.problem.contains("empty"), "{e}");
    }

    #[test]
    fn write_then_read_gives_the_same_trajectories() {
        let nan = f64::NAN;
        let positions = vec![
            [1.0, 2.0, 3.0],
            [nan; 3],
            [-4.5, 5.25, 1e4],
            [0.5, 0.0, 0.0],
        ];
        let t = Trajectories::new(
            vec!["l_knee_x".into(), "a,b".into()],
            119.88,
            0,
            2,
            positions,
        )
        .unwrap();
        let c = read(&write(&t)).unwrap();
        let back = &c.trajectories;
        assert_eq!(back.labels(), ["l_knee_x", "a_b"]);
        assert_eq!(back.frame_rate(), 119.88);
        assert_eq!((back.first_frame(), back.frames()), (0, 2));
        assert_eq!(back.get(0, 0), Some([1.0, 2.0, 3.0]));
        assert_eq!(back.get(0, 1), None);
        assert_eq!(back.get(1, 0), Some([-4.5, 5.25, 1e4]));
        assert_eq!(back.get(1, 1), Some([0.5, 0.0, 0.0]));
        assert_eq!(c.info.declared_units.as_deref(), Some("mm"));
    }
}
