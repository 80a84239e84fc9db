//! Stokes parameters from polarizer channels (to be written).
