//! The C3D writer: Intel processor, float storage, millimetres.

use super::header::{BLOCK, KEY, Processor};
use crate::{IoError, Trajectories, is_present};

/// POINT:SCALE written: negative means float storage; magnitude 1 keeps residuals in mm.
const SCALE: f32 = -1.0;
/// Largest parameter data we put in one entry: its `next` offset is a signed 16-bit number.
const MAX_PARAM_DATA: usize = 32_000;
/// Labels are stored in chunks of at most 255 (a dimension is one byte).
const MAX_PER_CHUNK: usize = 255;

/// Encodes trajectories as C3D bytes: Intel, float, residual −1 and (0, 0, 0) where missing.
///
/// Limits of the format: at most 65535 markers and 65535 frames, first frame between 1 and
/// 65535, labels at most 255 bytes; anything else is refused with [`IoError::Invalid`].
pub fn write(t: &Trajectories) -> Result<Vec<u8>, IoError> {
    let markers = t.markers();
    let frames = t.frames();
    let invalid = |m: String| Err(IoError::Invalid(format!("C3D writer: {m}")));
    let Ok(points) = u16::try_from(markers) else {
        return invalid(format!("{markers} markers; a C3D file holds at most 65535"));
    };
    let Ok(frame_count) = u16::try_from(frames) else {
        return invalid(format!("{frames} frames; a C3D file holds at most 65535"));
    };
    let first = match u16::try_from(t.first_frame()) {
        Ok(f) if f >= 1 => f,
        _ => {
            return invalid(format!(
                "first frame {}; C3D frame numbers run from 1 to 65535",
                t.first_frame()
            ));
        }
    };
    // An empty capture ends the frame before it starts, so header and parameters agree on 0.
    let last_long = u32::from(first) + u32::from(frame_count) - 1;
    let last = u16::try_from(last_long).unwrap_or(u16::MAX);
    if let Some(long) = t.labels().iter().find(|l| l.len() > 255) {
        return invalid(format!("label {long:?} is longer than 255 bytes"));
    }
    let rate = t.frame_rate() as f32;

    let mut section = ParamSection::default();
    let point = section.group("POINT", "3-D point parameters");
    let analog = section.group("ANALOG", "analog data parameters");
    let trial = section.group("TRIAL", "trial timing");
    section.int(point, "USED", points);
    section.int(point, "FRAMES", frame_count);
    // DATA_START is patched below once the section's size is known.
    let data_start_at = section.int(point, "DATA_START", 0);
    section.float(point, "SCALE", &[SCALE]);
    section.float(point, "RATE", &[rate]);
    let width = t.labels().iter().map(String::len).max().unwrap_or(0).max(1);
    let per_chunk = (MAX_PARAM_DATA / width).clamp(1, MAX_PER_CHUNK);
    let chunks: Vec<&[String]> = t.labels().chunks(per_chunk).collect();
    if chunks.is_empty() {
        section.strings(point, "LABELS", &[], 1);
        section.strings(point, "DESCRIPTIONS", &[], 1);
    }
    for (i, chunk) in chunks.iter().enumerate() {
        let suffix = if i == 0 {
            String::new()
        } else {
            (i + 1).to_string()
        };
        section.strings(point, &format!("LABELS{suffix}"), chunk, width);
        let empty = vec![String::new(); chunk.len()];
        section.strings(point, &format!("DESCRIPTIONS{suffix}"), &empty, 1);
    }
    section.strings(point, "UNITS", &["mm".to_string()], 2);
    section.int(analog, "USED", 0);
    // With no channels any rate works; the point rate gives py-c3d its expected ratio of 1.
    section.float(analog, "RATE", &[rate]);
    section.float(analog, "GEN_SCALE", &[1.0]);
    let first_long = u32::from(first);
    section.ints(
        trial,
        "ACTUAL_START_FIELD",
        &[(first_long & 0xffff) as u16, (first_long >> 16) as u16],
    );
    section.ints(
        trial,
        "ACTUAL_END_FIELD",
        &[(last_long & 0xffff) as u16, (last_long >> 16) as u16],
    );

    let mut params = section.finish();
    let param_blocks = params.len().div_ceil(BLOCK).max(1);
    let Ok(param_blocks_byte) = u8::try_from(param_blocks) else {
        return invalid(format!(
            "parameters need {param_blocks} blocks; a C3D file allows at most 255"
        ));
    };
    params.resize(param_blocks * BLOCK, 0);
    params[2] = param_blocks_byte;
    let data_start = 2 + param_blocks;
    let Ok(data_start16) = u16::try_from(data_start) else {
        return invalid(format!(
            "data would start at block {data_start}, past 65535"
        ));
    };
    params[data_start_at..data_start_at + 2].copy_from_slice(&data_start16.to_le_bytes());

    let data_bytes = frames * markers * 16;
    let mut out = Vec::with_capacity(BLOCK + params.len() + data_bytes.next_multiple_of(BLOCK));
    let mut header = [0u8; BLOCK];
    let mut put = |word: usize, b: &[u8]| header[2 * word..2 * word + b.len()].copy_from_slice(b);
    put(0, &[2, KEY]);
    put(1, &points.to_le_bytes());
    put(2, &0u16.to_le_bytes());
    put(3, &first.to_le_bytes());
    put(4, &last.to_le_bytes());
    put(5, &0u16.to_le_bytes());
    put(6, &SCALE.to_le_bytes());
    put(8, &data_start16.to_le_bytes());
    put(9, &1u16.to_le_bytes());
    put(10, &rate.to_le_bytes());
    out.extend_from_slice(&header);
    out.extend_from_slice(&params);
    for p in t.positions() {
        let sample = if is_present(*p) {
            [p[0] as f32, p[1] as f32, p[2] as f32, 0.0]
        } else {
            [0.0, 0.0, 0.0, -1.0]
        };
        for v in sample {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    out.resize(out.len().next_multiple_of(BLOCK), 0);
    Ok(out)
}

/// Builds the parameter section's bytes (Intel layout); entries are chained by `next`.
#[derive(Default)]
struct ParamSection {
    bytes: Vec<u8>,
    groups: u8,
    /// Byte offset of the previous entry's `next` field, patched when the next entry starts.
    last_next: Option<usize>,
}

impl ParamSection {
    fn begin(&mut self, name: &str, id: i8) -> usize {
        if self.bytes.is_empty() {
            self.bytes
                .extend_from_slice(&[1, KEY, 0, Processor::Intel.byte()]);
        }
        let start = self.bytes.len();
        if let Some(at) = self.last_next {
            let offset = (start - at) as i16;
            self.bytes[at..at + 2].copy_from_slice(&offset.to_le_bytes());
        }
        self.bytes.push(name.len() as u8);
        self.bytes.push(id as u8);
        self.bytes.extend_from_slice(name.as_bytes());
        let next_at = self.bytes.len();
        self.bytes.extend_from_slice(&[0, 0]);
        self.last_next = Some(next_at);
        next_at
    }

    fn group(&mut self, name: &str, description: &str) -> i8 {
        self.groups += 1;
        let id = self.groups as i8;
        self.begin(name, -id);
        self.bytes.push(description.len() as u8);
        self.bytes.extend_from_slice(description.as_bytes());
        id
    }

    /// A parameter entry; returns the byte offset of its data.
    fn param(&mut self, group: i8, name: &str, kind: i8, dims: &[usize], data: &[u8]) -> usize {
        self.begin(name, group);
        self.bytes.push(kind as u8);
        self.bytes.push(dims.len() as u8);
        self.bytes.extend(dims.iter().map(|&d| d as u8));
        let at = self.bytes.len();
        self.bytes.extend_from_slice(data);
        self.bytes.push(0); // empty description
        at
    }

    fn int(&mut self, group: i8, name: &str, value: u16) -> usize {
        self.param(group, name, 2, &[], &value.to_le_bytes())
    }

    fn ints(&mut self, group: i8, name: &str, values: &[u16]) {
        let data: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        self.param(group, name, 2, &[values.len()], &data);
    }

    fn float(&mut self, group: i8, name: &str, values: &[f32]) {
        let data: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        let dims: &[usize] = if values.len() == 1 {
            &[]
        } else {
            &[values.len()]
        };
        self.param(group, name, 4, dims, &data);
    }

    fn strings(&mut self, group: i8, name: &str, values: &[String], width: usize) {
        let mut data = Vec::with_capacity(values.len() * width);
        for v in values {
            let mut field = v.as_bytes().to_vec();
            field.resize(width, b' ');
            data.extend_from_slice(&field);
        }
        self.param(group, name, -1, &[width, values.len()], &data);
    }

    /// The section's bytes; the last entry's `next` stays 0, which ends the list.
    fn finish(self) -> Vec<u8> {
        self.bytes
    }
}
