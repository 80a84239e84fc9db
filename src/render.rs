//! Ideal images (to be written).
