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
#[inline]
pub fn quantize(v: f64, max: u16) -> u16 {
    if v.is_nan() || v <= 0.0 {
        0
    } else {
        v.round().min(max as f64) as u16
    }
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
}
