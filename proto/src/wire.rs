//! The one wire encoding of Ocelli: `encode` and `decode`, nothing else names postcard.
//!
//! Frame layout: postcard varint `PROTOCOL_VERSION`, then the postcard-encoded [`Envelope`].
//! The version is read first, so a peer on another version gets a clear error instead of a
//! garbled decode. `decode` rejects trailing bytes, oversized frames and any envelope that
//! fails [`Validate`](crate::validate::Validate). Decoding errors name the message kind and the
//! problem (truncation, unknown tag, bad option/bool byte); the tests in `tests/it/wire/` pin
//! every kind's bytes with golden vectors and exercise each rejection.

use crate::ids::NodeId;
use crate::msg::Envelope;
use crate::time::ClusterTime;
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
    let (env, rest) = postcard::take_from_bytes::<Envelope>(rest).map_err(|e| body_error(rest, &e))?;
    if !rest.is_empty() {
        return Err(WireError::TrailingBytes(rest.len()));
    }
    env.validate()?;
    Ok(env)
}

/// Kind names of [`crate::Message`] by wire tag (variant index). A test pins it to
/// [`crate::Message::kind`].
pub const MESSAGE_KINDS: [&str; 22] = [
    "hello",
    "hello_ack",
    "heartbeat",
    "measurement",
    "answers",
    "node_status",
    "priors",
    "command",
    "track_report",
    "assignment",
    "handover",
    "sync_beacon",
    "liveness",
    "measured_frame",
    "sample_request",
    "sample_set",
    "frame_report",
    "view_subscribe",
    "view_update",
    "people_frame",
    "tags_heard",
    "tag_homes",
];

/// Turn a postcard failure into an error that names the message kind and the problem
/// (postcard's own messages drop serde's detail, e.g. which enum tag was unknown).
fn body_error(body: &[u8], e: &postcard::Error) -> WireError {
    use postcard::Error as P;
    // The envelope header is three varints, then the message tag: read them on their own.
    let head = postcard::take_from_bytes::<(NodeId, u64, ClusterTime)>(body);
    let Ok((_, after_header)) = head else {
        return WireError::Malformed(match e {
            P::DeserializeUnexpectedEnd => "truncated frame: it ends inside the envelope header".into(),
            other => format!("envelope header: {other}"),
        });
    };
    let kind = match postcard::take_from_bytes::<u32>(after_header) {
        Err(_) => return WireError::Malformed("truncated frame: it ends before the message tag".into()),
        Ok((tag, _)) => match MESSAGE_KINDS.get(tag as usize) {
            Some(kind) => *kind,
            None => {
                return WireError::Malformed(format!(
                    "unknown message kind tag {tag} (this build knows 0..={})",
                    MESSAGE_KINDS.len() - 1
                ));
            }
        },
    };
    WireError::Malformed(match e {
        P::DeserializeUnexpectedEnd => format!("truncated frame: it ends inside a {kind} message"),
        P::SerdeDeCustom | P::DeserializeBadEnum => {
            format!("{kind}: unknown enum variant tag (or out-of-range value) in the message")
        }
        P::DeserializeBadOption => format!("{kind}: an option tag is neither 0 nor 1"),
        P::DeserializeBadBool => format!("{kind}: a bool byte is neither 0 nor 1"),
        P::DeserializeBadUtf8 | P::DeserializeBadChar => format!("{kind}: a string is not valid UTF-8"),
        P::DeserializeBadVarint => format!("{kind}: a varint does not terminate or overflows"),
        other => format!("{kind}: {other}"),
    })
}
