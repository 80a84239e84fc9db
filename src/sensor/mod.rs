//! IMX250MZR sensor emulation (to be written).

pub mod mosaic;
pub mod packing;
