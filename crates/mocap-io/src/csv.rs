//! csv reading and writing (being written).
use crate::{Capture, FormatError, ReadOptions, Trajectories};
/// Parses csv bytes.
pub fn parse(_bytes: &[u8], _options: &ReadOptions) -> Result<Capture, FormatError> {
    Err(FormatError::new("line 1", "csv reader not written yet"))
}
/// Encodes trajectories as csv text.
pub fn write(_t: &Trajectories) -> String {
    String::new()
}
