//! dop (to be written)
