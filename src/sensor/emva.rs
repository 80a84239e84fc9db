//! Photon-transfer analysis after EMVA 1288 (Release 3.1, §6; same method in 4.0 "linear"),
//! used to check the emulator against its configuration.
//!
//! For every exposure level a pair of flat-field frames A, B is taken:
//!
//! * mean μ_y = ½ (⟨y_A⟩ + ⟨y_B⟩);
//! * temporal variance σ²_y = 1/(2N) Σ [(y_A − ⟨y_A⟩) − (y_B − ⟨y_B⟩)]² — the difference
//!   removes every fixed pattern (PRNU, DSNU, RI);
//! * the dark pair (no light) gives μ_y.dark and σ²_y.dark.
//!
//! Then
//!
//! * saturation: the level of maximum temporal variance; μ_y.sat is its mean;
//! * system gain K (DN/e⁻): least-squares slope of σ²_y − σ²_y.dark against μ_y − μ_y.dark,
//!   a line through the origin, over the levels with μ_y − μ_y.dark ≤ 70 % of μ_y.sat − μ_y.dark
//!   (the linear range);
//! * temporal dark noise σ_d = √(σ²_y.dark − 1/12 DN²) / K (quantisation noise removed);
//! * saturation capacity μ_e.sat = (μ_y.sat − μ_y.dark) / K.

use crate::error::{Error, Result};

/// Mean and temporal variance of one frame pair, DN.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PairStats {
    /// μ_y = ½ (⟨y_A⟩ + ⟨y_B⟩).
    pub mean: f64,
    /// σ²_y from the pair difference.
    pub var: f64,
}

/// Statistics of a frame pair (equal lengths, at least 2 pixels).
pub fn pair_stats(a: &[u16], b: &[u16]) -> Result<PairStats> {
    if a.len() != b.len() || a.len() < 2 {
        return Err(Error::Invalid(format!(
            "frame pair sizes {} and {} differ or are too small",
            a.len(),
            b.len()
        )));
    }
    let n = a.len() as f64;
    let ma = a.iter().map(|&v| v as f64).sum::<f64>() / n;
    let mb = b.iter().map(|&v| v as f64).sum::<f64>() / n;
    let ss: f64 = a
        .iter()
        .zip(b)
        .map(|(&x, &y)| {
            let d = (x as f64 - ma) - (y as f64 - mb);
            d * d
        })
        .sum();
    Ok(PairStats {
        mean: 0.5 * (ma + mb),
        var: ss / (2.0 * n),
    })
}

/// Result of [`photon_transfer`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PhotonTransfer {
    /// System gain K, DN/e⁻.
    pub k: f64,
    /// Temporal dark noise σ_d, e⁻.
    pub dark_noise_e: f64,
    /// Saturation capacity μ_e.sat, e⁻.
    pub saturation_e: f64,
    /// μ_y.sat, DN.
    pub saturation_mean_dn: f64,
    /// Number of levels in the gain fit.
    pub fit_points: usize,
}

/// EMVA 1288 photon-transfer evaluation of a dark pair and the illuminated pairs.
pub fn photon_transfer(dark: PairStats, levels: &[PairStats]) -> Result<PhotonTransfer> {
    if levels.len() < 3 {
        return Err(Error::Invalid(format!(
            "photon transfer needs at least 3 illuminated levels, got {}",
            levels.len()
        )));
    }
    let sat = levels
        .iter()
        .max_by(|a, b| a.var.total_cmp(&b.var))
        .expect("non-empty");
    let limit = 0.7 * (sat.mean - dark.mean);
    let (mut sxy, mut sxx, mut n) = (0.0, 0.0, 0usize);
    for p in levels {
        let x = p.mean - dark.mean;
        if x > 0.0 && x <= limit {
            let y = p.var - dark.var;
            sxy += x * y;
            sxx += x * x;
            n += 1;
        }
    }
    if n < 2 || sxx <= 0.0 {
        return Err(Error::Invalid(format!(
            "only {n} levels in the linear range (up to 70 % of saturation)"
        )));
    }
    let k = sxy / sxx;
    let dark_noise_e = (dark.var - 1.0 / 12.0).max(0.0).sqrt() / k;
    Ok(PhotonTransfer {
        k,
        dark_noise_e,
        saturation_e: (sat.mean - dark.mean) / k,
        saturation_mean_dn: sat.mean,
        fit_points: n,
    })
}
