//! The `psns` command line: every command's outputs, bad input, progress; the house's layering.

// tests set a field or two of a default configuration
#![allow(clippy::field_reassign_with_default)]

#[path = "../common/mod.rs"]
mod common;

mod callers;
mod commands;
mod completeness;
mod full_disk;
mod layering;
mod lens;
mod messages;
mod names;
mod outputs;
mod progress;
mod raw;
mod saturation;
mod tools;
mod world;
