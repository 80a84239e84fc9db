//! The `psns` command line: every command's outputs, bad input, progress; the house's layering.

#[path = "../common/mod.rs"]
mod common;

mod commands;
mod layering;
mod lens;
mod outputs;
mod progress;
mod raw;
