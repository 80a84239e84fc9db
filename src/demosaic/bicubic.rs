//! Keys cubic convolution (a = −½) per channel, run as Nyquist demodulation.
//!
//! On a channel's sub-lattice (step 2) the Keys kernel sampled at half steps is
//! [−1/16, 0, 9/16, 1, 9/16, 0, −1/16]; per-channel cubic convolution followed by the Stokes
//! formulas is therefore demodulation with LP = [−1 0 9 16 9 0 −1]/32 (spec `demosaic.md` §1;
//! Gao & Gruev, Opt. Express 19(27) 2011, compare cubic interpolators). Same fused code as
//! [`super::bilinear`].

use super::bilinear::Kernel;

/// [−1 0 9 16 9 0 −1]/32.
pub const LP7: Kernel = Kernel {
    radius: 3,
    h: [16.0 / 32.0, 9.0 / 32.0, 0.0, -1.0 / 32.0],
};
