//! The OpenCV FileStorage import on arbitrary text, as an intrinsic and as an extrinsic file:
//! never panics.
#![no_main]

use libfuzzer_sys::fuzz_target;
use proto::opencv::{ImportOptions, parse_extrinsics, parse_intrinsics};
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let _ = parse_intrinsics(Path::new("fuzz.xml"), text, None);
    let _ = parse_extrinsics(Path::new("fuzz.xml"), text, &ImportOptions::default());
});
