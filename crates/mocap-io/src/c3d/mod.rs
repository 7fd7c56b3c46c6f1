//! C3D reading and writing (c3d.org format, all three processor types).
//!
//! Reading: the header's byte 1 points at the parameter section, whose byte 3 names the
//! processor (Intel, DEC with VAX floats, MIPS big-endian). Parameters are walked by their
//! `next` offsets inside the declared block count. Where header and parameters disagree
//! (point count, scale, rate, first frame, frame count, data start, analog size) the
//! parameters win and the header is the fallback, with a warning. POINT:SCALE's sign
//! decides integer (positive) or float (negative) storage. Coordinates come out in
//! millimetres; a sample is missing when its residual is negative or it is exactly
//! (0, 0, 0). Analog data is skipped but its size is counted when stepping frames.
//!
//! Nothing a file says is trusted for allocation: the frame count is clipped to the
//! complete frames the file holds (with a warning), and a file holding not one complete
//! frame of what it claims is refused before anything is allocated.
//!
//! Writing: Intel, float storage (POINT:SCALE −1), residual −1 and zero coordinates for
//! missing samples, groups POINT, ANALOG (empty) and TRIAL; read back by ezc3d and py-c3d.

mod data;
mod header;
mod params;
mod write;

use crate::{Capture, CaptureInfo, Format, FormatError, ReadOptions, Trajectories};
use data::{Counts, Decoded, FloatBe, FloatLe, FloatVax, IntBe, IntLe, SampleCodec};
use header::{BLOCK, Header, KEY, Processor, take};
use params::Params;

pub use write::write;

/// Parses C3D bytes into a capture in millimetres; see the module docs for the rules.
pub fn parse(bytes: &[u8], options: &ReadOptions) -> Result<Capture, FormatError> {
    if bytes.len() < BLOCK {
        return Err(FormatError::new(
            format!("byte {} (header)", bytes.len()),
            format!(
                "file is {} bytes, shorter than the {BLOCK}-byte C3D header: empty or truncated",
                bytes.len()
            ),
        ));
    }
    let Some([parameter_block, key]) = take::<2>(bytes, 0) else {
        return Err(FormatError::new(
            "byte 0 (header)",
            "cannot read the header",
        ));
    };
    if key != KEY {
        return Err(FormatError::new(
            "byte 1 (header)",
            format!("not a C3D file: byte 1 is 0x{key:02x}, a C3D file has 0x50 there"),
        ));
    }
    if parameter_block == 0 {
        return Err(FormatError::new(
            "byte 0 (header)",
            "the parameter section's block number is 0 (blocks count from 1)",
        ));
    }
    let param_start = (usize::from(parameter_block) - 1) * BLOCK;
    let Some([_, _, param_blocks, processor_byte]) = take::<4>(bytes, param_start) else {
        return Err(FormatError::new(
            "byte 0 (header)",
            format!(
                "the parameter section starts at block {parameter_block} (byte {param_start}), past the end of the {}-byte file",
                bytes.len()
            ),
        ));
    };
    let processor = Processor::from_byte(processor_byte).ok_or_else(|| {
        FormatError::new(
            format!("byte {} (parameter section)", param_start + 3),
            format!(
                "unknown processor type {processor_byte} (expected 84 Intel, 85 DEC or 86 MIPS)"
            ),
        )
    })?;
    let header = Header::read(bytes, processor)?;
    let header_data = usize::from(header.data_start).saturating_sub(1) * BLOCK;
    let params = Params::walk(bytes, param_start, param_blocks, header_data, processor);
    let mut warnings = params.warnings.clone();
    if params.len() == 0 {
        warnings.push(format!(
            "no parameters found (the section at byte {param_start} declares {param_blocks} blocks): using the header alone, marker labels generated"
        ));
    }
    let layout = Layout::resolve(bytes, &header, &params, parameter_block, &mut warnings)?;
    let labels = labels(&params, layout.points, &mut warnings);
    let declared_units = params
        .strings("POINT:UNITS")
        .and_then(|u| u.into_iter().next())
        .filter(|u| !u.is_empty());
    let unit_factor = match (options.units, &declared_units) {
        (Some(unit), declared) => {
            let declared = declared.as_deref().map(|u| (u, crate::mm_per_unit(u)));
            warnings.extend(unit.overriding(declared));
            unit.mm()
        }
        (None, Some(u)) => crate::mm_per_unit(u).unwrap_or_else(|| {
            warnings.push(format!(
                "POINT:UNITS is {u:?}, a unit we do not know: read as millimetres"
            ));
            1.0
        }),
        (None, None) => 1.0,
    };
    let storage_factor = if layout.float {
        1.0
    } else {
        f64::from(layout.scale.abs())
    };
    let factor = storage_factor * unit_factor;
    let data = bytes.get(layout.data_offset..).unwrap_or(&[]);
    let mut decoded = Decoded::with_capacity(layout.frames, layout.points);
    let counts = decode(&layout, processor, data, factor, false, &mut decoded);
    let Decoded {
        mut positions,
        seen,
    } = decoded;

    let unflagged_out_of_range = counts.out_of_range;
    // SIMI-style files flag every sample invalid although the coordinates are real.
    let mut flagged_positions = None;
    if counts.present == 0 && counts.flagged_nonzero > 0 {
        let mut decoded = Decoded::with_capacity(layout.frames, layout.points);
        let kept_counts = decode(&layout, processor, data, factor, true, &mut decoded);
        let kept = decoded.positions;
        if kept_counts.out_of_range > 0 {
            warnings.push(format!(
                "{} samples hold coordinates of ±1e9 or non-finite values (a gap fill): read as missing",
                kept_counts.out_of_range
            ));
        }
        if varies(&kept) {
            if options.keep_invalid_residuals {
                warnings.push(format!(
                    "every sample's residual is negative (invalid) although coordinates vary: {} samples kept because mocap-io.keep_invalid_residuals is set",
                    counts.flagged_nonzero
                ));
                positions = kept;
            } else {
                warnings.push(format!(
                    "every sample's residual is negative (invalid) although coordinates vary: {} samples read as missing (--set mocap-io.keep_invalid_residuals=true keeps them)",
                    counts.flagged_nonzero
                ));
                flagged_positions = Some(kept);
            }
        }
    }
    if flagged_positions.is_none() && unflagged_out_of_range > 0 && counts.present > 0 {
        warnings.push(format!(
            "{unflagged_out_of_range} samples hold coordinates of ±1e9 or non-finite values (a gap fill): read as missing"
        ));
    }
    if declared_units.is_none() && options.units.is_none() {
        let sample_source = flagged_positions.as_deref().unwrap_or(&positions);
        let typical = typical_coordinate(sample_source);
        if typical > 0.0 && typical < 10.0 {
            warnings.push(format!(
                "POINT:UNITS is absent; coordinates are under 10 in magnitude (median sample extent {typical:.3}), so the file is read as metres"
            ));
            for p in &mut positions {
                for c in p.iter_mut() {
                    *c *= 1000.0;
                }
            }
        } else {
            warnings.push(format!(
                "POINT:UNITS is absent; coordinates are typically {typical:.1} in magnitude, so the file is read as millimetres"
            ));
        }
    }
    let (labels, positions) = if options.keep_model_outputs {
        (labels, positions)
    } else {
        let (labels, positions, seen) =
            drop_model_outputs(&params, labels, positions, seen, &mut warnings);
        drop_computed_points(labels, positions, &seen, &mut warnings)
    };
    let mut labels = labels;
    crate::trc::unique_labels(&mut labels, "POINT:LABELS", &mut warnings);
    let trajectories = Trajectories::new(
        labels,
        f64::from(layout.rate),
        layout.first_frame,
        layout.frames,
        positions,
    )
    .map_err(|e| {
        FormatError::new(
            format!("byte {} (data section)", layout.data_offset),
            e.to_string(),
        )
    })?;
    Ok(Capture {
        format: Format::C3d,
        trajectories,
        info: CaptureInfo {
            declared_units,
            processor: Some(processor.name().to_string()),
            storage: Some(if layout.float { "float" } else { "integer" }.to_string()),
            point_scale: Some(f64::from(layout.scale)),
            warnings,
            stitched: Vec::new(),
        },
    })
}

/// POINT parameters that list model outputs stored as points (Vicon and Plug-in Gait
/// conventions), besides any that POINT:TYPE_GROUPS names.
const MODEL_OUTPUT_GROUPS: [&str; 6] = [
    "ANGLES",
    "FORCES",
    "MOMENTS",
    "POWERS",
    "SCALARS",
    "REACTIONS",
];

/// Removes the points whose labels a model-output list holds (angles, forces, moments,
/// powers stored as points are not marker positions); warns with how many and from where.
fn drop_model_outputs(
    params: &Params,
    labels: Vec<String>,
    positions: Vec<[f64; 3]>,
    seen: Vec<bool>,
    warnings: &mut Vec<String>,
) -> (Vec<String>, Vec<[f64; 3]>, Vec<bool>) {
    let mut groups: Vec<String> = MODEL_OUTPUT_GROUPS.iter().map(|g| g.to_string()).collect();
    // TYPE_GROUPS pairs a list's parameter name with its type name (ANGLES, ANGLE, ...);
    // a list of markers, should a file name one there, is not an output.
    for name in params.strings("POINT:TYPE_GROUPS").unwrap_or_default() {
        let name = name.trim().to_ascii_uppercase();
        if !name.is_empty() && !name.contains("MARKER") && !groups.contains(&name) {
            groups.push(name);
        }
    }
    let mut listed: Vec<String> = Vec::new();
    let mut sources: Vec<String> = Vec::new();
    for group in &groups {
        let Some(names) = params.strings(&format!("POINT:{group}")) else {
            continue;
        };
        let names: Vec<String> = names
            .into_iter()
            .map(|n| n.trim().to_string())
            .filter(|n| !n.is_empty())
            .collect();
        if !names.is_empty() {
            sources.push(format!("POINT:{group}"));
            listed.extend(names);
        }
    }
    // A label matches with or without its subject prefix ("Sub:RKneeAngles").
    let is_output = |label: &str| {
        let bare = label.rsplit(':').next().unwrap_or(label).trim();
        listed.iter().any(|l| l == label.trim() || l == bare)
    };
    let keep: Vec<bool> = labels.iter().map(|l| !is_output(l)).collect();
    let dropped = keep.iter().filter(|k| !**k).count();
    if dropped == 0 {
        return (labels, positions, seen);
    }
    if dropped == labels.len() {
        warnings.push(format!(
            "every point is listed in {} as a model output: all read as markers",
            sources.join(", ")
        ));
        return (labels, positions, seen);
    }
    let seen = kept(seen, &keep);
    let (labels, positions) = retain_points(labels, positions, &keep);
    warnings.push(format!(
        "{dropped} points listed in {} are model outputs, not markers: not read (--set mocap-io.keep_model_outputs=true keeps them)",
        sources.join(", ")
    ));
    (labels, positions, seen)
}

/// Removes the points no camera ever saw from a file whose other points cameras did see:
/// a present sample whose fourth word is 0 has no camera bit and no residual, which the
/// C3D format reserves for points a program computed (bone-model and virtual points,
/// hundreds of them in some Vicon exports), not tracked markers. A file that never fills
/// that word (every point "unseen", as many writers do) keeps every point. Points with no
/// present sample stay: they are missing markers, not computed ones.
fn drop_computed_points(
    labels: Vec<String>,
    positions: Vec<[f64; 3]>,
    seen: &[bool],
    warnings: &mut Vec<String>,
) -> (Vec<String>, Vec<[f64; 3]>) {
    let points = labels.len();
    if points == 0 || seen.len() != points || !seen.iter().any(|&s| s) {
        return (labels, positions);
    }
    let mut present = vec![false; points];
    for frame in positions.chunks_exact(points) {
        for (p, sample) in present.iter_mut().zip(frame) {
            *p |= crate::is_present(*sample);
        }
    }
    let keep: Vec<bool> = seen.iter().zip(&present).map(|(&s, &p)| s || !p).collect();
    let dropped: Vec<&str> = labels
        .iter()
        .zip(&keep)
        .filter(|(_, k)| !**k)
        .map(|(l, _)| l.as_str())
        .collect();
    if dropped.is_empty() {
        return (labels, positions);
    }
    let tracked = seen.iter().filter(|&&s| s).count();
    let examples = dropped
        .iter()
        .take(3)
        .copied()
        .collect::<Vec<_>>()
        .join(", ");
    let more = if dropped.len() > 3 { ", ..." } else { "" };
    warnings.push(format!(
        "{} points were never seen by a camera (every sample's residual word is 0: computed by a model, not tracked) while {tracked} were: not read as markers ({examples}{more}; --set mocap-io.keep_model_outputs=true keeps them)",
        dropped.len()
    ));
    retain_points(labels, positions, &keep)
}

/// The labels and frame-major positions of the points whose `keep` entry is true.
fn retain_points(
    labels: Vec<String>,
    positions: Vec<[f64; 3]>,
    keep: &[bool],
) -> (Vec<String>, Vec<[f64; 3]>) {
    let points = labels.len();
    let positions = positions
        .chunks(points.max(1))
        .flat_map(|frame| frame.iter().zip(keep).filter(|(_, k)| **k).map(|(p, _)| *p))
        .collect();
    (kept(labels, keep), positions)
}

/// The entries of a per-point list whose `keep` entry is true.
fn kept<T>(items: Vec<T>, keep: &[bool]) -> Vec<T> {
    items
        .into_iter()
        .zip(keep)
        .filter(|(_, k)| **k)
        .map(|(item, _)| item)
        .collect()
}

/// Where the frames are and how they are stored, after header and parameters are reconciled.
#[derive(Clone, Debug)]
struct Layout {
    points: usize,
    frames: usize,
    first_frame: i64,
    rate: f32,
    scale: f32,
    float: bool,
    data_offset: usize,
    frame_bytes: usize,
}

impl Layout {
    fn resolve(
        bytes: &[u8],
        header: &Header,
        params: &Params,
        parameter_block: u8,
        warnings: &mut Vec<String>,
    ) -> Result<Self, FormatError> {
        let points = prefer(
            "point count",
            params.number("POINT:USED").map(|v| v as usize),
            "POINT:USED",
            usize::from(header.points),
            warnings,
        );

        let valid_scale = |s: f32| s.is_finite() && s != 0.0;
        let scale = match params.float32("POINT:SCALE") {
            Some(s) if valid_scale(s) => {
                if s != header.scale {
                    warnings.push(format!(
                        "header scale {} disagrees with POINT:SCALE {s}: using the parameter",
                        header.scale
                    ));
                }
                s
            }
            other => {
                if !valid_scale(header.scale) {
                    return Err(FormatError::new(
                        "header words 7-8 and parameter POINT:SCALE",
                        format!(
                            "no usable point scale (header {}, parameter {other:?}): cannot tell integer from float storage",
                            header.scale
                        ),
                    ));
                }
                if other.is_some() {
                    warnings.push(format!(
                        "POINT:SCALE {other:?} is unusable: using the header scale {}",
                        header.scale
                    ));
                }
                header.scale
            }
        };
        let float = scale < 0.0;

        let valid_rate = |r: f32| r.is_finite() && r > 0.0;
        let rate = match params.float32("POINT:RATE") {
            Some(r) if valid_rate(r) => {
                if r != header.frame_rate {
                    warnings.push(format!(
                        "header frame rate {} disagrees with POINT:RATE {r}: using the parameter",
                        header.frame_rate
                    ));
                }
                r
            }
            _ if valid_rate(header.frame_rate) => header.frame_rate,
            _ => {
                warnings.push(format!(
                    "no usable frame rate (header {}, POINT:RATE {:?}): rate set to 0 (unknown)",
                    header.frame_rate,
                    params.float32("POINT:RATE")
                ));
                0.0
            }
        };

        // Not the header block, not the parameter section's first block, inside the file.
        // (Block counts in the parameter section are too often wrong to exclude more.)
        let valid_start = |b: usize| {
            b >= 2 && b != usize::from(parameter_block) && (b - 1) * BLOCK <= bytes.len()
        };
        let header_start = usize::from(header.data_start);
        let data_start = match params.number("POINT:DATA_START").map(|v| v as usize) {
            Some(p) if valid_start(p) => {
                if p != header_start {
                    warnings.push(format!(
                        "header data start block {header_start} disagrees with POINT:DATA_START {p}: using the parameter"
                    ));
                }
                p
            }
            param if valid_start(header_start) => {
                if let Some(p) = param {
                    warnings.push(format!(
                        "POINT:DATA_START {p} is not a possible data block: using the header's block {header_start}"
                    ));
                }
                header_start
            }
            param => {
                return Err(FormatError::new(
                    "header word 9 and parameter POINT:DATA_START",
                    format!(
                        "no usable data start block (header {header_start}, parameter {param:?}) in a {}-byte file",
                        bytes.len()
                    ),
                ));
            }
        };
        let data_offset = (data_start - 1) * BLOCK;

        let header_first = i64::from(header.first_frame);
        let trial_start = params
            .numbers("TRIAL:ACTUAL_START_FIELD")
            .and_then(long_field);
        let first_frame = prefer(
            "first frame",
            trial_start,
            "TRIAL:ACTUAL_START_FIELD",
            header_first,
            warnings,
        );

        let param_frames = frame_count_param(params);
        let claimed = prefer(
            "frame count",
            param_frames,
            "POINT:FRAMES",
            i64::from(header.frames()),
            warnings,
        )
        .max(0) as u64;

        let word = if float { 4 } else { 2 };
        let available = bytes.len().saturating_sub(data_offset);
        let header_analog = usize::from(header.analog_values);
        let analog = match analog_from_params(params, rate) {
            Some(a) if a != header_analog => {
                let fits = |analog: usize| {
                    frame_bytes(points, analog, word).is_some_and(|fb| {
                        (fb as u64)
                            .checked_mul(claimed)
                            .is_some_and(|n| n <= available as u64)
                    })
                };
                let pick = if fits(a) || !fits(header_analog) {
                    a
                } else {
                    header_analog
                };
                warnings.push(format!(
                    "header says {header_analog} analog values per frame, ANALOG:USED × ANALOG:RATE / POINT:RATE says {a}: using {pick}, which {} the file size",
                    if fits(pick) { "fits" } else { "does not fit" }
                ));
                pick
            }
            Some(a) => a,
            None => header_analog,
        };
        let frame_bytes = frame_bytes(points, analog, word).ok_or_else(|| {
            FormatError::new(
                "header and parameters POINT:USED, ANALOG:USED",
                format!("{points} points and {analog} analog values per frame overflow"),
            )
        })?;

        let complete = available.checked_div(frame_bytes).unwrap_or(0) as u64;
        let frames = if claimed > complete {
            if frame_bytes > 0 && complete == 0 {
                return Err(FormatError::new(
                    format!("byte {data_offset} (data section, block {data_start})"),
                    format!(
                        "the file claims {claimed} frames of {frame_bytes} bytes ({points} points, {analog} analog values) but only {available} bytes follow: not one complete frame (truncated, or absurd counts)"
                    ),
                ));
            }
            if frame_bytes == 0 {
                warnings.push(format!(
                    "the file claims {claimed} frames but stores no point or analog data: 0 frames read"
                ));
            } else {
                warnings.push(format!(
                    "the file claims {claimed} frames but its data section (byte {data_offset}, {available} bytes) holds {complete} complete frames of {frame_bytes} bytes: {complete} read"
                ));
            }
            complete
        } else {
            claimed
        };
        Ok(Layout {
            points,
            frames: frames as usize,
            first_frame,
            rate,
            scale,
            float,
            data_offset,
            frame_bytes,
        })
    }
}

/// The parameter's value when present, else the header's; warns when both exist and differ.
fn prefer<T: PartialEq + std::fmt::Display>(
    what: &str,
    param: Option<T>,
    key: &str,
    header: T,
    warnings: &mut Vec<String>,
) -> T {
    match param {
        Some(p) => {
            if p != header {
                warnings.push(format!(
                    "header {what} {header} disagrees with {key} {p}: using the parameter"
                ));
            }
            p
        }
        None => header,
    }
}

/// A 32-bit number stored as two unsigned 16-bit words, low word first (TRIAL fields).
fn long_field(words: Vec<f64>) -> Option<i64> {
    match words.as_slice() {
        [lo, hi, ..] => Some(*lo as i64 + (*hi as i64) * 65536),
        [lo] => Some(*lo as i64),
        [] => None,
    }
}

/// Frame count from POINT:FRAMES, extended past 65535 by POINT:LONG_FRAMES or the TRIAL fields.
fn frame_count_param(params: &Params) -> Option<i64> {
    if let Some(long) = params.number("POINT:LONG_FRAMES") {
        if long.is_finite() && long >= 0.0 {
            return Some(long as i64);
        }
    }
    let frames = params.number("POINT:FRAMES").map(|f| f as i64)?;
    let start = params
        .numbers("TRIAL:ACTUAL_START_FIELD")
        .and_then(long_field);
    let end = params
        .numbers("TRIAL:ACTUAL_END_FIELD")
        .and_then(long_field);
    if let (Some(s), Some(e)) = (start, end) {
        let trial = e - s + 1;
        // POINT:FRAMES is 16 bits: a longer trial shows as 65535 or as the count modulo 2^16.
        if trial > 65535 && (frames == 65535 || trial % 65536 == frames) {
            return Some(trial);
        }
    }
    Some(frames)
}

/// Analog values per frame from ANALOG:USED × ANALOG:RATE / POINT:RATE, when ANALOG:USED exists.
fn analog_from_params(params: &Params, point_rate: f32) -> Option<usize> {
    let used = params.number("ANALOG:USED")? as usize;
    if used == 0 {
        return Some(0);
    }
    let analog_rate = params.number("ANALOG:RATE")?;
    if !(point_rate > 0.0 && analog_rate.is_finite() && analog_rate > 0.0) {
        return None;
    }
    let per_frame = (analog_rate / f64::from(point_rate)).round();
    if !(1.0..=65535.0).contains(&per_frame) {
        return None;
    }
    used.checked_mul(per_frame as usize)
}

/// Bytes of one frame: 4 words per point plus the analog values.
fn frame_bytes(points: usize, analog: usize, word: usize) -> Option<usize> {
    points
        .checked_mul(4)?
        .checked_add(analog)?
        .checked_mul(word)
}

/// Marker labels from POINT:LABELS, LABELS2, LABELS3, ...; generated where the file has none.
fn labels(params: &Params, points: usize, warnings: &mut Vec<String>) -> Vec<String> {
    let mut labels: Vec<String> = Vec::with_capacity(points);
    let mut key = "POINT:LABELS".to_string();
    let mut n = 1;
    while labels.len() < points {
        let Some(chunk) = params.strings(&key) else {
            break;
        };
        let take = points - labels.len();
        labels.extend(chunk.into_iter().take(take));
        n += 1;
        key = format!("POINT:LABELS{n}");
    }
    if labels.len() < points {
        warnings.push(format!(
            "POINT:LABELS names {} of {points} points: the others are named P<number>",
            labels.len()
        ));
        let start = labels.len();
        labels.extend((start..points).map(|i| format!("P{}", i + 1)));
    }
    for (i, label) in labels.iter_mut().enumerate() {
        if label.is_empty() {
            *label = format!("P{}", i + 1);
        }
    }
    labels
}

/// Decodes the data section with the codec for this processor and storage.
fn decode(
    layout: &Layout,
    processor: Processor,
    data: &[u8],
    factor: f64,
    keep_flagged: bool,
    out: &mut Decoded,
) -> Counts {
    fn run<C: SampleCodec>(
        l: &Layout,
        data: &[u8],
        factor: f64,
        keep: bool,
        out: &mut Decoded,
    ) -> Counts {
        data::decode::<C>(data, l.frame_bytes, l.frames, l.points, factor, keep, out)
    }
    match (processor, layout.float) {
        (Processor::Intel, true) => run::<FloatLe>(layout, data, factor, keep_flagged, out),
        (Processor::Mips, true) => run::<FloatBe>(layout, data, factor, keep_flagged, out),
        (Processor::Dec, true) => run::<FloatVax>(layout, data, factor, keep_flagged, out),
        (Processor::Intel | Processor::Dec, false) => {
            run::<IntLe>(layout, data, factor, keep_flagged, out)
        }
        (Processor::Mips, false) => run::<IntBe>(layout, data, factor, keep_flagged, out),
    }
}

/// True when the present samples are not all the same point (real coordinates, not a fill value).
fn varies(positions: &[[f64; 3]]) -> bool {
    let mut present = positions.iter().filter(|p| crate::is_present(**p));
    let Some(first) = present.next() else {
        return false;
    };
    present.any(|p| p != first)
}

/// Median over present samples of the largest absolute coordinate (0 when none).
///
/// A median, not a maximum: a few wild samples must not decide the units of a capture.
fn typical_coordinate(positions: &[[f64; 3]]) -> f64 {
    let mut extents: Vec<f64> = positions
        .iter()
        .filter(|p| crate::is_present(**p))
        .map(|p| p[0].abs().max(p[1].abs()).max(p[2].abs()))
        .collect();
    if extents.is_empty() {
        return 0.0;
    }
    let mid = extents.len() / 2;
    let (_, median, _) = extents.select_nth_unstable_by(mid, f64::total_cmp);
    *median
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::MISSING;

    pub(super) fn make(markers: usize, frames: usize, first_frame: i64) -> Trajectories {
        let labels = (0..markers).map(|m| format!("M{m:03}")).collect();
        let mut positions = Vec::with_capacity(markers * frames);
        for f in 0..frames {
            for m in 0..markers {
                if (f + m) % 7 == 3 {
                    positions.push(MISSING);
                } else {
                    let t = f as f64 * 0.37 + m as f64;
                    positions.push([
                        t.sin() * 812.25,
                        t.cos() * -433.125,
                        1000.0 + m as f64 * 3.3,
                    ]);
                }
            }
        }
        Trajectories::new(labels, 120.0, first_frame, frames, positions).unwrap()
    }

    fn assert_round_trip(t: &Trajectories) -> Capture {
        let bytes = write(t).unwrap();
        assert_eq!(bytes.len() % BLOCK, 0);
        let c = parse(&bytes, &ReadOptions::default()).unwrap();
        let r = &c.trajectories;
        assert_eq!(r.labels(), t.labels());
        assert_eq!(r.frames(), t.frames());
        assert_eq!(r.first_frame(), t.first_frame());
        assert_eq!(r.frame_rate(), t.frame_rate());
        assert_eq!(r.missing_samples(), t.missing_samples());
        for (a, b) in r.positions().iter().zip(t.positions()) {
            assert_eq!(crate::is_present(*a), crate::is_present(*b));
            for k in 0..3 {
                if b[k].is_finite() {
                    assert!((a[k] - b[k]).abs() <= b[k].abs() * 1e-7, "{a:?} vs {b:?}");
                }
            }
        }
        assert!(c.info.warnings.is_empty(), "{:?}", c.info.warnings);
        assert_eq!(c.info.declared_units.as_deref(), Some("mm"));
        assert_eq!(c.info.processor.as_deref(), Some("intel"));
        assert_eq!(c.info.storage.as_deref(), Some("float"));
        c
    }

    #[test]
    fn written_files_read_back_equal_within_f32() {
        assert_round_trip(&make(12, 50, 1));
        assert_round_trip(&make(3, 7, 1234));
    }

    #[test]
    fn more_than_255_labels_continue_in_labels2() {
        let t = make(600, 3, 1);
        let bytes = write(&t).unwrap();
        assert_round_trip(&t);
        let header = Header::read(&bytes, Processor::Intel).unwrap();
        let params = Params::walk(
            &bytes,
            512,
            255,
            usize::from(header.data_start - 1) * BLOCK,
            Processor::Intel,
        );
        assert_eq!(params.strings("POINT:LABELS").unwrap().len(), 255);
        assert_eq!(params.strings("POINT:LABELS2").unwrap().len(), 255);
        assert_eq!(params.strings("POINT:LABELS3").unwrap().len(), 90);
    }

    #[test]
    fn empty_captures_round_trip() {
        assert_round_trip(&make(5, 0, 1));
        // No markers and no analog: frames store nothing, so none are claimed back.
        let bytes = write(&make(0, 4, 1)).unwrap();
        let c = parse(&bytes, &ReadOptions::default()).unwrap();
        assert_eq!((c.trajectories.markers(), c.trajectories.frames()), (0, 0));
    }

    #[test]
    fn writer_refuses_what_c3d_cannot_hold() {
        assert!(write(&make(2, 2, 0)).is_err());
        assert!(write(&make(1, 70_000, 1)).is_err());
        let long = Trajectories::new(vec!["x".repeat(300)], 100.0, 1, 0, vec![]).unwrap();
        assert!(write(&long).is_err());
    }

    #[test]
    fn integer_big_endian_and_vax_samples_decode_alike() {
        // One sample (10, -20, 30) with residual 5, and one flagged sample, per codec.
        let ints: [i16; 8] = [10, -20, 30, 5, 1, 2, 3, -1];
        let le: Vec<u8> = ints.iter().flat_map(|v| v.to_le_bytes()).collect();
        let be: Vec<u8> = ints.iter().flat_map(|v| v.to_be_bytes()).collect();
        let floats: Vec<f32> = ints.iter().map(|&v| f32::from(v)).collect();
        let vax: Vec<u8> = floats.iter().flat_map(|&v| header::to_vax(v)).collect();
        let fbe: Vec<u8> = floats.iter().flat_map(|v| v.to_be_bytes()).collect();
        let want = [[5.0, -10.0, 15.0], MISSING];
        for (bytes, codec) in [(&le, 0), (&be, 1), (&vax, 2), (&fbe, 3)] {
            let mut out = Decoded::with_capacity(1, 2);
            let counts = match codec {
                0 => data::decode::<IntLe>(bytes, 16, 1, 2, 0.5, false, &mut out),
                1 => data::decode::<IntBe>(bytes, 16, 1, 2, 0.5, false, &mut out),
                2 => data::decode::<FloatVax>(bytes, 32, 1, 2, 0.5, false, &mut out),
                _ => data::decode::<FloatBe>(bytes, 32, 1, 2, 0.5, false, &mut out),
            };
            assert_eq!(out.positions[0], want[0], "codec {codec}");
            assert!(!crate::is_present(out.positions[1]), "codec {codec}");
            assert_eq!((counts.present, counts.flagged), (1, 1));
            // Residual 5: a camera saw the first point; the flagged one counts as unseen.
            assert_eq!(out.seen, [true, false], "codec {codec}");
        }
    }

    /// Points no camera saw, in a file whose other points cameras did see, are computed
    /// (Vicon's bone-model points): dropped unless asked for. A file that never fills the
    /// residual word (our writer's) keeps every point.
    #[test]
    fn points_no_camera_saw_are_dropped_where_others_were_seen() {
        let t = make(4, 20, 1);
        let mut bytes = write(&t).unwrap();
        let unfilled = parse(&bytes, &ReadOptions::default()).unwrap();
        assert_eq!(unfilled.trajectories.markers(), 4);
        assert!(!unfilled.info.warnings.iter().any(|w| w.contains("camera")));

        // Markers 0 and 2 get camera mask 1 and residual 3 (0x0103) where present.
        let header = Header::read(&bytes, Processor::Intel).unwrap();
        let data = usize::from(header.data_start - 1) * BLOCK;
        for f in 0..t.frames() {
            for m in [0, 2] {
                let at = data + (f * 4 + m) * 16 + 12;
                let word = f32::from_le_bytes(bytes[at..at + 4].try_into().unwrap());
                if word == 0.0 {
                    bytes[at..at + 4].copy_from_slice(&259.0f32.to_le_bytes());
                }
            }
        }
        let read = parse(&bytes, &ReadOptions::default()).unwrap();
        assert_eq!(read.trajectories.labels(), ["M000", "M002"]);
        for f in 0..t.frames() {
            let before = unfilled.trajectories.get(f, 2);
            assert_eq!(read.trajectories.get(f, 1), before, "frame {f}");
        }
        let warning = read
            .info
            .warnings
            .iter()
            .find(|w| w.contains("never seen by a camera"))
            .expect("a warning naming the dropped points");
        assert!(
            warning.starts_with("2 points") && warning.contains("M001, M003"),
            "{warning}"
        );
        let keep = ReadOptions {
            keep_model_outputs: true,
            ..ReadOptions::default()
        };
        assert_eq!(parse(&bytes, &keep).unwrap().trajectories.markers(), 4);
    }

    /// `mocap-io.units` overrides POINT:UNITS (the writer's "mm"), and says so.
    #[test]
    fn a_unit_option_overrides_the_declared_one() {
        let t = make(3, 4, 1);
        let bytes = write(&t).unwrap();
        let as_cm = ReadOptions {
            units: Some(crate::LengthUnit::Cm),
            ..ReadOptions::default()
        };
        let read = parse(&bytes, &as_cm).unwrap();
        for (a, b) in read.trajectories.positions().iter().zip(t.positions()) {
            for k in 0..3 {
                let close = (a[k] - 10.0 * b[k]).abs() <= 1e-6 * b[k].abs().max(1.0);
                assert!(close || a[k].is_nan() && b[k].is_nan(), "{a:?} {b:?}");
            }
        }
        let said = read.info.warnings.join("\n");
        assert!(
            said.contains("read as cm (mocap-io.units), not as the file's \"mm\""),
            "{said}"
        );
        let as_mm = ReadOptions {
            units: Some(crate::LengthUnit::Mm),
            ..ReadOptions::default()
        };
        let same = parse(&bytes, &as_mm).unwrap();
        let bits = |t: &Trajectories| -> Vec<[u64; 3]> {
            t.positions().iter().map(|p| p.map(f64::to_bits)).collect()
        };
        let default = parse(&bytes, &ReadOptions::default()).unwrap();
        assert_eq!(bits(&same.trajectories), bits(&default.trajectories));
        assert!(
            !same
                .info
                .warnings
                .iter()
                .any(|w| w.contains("mocap-io.units"))
        );
    }
}

#[cfg(test)]
mod python_export {
    /// Writes sample files for tests/c3d_python_check.py, which reads them with ezc3d and
    /// py-c3d: `OSSIFY_PYTHON_CHECK=1 cargo test -p mocap-io --lib python_export`, then run
    /// the script. Without the variable it does nothing (Python is not a project dependency).
    #[test]
    fn write_files_for_python() {
        if std::env::var_os("OSSIFY_PYTHON_CHECK").is_none() {
            return;
        }
        let dir = std::env::temp_dir().join("ossify-c3d-python-check");
        std::fs::create_dir_all(&dir).unwrap();
        for (name, markers, frames, first) in [
            ("small", 12, 50, 1),
            ("labels600", 600, 5, 7),
            ("empty", 4, 0, 1),
        ] {
            let t = super::tests::make(markers, frames, first);
            std::fs::write(dir.join(format!("{name}.c3d")), super::write(&t).unwrap()).unwrap();
            let mut csv = String::new();
            for p in t.positions() {
                csv.push_str(&format!("{},{},{}\n", p[0], p[1], p[2]));
            }
            std::fs::write(dir.join(format!("{name}.txt")), csv).unwrap();
        }
    }
}
