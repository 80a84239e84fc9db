//! Scene configuration (to be written).
