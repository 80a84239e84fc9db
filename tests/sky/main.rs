//! The sky models, the sun and the camera chain against references and oracles.

mod camera_chain;
mod hosek;
mod reference;
mod stability;
