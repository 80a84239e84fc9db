//! `psns dataset`: builds, shards, resume, verify.

#[path = "../common/mod.rs"]
mod common;

mod build;
