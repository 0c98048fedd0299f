//! The recording reader on arbitrary bytes: never panics, reads to the end, and its skips lie in
//! order inside the file without overlapping.
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let Ok(back) = node_server::recording::read_bytes(data, Path::new("fuzz")) else {
        return;
    };
    assert_eq!(back.len, data.len() as u64);
    let mut end = 0;
    for s in &back.skipped {
        assert!(s.offset >= end && s.bytes > 0);
        end = s.offset + s.bytes;
    }
    assert!(end <= back.len);
});
