//! Demosaic methods and Stokes estimation against the emulator's truth and real frames.

// tests set a field or two of a default configuration
#![allow(clippy::field_reassign_with_default)]

#[path = "../common/mod.rs"]
mod common;

mod noise;
mod real;
mod real_sky;
mod scenes;
mod stokes_calibrated;
mod uniform;
