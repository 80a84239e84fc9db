//! The heading estimators from rendered and streamed frames.

// tests set a field or two of a default configuration
#![allow(clippy::field_reassign_with_default)]

#[path = "../common/mod.rs"]
mod common;

mod budget;
mod chain;
mod defaults;
mod inputs;
mod live;
mod masks;
