//! `psns dataset`: builds, shards, resume, verify.

// tests set a field or two of a default configuration
#![allow(clippy::field_reassign_with_default)]

#[path = "../common/mod.rs"]
mod common;

mod build;
mod plan;
mod recipes;
mod scene;
mod world;
