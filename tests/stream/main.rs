//! The frame stream: format, writer, readers (Python, C, Rust), reliability, bags.

// tests set a field or two of a default configuration
#![allow(clippy::field_reassign_with_default)]

#[path = "../common/mod.rs"]
mod common;

mod cli;
mod completeness;
mod nav_reader;
mod readers;
mod recordings;
mod reliability;
mod ros2;
mod roundtrip;
mod same_codes;
