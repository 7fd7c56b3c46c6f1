//! topo (being written).
mod topology;
pub use topology::*;
