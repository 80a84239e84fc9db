//! Raw frame stream (to be written).
