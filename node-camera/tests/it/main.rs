//! Integration tests of the camera node: real datasets and whole-pipeline runs.

mod multiviewx;
mod process;
