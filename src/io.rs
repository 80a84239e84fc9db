//! File output helpers (to be written).
