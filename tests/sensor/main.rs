//! The IMX250MZR emulator: noise, polarizer, presets, photon transfer, the fast path and its
//! noise statistics, golden hashes.

// tests set a field or two of a default configuration
#![allow(clippy::field_reassign_with_default)]

#[path = "../common/mod.rs"]
mod common;

mod fast_noise;
mod fast_path;
mod frame_payload;
mod golden;
mod noise;
mod polarizer;
mod presets;
mod ptc;
mod spectral;
