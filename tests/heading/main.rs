//! The heading estimators from rendered and streamed frames.

#[path = "../common/mod.rs"]
mod common;

mod chain;
