//! The wire contract: golden bytes, round trips, rejections.

mod golden;
mod reject;
mod roundtrip;
