//! OptiTrack Motive's CSV export (format versions 1.2x).
//!
//! ```text
//! Format Version,1.23,Take Name,walk,...,Export Frame Rate,120.000000,...,Length Units,Millimeters,Coordinate Space,Global
//!
//! ,Type,Rigid Body,...,Marker,Marker,Marker
//! ,Name,head,...,Bob:LKNE,Bob:LKNE,Bob:LKNE
//! ,ID,"1",...,"8908D55B",...
//! ,,Rotation,...,Position,Position,Position
//! Frame,Time (Seconds),X,...,X,Y,Z
//! 0,0.000000,0.1,...,107.554214,208.315002,-3.679659
//! ```
//!
//! The first line is `key,value` pairs; after it come rows named in their second cell
//! (`Type`, `Name`, `ID`, and in newer exports `Parent`), a row saying what each column
//! holds (`Position`, `Rotation`, ...), then the column header starting `Frame`. An
//! optional `TimeCode` column shifts every column right. Columns of type `Marker` holding
//! `Position` X, Y, Z are the measured markers, labelled (`Asset:Marker`) or not
//! (`Unlabeled 1036`); rigid bodies, the markers a rigid body or skeleton solve expects
//! (`Rigid Body Marker`, `Bone Marker`) and bones are solver output and are left out.
//! Missing samples are empty fields. Units: `Length Units` (metres where absent).

use super::{Layout, cell, cells, frame_rate, is_blank, read_rows, scale, table_warnings};
use crate::trc::{Lines, unique_labels};
use crate::{Capture, CaptureInfo, Format, FormatError, ReadOptions, Trajectories};

/// Parses a Motive CSV export into a capture in millimetres.
pub(crate) fn parse(bytes: &[u8], options: &ReadOptions) -> Result<Capture, FormatError> {
    let mut lines = Lines::new(bytes);
    let Some((first_no, first)) = lines.find(|(_, l)| !is_blank(l, b',')) else {
        return Err(FormatError::new("line 1", "empty file"));
    };
    let first = first.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(first);
    let meta = cells(first, b',');
    let at_meta = format!("line {first_no}");
    if !meta
        .first()
        .is_some_and(|c| c.eq_ignore_ascii_case("Format Version"))
    {
        return Err(FormatError::new(
            &at_meta,
            "a Motive export starts with `Format Version,...`",
        ));
    }
    // Keys and values alternate, but an empty or quoted value must not shift the rest:
    // each key's value is the cell after it.
    let value = |key: &str| {
        meta.iter()
            .position(|c| c.eq_ignore_ascii_case(key))
            .and_then(|i| meta.get(i + 1))
            .map(String::as_str)
    };
    let mut warnings = Vec::new();
    let frame_rate = match (value("Export Frame Rate"), value("Capture Frame Rate")) {
        (Some(rate), _) => frame_rate(rate, &at_meta, "Export Frame Rate")?,
        (None, Some(rate)) => frame_rate(rate, &at_meta, "Capture Frame Rate")?,
        (None, None) => {
            return Err(FormatError::new(
                &at_meta,
                "no `Export Frame Rate` or `Capture Frame Rate`: the frame rate is unknown",
            ));
        }
    };
    let declared_units = value("Length Units").filter(|u| !u.is_empty());
    let scale = scale(
        options.units,
        declared_units,
        ASSUMED_UNIT,
        &at_meta,
        &mut warnings,
    )?;
    if let Some(space) = value("Coordinate Space").filter(|s| !s.eq_ignore_ascii_case("Global")) {
        warnings.push(format!(
            "{at_meta}: Coordinate Space is `{space}`, not Global: markers are placed in their \
             assets' own frames, which move; export in Global space for a skeleton"
        ));
    }

    // The rows before the column header, by their names; the row with no name says what
    // each column holds.
    let mut named: Vec<(String, Vec<String>)> = Vec::new();
    let mut holds: Option<Vec<String>> = None;
    let (header_no, header) = loop {
        let Some((no, line)) = lines.next() else {
            return Err(FormatError::new(
                format!("line {}", lines.line_count() + 1),
                "the file ends before the column header `Frame,Time (Seconds),X,Y,Z,...`",
            ));
        };
        if is_blank(line, b',') {
            continue;
        }
        let row = cells(line, b',');
        if row[0].eq_ignore_ascii_case("Frame") {
            break (no, row);
        }
        match row.get(1).map(String::as_str) {
            Some("") | None => holds = Some(row),
            Some(name) => named.push((name.to_ascii_lowercase(), row)),
        }
    };
    let row_named = |name: &str| {
        named
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, row)| row.as_slice())
    };
    let (Some(types), Some(names)) = (row_named("type"), row_named("name")) else {
        return Err(FormatError::new(
            format!("line {header_no}"),
            "no `,Type,...` and `,Name,...` rows before the column header: the export does \
             not say which columns are markers",
        ));
    };
    let holds = holds.unwrap_or_default();

    let mut labels = Vec::new();
    let mut fields = Vec::new();
    let mut left_out: std::collections::BTreeMap<String, std::collections::BTreeSet<String>> =
        Default::default();
    let mut i = 0;
    while i < header.len() {
        let kind = cell(types, i);
        let is_marker_position =
            kind.eq_ignore_ascii_case("Marker") && cell(&holds, i).eq_ignore_ascii_case("Position");
        if !is_marker_position {
            if !kind.is_empty() && !kind.eq_ignore_ascii_case("Type") {
                left_out
                    .entry(kind.to_owned())
                    .or_default()
                    .insert(cell(names, i).to_owned());
            }
            i += 1;
            continue;
        }
        let name = cell(names, i);
        for (k, axis) in ["X", "Y", "Z"].into_iter().enumerate() {
            let j = i + k;
            if !cell(&header, j).eq_ignore_ascii_case(axis) || cell(names, j) != name {
                return Err(FormatError::new(
                    format!("line {header_no}, column {}", j + 1),
                    format!(
                        "marker `{name}`: expected its {axis} column here, found `{}` of `{}` \
                         (a marker's position is X, Y, Z in that order)",
                        cell(&header, j),
                        cell(names, j)
                    ),
                ));
            }
        }
        labels.push(if name.is_empty() {
            format!("M{:03}", labels.len())
        } else {
            name.to_owned()
        });
        fields.push([i, i + 1, i + 2]);
        i += 3;
    }
    if labels.is_empty() {
        let found: Vec<&str> = left_out.keys().map(String::as_str).collect();
        return Err(FormatError::new(
            format!("line {header_no}"),
            format!(
                "no marker positions (columns of Type `Marker`): the export holds {}; export \
                 again with Markers ticked",
                if found.is_empty() {
                    "no data columns".to_owned()
                } else {
                    found.join(", ")
                }
            ),
        ));
    }
    if !left_out.is_empty() {
        let what: Vec<String> = left_out
            .iter()
            .map(|(kind, names)| format!("{} {kind}", names.len()))
            .collect();
        warnings.push(format!(
            "left out {}: solver output, not measured markers (ossify reads the Type \
             `Marker` positions)",
            what.join(", ")
        ));
    }
    let unlabeled = labels
        .iter()
        .filter(|l| l.starts_with("Unlabeled "))
        .count();
    if unlabeled > 0 {
        warnings.push(format!(
            "{unlabeled} of {} markers are Motive's unlabeled tracks (`Unlabeled N`): each \
             is one stretch of a marker; pieces that can be followed across their gaps are \
             joined (mocap-io.stitch), and labelling the take in Motive (any names) gives \
             whole trajectories",
            labels.len()
        ));
    }
    unique_labels(&mut labels, &format!("line {header_no}"), &mut warnings);

    let layout = Layout {
        labels,
        fields,
        frame_field: Some(0),
        time_field: header
            .get(1)
            .is_some_and(|c| c.to_ascii_lowercase().starts_with("time"))
            .then_some(1),
        sep: b',',
        decimal_comma: false,
    };
    let table = read_rows(lines, &layout, scale, bytes.len(), |_| false)?;
    let Some(first_frame) = table.first_frame else {
        return Err(FormatError::new(
            format!("line {}", header_no + 1),
            "no data rows after the column header",
        ));
    };
    table_warnings(&table, &mut warnings);
    let trajectories = Trajectories::new(
        layout.labels,
        frame_rate,
        first_frame,
        table.rows,
        table.positions,
    )
    .map_err(|e| FormatError::new(format!("line {header_no}"), e.to_string()))?;
    Ok(Capture {
        format: Format::MotiveCsv,
        trajectories,
        info: CaptureInfo {
            declared_units: declared_units.map(str::to_owned),
            warnings,
            ..CaptureInfo::default()
        },
    })
}

/// The unit a Motive export without `Length Units` is read in (Motive's own default):
/// millimetres per unit and its name.
pub(crate) const ASSUMED_UNIT: (f64, &str) = (1000.0, "metres");

#[cfg(test)]
mod tests {
    use super::*;

    /// A Motive 1.24 export with a TimeCode column, a rigid body, two labelled markers and
    /// one unlabeled track, in centimetres (the layout of a real export, values made up).
    const TAKE: &str = "\
Format Version,1.24,Take Name,Take 2026-08-04 03.25.39 PM,Take Notes,,Capture Frame Rate,120.000000,Export Frame Rate,60.000000,Capture Start Time,2026-08-04 03.25.40.230 ,Capture Start Frame,868362,Total Frames in Take,3,Total Exported Frames,3,Rotation Type,Quaternion,Length Units,Centimeters,Coordinate Space,Global\r
\r
,Type,,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Marker,Marker,Marker,Marker,Marker,Marker,Marker,Marker,Marker\r
,Name,,cam,cam,cam,cam,cam,cam,cam,cam,Cam:Marker 001,Cam:Marker 001,Cam:Marker 001,Cam:Marker 002,Cam:Marker 002,Cam:Marker 002,Unlabeled 1189,Unlabeled 1189,Unlabeled 1189\r
,ID,,\"1\",\"1\",\"1\",\"1\",\"1\",\"1\",\"1\",\"1\",\"4CF0B31A\",\"4CF0B31A\",\"4CF0B31A\",\"4CF0B31B\",\"4CF0B31B\",\"4CF0B31B\",\"5A2FB614\",\"5A2FB614\",\"5A2FB614\"\r
,,,Rotation,Rotation,Rotation,Rotation,Position,Position,Position,Mean Marker Error,Position,Position,Position,Position,Position,Position,Position,Position,Position\r
Frame,Time (Seconds),TimeCode,X,Y,Z,W,X,Y,Z,,X,Y,Z,X,Y,Z,X,Y,Z\r
0,0.000000,15:26:46:12.02,0,0,0,1,1,2,3,0.0001,-92.003639,311.561951,134.137253,1.5,2.5,3.5,,,\r
1,0.016667,15:26:46:12.03,0,0,0,1,1,2,3,0.0001,-92.011810,313.831543,137.288467,,,,4,5,6\r
2,0.033333,15:26:46:12.04,,,,,,,,,-92.1,313.9,137.3,1.6,2.6,3.6,,,\r
";

    #[test]
    fn a_motive_export_gives_its_markers_in_millimetres_and_leaves_solver_output_out() {
        let c = parse(TAKE.as_bytes(), &ReadOptions::default()).unwrap();
        let t = &c.trajectories;
        assert_eq!(c.format, Format::MotiveCsv);
        assert_eq!(
            t.labels(),
            ["Cam:Marker 001", "Cam:Marker 002", "Unlabeled 1189"]
        );
        // The export's rate, not the capture's.
        assert_eq!(t.frame_rate(), 60.0);
        assert_eq!((t.first_frame(), t.frames()), (0, 3));
        let p = t.get(0, 0).unwrap();
        assert!((p[0] + 920.03639).abs() < 1e-9 && (p[2] - 1341.37253).abs() < 1e-9);
        assert_eq!(t.get(1, 1), None);
        assert_eq!(t.get(1, 2), Some([40.0, 50.0, 60.0]));
        assert_eq!(t.get(0, 2), None);
        assert_eq!(c.info.declared_units.as_deref(), Some("Centimeters"));
        let w = c.info.warnings.join("\n");
        assert!(w.contains("left out 1 Rigid Body"), "{w}");
        assert!(
            w.contains("1 of 3 markers are Motive's unlabeled tracks"),
            "{w}"
        );
    }

    #[test]
    fn a_motive_export_without_units_is_read_as_metres_and_says_so() {
        let take = TAKE.replace("Length Units,Centimeters,", "");
        let c = parse(take.as_bytes(), &ReadOptions::default()).unwrap();
        assert_eq!(c.trajectories.get(0, 1).map(|p| p[0]), Some(1500.0));
        assert!(c.info.warnings.iter().any(|w| w.contains("read as metres")));
        let options = ReadOptions {
            units: Some(crate::LengthUnit::Mm),
            ..ReadOptions::default()
        };
        let c = parse(take.as_bytes(), &options).unwrap();
        assert_eq!(c.trajectories.get(0, 1).map(|p| p[0]), Some(1.5));
    }

    /// A Motive export without `Length Units` over millimetres is read as metres (its
    /// markers hundreds of metres apart), and the spacing warning, knowing the unit the
    /// reader assumed, names millimetres as the unit that fits.
    #[test]
    fn millimetres_read_as_assumed_metres_are_said_with_the_unit_that_fits() {
        let take = TAKE.replace("Length Units,Centimeters,", "");
        let c = parse(take.as_bytes(), &ReadOptions::default()).unwrap();
        let warning = crate::implausible_spacing(&c, &ReadOptions::default()).expect("a warning");
        assert!(
            warning.contains("--set mocap-io.units=mm reads them so"),
            "{warning}"
        );
    }

    #[test]
    fn a_broken_motive_export_is_refused_naming_the_place() {
        let refused = |text: &str, place: &str, says: &str| {
            let e = parse(text.as_bytes(), &ReadOptions::default()).unwrap_err();
            assert!(e.location == place && e.problem.contains(says), "{e}");
        };
        refused(
            &TAKE.replace("Export Frame Rate,60.000000,", "Export Frame Rate,fast,"),
            "line 1",
            "Export Frame Rate `fast`",
        );
        refused(
            &TAKE.replace(",Type,,Rigid", ",Kind,,Rigid"),
            "line 7",
            "no `,Type,...`",
        );
        refused(
            &TAKE.replace("X,Y,Z,X,Y,Z,X,Y,Z\r", "X,Z,Y,X,Y,Z,X,Y,Z\r"),
            "line 7, column 13",
            "marker `Cam:Marker 001`: expected its Y column",
        );
        refused(
            &TAKE.replace("-92.011810", "-92.0x"),
            "line 9, field 12",
            "`-92.0x` is not a number (marker Cam:Marker 001, x)",
        );
        let no_markers: String = TAKE
            .lines()
            .map(|l| l.split(',').take(11).collect::<Vec<_>>().join(",") + "\n")
            .collect();
        refused(&no_markers, "line 7", "holds Rigid Body");
        refused(
            &TAKE[..TAKE.find("Frame,Time").unwrap()],
            "line 7",
            "ends before",
        );
    }

    #[test]
    fn every_cut_short_export_reads_or_fails_without_a_panic() {
        // A file cut anywhere (a copy interrupted, a partial download) must give a capture
        // or an error naming a place, never a panic.
        for end in (0..=TAKE.len()).filter(|&e| TAKE.is_char_boundary(e)) {
            if let Err(e) = parse(&TAKE.as_bytes()[..end], &ReadOptions::default()) {
                assert!(e.location.starts_with("line "), "{e}");
            }
        }
    }
}
