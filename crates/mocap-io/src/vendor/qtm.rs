//! Qualisys Track Manager's TSV export of 3D marker data.
//!
//! ```text
//! (→ is a tab)
//! NO_OF_FRAMES→2000
//! NO_OF_CAMERAS→10
//! NO_OF_MARKERS→2
//! FREQUENCY→100
//! ...
//! DATA_INCLUDED→3D
//! MARKER_NAMES→LASI→New 0002
//! TRAJECTORY_TYPES→Measured→Mixed
//! Frame→Time→LASI X→LASI Y→LASI Z→New 0002 X→New 0002 Y→New 0002 Z
//! 1→0.00000→819.834→277.770→22.421→0.000→0.000→0.000
//! ```
//!
//! Tab separated. The header is `KEY<tab>value...` lines (upper-case keys; `FILE_VERSION`
//! and `EVENT` lines in newer exports); the `Frame`/`Time` column header is optional, and
//! without it a row is either the markers' triples or frame, time and the triples.
//! Coordinates are millimetres. Missing samples are written as 0.000 (older versions),
//! `null` or empty fields. `FREQUENCY` may be `EXT` (an external clock); the rate then
//! comes from the Time column.

use super::{Layout, cells, frame_rate, rate_from_times, read_rows, scale, table_warnings};
use crate::trc::{Lines, show, unique_labels};
use crate::{Capture, CaptureInfo, Format, FormatError, ReadOptions, Trajectories};

/// Whether a line is a header line: an upper-case key, then a tab or the end.
fn is_key_line(line: &[u8]) -> bool {
    let key = line.split(|&b| b == b'\t').next().unwrap_or(b"");
    let key = key
        .strip_prefix(b"\xEF\xBB\xBF")
        .unwrap_or(key)
        .trim_ascii();
    !key.is_empty()
        && key[0].is_ascii_uppercase()
        && key
            .iter()
            .all(|&b| b.is_ascii_uppercase() || b.is_ascii_digit() || b == b'_')
}

/// Whether the bytes open a QTM TSV header (for files without the `.tsv` extension).
pub(crate) fn sniff(bytes: &[u8]) -> bool {
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    bytes.starts_with(b"NO_OF_FRAMES\t") || bytes.starts_with(b"FILE_VERSION\t")
}

/// Parses a QTM 3D TSV export into a capture in millimetres.
pub(crate) fn parse(bytes: &[u8], options: &ReadOptions) -> Result<Capture, FormatError> {
    let mut lines = Lines::new(bytes);
    let mut header: Vec<(usize, String, Vec<String>)> = Vec::new();
    let mut first_row = None;
    for (no, line) in lines.by_ref() {
        if line.iter().all(u8::is_ascii_whitespace) {
            continue;
        }
        if !is_key_line(line) {
            first_row = Some((no, line));
            break;
        }
        let mut row = cells(line, b'\t');
        let key = row.remove(0).trim_start_matches('\u{feff}').to_owned();
        while row.last().is_some_and(String::is_empty) {
            row.pop();
        }
        header.push((no, key, row));
    }
    let key = |name: &str| header.iter().find(|(_, k, _)| k == name);
    let Some((names_no, _, names)) = key("MARKER_NAMES") else {
        return Err(FormatError::new(
            format!("line {}", header.last().map_or(1, |h| h.0 + 1)),
            "no `MARKER_NAMES` line: export the TSV with its header (QTM's \"Include TSV \
             header\") so the markers have names and the rate is known",
        ));
    };
    let names_no = *names_no;
    if let Some((no, _, data)) = key("DATA_INCLUDED")
        && !data.first().is_some_and(|d| d.eq_ignore_ascii_case("3D"))
    {
        return Err(FormatError::new(
            format!("line {no}"),
            format!(
                "DATA_INCLUDED is `{}`: this export holds no 3D marker positions (export \
                 the 3D data)",
                data.join(" ")
            ),
        ));
    }
    let mut warnings = Vec::new();
    if let Some((no, _, count)) = key("NO_OF_MARKERS")
        && count.first().and_then(|c| c.parse::<usize>().ok()) != Some(names.len())
    {
        warnings.push(format!(
            "line {no}: NO_OF_MARKERS says {}, MARKER_NAMES names {}; read the names",
            count.join(" "),
            names.len()
        ));
    }
    let mut labels = names.clone();
    let m = labels.len();
    if m == 0 {
        return Err(FormatError::new(
            format!("line {names_no}"),
            "MARKER_NAMES names no marker",
        ));
    }

    // The column header when there is one; else the first row's width says whether the
    // rows carry a frame and a time.
    let Some((row_no, row)) = first_row else {
        return Err(FormatError::new(
            format!("line {}", lines.line_count() + 1),
            "no data rows after the header",
        ));
    };
    let mut pending = Some((row_no, row));
    let (frame_field, time_field, fields) = if row
        .split(|&b| b == b'\t')
        .next()
        .is_some_and(|c| c.trim_ascii().eq_ignore_ascii_case(b"Frame"))
    {
        pending = None;
        let columns = cells(row, b'\t');
        let find = |name: &str| columns.iter().position(|c| c.eq_ignore_ascii_case(name));
        let mut fields = Vec::with_capacity(m);
        for name in &labels {
            let mut triple = [0; 3];
            for (k, axis) in ["X", "Y", "Z"].into_iter().enumerate() {
                triple[k] = find(&format!("{name} {axis}")).ok_or_else(|| {
                    FormatError::new(
                        format!("line {row_no}"),
                        format!("the column header has no `{name} {axis}` column"),
                    )
                })?;
            }
            fields.push(triple);
        }
        (Some(0), find("Time"), fields)
    } else {
        // Every field is written, empty or not, so the count is the layout's (plus one
        // where the row ends with a tab).
        let width = row.split(|&b| b == b'\t').count();
        let skip = if width == 3 * m + 2 || width == 3 * m + 3 {
            2
        } else if width == 3 * m || width == 3 * m + 1 {
            0
        } else {
            return Err(FormatError::new(
                format!("line {row_no}"),
                format!(
                    "the first row has {width} fields where MARKER_NAMES' {m} markers take \
                     {} (or {} with frame and time)",
                    3 * m,
                    3 * m + 2
                ),
            ));
        };
        let fields = (0..m).map(|i| [skip + 3 * i, skip + 3 * i + 1, skip + 3 * i + 2]);
        let (frame, time) = if skip == 2 {
            (Some(0), Some(1))
        } else {
            (None, None)
        };
        (frame, time, fields.collect())
    };
    let scale = scale(
        options.units,
        Some("mm"),
        (1.0, "millimetres"),
        &format!("line {names_no}"),
        &mut warnings,
    )?;
    unique_labels(&mut labels, &format!("line {names_no}"), &mut warnings);
    let layout = Layout {
        labels,
        fields,
        frame_field,
        time_field,
        sep: b'\t',
        decimal_comma: true,
    };
    let rows = pending.into_iter().chain(lines);
    let table = read_rows(rows, &layout, scale, bytes.len(), |_| false)?;
    if table.rows == 0 {
        return Err(FormatError::new(
            format!("line {row_no}"),
            "no data rows after the header",
        ));
    }
    let frame_rate = match key("FREQUENCY") {
        Some((no, _, f)) if f.first().is_some_and(|f| !f.eq_ignore_ascii_case("EXT")) => {
            frame_rate(&f[0], &format!("line {no}"), "FREQUENCY")?
        }
        found => rate_from_times(&table).ok_or_else(|| {
            FormatError::new(
                format!("line {}", found.map_or(names_no, |f| f.0)),
                format!(
                    "FREQUENCY is {}, and the rows carry no times to tell the rate from",
                    found.map_or("absent".to_owned(), |f| format!(
                        "`{}`",
                        show(f.2.join(" ").as_bytes())
                    ))
                ),
            )
        })?,
    };
    table_warnings(&table, &mut warnings);
    let trajectories = Trajectories::new(
        layout.labels,
        frame_rate,
        table.first_frame.unwrap_or(1),
        table.rows,
        table.positions,
    )
    .map_err(|e| FormatError::new(format!("line {names_no}"), e.to_string()))?;
    Ok(Capture {
        format: Format::QtmTsv,
        trajectories,
        info: CaptureInfo {
            declared_units: None,
            warnings,
            ..CaptureInfo::default()
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A QTM export with its column header (trailing tab as QTM writes it), a gap written
    /// as zeros and one as `null`.
    const EXPORT: &str = "\
NO_OF_FRAMES\t3
NO_OF_CAMERAS\t10
NO_OF_MARKERS\t2
FREQUENCY\t100
NO_OF_ANALOG\t0
ANALOG_FREQUENCY\t0
DESCRIPTION\t--
TIME_STAMP\t2026-01-19, 10:19:43.755\t2063631.96175450
DATA_INCLUDED\t3D
MARKER_NAMES\tLASI\tNew 0002\t
TRAJECTORY_TYPES\tMeasured\tMixed
Frame\tTime\tLASI X\tLASI Y\tLASI Z\tNew 0002 X\tNew 0002 Y\tNew 0002 Z\t
1\t0.00000\t819.834\t277.770\t22.421\t0.000\t0.000\t0.000
2\t0.01000\t819.9\t277.8\t22.5\t694.169\t12.0\t13.0
3\t0.02000\tnull\tnull\tnull\t694.2\t12.1\t13.1
";

    #[test]
    fn a_qtm_export_gives_its_markers_with_gaps_missing() {
        let c = parse(EXPORT.as_bytes(), &ReadOptions::default()).unwrap();
        let t = &c.trajectories;
        assert_eq!(c.format, Format::QtmTsv);
        assert_eq!(t.labels(), ["LASI", "New 0002"]);
        assert_eq!((t.frame_rate(), t.first_frame(), t.frames()), (100.0, 1, 3));
        assert_eq!(t.get(0, 0), Some([819.834, 277.770, 22.421]));
        assert_eq!((t.get(0, 1), t.get(2, 0)), (None, None));
        assert_eq!(t.get(1, 1), Some([694.169, 12.0, 13.0]));
        assert!(
            c.info
                .warnings
                .iter()
                .any(|w| w.contains("exactly (0, 0, 0)"))
        );
    }

    #[test]
    fn a_qtm_export_without_column_header_or_frame_rate_still_reads() {
        // No Frame/Time header: the rows' width says they carry frame and time.
        let bare = EXPORT.replace(
            "Frame\tTime\tLASI X\tLASI Y\tLASI Z\tNew 0002 X\tNew 0002 Y\tNew 0002 Z\t\n",
            "",
        );
        let c = parse(bare.as_bytes(), &ReadOptions::default()).unwrap();
        assert_eq!(c.trajectories.get(1, 1), Some([694.169, 12.0, 13.0]));
        assert_eq!(c.trajectories.first_frame(), 1);
        // Only the triples, a decimal comma, and an external clock with no times: refused.
        let triples: String = bare
            .lines()
            .map(|l| match l.split_once('\t') {
                Some((f, rest)) if f.parse::<u32>().is_ok() => {
                    rest.split_once('\t').map_or("", |r| r.1).replace('.', ",") + "\n"
                }
                _ => l.to_owned() + "\n",
            })
            .collect();
        let c = parse(triples.as_bytes(), &ReadOptions::default()).unwrap();
        assert_eq!(c.trajectories.get(1, 0), Some([819.9, 277.8, 22.5]));
        let ext = triples.replace("FREQUENCY\t100", "FREQUENCY\tEXT");
        let e = parse(ext.as_bytes(), &ReadOptions::default()).unwrap_err();
        assert!(e.location == "line 4" && e.problem.contains("`EXT`"), "{e}");
        // An external clock with times: the rate is theirs.
        let timed = EXPORT.replace("FREQUENCY\t100", "FREQUENCY\tEXT");
        let rate = parse(timed.as_bytes(), &ReadOptions::default())
            .unwrap()
            .trajectories
            .frame_rate();
        assert!((rate - 100.0).abs() < 1e-9, "{rate}");
    }

    #[test]
    fn a_qtm_export_that_is_not_3d_markers_is_refused_naming_the_line() {
        let refused = |text: &str, place: &str, says: &str| {
            let e = parse(text.as_bytes(), &ReadOptions::default()).unwrap_err();
            assert!(e.location == place && e.problem.contains(says), "{e}");
        };
        refused(&EXPORT.replace("\t3D", "\t6D"), "line 9", "`6D`");
        refused(
            &EXPORT.replace("MARKER_NAMES", "MARKERS"),
            "line 12",
            "MARKER_NAMES",
        );
        refused(
            &EXPORT.replace("New 0002 Y", "New 0002 y2"),
            "line 12",
            "`New 0002 Y`",
        );
        refused(
            &EXPORT.replace("819.9", "8x"),
            "line 14, field 3",
            "(marker LASI, x)",
        );
        assert!(sniff(EXPORT.as_bytes()) && !sniff(b"frame,a_x"));
    }

    #[test]
    fn every_cut_short_export_reads_or_fails_without_a_panic() {
        // A file cut anywhere (a copy interrupted, a partial download) must give a capture
        // or an error naming a place, never a panic.
        for end in (0..=EXPORT.len()).filter(|&e| EXPORT.is_char_boundary(e)) {
            if let Err(e) = parse(&EXPORT.as_bytes()[..end], &ReadOptions::default()) {
                assert!(e.location.starts_with("line "), "{e}");
            }
        }
    }
}
