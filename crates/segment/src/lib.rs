//! segment (being written).
mod segmentation;
pub use segmentation::*;
