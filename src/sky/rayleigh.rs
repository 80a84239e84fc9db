//! rayleigh (to be written)
