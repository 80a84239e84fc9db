//! berry (to be written)
