//! The point data section: frames of (x, y, z, residual) words, decoded without per-frame allocation.

use super::header::vax_f32;
use crate::MISSING;

/// How one stored point sample is decoded; one implementation per processor × storage.
pub trait SampleCodec {
    /// Bytes of one point (4 words).
    const BYTES: usize;
    /// Decodes one point's bytes (exactly `BYTES` long) into raw coordinates (file units,
    /// integer scale applied by the caller) and its fourth word as a number: negative
    /// flags the sample invalid, 0 says no camera saw it (a computed point), positive
    /// holds the camera mask and residual.
    fn decode(b: &[u8]) -> ([f32; 3], f32);
}

macro_rules! int_codec {
    ($name:ident, $from:ident) => {
        /// 16-bit integer samples.
        pub struct $name;
        impl SampleCodec for $name {
            const BYTES: usize = 8;
            #[inline(always)]
            fn decode(b: &[u8]) -> ([f32; 3], f32) {
                let Ok(w) = <[u8; 8]>::try_from(b) else {
                    return ([0.0; 3], -1.0);
                };
                let x = i16::$from([w[0], w[1]]);
                let y = i16::$from([w[2], w[3]]);
                let z = i16::$from([w[4], w[5]]);
                let r = i16::$from([w[6], w[7]]);
                ([f32::from(x), f32::from(y), f32::from(z)], f32::from(r))
            }
        }
    };
}

macro_rules! float_codec {
    ($name:ident, $conv:expr) => {
        /// 32-bit float samples.
        pub struct $name;
        impl SampleCodec for $name {
            const BYTES: usize = 16;
            #[inline(always)]
            fn decode(b: &[u8]) -> ([f32; 3], f32) {
                let Ok(w) = <[u8; 16]>::try_from(b) else {
                    return ([0.0; 3], -1.0);
                };
                let f = $conv;
                let x = f([w[0], w[1], w[2], w[3]]);
                let y = f([w[4], w[5], w[6], w[7]]);
                let z = f([w[8], w[9], w[10], w[11]]);
                let r = f([w[12], w[13], w[14], w[15]]);
                ([x, y, z], r)
            }
        }
    };
}

int_codec!(IntLe, from_le_bytes);
int_codec!(IntBe, from_be_bytes);
float_codec!(FloatLe, f32::from_le_bytes);
float_codec!(FloatBe, f32::from_be_bytes);
float_codec!(FloatVax, vax_f32);

/// Counts gathered while decoding, for the missing-sample rules and warnings.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Counts {
    /// Samples kept as present.
    pub present: usize,
    /// Samples whose residual word is negative.
    pub flagged: usize,
    /// Samples whose residual is negative although their coordinates are not all zero.
    pub flagged_nonzero: usize,
    /// Samples stored as exactly (0, 0, 0).
    pub zero: usize,
    /// Samples with a coordinate that is not finite or reaches ±1e9 (a vendor gap fill).
    pub out_of_range: usize,
}

/// What decoding gives: positions frame-major (mm, [`MISSING`] where absent) and, per
/// point, whether a camera saw any of its present samples (a positive fourth word).
#[derive(Clone, Debug, Default)]
pub struct Decoded {
    /// `frames × points` positions, frame-major.
    pub positions: Vec<[f64; 3]>,
    /// One entry per point.
    pub seen: Vec<bool>,
}

impl Decoded {
    /// Room for `frames` frames of `points` points, so decoding does not reallocate.
    pub fn with_capacity(frames: usize, points: usize) -> Self {
        Self {
            positions: Vec::with_capacity(frames * points),
            seen: vec![false; points],
        }
    }
}

/// Stored coordinates this large are gap fills (SIMI writes −1e9), not positions.
pub const GAP_FILL: f32 = 1.0e9;

/// Decodes `frames` frames of `points` samples each, appending millimetres to `out`.
///
/// `frame_bytes` is the stride (points plus analog data, which is skipped); `factor` turns
/// stored numbers into millimetres (integer scale × unit factor). A sample is missing when
/// its residual is negative (unless `keep_flagged`), its coordinates are exactly zero, or a
/// coordinate is not finite or reaches ±1e9 (stored units). `out.seen[p]` becomes true
/// when a present sample of point p has a positive fourth word (cameras saw it). The
/// caller has checked that `data` holds the frames and made `out` with
/// [`Decoded::with_capacity`], so the loop does not allocate.
pub fn decode<C: SampleCodec>(
    data: &[u8],
    frame_bytes: usize,
    frames: usize,
    points: usize,
    factor: f64,
    keep_flagged: bool,
    out: &mut Decoded,
) -> Counts {
    let mut counts = Counts::default();
    let point_bytes = points * C::BYTES;
    if frame_bytes == 0 || point_bytes == 0 {
        return counts;
    }
    for frame in data.chunks_exact(frame_bytes).take(frames) {
        let Some(point_data) = frame.get(..point_bytes) else {
            break;
        };
        for (point, sample) in point_data.chunks_exact(C::BYTES).enumerate() {
            let ([x, y, z], word) = C::decode(sample);
            // NaN is neither: not flagged, not seen.
            let flagged = word < 0.0;
            let zero = x == 0.0 && y == 0.0 && z == 0.0;
            counts.flagged += usize::from(flagged);
            counts.zero += usize::from(zero);
            counts.flagged_nonzero += usize::from(flagged && !zero);
            // NaN fails these comparisons too, so it lands in `out_of_range`.
            let in_range = x.abs() < GAP_FILL && y.abs() < GAP_FILL && z.abs() < GAP_FILL;
            counts.out_of_range += usize::from(!in_range);
            let p = [
                f64::from(x) * factor,
                f64::from(y) * factor,
                f64::from(z) * factor,
            ];
            if zero || (flagged && !keep_flagged) || !in_range {
                out.positions.push(MISSING);
            } else {
                counts.present += 1;
                if word > 0.0
                    && let Some(seen) = out.seen.get_mut(point)
                {
                    *seen = true;
                }
                out.positions.push(p);
            }
        }
    }
    counts
}
