//! f64 elementary functions for the per-pixel sky (`docs/performance.md`, issue 9).
//!
//! The per-pixel sky calls these instead of `f64::exp` and friends, so that one definition serves
//! the scalar path (the sky's `Sky::sample`) and the row evaluator, and both give the same
//! bits. For now they are the platform's libm.

/// eˣ.
#[inline(always)]
pub fn exp(x: f64) -> f64 {
    x.exp()
}

/// Natural logarithm.
#[inline(always)]
pub fn ln(x: f64) -> f64 {
    x.ln()
}

/// xʸ for x ≥ 0.
#[inline(always)]
pub fn powf(x: f64, y: f64) -> f64 {
    x.powf(y)
}

/// atan2(y, x) in (−π, π].
#[inline(always)]
pub fn atan2(y: f64, x: f64) -> f64 {
    y.atan2(x)
}

/// arccos in [0, π] for x in [−1, 1].
#[inline(always)]
pub fn acos(x: f64) -> f64 {
    x.acos()
}

/// √(x² + y²).
#[inline(always)]
pub fn hypot(x: f64, y: f64) -> f64 {
    x.hypot(y)
}
