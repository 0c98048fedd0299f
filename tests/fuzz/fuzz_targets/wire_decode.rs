//! `proto::decode` on arbitrary bytes: never panics, and what it accepts encodes back to a frame
//! that decodes to the same envelope.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(env) = proto::decode(data) {
        let frame = proto::encode(&env).expect("a decoded envelope encodes");
        assert_eq!(proto::decode(&frame).expect("re-encoded frame decodes"), env);
    }
});
