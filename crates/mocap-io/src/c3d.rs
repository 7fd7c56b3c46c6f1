//! C3D reading and writing (being written).
use crate::{Capture, FormatError, IoError, ReadOptions, Trajectories};
/// Parses C3D bytes.
pub fn parse(_bytes: &[u8], _options: &ReadOptions) -> Result<Capture, FormatError> {
    Err(FormatError::new("byte 0", "C3D reader not written yet"))
}
/// Encodes trajectories as C3D bytes.
pub fn write(_t: &Trajectories) -> Result<Vec<u8>, IoError> {
    Err(IoError::Invalid("C3D writer not written yet".into()))
}
