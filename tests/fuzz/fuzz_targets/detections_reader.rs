//! The JSON Lines detections reader on arbitrary bytes: never panics, and what it accepts is
//! finite.
#![no_main]

use lab::replay::detections::read_detections;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(dets) = read_detections(data) {
        for d in dets {
            assert!(d.t.is_finite() && d.u.is_finite() && d.v.is_finite());
        }
    }
});
