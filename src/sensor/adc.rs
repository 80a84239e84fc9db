//! Gain, black level and the ADC (`sensor.md` §6 stages 10–12).
//!
//! v = K₀ 10^(g/20) n + b in 12-bit DN (K₀ = 4095/10 500 DN/e⁻ at 0 dB), then the ADC rounds to the
//! nearest code of the output depth and clips to [0, 2^bits − 1]. An output depth below 12 bit is
//! modelled as an ADC of that depth: the 12-bit value is scaled by 2^(bits − 12) before rounding
//! (so 8-bit output is v/16 rounded, not truncated, and the ground truth scales the same way).

/// System gain in 12-bit DN per electron: K₀ · 10^(g/20).
#[inline]
pub fn system_gain(k0: f64, gain_db: f64) -> f64 {
    k0 * 10f64.powf(gain_db / 20.0)
}

/// Factor from 12-bit DN to output DN, 2^(bits − 12).
#[inline]
pub fn output_scale(bit_depth: u8) -> f64 {
    2f64.powi(bit_depth as i32 - 12)
}

/// Largest code of the output depth, 2^bits − 1.
#[inline]
pub fn max_code(bit_depth: u8) -> u16 {
    ((1u32 << bit_depth) - 1) as u16
}

/// Round to nearest and clip to [0, max]; NaN maps to 0.
#[inline(always)]
pub fn quantize(v: f64, max: u16) -> u16 {
    // branch-free (row loops vectorise) and without libm's round: `image::round_clamp`
    crate::image::round_clamp(v, max as f64) as u16
}

#[cfg(test)]
mod tests {
    use super::*;
    #[test]
    fn adc_basics() {
        assert_eq!(max_code(12), 4095);
        assert_eq!(max_code(8), 255);
        assert_eq!(quantize(4095.6, 4095), 4095);
        assert_eq!(quantize(1e30, 4095), 4095);
        assert_eq!(quantize(-3.0, 4095), 0);
        assert_eq!(quantize(f64::NAN, 255), 0);
        assert_eq!(quantize(2.5, 255), 3);
        assert!((system_gain(0.39, 48.0) / 0.39 - 251.19).abs() < 0.01);
        assert_eq!(output_scale(8), 1.0 / 16.0);
    }

    /// The branch-free rounding is f64::round clipped, bit for bit, at halves, just below and
    /// above them, near the top code and over a wide random range.
    #[test]
    fn quantize_is_round_half_away_clipped() {
        let old = |v: f64, max: u16| {
            if v.is_nan() || v <= 0.0 {
                0
            } else {
                v.round().min(max as f64) as u16
            }
        };
        let mut vals = vec![
            0.5, 1.5, 254.5, 255.5, 4094.5, 4095.5, 65534.5, 65535.0, 70000.0,
        ];
        for k in 0..5000u32 {
            let h = k as f64 + 0.5;
            let (down, up) = (
                f64::from_bits(h.to_bits() - 1),
                f64::from_bits(h.to_bits() + 1),
            );
            vals.extend([h, down, up, k as f64]);
        }
        let mut x = 0x9e37_79b9_7f4a_7c15u64;
        for _ in 0..200_000 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            vals.push((x >> 11) as f64 / (1u64 << 53) as f64 * 70_000.0);
        }
        for &v in &vals {
            for max in [255u16, 1023, 4095, 65535] {
                assert_eq!(quantize(v, max), old(v, max), "v = {v}, max = {max}");
            }
        }
    }
}
