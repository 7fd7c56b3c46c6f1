//! bonefit (being written).
mod skeleton;
pub use skeleton::*;
