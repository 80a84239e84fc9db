//! Elementary functions: f64 for the per-pixel sky, f32 for the fast path's noise
//! ([`ln_f32`], [`exp_f32`]) (`docs/performance.md`).
//!
//! The per-pixel sky calls these instead of libm, so that one definition serves the scalar path
//! (the sky's `Sky::sample`) and the row evaluator, and both give the same bits. libm's functions
//! are opaque calls, one value at a time; these are branch-free `#[inline(always)]` code (range
//! reduction, a polynomial, selects for the special cases, a 9-entry table for `atan2` read by
//! selects), so a loop over a row compiles to AVX-512 or AVX2 vectors inside a `simd_dispatch!`
//! kernel; [`exp_in_place`] and [`powf_lanes`] take a chunk at a time.
//!
//! Only `*`, `+`, `-`, `/`, `sqrt`, comparisons and bit operations are used, never `mul_add`:
//! each is one exactly rounded IEEE operation in every instruction set (Rust never fuses them),
//! so the plain, AVX2 and AVX-512 builds agree bit for bit, and a scalar caller outside a
//! dispatched kernel pays no software FMA.
//!
//! Accuracy, tested against glibc's libm (`tests` below, over ranges and special values):
//! `exp`, `ln`, `hypot` within 1 ulp of libm; `atan2`, `acos` within 2 ulp; `powf(x, y)` within
//! 2 + |y ln x| ulp (it is exp(y ln x) without extra precision); 74-99 % of values are libm's
//! bit for bit (`tests::most_values_are_libms`). A raw frame depends on the sky only through steps that round
//! or draw (the f32 Stokes planes, `--exact`'s Poisson draws, the fast path's whole electrons),
//! so a last-bit difference moves a raw code only if a value lies within an ulp of such a
//! boundary: when these replaced libm, no stream, golden hash or `psns render --raw` file changed
//! (`docs/performance.md`).

/// ln 2 with its low 32 mantissa bits cleared, so that `n * LN2_HI` is exact for |n| < 2³².
const LN2_HI: f64 = 0.693_146_705_627_441_4;
/// ln 2 − [`LN2_HI`].
const LN2_LO: f64 = 4.749_325_039_031_672_6e-7;
const PI_HI: f64 = std::f64::consts::PI;
/// π − [`PI_HI`].
const PI_LO: f64 = 1.224_646_799_147_353_2e-16;
const PIO2_HI: f64 = std::f64::consts::FRAC_PI_2;
/// π/2 − [`PIO2_HI`].
const PIO2_LO: f64 = 6.123_233_995_736_766e-17;
/// 1.5 · 2⁵²: adding and subtracting it rounds a double of magnitude < 2⁵¹ to an integer.
const ROUND: f64 = 6_755_399_441_055_744.0;

/// Returns `a` where `c`, else `b` (compiles to a blend).
#[inline(always)]
fn sel(c: bool, a: f64, b: f64) -> f64 {
    if c {
        a
    } else {
        b
    }
}

/// The integer-valued double n (|n| < 2⁵¹) as an integer, through the bits of n + [`ROUND`]:
/// integer lanes, where `n as i64` would be a scalar conversion with saturation checks.
#[inline(always)]
fn to_int(n: f64) -> u64 {
    (n + ROUND).to_bits().wrapping_sub(ROUND.to_bits())
}

/// The integer n (|n| < 2⁵¹) as a double, the inverse of [`to_int`].
#[inline(always)]
fn to_f64(n: i64) -> f64 {
    f64::from_bits(ROUND.to_bits().wrapping_add(n as u64)) - ROUND
}

/// 2ⁿ for an integer-valued n in [−1022, 1023].
#[inline(always)]
fn pow2(n: f64) -> f64 {
    f64::from_bits(to_int(n).wrapping_add(1023) << 52)
}

/// eˣ, within 1 ulp of libm. Overflows to +∞ above 709.78, underflows (through subnormals) to
/// 0 below −745.1; NaN gives NaN.
///
/// ```
/// assert_eq!(psns::vmath::exp(0.0), 1.0);
/// assert!((psns::vmath::exp(1.0) - std::f64::consts::E).abs() <= f64::EPSILON * 3.0);
/// ```
#[inline(always)]
pub fn exp(x: f64) -> f64 {
    // Clamp first so the scale factors below stay finite; the selects at the end restore ±∞/0.
    let (n, p) = exp_reduce(x.clamp(-746.0, 710.0));
    // 2ⁿ as two normal factors, so results down to the subnormals scale without overflow.
    let n1 = ((n * 0.5 + ROUND) - ROUND).clamp(-1022.0, 1023.0);
    let y = p * pow2(n1) * pow2(n - n1);
    let y = sel(x > 709.782_712_893_384, f64::INFINITY, y);
    let y = sel(x < -745.133_219_101_941_1, 0.0, y);
    sel(x.is_nan(), x, y)
}

/// Largest |x| for which [`exp_normal`] equals [`exp`]: e^±708 and its p·2ⁿ are normal numbers.
const EXP_NORMAL_MAX: f64 = 708.0;

/// [`exp`] for |x| ≤ [`EXP_NORMAL_MAX`], the same bits: the result is a normal number, so
/// p·2ⁿ is one exact scaling (the same value as `exp`'s two factors) and no clamp or select is
/// needed. Outside that range the result is meaningless.
#[inline(always)]
fn exp_normal(x: f64) -> f64 {
    let (n, p) = exp_reduce(x);
    p * pow2(n)
}

/// n = round(x / ln 2) and p = e^r, r = x − n ln 2 (|r| ≤ 0.347), for |x| ≤ 746: eˣ = p·2ⁿ.
#[inline(always)]
fn exp_reduce(xc: f64) -> (f64, f64) {
    let n = (xc * std::f64::consts::LOG2_E + ROUND) - ROUND;
    // r = x − n ln 2 in two steps: n·LN2_HI is exact and x − n·LN2_HI cancels exactly.
    let r = (xc - n * LN2_HI) - n * LN2_LO;
    // e^r − 1 − r = r² Σ rᵏ/(k+2)!, |r| ≤ 0.347: degree 13 leaves < 1e-17 relative.
    let mut q = 1.0 / 6_227_020_800.0; // 1/13!
    q = q * r + 1.0 / 479_001_600.0;
    q = q * r + 1.0 / 39_916_800.0;
    q = q * r + 1.0 / 3_628_800.0;
    q = q * r + 1.0 / 362_880.0;
    q = q * r + 1.0 / 40_320.0;
    q = q * r + 1.0 / 5_040.0;
    q = q * r + 1.0 / 720.0;
    q = q * r + 1.0 / 120.0;
    q = q * r + 1.0 / 24.0;
    q = q * r + 1.0 / 6.0;
    q = q * r + 0.5;
    (n, 1.0 + (r + r * r * q))
}

/// [`exp`] of every value of `x`, in place, the same bits. A chunk whose values all lie in
/// |x| ≤ 708 (one vectorised check; the sky's arguments lie far inside) takes `exp_normal`,
/// without the clamp and the selects for ∞, 0 and NaN; any other chunk the full [`exp`].
///
/// ```
/// let mut x = [0.0, 1.0, -800.0];
/// psns::vmath::exp_in_place(&mut x);
/// assert_eq!(x, [1.0, psns::vmath::exp(1.0), 0.0]);
/// ```
#[inline(always)]
pub fn exp_in_place(x: &mut [f64]) {
    // `&`, not `&&`: no early exit, so the check vectorises; NaN fails it
    let normal = x.iter().fold(true, |a, &v| a & (v.abs() <= EXP_NORMAL_MAX));
    if normal {
        for v in x.iter_mut() {
            *v = exp_normal(*v);
        }
    } else {
        for v in x.iter_mut() {
            *v = exp(*v);
        }
    }
}

/// Natural logarithm, within 1 ulp of libm. ln 0 = −∞, ln x = NaN for x < 0, ln ∞ = ∞.
///
/// ```
/// assert_eq!(psns::vmath::ln(1.0), 0.0);
/// assert!((psns::vmath::ln(std::f64::consts::E) - 1.0).abs() <= f64::EPSILON);
/// ```
#[inline(always)]
pub fn ln(x: f64) -> f64 {
    // Subnormals: scale by 2⁵⁴ first.
    let tiny = x < f64::MIN_POSITIVE;
    let xs = sel(tiny, x * 18_014_398_509_481_984.0, x);
    let bits = xs.to_bits();
    let e = ((bits >> 52) & 0x7ff) as i64 - 1023 - if tiny { 54 } else { 0 };
    let m = f64::from_bits((bits & 0x000f_ffff_ffff_ffff) | 0x3ff0_0000_0000_0000);
    // m in [√½, √2): f = m − 1 in [−0.29, 0.41].
    let big = m > std::f64::consts::SQRT_2;
    let m = sel(big, m * 0.5, m);
    let k = to_f64(e + i64::from(big));
    let f = m - 1.0;
    // ln(1 + f) = 2 atanh s = 2s + s R(s²), s = f/(2 + f), |s| ≤ 0.172; and
    // 2s = f − hfsq + s·hfsq with hfsq = f²/2 (the arrangement of fdlibm's log).
    let s = f / (2.0 + f);
    let z = s * s;
    let mut rr = 2.0 / 23.0;
    rr = rr * z + 2.0 / 21.0;
    rr = rr * z + 2.0 / 19.0;
    rr = rr * z + 2.0 / 17.0;
    rr = rr * z + 2.0 / 15.0;
    rr = rr * z + 2.0 / 13.0;
    rr = rr * z + 2.0 / 11.0;
    rr = rr * z + 2.0 / 9.0;
    rr = rr * z + 2.0 / 7.0;
    rr = rr * z + 2.0 / 5.0;
    rr = rr * z + 2.0 / 3.0;
    let r = rr * z;
    let hfsq = 0.5 * f * f;
    let y = k * LN2_HI - ((hfsq - (s * (hfsq + r) + k * LN2_LO)) - f);
    let y = sel(x == 0.0, f64::NEG_INFINITY, y);
    let y = sel(x == f64::INFINITY, x, y);
    sel(x < 0.0 || x.is_nan(), f64::NAN, y)
}

/// xʸ for x ≥ 0 (NaN for x < 0), as exp(y ln x): within 2 + |y ln x| ulp of libm. x⁰ = 1 and
/// 1ʸ = 1 exactly; 0ʸ = 0 for y > 0 and ∞ for y < 0.
///
/// ```
/// assert_eq!(psns::vmath::powf(0.25, 0.5), 0.5);
/// assert_eq!(psns::vmath::powf(0.3, 0.0), 1.0);
/// ```
#[inline(always)]
pub fn powf(x: f64, y: f64) -> f64 {
    powf_fix(x, y, exp(y * ln(x)))
}

/// [`powf`]'s special cases, given v = exp(y ln x).
#[inline(always)]
fn powf_fix(x: f64, y: f64, v: f64) -> f64 {
    let v = sel(x == 0.0, sel(y < 0.0, f64::INFINITY, 0.0), v);
    sel(y == 0.0 || x == 1.0, 1.0, v)
}

/// [`powf`]`(x[j], y)` into `out[j]` (same length), the same bits, the exponential by
/// [`exp_in_place`].
///
/// ```
/// let mut out = [0.0; 3];
/// psns::vmath::powf_lanes(&[0.25, 0.0, 1.0], 0.5, &mut out);
/// assert_eq!(out, [0.5, 0.0, 1.0]);
/// ```
#[inline(always)]
pub fn powf_lanes(x: &[f64], y: f64, out: &mut [f64]) {
    assert_eq!(x.len(), out.len());
    for (o, &x) in out.iter_mut().zip(x) {
        *o = y * ln(x);
    }
    exp_in_place(out);
    for (o, &x) in out.iter_mut().zip(x) {
        *o = powf_fix(x, y, *o);
    }
}

/// atan(k/8) for k = 0..=8, high and low parts.
const ATAN_HI: [f64; 9] = [
    0.0,
    0.124_354_994_546_761_44,
    0.244_978_663_126_864_14,
    0.358_770_670_270_572_25,
    0.463_647_609_000_806_1,
    0.558_599_315_343_562_4,
    0.643_501_108_793_284_4,
    0.718_829_999_621_624_5,
    std::f64::consts::FRAC_PI_4,
];
const ATAN_LO: [f64; 9] = [
    0.0,
    -3.125_324_142_453_938_3e-18,
    1.069_875_561_873_445_1e-17,
    -2.462_381_558_263_863_5e-17,
    2.269_877_745_296_168_7e-17,
    -5.455_630_548_591_626_4e-18,
    1.583_478_505_144_428_6e-17,
    -2.147_838_844_445_698_3e-17,
    3.061_616_997_868_383e-17,
];

/// `t[k]` for the integer-valued kf = k ≤ 8 by a chain of selects: blends, where an index
/// would be a gather in vector code.
#[inline(always)]
fn table9(t: [f64; 9], kf: f64) -> f64 {
    let mut v = t[0];
    for (i, &ti) in t.iter().enumerate().skip(1) {
        v = sel(kf >= i as f64, ti, v);
    }
    v
}

/// atan2(y, x) in [−π, π], within 2 ulp of libm (the signs of zeros as in IEEE 754:
/// atan2(±0, −0) = ±π). Infinite arguments are not handled (atan2(∞, ∞) gives NaN).
///
/// ```
/// use std::f64::consts::{FRAC_PI_2, FRAC_PI_4};
/// assert_eq!(psns::vmath::atan2(1.0, 0.0), FRAC_PI_2);
/// assert!((psns::vmath::atan2(1.0, 1.0) - FRAC_PI_4).abs() <= f64::EPSILON);
/// ```
#[inline(always)]
pub fn atan2(y: f64, x: f64) -> f64 {
    let (ax, ay) = (x.abs(), y.abs());
    let swap = ay > ax;
    let (num, den) = (sel(swap, ax, ay), sel(swap, ay, ax));
    // 0/0 (both zero) reads as t = 0, so the quadrant logic gives ±0 or ±π.
    let t = sel(den == 0.0, 0.0, num / den);
    // atan t = atan c + atan u, c = k/8 the nearest eighth, u = (t − c)/(1 + tc), |u| ≤ 1/16.
    let kf = (t * 8.0 + ROUND) - ROUND;
    // (NaN: any entry; the result is NaN anyway)
    let c = kf * 0.125;
    let u = (t - c) / (1.0 + t * c);
    let z = u * u;
    // atan u − u = u z P(z), P = −1/3 + z/5 − …; z ≤ 1/256, so to z⁷ leaves < 1e-19.
    let mut p = -1.0 / 17.0;
    p = p * z + 1.0 / 15.0;
    p = p * z - 1.0 / 13.0;
    p = p * z + 1.0 / 11.0;
    p = p * z - 1.0 / 9.0;
    p = p * z + 1.0 / 7.0;
    p = p * z - 1.0 / 5.0;
    p = p * z + 1.0 / 3.0;
    // atan t = hi + lo; the quadrant gives C ± atan t with C ∈ {0, π/2, π}, each in two parts.
    let (hi, lo) = (table9(ATAN_HI, kf), table9(ATAN_LO, kf) + (u - u * z * p));
    let neg = x.is_sign_negative();
    let minus = swap != neg; // π/2 − a for x ≥ 0, π − a for x < 0
    let (c_hi, c_lo) = match (swap, neg) {
        (false, false) => (0.0, 0.0),
        (true, _) => (PIO2_HI, PIO2_LO),
        (false, true) => (PI_HI, PI_LO),
    };
    let (hi, lo) = (sel(minus, -hi, hi), sel(minus, -lo, lo));
    let a = ((c_hi + hi) + (c_lo + lo)).copysign(y);
    sel(x.is_nan() || y.is_nan(), f64::NAN, a)
}

/// arccos x in [0, π] for x in [−1, 1] (NaN outside), within 2 ulp of libm: atan2(√(1−x²), x)
/// with 1 − x² as (1 − x)(1 + x), exact where it matters (|x| near 1).
///
/// ```
/// assert_eq!(psns::vmath::acos(1.0), 0.0);
/// assert!((psns::vmath::acos(0.0) - std::f64::consts::FRAC_PI_2).abs() <= f64::EPSILON);
/// ```
#[inline(always)]
pub fn acos(x: f64) -> f64 {
    atan2(((1.0 - x) * (1.0 + x)).sqrt(), x)
}

/// √(x² + y²), within 1 ulp of libm (which rounds it correctly), scaled by a power of two where
/// x² or y² would overflow or lose precision.
///
/// ```
/// assert_eq!(psns::vmath::hypot(3.0, 4.0), 5.0);
/// assert_eq!(psns::vmath::hypot(3e300, 4e300), 5e300);
/// ```
#[inline(always)]
pub fn hypot(x: f64, y: f64) -> f64 {
    let (ax, ay) = (x.abs(), y.abs());
    let big = ax.max(ay);
    // s and its reciprocal are powers of two, so `* inv` is `/ s` exactly (no division).
    let (hi, lo) = (big > 1e150, big < 1e-150);
    let s = sel(hi, 2f64.powi(-600), sel(lo, 2f64.powi(600), 1.0));
    let inv = sel(hi, 2f64.powi(600), sel(lo, 2f64.powi(-600), 1.0));
    let (sx, sy) = (ax * s, ay * s);
    let h = (sx * sx + sy * sy).sqrt() * inv;
    sel(ax == f64::INFINITY || ay == f64::INFINITY, f64::INFINITY, h)
}

// f32: the sensor's fast-path noise. These use
// `mul_add`, which is exactly rounded with or without the FMA instruction, so every build agrees.

/// ln x for finite x > 0 (normal numbers), f32, branch-free: x = 2^e m with m in [√½, √2),
/// ln m = 2 atanh(s), s = (m − 1)/(m + 1), |s| ≤ 0.172, series to s⁹ (error < 3e-9 relative).
#[inline(always)]
pub fn ln_f32(x: f32) -> f32 {
    let bits = x.to_bits();
    let mut e = ((bits >> 23) & 0xff) as i32 - 127;
    let mut m = f32::from_bits((bits & 0x007f_ffff) | 0x3f80_0000);
    let big = m > std::f32::consts::SQRT_2;
    m = if big { 0.5 * m } else { m };
    e += big as i32;
    let s = (m - 1.0) / (m + 1.0);
    let s2 = s * s;
    let series = s2
        .mul_add(1.0 / 9.0, 1.0 / 7.0)
        .mul_add(s2, 0.2)
        .mul_add(s2, 1.0 / 3.0)
        .mul_add(s2, 1.0);
    (e as f32).mul_add(std::f32::consts::LN_2, 2.0 * s * series)
}

/// e^x for f32, x in [−87, 0], branch-free: 2^n e^r with |r| ≤ ln2/2 and a degree-6 Taylor
/// polynomial (relative error < 3e-7).
#[inline(always)]
pub fn exp_f32(x: f32) -> f32 {
    let x = x.max(-87.0);
    let n = (x * std::f32::consts::LOG2_E).round_ties_even();
    // ln 2 in two parts so r keeps its precision
    let r = x - n * 0.693_145_75 - n * 1.428_606_8e-6;
    let p = 1.0
        + r * (1.0
            + r * (0.5
                + r * (1.0 / 6.0 + r * (1.0 / 24.0 + r * (1.0 / 120.0 + r * (1.0 / 720.0))))));
    p * f32::from_bits((((n as i32) + 127) as u32) << 23)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ln_f32_matches_std() {
        let mut x = 1e-30f32;
        while x < 1e30 {
            let (a, b) = (ln_f32(x), x.ln());
            assert!((a - b).abs() <= 2e-7 * b.abs().max(1.0), "{x}: {a} {b}");
            x *= 1.37;
        }
        assert_eq!(ln_f32(1.0), 0.0);
    }

    use rand::{Rng, SeedableRng};

    /// A dispatched loop applying `$f` to a slice.
    macro_rules! simd_loop {
        ($name:ident, $f:expr) => {
            mod $name {
                #[allow(unused_imports)]
                use super::super::*;
                crate::simd::simd_dispatch!(pub fn run = body(xs: &[f64], out: &mut [f64]));
                #[inline(always)]
                fn body(xs: &[f64], out: &mut [f64]) {
                    for (o, &x) in out.iter_mut().zip(xs) {
                        *o = $f(x);
                    }
                }
            }
        };
    }

    /// Distance in ulps between two finite doubles of the same sign (or both zero).
    fn ulps(a: f64, b: f64) -> u64 {
        if a == b || (a.is_nan() && b.is_nan()) {
            return 0;
        }
        if a.is_sign_negative() != b.is_sign_negative() || !a.is_finite() || !b.is_finite() {
            return u64::MAX;
        }
        a.abs().to_bits().abs_diff(b.abs().to_bits())
    }

    fn rng() -> rand_chacha::ChaCha8Rng {
        rand_chacha::ChaCha8Rng::seed_from_u64(9)
    }

    /// Largest ulp distance from libm over `xs`, and the argument where it occurs.
    fn worst(
        xs: impl Iterator<Item = f64>,
        ours: impl Fn(f64) -> f64,
        libm: impl Fn(f64) -> f64,
    ) -> (u64, f64) {
        xs.map(|x| (ulps(ours(x), libm(x)), x))
            .max_by_key(|p| p.0)
            .unwrap()
    }

    #[test]
    fn exp_is_within_one_ulp_of_libm() {
        let mut r = rng();
        let xs = (0..400_000)
            .map(|i| match i % 4 {
                0 => r.random_range(-1.0..1.0),
                1 => r.random_range(-40.0..40.0),
                2 => r.random_range(-745.2..709.8),
                _ => r.random_range(-1e-8..1e-8),
            })
            .chain([
                0.0, -0.0, 709.78, 709.8, -708.4, -745.1, -745.2, -1000.0, 1000.0,
            ]);
        let (u, x) = worst(xs, exp, f64::exp);
        assert!(u <= 1, "exp({x}) is {u} ulp from libm");
        assert!(exp(f64::NAN).is_nan());
        assert_eq!(exp(f64::INFINITY), f64::INFINITY);
        assert_eq!(exp(f64::NEG_INFINITY), 0.0);
    }

    /// `exp_in_place` and `powf_lanes` give `exp`'s and `powf`'s bits, in a dispatched loop (so
    /// at the CPU's instruction set), for chunks in range (`exp_normal`) and chunks with one
    /// value out of range, ±∞ or NaN (the full `exp`).
    #[test]
    fn exp_in_place_and_powf_lanes_are_exp_and_powf_bit_for_bit() {
        mod lanes {
            crate::simd::simd_dispatch!(pub fn exp_run = exp_body(x: &mut [f64]));
            #[inline(always)]
            fn exp_body(x: &mut [f64]) {
                super::super::exp_in_place(x);
            }
            crate::simd::simd_dispatch!(pub fn pow_run = pow_body(x: &[f64], y: f64, out: &mut [f64]));
            #[inline(always)]
            fn pow_body(x: &[f64], y: f64, out: &mut [f64]) {
                super::super::powf_lanes(x, y, out);
            }
        }
        let mut r = rng();
        for i in 0..4000 {
            let n = 1 + i % 64;
            let mut xs: Vec<f64> = (0..n)
                .map(|k| match k % 3 {
                    0 => r.random_range(-1.0..1.0),
                    1 => r.random_range(-40.0..40.0),
                    _ => r.random_range(-708.0..=708.0),
                })
                .collect();
            if i % 4 == 1 {
                xs[n / 2] = [
                    708.0,
                    -708.0,
                    708.000_000_000_000_1,
                    -708.000_000_000_000_1,
                    709.8,
                    -745.0,
                    -746.0,
                    1e300,
                    f64::INFINITY,
                    f64::NEG_INFINITY,
                    f64::NAN,
                ][(i / 4) % 11];
            }
            let mut got = xs.clone();
            lanes::exp_run(&mut got);
            for (&x, &g) in xs.iter().zip(&got) {
                assert_eq!(g.to_bits(), exp(x).to_bits(), "exp_in_place({x})");
            }
            let y = [0.3, 0.0, -0.5, 1.0, 0.01][i % 5];
            let px: Vec<f64> = (0..n)
                .map(|k| match k % 4 {
                    0 => r.random_range(1e-4..=1.0),
                    1 => [0.0, 1.0, 1e-300, 1e300][(i / 5) % 4],
                    _ => r.random_range(0.0..10.0),
                })
                .collect();
            let mut out = vec![0.0; n];
            lanes::pow_run(&px, y, &mut out);
            for (&x, &g) in px.iter().zip(&out) {
                assert_eq!(g.to_bits(), powf(x, y).to_bits(), "powf_lanes({x}, {y})");
            }
        }
        // exp_normal's whole range: the same bits as exp
        for x in (0..200_000)
            .map(|_| r.random_range(-708.0..=708.0))
            .chain([708.0, -708.0])
        {
            assert_eq!(exp_normal(x).to_bits(), exp(x).to_bits(), "exp_normal({x})");
        }
    }

    #[test]
    fn ln_is_within_one_ulp_of_libm() {
        let mut r = rng();
        let xs = (0..400_000)
            .map(|i| match i % 4 {
                0 => r.random_range(0.5..2.0),
                1 => 1.0 + r.random_range(-1e-6..1e-6),
                2 => 10f64.powf(r.random_range(-300.0..300.0)),
                _ => f64::from_bits(r.random_range(1..1u64 << 52)), // subnormal
            })
            .chain([
                1.0,
                f64::MIN_POSITIVE,
                f64::MAX,
                std::f64::consts::SQRT_2,
                std::f64::consts::FRAC_1_SQRT_2,
            ]);
        let (u, x) = worst(xs, ln, f64::ln);
        assert!(u <= 1, "ln({x}) is {u} ulp from libm");
        assert_eq!(ln(0.0), f64::NEG_INFINITY);
        assert!(ln(-1.0).is_nan() && ln(f64::NAN).is_nan());
        assert_eq!(ln(f64::INFINITY), f64::INFINITY);
    }

    #[test]
    fn atan2_and_acos_are_within_two_ulp_of_libm() {
        let mut r = rng();
        let mut worst_u = (0, 0.0, 0.0);
        for i in 0..400_000 {
            let (y, x) = match i % 3 {
                0 => (r.random_range(-1.0..1.0), r.random_range(-1.0..1.0)),
                1 => (r.random_range(-1e-3..1e-3), r.random_range(-2.0..2.0)),
                _ => (r.random_range(-1e5..1e5), r.random_range(-1e-2..1e-2)),
            };
            let u = ulps(atan2(y, x), y.atan2(x));
            if u > worst_u.0 {
                worst_u = (u, y, x);
            }
        }
        assert!(
            worst_u.0 <= 2,
            "atan2{:?} is {} ulp from libm",
            (worst_u.1, worst_u.2),
            worst_u.0
        );
        for (y, x) in [
            (0.0, 0.0),
            (-0.0, 0.0),
            (0.0, -0.0),
            (-0.0, -0.0),
            (0.0, -1.0),
            (-0.0, -1.0),
            (1.0, 0.0),
            (-1.0, -0.0),
        ] {
            assert_eq!(
                atan2(y, x).to_bits(),
                y.atan2(x).to_bits(),
                "atan2({y}, {x})"
            );
        }
        assert!(atan2(f64::NAN, 1.0).is_nan() && atan2(1.0, f64::NAN).is_nan());
        let xs = (0..200_000)
            .map(|i| match i % 2 {
                0 => r.random_range(-1.0..=1.0),
                _ => 1.0 - r.random_range(0.0..1e-6),
            })
            .chain([-1.0, 1.0, 0.0, -0.0, 0.5, -0.5]);
        let (u, x) = worst(xs, acos, f64::acos);
        assert!(u <= 2, "acos({x}) is {u} ulp from libm");
        assert!(acos(1.0 + 1e-15).is_nan() && acos(-2.0).is_nan());
    }

    #[test]
    fn powf_is_within_its_bound_of_libm() {
        let mut r = rng();
        for _ in 0..300_000 {
            let x: f64 = r.random_range(1e-4..=1.0);
            let y: f64 = r.random_range(0.0..=1.0);
            let bound = 2 + (y * x.ln()).abs().ceil() as u64;
            let u = ulps(powf(x, y), x.powf(y));
            assert!(
                u <= bound,
                "powf({x}, {y}) is {u} ulp from libm (bound {bound})"
            );
        }
        assert_eq!(powf(0.0, 0.3), 0.0);
        assert_eq!(powf(0.0, 0.0), 1.0);
        assert_eq!(powf(1.0, 0.37), 1.0);
        assert_eq!(powf(0.0, -1.0), f64::INFINITY);
        assert!(powf(-0.5, 0.5).is_nan());
    }

    #[test]
    fn hypot_is_within_one_ulp_of_libm() {
        let mut r = rng();
        let mut worst_u = 0;
        for i in 0..300_000 {
            let s = [1.0, 1e200, 1e-200, 1e300][i % 4];
            let (x, y): (f64, f64) = (r.random_range(-1.0..1.0) * s, r.random_range(-1.0..1.0) * s);
            worst_u = worst_u.max(ulps(hypot(x, y), x.hypot(y)));
        }
        assert!(worst_u <= 1, "hypot is {worst_u} ulp from libm");
        assert_eq!(hypot(0.0, 0.0), 0.0);
        assert_eq!(hypot(f64::INFINITY, f64::NAN), f64::INFINITY);
        assert!(hypot(f64::NAN, 1.0).is_nan());
    }

    /// Most arguments give libm's value bit for bit in a dispatched loop (74-99 % when measured;
    /// the ulp bounds are tested above). Speed: `cargo bench --bench sky`.
    #[test]
    fn most_values_are_libms() {
        simd_loop!(exp_loop, exp);
        simd_loop!(ln_loop, ln);
        simd_loop!(acos_loop, acos);
        simd_loop!(pow_loop, |x| powf(x, 0.3));
        simd_loop!(atan2_loop, |x| atan2(x, 0.7));
        simd_loop!(hypot_loop, |x| hypot(x, 0.7));
        let mut r = rng();
        let n = 1 << 16;
        let mut xs =
            |lo: f64, hi: f64| -> Vec<f64> { (0..n).map(|_| r.random_range(lo..hi)).collect() };
        type Loop = fn(&[f64], &mut [f64]);
        type Case = (&'static str, Vec<f64>, Loop, fn(f64) -> f64);
        let cases: [Case; 6] = [
            ("exp", xs(-20.0, 5.0), exp_loop::run, f64::exp),
            ("ln", xs(1e-3, 10.0), ln_loop::run, f64::ln),
            ("acos", xs(-1.0, 1.0), acos_loop::run, f64::acos),
            ("powf(x, 0.3)", xs(1e-3, 1.0), pow_loop::run, |x| {
                x.powf(0.3)
            }),
            ("atan2(x, 0.7)", xs(-3.0, 3.0), atan2_loop::run, |x| {
                x.atan2(0.7)
            }),
            ("hypot(x, 0.7)", xs(-3.0, 3.0), hypot_loop::run, |x| {
                x.hypot(0.7)
            }),
        ];
        for (name, xs, ours, libm) in cases {
            let mut a = vec![0.0; n];
            ours(&xs, &mut a);
            let same = a
                .iter()
                .zip(&xs)
                .filter(|(p, &x)| p.to_bits() == libm(x).to_bits())
                .count();
            let share = same as f64 / n as f64;
            assert!(share > 0.7, "{name}: {:.1} % equal to libm", 100.0 * share);
        }
    }
}
