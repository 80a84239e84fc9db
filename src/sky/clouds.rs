//! clouds (to be written)
