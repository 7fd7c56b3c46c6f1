//! Vicon Nexus's CSV export: sections, of which `Trajectories` holds the markers.
//!
//! ```text
//! Devices,,,,
//! 1000,,,,
//! ...                                       (force plates, EMG: not read)
//! ,,,,,,,,
//! Trajectories,,,,,,,,
//! 100,,,,,,,,
//! ,,Bob:LASI,,,Bob:RASI,,
//! Frame,Sub Frame,X,Y,Z,X,Y,Z
//! ,,mm,mm,mm,mm,mm,mm
//! 1,0,209.331,1219.74,1780.67,,,
//! ```
//!
//! A section is its title, its rate in Hz, a row of names (each over its first column),
//! a row of components, a row of units, then data rows, up to a blank row (Nexus pads
//! every row with commas to the table's width) or the end of the file. In `Trajectories`
//! each marker is an X, Y, Z triple; missing samples are empty fields.

use super::{Layout, cell, cells, frame_rate, is_blank, read_rows, scale, table_warnings};
use crate::trc::{Lines, unique_labels};
use crate::{Capture, CaptureInfo, Format, FormatError, ReadOptions, Trajectories};

/// Section titles Nexus writes.
pub(crate) const SECTIONS: [&str; 5] = [
    "Devices",
    "Trajectories",
    "Model Outputs",
    "Joints",
    "Segments",
];

/// The section a line opens, if its first cell is a title.
fn section_of(line: &[u8]) -> Option<&'static str> {
    let first = line.split(|&b| b == b',').next()?;
    let first = first
        .strip_prefix(b"\xEF\xBB\xBF")
        .unwrap_or(first)
        .trim_ascii();
    SECTIONS
        .into_iter()
        .find(|s| first.eq_ignore_ascii_case(s.as_bytes()))
}

/// Parses a Nexus CSV export's Trajectories section into a capture in millimetres.
pub(crate) fn parse(bytes: &[u8], options: &ReadOptions) -> Result<Capture, FormatError> {
    let mut lines = Lines::new(bytes);
    let mut others = Vec::new();
    let title_no = loop {
        let Some((no, line)) = lines.next() else {
            return Err(FormatError::new(
                format!("line {}", lines.line_count().max(1)),
                if others.is_empty() {
                    "no `Trajectories` section (a Nexus CSV export of the markers has one)"
                        .to_owned()
                } else {
                    format!(
                        "no `Trajectories` section, only {}: export the trajectories too",
                        others.join(", ")
                    )
                },
            ));
        };
        match section_of(line) {
            Some("Trajectories") => break no,
            Some(other) if !others.contains(&other) => others.push(other),
            _ => {}
        }
    };
    // The section's four heading rows, each named for the error when it is missing.
    let mut heading = |what: &str| {
        lines
            .find(|(_, l)| !is_blank(l, b','))
            .map(|(no, l)| (no, cells(l, b',')))
            .ok_or_else(|| {
                FormatError::new(
                    format!("line {title_no}"),
                    format!("the Trajectories section ends before its {what} row"),
                )
            })
    };
    let (rate_no, rate) = heading("frame rate")?;
    let frame_rate = frame_rate(&rate[0], &format!("line {rate_no}"), "the frame rate")?;
    let (names_no, names) = heading("marker names")?;
    let (header_no, header) = heading("`Frame,Sub Frame,X,Y,Z,...`")?;
    if !header[0].eq_ignore_ascii_case("Frame") {
        return Err(FormatError::new(
            format!("line {header_no}"),
            format!(
                "expected the `Frame,Sub Frame,X,Y,Z,...` row, found `{}`",
                header[0]
            ),
        ));
    }
    let (units_no, units) = heading("units")?;
    // Nexus writes units under the components; a table without them has its first data
    // row there.
    let units_row = units[0].is_empty().then(|| units.clone());

    let mut warnings = Vec::new();
    let mut labels = Vec::new();
    let mut fields = Vec::new();
    let mut skipped = Vec::new();
    for (i, name) in names.iter().enumerate().filter(|(_, n)| !n.is_empty()) {
        let xyz = (0..3).all(|k| cell(&header, i + k).eq_ignore_ascii_case(["X", "Y", "Z"][k]));
        let alone = (1..3).all(|k| cell(&names, i + k).is_empty());
        if xyz && alone {
            labels.push(name.clone());
            fields.push([i, i + 1, i + 2]);
        } else {
            skipped.push(format!("{name} (column {})", i + 1));
        }
    }
    if !skipped.is_empty() {
        warnings.push(format!(
            "line {names_no}: left out {} names over columns that are not an X, Y, Z \
             triple: {}",
            skipped.len(),
            skipped.join(", ")
        ));
    }
    if labels.is_empty() {
        return Err(FormatError::new(
            format!("line {names_no}"),
            "the Trajectories section names no marker over X, Y, Z columns",
        ));
    }
    // One unit for the section: the first marker's, as the others' must agree.
    let declared = units_row.as_ref().map(|u| cell(u, fields[0][0]).to_owned());
    if let (Some(row), Some(unit)) = (&units_row, &declared)
        && let Some((label, other)) = labels
            .iter()
            .zip(&fields)
            .map(|(l, f)| (l, cell(row, f[0])))
            .find(|(_, u)| u != unit)
    {
        return Err(FormatError::new(
            format!("line {units_no}"),
            format!("marker {label} is in `{other}` where the first is in `{unit}`"),
        ));
    }
    let scale = scale(
        options.units,
        declared.as_deref(),
        (1.0, "millimetres"),
        &format!(
            "line {}",
            if units_row.is_some() {
                units_no
            } else {
                header_no
            }
        ),
        &mut warnings,
    )?;
    unique_labels(&mut labels, &format!("line {names_no}"), &mut warnings);

    let layout = Layout {
        labels,
        fields,
        frame_field: Some(0),
        time_field: None,
        sep: b',',
        decimal_comma: false,
    };
    // Without a units row its line is the first data row.
    let first_row = units_row
        .is_none()
        .then(|| (units_no, bytes_of_row(&units)));
    let rows = first_row
        .iter()
        .map(|(no, row)| (*no, row.as_slice()))
        .chain(lines.by_ref());
    let table = read_rows(rows, &layout, scale, bytes.len(), |line| {
        is_blank(line, b',') || section_of(line).is_some()
    })?;
    let Some(first_frame) = table.first_frame else {
        return Err(FormatError::new(
            format!("line {units_no}"),
            "the Trajectories section has no data rows",
        ));
    };
    // Sections after this one, to say what was not read.
    for (_, line) in lines {
        if let Some(other) = section_of(line).filter(|s| !others.contains(s)) {
            others.push(other);
        }
    }
    if !others.is_empty() {
        warnings.push(format!(
            "read the Trajectories section; left out {}",
            others.join(", ")
        ));
    }
    table_warnings(&table, &mut warnings);
    let trajectories = Trajectories::new(
        layout.labels,
        frame_rate,
        first_frame,
        table.rows,
        table.positions,
    )
    .map_err(|e| FormatError::new(format!("line {names_no}"), e.to_string()))?;
    Ok(Capture {
        format: Format::NexusCsv,
        trajectories,
        info: CaptureInfo {
            declared_units: declared,
            warnings,
            ..CaptureInfo::default()
        },
    })
}

/// A row's cells joined back into a line, for a row read as a heading that was data.
fn bytes_of_row(row: &[String]) -> Vec<u8> {
    row.join(",").into_bytes()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A Nexus export with a Devices section before the markers and a Model Outputs
    /// section after them, rows padded with commas as Nexus writes them.
    const EXPORT: &str = "\
Devices,,,,,,,
1000,,,,,,,
,,Force Plate #1 - Force,,,,,
Frame,Sub Frame,Fx,Fy,Fz,,,
,,N,N,N,,,
1,0,0,0,0,,,
1,1,0,0,0,,,
,,,,,,,
Trajectories,,,,,,,
100,,,,,,,
,,Bob:LASI,,,Bob:RASI,,
Frame,Sub Frame,X,Y,Z,X,Y,Z
,,mm,mm,mm,mm,mm,mm
1,0,209.331,1219.74,1780.67,,,
2,0,209.5,1219.8,1780.7,175.119,1132.69,655.432
,,,,,,,
Model Outputs,,,,,,,
100,,,,,,,
,,Bob:LKneeAngles,,,,,
Frame,Sub Frame,X,Y,Z,,,
,,deg,deg,deg,,,
1,0,1,2,3,,,
";

    #[test]
    fn a_nexus_export_gives_its_trajectories_section() {
        let c = parse(EXPORT.as_bytes(), &ReadOptions::default()).unwrap();
        let t = &c.trajectories;
        assert_eq!(c.format, Format::NexusCsv);
        assert_eq!(t.labels(), ["Bob:LASI", "Bob:RASI"]);
        assert_eq!((t.frame_rate(), t.first_frame(), t.frames()), (100.0, 1, 2));
        assert_eq!(t.get(0, 0), Some([209.331, 1219.74, 1780.67]));
        assert_eq!(t.get(0, 1), None);
        assert_eq!(t.get(1, 1), Some([175.119, 1132.69, 655.432]));
        assert_eq!(c.info.declared_units.as_deref(), Some("mm"));
        let w = c.info.warnings.join("\n");
        assert!(w.contains("left out Devices, Model Outputs"), "{w}");
    }

    #[test]
    fn a_nexus_export_in_metres_or_without_units_is_read_as_it_says() {
        let metres = EXPORT.replace(",,mm,mm,mm,mm,mm,mm", ",,m,m,m,m,m,m");
        let c = parse(metres.as_bytes(), &ReadOptions::default()).unwrap();
        assert_eq!(
            c.trajectories.get(0, 0),
            Some([209331.0, 1219740.0, 1780670.0])
        );
        let bare = EXPORT.replace(",,mm,mm,mm,mm,mm,mm\n", "");
        let c = parse(bare.as_bytes(), &ReadOptions::default()).unwrap();
        assert_eq!(c.trajectories.frames(), 2);
        assert_eq!(c.trajectories.get(0, 0), Some([209.331, 1219.74, 1780.67]));
        assert!(c.info.warnings.iter().any(|w| w.contains("no length unit")));
    }

    #[test]
    fn a_broken_nexus_export_is_refused_naming_the_place() {
        let refused = |text: &str, place: &str, says: &str| {
            let e = parse(text.as_bytes(), &ReadOptions::default()).unwrap_err();
            assert!(e.location == place && e.problem.contains(says), "{e}");
        };
        refused(
            &EXPORT[..EXPORT.find("Trajectories").unwrap()],
            "line 8",
            "only Devices",
        );
        refused(
            &EXPORT.replace("100,,,,,,,\n,,Bob", "fast,,,\n,,Bob"),
            "line 10",
            "`fast`",
        );
        refused(
            &EXPORT.replace(",,mm,mm,mm,mm,mm,mm", ",,mm,mm,mm,m,m,m"),
            "line 13",
            "marker Bob:RASI is in `m`",
        );
        refused(
            &EXPORT.replace("209.5,", "20x,"),
            "line 15, field 3",
            "`20x` is not a number (marker Bob:LASI, x)",
        );
        refused(
            &EXPORT.replace("Frame,Sub Frame,X,Y,Z,X", "Time,Sub Frame,X,Y,Z,X"),
            "line 12",
            "expected the `Frame,Sub Frame",
        );
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
