//! The sky models, the sun and the camera chain against references and oracles.

// tests set a field or two of a default configuration
#![allow(clippy::field_reassign_with_default)]

#[path = "../common/mod.rs"]
mod common;

mod camera_chain;
mod hosek;
mod models;
mod reference;
mod stability;
