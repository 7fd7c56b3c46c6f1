//! trc reading and writing (being written).
use crate::{Capture, FormatError, ReadOptions, Trajectories};
/// Parses trc bytes.
pub fn parse(_bytes: &[u8], _options: &ReadOptions) -> Result<Capture, FormatError> {
    Err(FormatError::new("line 1", "trc reader not written yet"))
}
/// Encodes trajectories as trc text.
pub fn write(_t: &Trajectories) -> String {
    String::new()
}
