//! The TCP frame codec on an arbitrary byte stream delivered in arbitrary pieces: never panics,
//! never yields a frame over its limit, and never returns an error.
#![no_main]

use bytes::BytesMut;
use libfuzzer_sys::fuzz_target;
use runtime::transport::codec::{Frame, FrameCodec};
use tokio_util::codec::Decoder;

fuzz_target!(|data: &[u8]| {
    let Some((&[max, piece], stream)) = data.split_first_chunk::<2>() else {
        return;
    };
    let max = usize::from(max) * 4;
    let piece = usize::from(piece).max(1);
    let mut codec = FrameCodec::new(max);
    let mut buf = BytesMut::new();
    for chunk in stream.chunks(piece) {
        buf.extend_from_slice(chunk);
        while let Some(frame) = codec.decode(&mut buf).expect("the codec never fails") {
            if let Frame::Data(d) = frame {
                assert!(d.len() <= max);
            }
        }
    }
    while let Some(frame) = codec.decode_eof(&mut buf).unwrap_or(None) {
        if let Frame::Data(d) = frame {
            assert!(d.len() <= max);
        }
    }
});
