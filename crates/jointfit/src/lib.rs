//! jointfit (being written).
mod pairfits;
pub use pairfits::*;
