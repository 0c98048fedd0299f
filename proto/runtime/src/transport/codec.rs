//! TCP framing: a 4-byte big-endian length, then the frame (one encoded `Envelope`).
//!
//! Like `tokio_util`'s `LengthDelimitedCodec` with a maximum frame length, except that an
//! oversized frame does not kill the stream: the decoder reports it as
//! [`Frame::Oversized`], skips its bytes without buffering them, and goes on with the next
//! frame. The receiver counts the rejection and the link stays up.

use bytes::{Buf, BufMut, Bytes, BytesMut};
use std::io;
use tokio_util::codec::{Decoder, Encoder};

/// Bytes of the length prefix.
pub const LEN_BYTES: usize = 4;

/// One item read from the stream.
#[derive(Debug, PartialEq)]
pub enum Frame {
    Data(BytesMut),
    /// A frame whose length prefix exceeded the maximum; its bytes are skipped.
    Oversized {
        len: usize,
    },
}

/// Length-prefixed frame codec with a receive limit.
#[derive(Debug)]
pub struct FrameCodec {
    max: usize,
    /// Bytes of an oversized frame still to skip.
    skipping: usize,
}

impl FrameCodec {
    pub fn new(max: usize) -> Self {
        FrameCodec { max, skipping: 0 }
    }
}

impl Decoder for FrameCodec {
    type Item = Frame;
    type Error = io::Error;

    fn decode(&mut self, src: &mut BytesMut) -> Result<Option<Frame>, io::Error> {
        if self.skipping > 0 {
            let n = self.skipping.min(src.len());
            src.advance(n);
            self.skipping -= n;
            if self.skipping > 0 {
                return Ok(None);
            }
        }
        if src.len() < LEN_BYTES {
            return Ok(None);
        }
        let len = u32::from_be_bytes([src[0], src[1], src[2], src[3]]) as usize;
        if len > self.max {
            src.advance(LEN_BYTES);
            self.skipping = len;
            return Ok(Some(Frame::Oversized { len }));
        }
        if src.len() < LEN_BYTES + len {
            src.reserve(LEN_BYTES + len - src.len());
            return Ok(None);
        }
        src.advance(LEN_BYTES);
        Ok(Some(Frame::Data(src.split_to(len))))
    }
}

/// The sender does not enforce the receive limit: `proto::wire::encode` already refuses to
/// build an oversized envelope, and tools must be able to send one to prove the receiver
/// rejects it. Only what cannot be expressed in the prefix is refused.
impl Encoder<Bytes> for FrameCodec {
    type Error = io::Error;

    fn encode(&mut self, item: Bytes, dst: &mut BytesMut) -> Result<(), io::Error> {
        let len = u32::try_from(item.len())
            .map_err(|_| io::Error::new(io::ErrorKind::InvalidInput, "frame longer than u32::MAX"))?;
        dst.reserve(LEN_BYTES + item.len());
        dst.put_u32(len);
        dst.extend_from_slice(&item);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn framed(payloads: &[&[u8]]) -> BytesMut {
        let mut c = FrameCodec::new(usize::MAX);
        let mut buf = BytesMut::new();
        for p in payloads {
            c.encode(Bytes::copy_from_slice(p), &mut buf).unwrap();
        }
        buf
    }

    #[test]
    fn frames_round_trip_and_partial_input_waits() {
        let mut buf = framed(&[b"abc", b"", b"hello"]);
        let mut c = FrameCodec::new(16);
        let mut partial = buf.split_to(5);
        assert_eq!(c.decode(&mut partial).unwrap(), None);
        partial.unsplit(buf);
        let mut buf = partial;
        assert_eq!(
            c.decode(&mut buf).unwrap(),
            Some(Frame::Data(BytesMut::from(&b"abc"[..])))
        );
        assert_eq!(c.decode(&mut buf).unwrap(), Some(Frame::Data(BytesMut::new())));
        assert_eq!(
            c.decode(&mut buf).unwrap(),
            Some(Frame::Data(BytesMut::from(&b"hello"[..])))
        );
        assert_eq!(c.decode(&mut buf).unwrap(), None);
    }

    #[test]
    fn frame_at_the_limit_passes_one_past_is_skipped_and_the_stream_continues() {
        let at = vec![1u8; 8];
        let past = vec![2u8; 9];
        let mut buf = framed(&[&at, &past, b"next"]);
        let mut c = FrameCodec::new(8);
        assert_eq!(
            c.decode(&mut buf).unwrap(),
            Some(Frame::Data(BytesMut::from(&at[..])))
        );
        assert_eq!(c.decode(&mut buf).unwrap(), Some(Frame::Oversized { len: 9 }));
        assert_eq!(
            c.decode(&mut buf).unwrap(),
            Some(Frame::Data(BytesMut::from(&b"next"[..])))
        );
    }

    #[test]
    fn oversized_frame_arriving_in_pieces_is_skipped_without_buffering() {
        let big = vec![3u8; 100];
        let all = framed(&[&big, b"ok"]);
        let mut c = FrameCodec::new(10);
        let mut out = Vec::new();
        let mut buf = BytesMut::new();
        for chunk in all.chunks(7) {
            buf.extend_from_slice(chunk);
            while let Some(f) = c.decode(&mut buf).unwrap() {
                out.push(f);
            }
            assert!(buf.len() <= LEN_BYTES + 10, "buffered {} bytes", buf.len());
        }
        assert_eq!(
            out,
            vec![
                Frame::Oversized { len: 100 },
                Frame::Data(BytesMut::from(&b"ok"[..]))
            ]
        );
    }
}
