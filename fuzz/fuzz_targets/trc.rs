//! Fuzz target: the TRC parser must return Ok or Err on any bytes, never panic or hang.
#![no_main]

use libfuzzer_sys::fuzz_target;
use mocap_io::{ReadOptions, trc};

fuzz_target!(|data: &[u8]| {
    if let Ok(capture) = trc::parse(data, &ReadOptions::default()) {
        let t = &capture.trajectories;
        assert_eq!(t.positions().len(), t.frames() * t.markers());
    }
});
