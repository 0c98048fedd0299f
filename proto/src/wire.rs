//! The one wire encoding of Ocelli: `encode` and `decode`, nothing else names postcard.
//!
//! Frame layout: postcard varint `PROTOCOL_VERSION`, then the postcard-encoded [`Envelope`].
//! The version is read first, so a peer on another version gets a clear error instead of a
//! garbled decode. `decode` rejects trailing bytes, oversized frames and any envelope that
//! fails [`Validate`](crate::validate::Validate).

use crate::msg::Envelope;
use crate::validate::{Validate, ValidationError};
use crate::{MAX_FRAME_BYTES, PROTOCOL_VERSION};
use thiserror::Error;

/// Why a frame was not accepted.
#[derive(Debug, Error, PartialEq)]
pub enum WireError {
    #[error("frame of {len} bytes exceeds the maximum of {max} bytes")]
    Oversized { len: usize, max: usize },
    #[error("empty frame")]
    Empty,
    #[error("protocol version {got} is not supported (this build speaks {expected})")]
    Version { got: u16, expected: u16 },
    #[error("malformed frame: {0}")]
    Malformed(String),
    #[error("{0} trailing bytes after the message")]
    TrailingBytes(usize),
    #[error("invalid message: {0}")]
    Invalid(#[from] ValidationError),
}

/// Encode an envelope into a frame.
///
/// # Errors
/// [`WireError::Invalid`] if the envelope fails validation (a node must not send what its peer
/// would reject) and [`WireError::Oversized`] if it encodes past [`MAX_FRAME_BYTES`].
pub fn encode(env: &Envelope) -> Result<Vec<u8>, WireError> {
    env.validate()?;
    let mut out = postcard::to_stdvec(&PROTOCOL_VERSION).map_err(|e| WireError::Malformed(e.to_string()))?;
    out = postcard::to_extend(env, out).map_err(|e| WireError::Malformed(e.to_string()))?;
    if out.len() > MAX_FRAME_BYTES {
        return Err(WireError::Oversized {
            len: out.len(),
            max: MAX_FRAME_BYTES,
        });
    }
    Ok(out)
}

/// Decode and validate one frame.
///
/// # Errors
/// Every way a frame can be wrong maps to one [`WireError`] variant; nothing panics.
pub fn decode(frame: &[u8]) -> Result<Envelope, WireError> {
    if frame.is_empty() {
        return Err(WireError::Empty);
    }
    if frame.len() > MAX_FRAME_BYTES {
        return Err(WireError::Oversized {
            len: frame.len(),
            max: MAX_FRAME_BYTES,
        });
    }
    let (version, rest) =
        postcard::take_from_bytes::<u16>(frame).map_err(|e| WireError::Malformed(format!("header: {e}")))?;
    if version != PROTOCOL_VERSION {
        return Err(WireError::Version {
            got: version,
            expected: PROTOCOL_VERSION,
        });
    }
    let (env, rest) =
        postcard::take_from_bytes::<Envelope>(rest).map_err(|e| WireError::Malformed(e.to_string()))?;
    if !rest.is_empty() {
        return Err(WireError::TrailingBytes(rest.len()));
    }
    env.validate()?;
    Ok(env)
}
