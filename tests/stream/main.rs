//! The frame stream: format, writer, readers (Python, C, Rust), reliability, bags.

#[path = "../common/mod.rs"]
mod common;

mod cli;
mod readers;
mod reliability;
mod ros2;
mod roundtrip;
