//! Demosaic methods (to be written).
