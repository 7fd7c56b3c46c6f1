//! TRC (Motion Analysis / OpenSim) reading and writing.
//!
//! # Layout read
//!
//! ```text
//! PathFileType  4  (X/Y/Z)  walk.trc                      line 1
//! DataRate  CameraRate  NumFrames  NumMarkers  Units ...  line 2: keys
//! 60.00     60.00       151        41          mm    ...  line 3: their values
//! Frame#  Time  R.ASIS  <tab><tab>  L.ASIS  ...           line 4: marker labels
//!               X1  Y1  Z1  X2  Y2  Z2 ...                line 5: coordinate names (optional)
//! 1       0.000 617.2  1055.3  170.8  ...                 data rows
//! ```
//!
//! Rules (each one met in a real file):
//! - Fields are tab separated (a line without a tab is split on runs of spaces); spaces
//!   around a field are ignored, CRLF and LF line endings both work, blank lines are skipped.
//! - Header values are matched to keys by name (any order, any case); missing
//!   `OrigDataRate`, `OrigDataStartFrame`, `OrigNumFrames` are fine. A missing `Units`
//!   means millimetres (with a warning); `mm`, `cm`, `dm`, `m` and `in` (or their names
//!   spelled out) are converted to millimetres, any other unit is an error naming line 3.
//! - The markers are the labels named on line 4, in order (labels may contain spaces
//!   when the line is tab separated). A `NumMarkers` that disagrees is a warning; values
//!   beyond the named markers' columns are ignored with a warning (BTK's `Gait.trc`
//!   declares 66 markers, names 33, and carries unnamed data in columns past both).
//! - A sample is missing when any of its three fields is empty, when its row ends before
//!   it, when a field reads `nan` (OpenSim writes gaps that way), or when it is exactly
//!   (0, 0, 0): the gap convention several vendors use in C3D, applied here too so one
//!   capture reads the same from either format.
//! - Frame count = data rows; a `NumFrames` that disagrees is a warning. The first frame
//!   is the `Frame#` of the first data row.
//! - Frame rate: `DataRate`, else `CameraRate`, else the `Time` column's mean step, with a
//!   warning for each fallback; none of them usable is an error.
//! - A field that is neither empty nor a number is an error naming its line and field.
//!
//! # Layout written
//!
//! What OpenSim's own `TRCFileAdapter` writes and reads: tab separated, the eight header
//! keys in their standard order, units `mm`, one blank line after the coordinate line, a
//! tab after every value (as OpenSim does), positions with five decimals, empty fields
//! for missing samples, `Frame#` counting from the first frame and `Time` = frame index /
//! frame rate in seconds.

use std::fmt::Write as _;

use crate::{Capture, CaptureInfo, Format, FormatError, ReadOptions, Trajectories};

/// Decimals written for positions (millimetres): 10 nm, far below any capture's noise.
const POSITION_DECIMALS: usize = 5;
/// Decimals written for the `Time` column (seconds).
const TIME_DECIMALS: usize = 6;

/// Parses TRC bytes into a capture in millimetres (see the module docs for the rules).
pub fn parse(bytes: &[u8], options: &ReadOptions) -> Result<Capture, FormatError> {
    let mut lines = Lines::new(bytes);
    let mut warnings = Vec::new();

    // Line 1: the file-type line.
    let (first_no, first) = match lines.next_nonblank() {
        Some(line) => line,
        None => {
            return Err(FormatError::new(
                "line 1",
                "empty file: a TRC file starts with a `PathFileType` line",
            ));
        }
    };
    let first = first.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(first);
    let head = fields(first).find(|f| !f.is_empty()).unwrap_or(b"");
    if !head.eq_ignore_ascii_case(b"PathFileType") {
        return Err(FormatError::new(
            format!("line {first_no}"),
            format!(
                "not a TRC file: expected a `PathFileType` line, found `{}`",
                show(head)
            ),
        ));
    }

    // Lines 2 and 3: header keys and their values.
    let (keys_no, keys_line) = lines.next().ok_or_else(|| {
        FormatError::new(
            format!("line {}", first_no + 1),
            "file ends before the header's key line (DataRate CameraRate NumFrames NumMarkers Units ...)",
        )
    })?;
    let (values_no, values_line) = lines.next().ok_or_else(|| {
        FormatError::new(
            format!("line {}", keys_no + 1),
            "file ends before the line of header values that follows the key line",
        )
    })?;
    let keys: Vec<&[u8]> = fields(keys_line).filter(|f| !f.is_empty()).collect();
    let values: Vec<&[u8]> = fields(values_line).filter(|f| !f.is_empty()).collect();
    if !keys.iter().any(|k| k.eq_ignore_ascii_case(b"DataRate"))
        && !keys.iter().any(|k| k.eq_ignore_ascii_case(b"NumMarkers"))
    {
        return Err(FormatError::new(
            format!("line {keys_no}"),
            "expected the header's key line (DataRate CameraRate NumFrames NumMarkers Units ...)",
        ));
    }
    if keys.len() != values.len() {
        warnings.push(format!(
            "line {values_no}: {} header values for {} keys; keys without a value are ignored",
            values.len(),
            keys.len()
        ));
    }
    let header = Header {
        keys: &keys,
        values: &values,
        line: values_no,
    };
    let data_rate = header.number("DataRate")?;
    let camera_rate = header.number("CameraRate")?;
    let declared_frames = header.number("NumFrames")?;
    let declared_markers = header.number("NumMarkers")?;
    let (declared_units, scale) = match (options.units, header.get("Units")) {
        (Some(unit), declared) => {
            let text = declared.map(|(_, text)| String::from_utf8_lossy(text).into_owned());
            let declared = text.as_deref().map(|t| (t, crate::mm_per_unit(t)));
            warnings.extend(
                unit.overriding(declared)
                    .map(|w| format!("line {values_no}: {w}")),
            );
            (text, unit.mm())
        }
        (None, Some((field, text))) => {
            let units = String::from_utf8_lossy(text).into_owned();
            let scale = crate::mm_per_unit(&units).ok_or_else(|| {
                FormatError::new(
                    format!("line {values_no}, field {field}"),
                    format!(
                        "unknown units `{}` (expected {})",
                        show(text),
                        crate::KNOWN_UNITS
                    ),
                )
            })?;
            (Some(units), scale)
        }
        (None, None) => {
            warnings.push(format!(
                "line {keys_no}: no `Units` key; assuming millimetres"
            ));
            (None, 1.0)
        }
    };

    // Line 4: `Frame#  Time  label1 <tab><tab> label2 ...`.
    let (labels_no, labels_line) = lines.next_nonblank().ok_or_else(|| {
        FormatError::new(
            format!("line {}", values_no + 1),
            "file ends before the marker-label line (`Frame#  Time  label ...`)",
        )
    })?;
    let mut label_fields = fields(labels_line).filter(|f| !f.is_empty());
    let frame_head = label_fields.next().unwrap_or(b"");
    if !frame_head.eq_ignore_ascii_case(b"Frame#") && !frame_head.eq_ignore_ascii_case(b"Frame") {
        return Err(FormatError::new(
            format!("line {labels_no}"),
            format!(
                "expected the marker-label line starting with `Frame#`, found `{}`",
                show(frame_head)
            ),
        ));
    }
    let _time_head = label_fields.next();
    let mut labels: Vec<String> = label_fields
        .map(|f| String::from_utf8_lossy(f).into_owned())
        .collect();
    if labels.is_empty() {
        return Err(FormatError::new(
            format!("line {labels_no}"),
            "no marker labels after `Frame#` and `Time`: a capture needs at least one marker",
        ));
    }
    let markers = labels.len();
    if let Some(declared) = declared_markers.filter(|d| *d != markers as f64) {
        warnings.push(format!(
            "line {labels_no}: NumMarkers says {declared} but {markers} marker labels are named; reading the {markers} named markers"
        ));
    }
    unique_labels(&mut labels, &format!("line {labels_no}"), &mut warnings);

    // Line 5 (optional): `X1 Y1 Z1 X2 ...`; data rows start with a frame number instead.
    let mut pending = lines.next_nonblank();
    if let Some((xyz_no, xyz_line)) = pending {
        let head = fields(xyz_line).find(|f| !f.is_empty()).unwrap_or(b"");
        if head.first().is_some_and(|c| c.eq_ignore_ascii_case(&b'X')) {
            let coordinates = fields(xyz_line).filter(|f| !f.is_empty()).count();
            if coordinates != 3 * markers {
                warnings.push(format!(
                    "line {xyz_no}: {coordinates} coordinate names for {markers} named markers"
                ));
            }
            pending = lines.next_nonblank();
        }
    }

    // Data rows.
    let limit = sample_limit(bytes.len());
    let columns = 2 + 3 * markers;
    let mut positions: Vec<[f64; 3]> = Vec::new();
    let mut frame_column = FrameColumn::default();
    let mut times: Vec<(usize, f64)> = Vec::new();
    let mut rows = 0usize;
    let mut counts = GapCounts::default();
    let mut extra = ExtraColumns::default();
    let mut row = vec![[f64::NAN; 3]; markers];
    while let Some((line_no, line)) = pending {
        if (rows + 1).saturating_mul(markers) > limit {
            return Err(FormatError::new(
                format!("line {line_no}"),
                format!(
                    "{} rows of {markers} markers is more data than a {}-byte file can hold; refusing to allocate",
                    rows + 1,
                    bytes.len()
                ),
            ));
        }
        row.fill([f64::NAN; 3]);
        let mut seen = 0usize;
        for (index, field) in fields(line).enumerate() {
            seen = index + 1;
            let at = || format!("line {line_no}, field {}", index + 1);
            match index {
                0 => frame_column.record(field, at)?,
                1 => {
                    if !field.is_empty() {
                        let t = parse_number(field).ok_or_else(|| {
                            FormatError::new(
                                at(),
                                format!("time `{}` is not a number", show(field)),
                            )
                        })?;
                        if t.is_finite() {
                            times.push((rows, t));
                        }
                    }
                }
                _ if index < columns => {
                    if field.is_empty() {
                        continue;
                    }
                    let m = (index - 2) / 3;
                    let c = (index - 2) % 3;
                    let v = parse_number(field).ok_or_else(|| {
                        let label = labels.get(m).map(String::as_str).unwrap_or("?");
                        FormatError::new(
                            at(),
                            format!(
                                "`{}` is not a number (marker {label}, {})",
                                show(field),
                                ["x", "y", "z"][c]
                            ),
                        )
                    })?;
                    if let Some(sample) = row.get_mut(m) {
                        sample[c] = v * scale;
                    }
                }
                _ => {
                    if !field.is_empty() {
                        extra.note(index + 1, line_no);
                    }
                }
            }
        }
        if seen < columns {
            counts.short_rows += 1;
        }
        counts.settle(&mut row);
        positions.extend_from_slice(&row);
        rows += 1;
        pending = lines.next_nonblank();
    }

    let Some(first_frame) = frame_column.first else {
        return Err(FormatError::new(
            format!("line {}", lines.line_count() + 1),
            "no data rows after the header",
        ));
    };
    if let Some(declared) = declared_frames.filter(|d| *d != rows as f64) {
        warnings.push(format!(
            "line {values_no}: NumFrames says {declared} but the file has {rows} data rows; reading {rows}"
        ));
    }
    warn_frame_jumps("Frame# is", frame_column.jumps, &mut warnings);
    extra.warn(markers, &mut warnings);
    counts.warn(&mut warnings);

    let frame_rate = choose_rate(data_rate, camera_rate, &times, values_no, &mut warnings)?;
    let trajectories = Trajectories::new(labels, frame_rate, first_frame, rows, positions)
        .map_err(|e| FormatError::new(format!("line {labels_no}"), e.to_string()))?;
    Ok(Capture {
        format: Format::Trc,
        trajectories,
        info: CaptureInfo {
            declared_units,
            warnings,
            ..CaptureInfo::default()
        },
    })
}

/// Encodes trajectories as OpenSim-style TRC text in millimetres (see the module docs).
///
/// Labels are written with tabs and line breaks replaced by `_`, and an empty label as
/// `M<n>` (1-based marker number), so the file always parses back to the same markers.
/// A present sample at exactly (0, 0, 0) reads back as missing (see the module docs).
/// An unknown frame rate (0) is written as `0.00` with every `Time` 0, which the reader
/// refuses: give trajectories a rate before exporting them.
pub fn write(t: &Trajectories) -> String {
    let markers = t.markers();
    let rate = t.frame_rate();
    let rate_text = format_rate(rate);
    // Roughly 12 bytes per coordinate; reserving avoids repeated regrowth on big captures.
    let mut out = String::with_capacity(256 + markers * 24 + t.frames() * (16 + markers * 36));
    let _ = writeln!(out, "PathFileType\t4\t(X/Y/Z)\tossify.trc");
    let _ = writeln!(
        out,
        "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames"
    );
    let _ = writeln!(
        out,
        "{rate_text}\t{rate_text}\t{frames}\t{markers}\tmm\t{rate_text}\t{first}\t{frames}",
        frames = t.frames(),
        first = t.first_frame()
    );
    out.push_str("Frame#\tTime");
    for (i, label) in t.labels().iter().enumerate() {
        out.push('\t');
        out.push_str(&clean_label(label, i));
        out.push_str("\t\t");
    }
    out.push_str("\t\n\t");
    for i in 1..=markers {
        let _ = write!(out, "\tX{i}\tY{i}\tZ{i}");
    }
    out.push_str("\t\n\n");
    for f in 0..t.frames() {
        let time = if rate > 0.0 { f as f64 / rate } else { 0.0 };
        let _ = write!(
            out,
            "{}\t{time:.TIME_DECIMALS$}",
            t.first_frame().saturating_add(f as i64)
        );
        push_samples(&mut out, t.frame(f), '\t');
        out.push_str("\t\n");
    }
    out
}

/// The rate as text that parses back to the same `f64`; whole rates get two decimals
/// (`60.00`) as Motion Analysis and OpenSim write them.
fn format_rate(rate: f64) -> String {
    if rate.fract() == 0.0 && rate.abs() < 1e15 {
        format!("{rate:.2}")
    } else {
        format!("{rate}")
    }
}

/// A label safe inside a tab-separated line, never empty.
/// The frame-number column of a text capture: the first number and how often it jumps.
///
/// Rows are read in file order as consecutive frames whatever their numbers say; jumps
/// are only counted, for a warning.
#[derive(Default)]
pub(crate) struct FrameColumn {
    /// Number of the first data row.
    pub(crate) first: Option<i64>,
    previous: Option<i64>,
    /// Rows whose number is not the previous one plus one.
    pub(crate) jumps: usize,
}

impl FrameColumn {
    /// Reads one row's frame number; `at` names the field for the error.
    pub(crate) fn record(
        &mut self,
        field: &[u8],
        at: impl Fn() -> String,
    ) -> Result<(), FormatError> {
        let frame = parse_frame(field).ok_or_else(|| {
            FormatError::new(
                at(),
                format!("frame number `{}` is not an integer", show(field)),
            )
        })?;
        self.first.get_or_insert(frame);
        if self
            .previous
            .is_some_and(|p| p.checked_add(1) != Some(frame))
        {
            self.jumps += 1;
        }
        self.previous = Some(frame);
        Ok(())
    }
}

/// Says, when `jumps` rows' frame numbers were not the previous one's plus one, that rows
/// are read in file order anyway; `subject` names the column ("frame numbers are").
pub(crate) fn warn_frame_jumps(subject: &str, jumps: usize, warnings: &mut Vec<String>) {
    if jumps > 0 {
        warnings.push(format!(
            "{subject} not consecutive at {jumps} rows; rows are read in file order as \
             consecutive frames"
        ));
    }
}

/// Appends one frame's samples as `sep x sep y sep z` per marker (mm, fixed decimals),
/// with empty fields for missing samples: the row body both text writers share.
pub(crate) fn push_samples(out: &mut String, samples: &[[f64; 3]], sep: char) {
    for p in samples {
        if crate::is_present(*p) {
            for c in p {
                out.push(sep);
                push_position(out, *c);
            }
        } else {
            out.extend([sep, sep, sep]);
        }
    }
}

/// Largest magnitude (mm) written from its count of thousandths: [`crate::ABSURD_MM`],
/// beyond which no trajectory holds a sample, and below which a double's distance from
/// the thousandth it is nearest to is far under the fifth decimal's half.
const WHOLE_THOUSANDTHS_MAX: f64 = crate::ABSURD_MM;

/// Appends `v` with [`POSITION_DECIMALS`] decimals, exactly as `{:.5}` writes it. A value
/// that is a whole number of thousandths of a millimetre (every position export writes is
/// rounded so) is written from that integer count, several times faster than the float
/// formatter, which is most of the time spent writing a big TRC; any other value goes
/// through `{:.5}`.
fn push_position(out: &mut String, v: f64) {
    let thousandths = (v * 1000.0).round();
    if v.abs() < WHOLE_THOUSANDTHS_MAX && thousandths / 1000.0 == v {
        // `{:.5}` keeps the sign of −0.0, and of a negative value that rounds to zero.
        if v.is_sign_negative() {
            out.push('-');
        }
        let k = thousandths.abs() as u64;
        let _ = write!(out, "{}.{:03}00", k / 1000, k % 1000);
    } else {
        let _ = write!(out, "{v:.POSITION_DECIMALS$}");
    }
}

pub(crate) fn clean_label(label: &str, index: usize) -> String {
    let cleaned: String = label
        .trim()
        .chars()
        .map(|c| if c.is_control() { '_' } else { c })
        .collect();
    if cleaned.is_empty() {
        format!("M{}", index + 1)
    } else {
        cleaned
    }
}

/// Header values looked up by key name.
struct Header<'a> {
    keys: &'a [&'a [u8]],
    values: &'a [&'a [u8]],
    line: usize,
}

impl Header<'_> {
    /// The 1-based field number and text of a key's value, if the file gives one.
    fn get(&self, key: &str) -> Option<(usize, &[u8])> {
        let i = self
            .keys
            .iter()
            .position(|k| k.eq_ignore_ascii_case(key.as_bytes()))?;
        self.values.get(i).map(|v| (i + 1, *v))
    }

    /// A key's numeric value; a value that is not a number is an error naming it.
    fn number(&self, key: &str) -> Result<Option<f64>, FormatError> {
        let Some((field, text)) = self.get(key) else {
            return Ok(None);
        };
        match parse_number(text) {
            Some(v) => Ok(Some(v)),
            None => Err(FormatError::new(
                format!("line {}, field {field}", self.line),
                format!("{key} `{}` is not a number", show(text)),
            )),
        }
    }
}

/// DataRate, else CameraRate, else the Time column; errors when none gives a rate.
fn choose_rate(
    data_rate: Option<f64>,
    camera_rate: Option<f64>,
    times: &[(usize, f64)],
    header_line: usize,
    warnings: &mut Vec<String>,
) -> Result<f64, FormatError> {
    let usable = |r: Option<f64>| r.filter(|r| r.is_finite() && *r > 0.0);
    if let Some(rate) = usable(data_rate) {
        return Ok(rate);
    }
    if let Some(rate) = usable(camera_rate) {
        warnings.push(format!(
            "line {header_line}: no usable DataRate; using CameraRate {rate} Hz"
        ));
        return Ok(rate);
    }
    if let (Some(&(r0, t0)), Some(&(r1, t1))) = (times.first(), times.last()) {
        let rate = (r1 as f64 - r0 as f64) / (t1 - t0);
        if r1 > r0 && t1 > t0 && rate.is_finite() {
            warnings.push(format!(
                "line {header_line}: no usable DataRate or CameraRate; {rate:.4} Hz from the Time column"
            ));
            return Ok(rate);
        }
    }
    Err(FormatError::new(
        format!("line {header_line}"),
        "no frame rate: DataRate and CameraRate are missing or not positive, and the Time column does not increase",
    ))
}

/// Counts of the gap conventions met, for one warning each.
#[derive(Default)]
pub(crate) struct GapCounts {
    /// Samples with one or two of three coordinates present: read as missing.
    pub partial: usize,
    /// Samples at exactly (0, 0, 0): read as missing.
    pub zeros: usize,
    /// Rows that end before the last marker's columns.
    pub short_rows: usize,
}

impl GapCounts {
    /// Turns partial and all-zero samples of a row into missing ones, counting them.
    pub(crate) fn settle(&mut self, row: &mut [[f64; 3]]) {
        for p in row {
            let present = p.iter().filter(|c| c.is_finite()).count();
            if present == 3 {
                if *p == [0.0; 3] {
                    self.zeros += 1;
                    *p = crate::MISSING;
                }
            } else if present > 0 {
                self.partial += 1;
                *p = crate::MISSING;
            }
        }
    }

    /// Adds one warning per convention met.
    pub(crate) fn warn(&self, warnings: &mut Vec<String>) {
        if self.partial > 0 {
            warnings.push(format!(
                "{} samples have only one or two of their three coordinates; read as missing",
                self.partial
            ));
        }
        if self.zeros > 0 {
            warnings.push(format!(
                "{} samples are exactly (0, 0, 0); read as missing (a common gap convention)",
                self.zeros
            ));
        }
        if self.short_rows > 0 {
            warnings.push(format!(
                "{} rows end before the last marker's columns; the samples they omit are missing",
                self.short_rows
            ));
        }
    }
}

/// Non-empty values found past the named markers' columns.
#[derive(Default)]
struct ExtraColumns {
    rows: usize,
    last_line: usize,
    max_field: usize,
}

impl ExtraColumns {
    fn note(&mut self, field: usize, line: usize) {
        if self.last_line != line {
            self.rows += 1;
            self.last_line = line;
        }
        self.max_field = self.max_field.max(field);
    }

    fn warn(&self, markers: usize, warnings: &mut Vec<String>) {
        if self.rows > 0 {
            warnings.push(format!(
                "{} rows carry values past the {markers} named markers (up to field {}); they have no label and are ignored",
                self.rows, self.max_field
            ));
        }
    }
}

/// Renames the second and later markers of a repeated label `LABEL#2`, `LABEL#3`, … (a
/// name no other marker has), so every output names each marker once, and says so: the
/// stages tell markers apart by index, but a segment listing `RKNE` twice tells a person
/// nothing (c3d.org's Sample_Jump2 repeats eleven labels, its virtual points among them).
pub(crate) fn unique_labels(labels: &mut [String], at: &str, warnings: &mut Vec<String>) {
    let mut taken: std::collections::BTreeSet<String> = labels.iter().cloned().collect();
    let mut seen: std::collections::BTreeMap<String, usize> = std::collections::BTreeMap::new();
    let mut renamed = Vec::new();
    for label in labels.iter_mut() {
        let count = seen.entry(label.clone()).or_insert(0);
        *count += 1;
        if *count == 1 {
            continue;
        }
        let mut k = *count;
        let mut name = format!("{label}#{k}");
        while taken.contains(&name) {
            k += 1;
            name = format!("{label}#{k}");
        }
        taken.insert(name.clone());
        renamed.push(name.clone());
        *label = name;
    }
    if !renamed.is_empty() {
        let repeated: Vec<String> = seen
            .iter()
            .filter(|(_, n)| **n > 1)
            .map(|(l, n)| format!("{l} ({n}×)"))
            .collect();
        warnings.push(format!(
            "{at}: marker labels repeat: {}; the later markers are named {} in the outputs",
            repeated.join(", "),
            renamed.join(", ")
        ));
    }
}

/// Most samples a file of `len` bytes may produce before we refuse to allocate.
///
/// Rows may omit trailing markers, so a tiny file can claim huge counts; a real file
/// spends at least a byte per sample except in such short rows, so 4 samples per byte
/// (plus a floor) admits every real capture and bounds memory to ~100 bytes per input byte.
pub(crate) fn sample_limit(len: usize) -> usize {
    len.saturating_mul(4).saturating_add(1 << 20)
}

/// A frame number: an integer, or a float with no fractional part.
pub(crate) fn parse_frame(field: &[u8]) -> Option<i64> {
    let text = std::str::from_utf8(field).ok()?;
    if let Ok(v) = text.parse::<i64>() {
        return Some(v);
    }
    let v = text.parse::<f64>().ok()?;
    (v.is_finite() && v.fract() == 0.0 && v.abs() < 9.0e15).then_some(v as i64)
}

/// A number, with NaN spellings (`nan`, `-nan(ind)`, `1.#QNAN`) as NaN; `None` if not a number.
pub(crate) fn parse_number(field: &[u8]) -> Option<f64> {
    let text = std::str::from_utf8(field).ok()?;
    if let Ok(v) = text.parse::<f64>() {
        return Some(v);
    }
    let lower = text.to_ascii_lowercase();
    let nan_like = lower.trim_start_matches(['-', '+']).starts_with("nan")
        || lower.contains("#ind")
        || lower.contains("#qnan")
        || lower.contains("#snan");
    nan_like.then_some(f64::NAN)
}

/// A field for an error message: lossy UTF-8, at most 40 characters.
pub(crate) fn show(field: &[u8]) -> String {
    let text = String::from_utf8_lossy(field);
    let mut shown: String = text.chars().take(40).collect();
    if text.chars().count() > 40 {
        shown.push('…');
    }
    shown
}

/// Lines of a byte buffer with their 1-based numbers, `\r` stripped.
pub(crate) struct Lines<'a> {
    rest: &'a [u8],
    number: usize,
    done: bool,
}

impl<'a> Lines<'a> {
    pub(crate) fn new(bytes: &'a [u8]) -> Self {
        Self {
            rest: bytes,
            number: 0,
            done: bytes.is_empty(),
        }
    }

    /// The number of lines handed out so far.
    pub(crate) fn line_count(&self) -> usize {
        self.number
    }

    /// The next line that holds more than whitespace.
    pub(crate) fn next_nonblank(&mut self) -> Option<(usize, &'a [u8])> {
        self.find(|(_, line)| !line.iter().all(u8::is_ascii_whitespace))
    }
}

impl<'a> Iterator for Lines<'a> {
    type Item = (usize, &'a [u8]);

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        let (line, rest) = match self.rest.iter().position(|&b| b == b'\n') {
            Some(i) => (&self.rest[..i], &self.rest[i + 1..]),
            None => {
                self.done = true;
                (self.rest, &self.rest[self.rest.len()..])
            }
        };
        self.rest = rest;
        if rest.is_empty() {
            // A final newline does not open another (empty) line.
            self.done = true;
        }
        self.number += 1;
        Some((self.number, line.strip_suffix(b"\r").unwrap_or(line)))
    }
}

/// The fields of a TRC line: split on tabs when it has any, else on runs of spaces;
/// each field trimmed of surrounding spaces.
fn fields(line: &[u8]) -> Fields<'_> {
    Fields {
        rest: Some(line),
        tabs: line.contains(&b'\t'),
    }
}

/// Iterator behind [`fields`]; allocation-free.
struct Fields<'a> {
    rest: Option<&'a [u8]>,
    tabs: bool,
}

impl<'a> Iterator for Fields<'a> {
    type Item = &'a [u8];

    fn next(&mut self) -> Option<&'a [u8]> {
        let rest = self.rest?;
        if self.tabs {
            match rest.iter().position(|&b| b == b'\t') {
                Some(i) => {
                    self.rest = Some(&rest[i + 1..]);
                    Some(rest[..i].trim_ascii())
                }
                None => {
                    self.rest = None;
                    Some(rest.trim_ascii())
                }
            }
        } else {
            let start = rest.iter().position(|b| !b.is_ascii_whitespace());
            let Some(start) = start else {
                self.rest = None;
                return None;
            };
            let rest = &rest[start..];
            let end = rest
                .iter()
                .position(u8::is_ascii_whitespace)
                .unwrap_or(rest.len());
            self.rest = Some(&rest[end..]);
            Some(&rest[..end])
        }
    }
}

#[cfg(test)]
mod tests {
    /// The integer path writes every whole number of thousandths as `{:.5}` does (signs,
    /// zeros, carries, large values), and anything else goes through `{:.5}` itself.
    #[test]
    fn positions_are_written_as_five_decimals_exactly() {
        let mut values: Vec<f64> = vec![0.0, -0.0, 1e-3, -1e-3, 0.5, -0.5, 999.999, -1000.0];
        // Thousandths across magnitudes, and values that are not whole thousandths.
        let mut k: i64 = 1;
        while k < 900_000_000_000 {
            for d in [-1, 0, 1, 7, 499, 500, 501, 999] {
                values.push((k + d) as f64 / 1000.0);
                values.push(-((k + d) as f64) / 1000.0);
            }
            k = k * 3 + 1;
        }
        values.extend([
            0.12345678,
            -2.0000049,
            3.0000051,
            1e-9,
            -7.77777e3,
            1e12 + 0.5,
        ]);
        for v in values {
            let mut got = String::new();
            super::push_position(&mut got, v);
            assert_eq!(got, format!("{v:.5}"), "{v:e}");
        }
    }

    use super::*;

    fn read(text: &str) -> Result<Capture, FormatError> {
        parse(text.as_bytes(), &ReadOptions::default())
    }

    const HEADER: &str = "PathFileType\t4\t(X/Y/Z)\tt.trc\n\
        DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames\n\
        100.00\t100.00\t2\t2\tmm\t100.00\t1\t2\n\
        Frame#\tTime\tA\t\t\tB b\t\t\t\n\
        \t\tX1\tY1\tZ1\tX2\tY2\tZ2\t\n\n";

    #[test]
    fn reads_a_small_file_with_a_gap() {
        let text = format!("{HEADER}5\t0.00\t1\t2\t3\t4\t5\t6\t\n6\t0.01\t7\t8\t9\t\t\t\t\n");
        let c = read(&text).unwrap();
        let t = &c.trajectories;
        assert_eq!(t.labels(), ["A", "B b"]);
        assert_eq!((t.frames(), t.first_frame(), t.frame_rate()), (2, 5, 100.0));
        assert_eq!(t.get(0, 1), Some([4.0, 5.0, 6.0]));
        assert_eq!(t.get(1, 0), Some([7.0, 8.0, 9.0]));
        assert_eq!(t.get(1, 1), None);
        assert_eq!(c.info.declared_units.as_deref(), Some("mm"));
        assert!(c.info.warnings.is_empty(), "{:?}", c.info.warnings);
    }

    /// A repeated label's later markers get names of their own, never one the file
    /// already uses, and the warning says which.
    #[test]
    fn repeated_labels_are_told_apart_and_said() {
        let mut labels: Vec<String> = ["A", "B", "A", "A#2", "A", "B"]
            .iter()
            .map(|l| l.to_string())
            .collect();
        let mut warnings = Vec::new();
        unique_labels(&mut labels, "line 4", &mut warnings);
        assert_eq!(labels, ["A", "B", "A#3", "A#2", "A#4", "B#2"]);
        assert_eq!(warnings.len(), 1);
        assert!(
            warnings[0].starts_with("line 4: marker labels repeat: A (3×), B (2×);")
                && warnings[0].ends_with("named A#3, A#4, B#2 in the outputs"),
            "{warnings:?}"
        );
        let text = HEADER.replace("\tB b\t", "\tA\t");
        let rows = "5\t0.00\t1\t2\t3\t4\t5\t6\t\n6\t0.01\t1\t2\t3\t4\t5\t6\t\n";
        let c = read(&format!("{text}{rows}")).unwrap();
        assert_eq!(c.trajectories.labels(), ["A", "A#2"]);
        assert_eq!(c.info.warnings.len(), 1, "{:?}", c.info.warnings);
    }

    #[test]
    fn keys_match_values_by_name_and_units_convert() {
        let text = "PathFileType 4 (X/Y/Z) x.trc\nUnits NumMarkers DataRate\nm 1 50\n\
            Frame# Time A\nX1 Y1 Z1\n1 0 0.001 0.002 0.003\n";
        let c = read(text).unwrap();
        assert_eq!(c.trajectories.frame_rate(), 50.0);
        let p = c.trajectories.get(0, 0).unwrap();
        assert!((p[0] - 1.0).abs() < 1e-12 && (p[2] - 3.0).abs() < 1e-12);
        assert_eq!(c.info.declared_units.as_deref(), Some("m"));
    }

    #[test]
    fn short_rows_zero_samples_and_nan_text_are_missing() {
        let text = format!("{HEADER}1\t0\t0\t0\t0\t1\t2\t3\n2\t0.01\tnan\tnan\tnan\n");
        let c = read(&text).unwrap();
        let t = &c.trajectories;
        assert_eq!(t.missing_samples(), 3);
        assert_eq!(t.get(0, 1), Some([1.0, 2.0, 3.0]));
        assert!(c.info.warnings.iter().any(|w| w.contains("(0, 0, 0)")));
        assert!(
            c.info
                .warnings
                .iter()
                .any(|w| w.contains("rows end before"))
        );
    }

    #[test]
    fn rate_falls_back_to_camera_rate_then_time() {
        let text = "PathFileType\t4\nDataRate\tCameraRate\tNumMarkers\n0\t120\t1\n\
            Frame#\tTime\tA\n1\t0\t1\t1\t1\n";
        assert_eq!(read(text).unwrap().trajectories.frame_rate(), 120.0);
        let text = "PathFileType\t4\nDataRate\tNumMarkers\t\nx0\t1\n";
        let e = read(text).unwrap_err();
        assert_eq!(e.location, "line 3, field 1");
        let text = "PathFileType\t4\nDataRate\tNumMarkers\n0\t1\nFrame#\tTime\tA\n\
            1\t0.5\t1\t1\t1\n2\t0.75\t1\t1\t1\n3\t1.0\t1\t1\t1\n";
        let c = read(text).unwrap();
        assert!((c.trajectories.frame_rate() - 4.0).abs() < 1e-12);
        assert!(c.info.warnings.iter().any(|w| w.contains("Time column")));
        let text = "PathFileType\t4\nDataRate\tNumMarkers\n0\t1\nFrame#\tTime\tA\n1\t0\t1\t1\t1\n";
        assert!(read(text).unwrap_err().problem.contains("no frame rate"));
    }

    #[test]
    fn errors_name_line_and_field() {
        let text = format!("{HEADER}1\t0\t1\t2\tx3\t4\t5\t6\n");
        let e = read(&text).unwrap_err();
        assert_eq!(e.location, "line 7, field 5");
        assert!(
            e.problem.contains("x3") && e.problem.contains("marker A, z"),
            "{e}"
        );
        let e = read(&HEADER.replace("\tmm\t", "\tfurlong\t")).unwrap_err();
        assert_eq!(e.location, "line 3, field 5");
        let e = read(HEADER).unwrap_err();
        assert!(e.problem.contains("no data rows"), "{e}");
        let e = read("").unwrap_err();
        assert!(e.problem.contains("empty"), "{e}");
        let e = read("hello\n").unwrap_err();
        assert!(e.problem.contains("not a TRC"), "{e}");
        let e = read(&HEADER.replace("\tA\t\t\tB b", "\t\t\t\t")).unwrap_err();
        assert_eq!(e.location, "line 4");
        assert!(e.problem.contains("no marker labels"), "{e}");
    }

    #[test]
    fn disagreeing_counts_and_extra_columns_warn() {
        let text = "PathFileType\t4\nDataRate\tNumFrames\tNumMarkers\tUnits\n100\t9\t4\tcm\n\
            Frame#\tTime\tA\t\t\n\t\tX1\tY1\tZ1\n1\t0\t1\t2\t3\t\t\t\t7\t8\t9\n";
        let c = read(text).unwrap();
        assert_eq!(c.trajectories.get(0, 0), Some([10.0, 20.0, 30.0]));
        let w = c.info.warnings.join("\n");
        assert!(w.contains("NumFrames says 9"), "{w}");
        assert!(w.contains("NumMarkers says 4"), "{w}");
        assert!(
            w.contains("past the 1 named markers (up to field 11)"),
            "{w}"
        );
    }

    #[test]
    fn huge_marker_counts_with_empty_rows_are_refused() {
        let labels: String = (0..20_000).map(|i| format!("\tm{i}")).collect();
        let mut text = format!("PathFileType\t4\nDataRate\n100\nFrame#\tTime{labels}\n");
        for i in 0..300 {
            text.push_str(&format!("{i}\n"));
        }
        let e = read(&text).unwrap_err();
        assert!(e.problem.contains("refusing"), "{e}");
    }

    #[test]
    fn write_then_read_gives_the_same_trajectories() {
        let nan = f64::NAN;
        let positions = vec![
            [1.5, -2.25, 3.125],
            [nan, nan, nan],
            [4.0, 5.0, 6.0],
            [7.0, 8.0, 9.0],
        ];
        let t = Trajectories::new(vec!["L\tA".into(), "".into()], 59.94, -3, 2, positions).unwrap();
        let text = write(&t);
        let c = read(&text).unwrap();
        let back = &c.trajectories;
        assert_eq!(back.labels(), ["L_A", "M2"]);
        assert_eq!(back.frame_rate(), 59.94);
        assert_eq!(back.first_frame(), -3);
        assert_eq!(back.frames(), 2);
        assert_eq!(back.get(0, 0), Some([1.5, -2.25, 3.125]));
        assert_eq!(back.get(0, 1), None);
        assert!(c.info.warnings.is_empty(), "{:?}", c.info.warnings);
        // Every data row has 2 + 3 × markers fields plus OpenSim's trailing tab.
        let row = text.lines().nth(6).unwrap();
        assert_eq!(row.split('\t').count(), 2 + 3 * 2 + 1);
    }

    #[test]
    fn labels_separated_by_single_tabs_and_no_coordinate_line() {
        let text = "PathFileType\t4\nNumMarkers\tDataRate\n2\t30\nFrame#\tTime\tA\tB\n\
            7\t0\t1\t2\t3\t4\t5\t6\n";
        let c = read(text).unwrap();
        assert_eq!(c.trajectories.labels(), ["A", "B"]);
        assert_eq!(c.trajectories.first_frame(), 7);
        assert_eq!(c.trajectories.get(0, 1), Some([4.0, 5.0, 6.0]));
        assert!(c.info.warnings.iter().any(|w| w.contains("no `Units`")));
    }

    #[test]
    fn number_spellings() {
        assert_eq!(parse_number(b"1e3"), Some(1000.0));
        assert!(parse_number(b"-nan(ind)").unwrap().is_nan());
        assert!(parse_number(b"1.#QNAN").unwrap().is_nan());
        assert_eq!(parse_number(b"1,5"), None);
        assert_eq!(parse_frame(b"12.0"), Some(12));
        assert_eq!(parse_frame(b"12.5"), None);
    }
}
