//! Fuzz target: the C3D parser must return Ok or Err on any bytes, never panic or hang.
#![no_main]

use libfuzzer_sys::fuzz_target;
use mocap_io::{ReadOptions, c3d};

fuzz_target!(|data: &[u8]| {
    for keep_invalid_residuals in [false, true] {
        let options = ReadOptions {
            keep_invalid_residuals,
            keep_model_outputs: keep_invalid_residuals,
            ..ReadOptions::default()
        };
        if let Ok(capture) = c3d::parse(data, &options) {
            let t = &capture.trajectories;
            assert_eq!(t.positions().len(), t.frames() * t.markers());
        }
    }
});
