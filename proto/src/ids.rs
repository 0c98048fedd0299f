//! Identifiers of nodes and targets, and the roles nodes play.

use serde::{Deserialize, Serialize};
use std::fmt;

/// A node's id, unique within a deployment (cameras, heads and the server share one space).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub struct NodeId(pub u32);

/// A target (track) id. Heads allocate local ids; the server hands out global ones.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub struct TargetId(pub u32);

/// A radio tag's identity, as a BLE device is known by its 48-bit MAC address.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub struct TagId(pub u64);

impl TagId {
    /// The tag of simulated target `target`: a locally administered unicast MAC
    /// (`02:00:00:00:xx:xx`), so simulated tags never collide with real ones.
    pub fn simulated(target: u32) -> TagId {
        TagId(0x0200_0000_0000 | u64::from(target & 0xffff))
    }

    /// Parse `aa:bb:cc:dd:ee:ff` (or with `-`, or the twelve hex digits bare, as recorded BLE
    /// files write them), case-insensitive.
    pub fn parse_mac(s: &str) -> Option<TagId> {
        let s = s.trim();
        if s.len() == 12 && s.bytes().all(|b| b.is_ascii_hexdigit()) {
            return u64::from_str_radix(s, 16).ok().map(TagId);
        }
        let parts: Vec<&str> = s.split([':', '-']).collect();
        if parts.len() != 6 {
            return None;
        }
        let mut v = 0u64;
        for p in parts {
            if p.len() != 2 {
                return None;
            }
            v = (v << 8) | u64::from(u8::from_str_radix(p, 16).ok()?);
        }
        Some(TagId(v))
    }
}

impl fmt::Display for TagId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let b = self.0.to_be_bytes();
        write!(
            f,
            "{:02x}:{:02x}:{:02x}:{:02x}:{:02x}:{:02x}",
            b[2], b[3], b[4], b[5], b[6], b[7]
        )
    }
}

impl fmt::Display for NodeId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "n{}", self.0)
    }
}

impl fmt::Display for TargetId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "t{}", self.0)
    }
}

/// The role a process plays. Order is part of the wire format.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Role {
    Camera,
    Head,
    Server,
    /// Benchmarks, probes and other tools that speak the protocol.
    Tool,
    /// A two-microphone acoustic node (paper 001).
    Acoustic,
    /// A visualization node: subscribes to the server's view feed and has no say in tracking.
    Viewer,
}

impl fmt::Display for Role {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Role::Camera => "camera",
            Role::Head => "head",
            Role::Server => "server",
            Role::Tool => "tool",
            Role::Acoustic => "acoustic",
            Role::Viewer => "viewer",
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tag_ids_print_and_parse_as_macs() {
        let t = TagId::simulated(7);
        assert_eq!(t.to_string(), "02:00:00:00:00:07");
        assert_eq!(TagId::parse_mac("02:00:00:00:00:07"), Some(t));
        assert_eq!(
            TagId::parse_mac("AA-bb-CC-dd-EE-ff"),
            Some(TagId(0xaabb_ccdd_eeff))
        );
        assert_eq!(TagId::parse_mac("B827eb4521b4"), Some(TagId(0xb827_eb45_21b4)));
        for bad in [
            "",
            "aa:bb",
            "aa:bb:cc:dd:ee:fg",
            "aaa:bb:cc:dd:ee:ff",
            "aa:bb:cc:dd:ee:ff:00",
            "b827eb4521b",
            "b827eb4521bg",
            "+b827eb4521b",
        ] {
            assert_eq!(TagId::parse_mac(bad), None, "{bad:?}");
        }
    }
}
