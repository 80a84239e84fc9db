//! Demosaic methods and Stokes estimation against the emulator's truth and real frames.

#[path = "../common/mod.rs"]
mod common;

mod noise;
mod real;
mod real_sky;
mod scenes;
mod stokes_calibrated;
mod uniform;
