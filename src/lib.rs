//! # psns — Polarized Skylight Navigation Simulator
//!
//! A hardware-in-the-loop emulator of the Sony IMX250MZR division-of-focal-plane polarization
//! camera looking at a clear sky, after Liang & Bai, "Polarized Skylight Navigation Simulation
//! Dataset" (PSNS), extended down to the sensor.
//!
//! Chain: [`sun`] → [`sky`] (Hosek–Wilkie radiance, Berry AOP, Wang/PSNS DOP, Rayleigh) →
//! [`camera`] (pinhole, attitude, sensor-frame AOP) → [`render`] (ideal images) → [`sensor`]
//! (raw mosaic) → [`demosaic`]/[`stokes`] → [`stream`].
//!
//! Conventions (see `docs/conventions.md`): ENU world frame, compass azimuths, sensor angles
//! from +x (columns) toward +y (rows, down), row-major images with row 0 at the top.

#![warn(missing_docs)]

pub mod angle;
pub mod camera;
pub mod config;
pub mod dataset;
pub mod demosaic;
pub mod error;
pub mod gige;
pub mod heading;
pub mod image;
pub mod io;
pub mod memory;
pub mod names;
pub mod options;
pub mod pipeline;
pub mod progress;
pub mod record;
pub mod render;
pub mod rng;
pub mod ros2;
pub mod sensor;
pub mod simd;
pub mod sky;
pub mod stokes;
pub mod stream;
pub mod sun;
pub mod trajectory;
pub mod vmath;
pub mod world;

pub use error::{Error, Result};
