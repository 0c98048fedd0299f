//! The JSON Lines detections reader on arbitrary bytes: never panics, what it accepts is
//! finite, and every line it skips is counted.
#![no_main]

use lab::replay::detections::read_detections;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(read) = read_detections(data) {
        for d in &read.detections {
            assert!(d.t.is_finite() && d.u.is_finite() && d.v.is_finite());
        }
        assert!(read.skipped.first.len() <= read.skipped.count);
    }
});
