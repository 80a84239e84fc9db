//! Stability statistics of the sky DOP (and the AOP's continuity in sun position) on a grid of
//! directions.
//!
//! For one scene (turbidity, sun zenith, wavelength and the rest of [`SkyParams`]) the DOP is
//! evaluated on a grid of view directions above the horizon, zenith 1°, 3°, …, 89° (step 2°)
//! × azimuth 0°, 4°, …, 356° (4050 directions by default), with the sun at azimuth 0 (the field
//! is covariant under a rotation of the sun's azimuth). Counted:
//!
//! * **pinned low**: DOP ≤ 0.001 among the directions 40°…140° from the sun (where the four
//!   neutral points and the sun are not, for neutral-point distances up to 40°);
//! * **pinned high**: DOP ≥ 0.95 anywhere (the Rayleigh limit for air is about 0.94);
//! * **max jump**: the largest |ΔDOP| between neighbouring directions 2° apart in zenith angle
//!   (same azimuth);
//! * **AOP shift**: the median over the directions of the axial AOP change when the sun sinks
//!   by [`AOP_SUN_STEP_DEG`] (rises, at the horizon). A continuous model moves by about that
//!   step; a model that turns every angle by 90° at some sun position (pyskylumos 0.1.3's
//!   Berry and asymmetric skies, `docs/sky.md`) shows 90° in the cell where it does.
//!
//! Pure: no files, no allocation beyond the result.

use super::{direction, PolarizationField, SkyParams, SunPosition};
use crate::error::Result;

/// DOP at or below which a direction counts as pinned low.
pub const PINNED_LOW: f64 = 0.001;
/// DOP at or above which a direction counts as pinned high.
pub const PINNED_HIGH: f64 = 0.95;
/// Scattering angles (degrees from the sun) where a low DOP counts as pinned.
pub const LOW_GAMMA_DEG: (f64, f64) = (40.0, 140.0);
/// Largest acceptable DOP change between directions 2° apart in zenith.
pub const MAX_JUMP: f64 = 0.15;
/// Sun step of the AOP-shift statistic, degrees of zenith angle.
pub const AOP_SUN_STEP_DEG: f64 = 0.5;
/// Median AOP shift (degrees) above which a cell counts as an AOP flip.
pub const MAX_AOP_SHIFT_DEG: f64 = 10.0;

/// Direction grid: zenith from `zenith_step/2` in steps of `zenith_step_deg` below 90°,
/// azimuth from 0 in steps of `azimuth_step_deg`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Grid {
    /// Zenith step, degrees (the jump statistic compares neighbours this far apart).
    pub zenith_step_deg: f64,
    /// Azimuth step, degrees.
    pub azimuth_step_deg: f64,
}

impl Default for Grid {
    /// 2° in zenith × 4° in azimuth: 45 × 90 = 4050 directions.
    fn default() -> Self {
        Grid {
            zenith_step_deg: 2.0,
            azimuth_step_deg: 4.0,
        }
    }
}

impl Grid {
    fn zeniths(&self) -> impl Iterator<Item = f64> + '_ {
        let n = (90.0 / self.zenith_step_deg).floor() as usize;
        (0..n).map(move |i| (i as f64 + 0.5) * self.zenith_step_deg)
    }

    fn azimuths(&self) -> impl Iterator<Item = f64> + '_ {
        let n = (360.0 / self.azimuth_step_deg).round() as usize;
        (0..n).map(move |j| j as f64 * self.azimuth_step_deg)
    }
}

/// Stability statistics of one scene's DOP.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Stability {
    /// Directions evaluated.
    pub directions: usize,
    /// Directions 40°…140° from the sun.
    pub mid_directions: usize,
    /// Of those, DOP ≤ [`PINNED_LOW`].
    pub pinned_low: usize,
    /// Directions with DOP ≥ [`PINNED_HIGH`].
    pub pinned_high: usize,
    /// Largest |ΔDOP| between directions one zenith step apart.
    pub max_jump: f64,
    /// Neighbour pairs with |ΔDOP| > [`MAX_JUMP`].
    pub jumps: usize,
    /// Neighbour pairs compared.
    pub pairs: usize,
    /// Largest DOP on the grid.
    pub max_dop: f64,
    /// Median axial AOP change, degrees, over the directions polarized at both sun positions,
    /// when the sun's zenith angle changes by [`AOP_SUN_STEP_DEG`].
    pub median_aop_shift_deg: f64,
}

impl Stability {
    /// Fraction of the directions 40°…140° from the sun pinned low.
    pub fn low_fraction(&self) -> f64 {
        self.pinned_low as f64 / self.mid_directions.max(1) as f64
    }

    /// Fraction of all directions pinned high.
    pub fn high_fraction(&self) -> f64 {
        self.pinned_high as f64 / self.directions.max(1) as f64
    }

    /// True when nothing is pinned and no jump exceeds [`MAX_JUMP`].
    pub fn is_stable(&self) -> bool {
        self.pinned_low == 0 && self.pinned_high == 0 && self.jumps == 0
    }

    /// True when the AOP turns as a whole with a small move of the sun (median shift above
    /// [`MAX_AOP_SHIFT_DEG`]).
    pub fn aop_flips(&self) -> bool {
        self.median_aop_shift_deg > MAX_AOP_SHIFT_DEG
    }
}

/// Stability statistics of the DOP for `params` (its turbidity, wavelength, model …) with the
/// sun at `sun_zenith_deg` (0..90), on `grid`. Errors as [`PolarizationField::new`].
pub fn stability(sun_zenith_deg: f64, params: &SkyParams, grid: Grid) -> Result<Stability> {
    let sun = SunPosition::new(sun_zenith_deg, 0.0);
    let field = PolarizationField::new(sun, params)?;
    let z2 = if sun_zenith_deg + AOP_SUN_STEP_DEG <= 90.0 {
        sun_zenith_deg + AOP_SUN_STEP_DEG
    } else {
        sun_zenith_deg - AOP_SUN_STEP_DEG
    };
    let moved = PolarizationField::new(SunPosition::new(z2, 0.0), params)?;
    let s = sun.vector();
    let mut st = Stability::default();
    let mut shifts = Vec::with_capacity(4096);
    for a in grid.azimuths() {
        let mut prev: Option<f64> = None;
        for z in grid.zeniths() {
            let v = direction(z, a);
            let here = field.sample(v);
            let d = here.dop;
            let there = moved.sample(v);
            if d > 0.0 && there.dop > 0.0 {
                let x = super::aop_chart_deg(v, here.e) - super::aop_chart_deg(v, there.e);
                let x = x.rem_euclid(180.0);
                shifts.push(x.min(180.0 - x));
            }
            st.directions += 1;
            st.max_dop = st.max_dop.max(d);
            let gamma = v.dot(s).clamp(-1.0, 1.0).acos().to_degrees();
            if (LOW_GAMMA_DEG.0..=LOW_GAMMA_DEG.1).contains(&gamma) {
                st.mid_directions += 1;
                if d <= PINNED_LOW {
                    st.pinned_low += 1;
                }
            }
            if d >= PINNED_HIGH {
                st.pinned_high += 1;
            }
            if let Some(p) = prev {
                let j = (d - p).abs();
                st.pairs += 1;
                st.max_jump = st.max_jump.max(j);
                if j > MAX_JUMP {
                    st.jumps += 1;
                }
            }
            prev = Some(d);
        }
    }
    if !shifts.is_empty() {
        shifts.sort_by(f64::total_cmp);
        st.median_aop_shift_deg = shifts[shifts.len() / 2];
    }
    Ok(st)
}

/// One cell of a stability map.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MapCell {
    /// Turbidity.
    pub turbidity: f64,
    /// Sun zenith, degrees.
    pub sun_zenith_deg: f64,
    /// Wavelength, nm.
    pub wavelength_nm: f64,
    /// The statistics.
    pub stats: Stability,
}

/// Stability over turbidity × sun zenith × wavelength (all other parameters from `base`), in
/// that nesting order (wavelength innermost). The first error (a value out of range) is returned.
pub fn stability_map(
    base: &SkyParams,
    turbidities: &[f64],
    sun_zeniths_deg: &[f64],
    wavelengths_nm: &[f64],
    grid: Grid,
) -> Result<Vec<MapCell>> {
    let mut out =
        Vec::with_capacity(turbidities.len() * sun_zeniths_deg.len() * wavelengths_nm.len());
    for &t in turbidities {
        for &z in sun_zeniths_deg {
            for &w in wavelengths_nm {
                let p = SkyParams {
                    turbidity: t,
                    wavelength_nm: w,
                    ..base.clone()
                };
                out.push(MapCell {
                    turbidity: t,
                    sun_zenith_deg: z,
                    wavelength_nm: w,
                    stats: stability(z, &p, grid)?,
                });
            }
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sky::PolarizationModel;

    #[test]
    fn default_grid_has_4050_directions() {
        let st = stability(50.0, &SkyParams::default(), Grid::default()).unwrap();
        assert_eq!(st.directions, 4050);
        assert_eq!(st.pairs, 44 * 90);
        assert!(st.mid_directions > 1000 && st.mid_directions < 4050);
    }

    #[test]
    fn default_scene_is_stable() {
        let st = stability(50.0, &SkyParams::default(), Grid::default()).unwrap();
        assert!(st.is_stable(), "{st:?}");
        assert!(st.max_dop > 0.5 && st.max_dop < 0.6);
    }

    #[test]
    fn rayleigh_counts_match_hand_values() {
        // Rayleigh with DOP_max 1: DOP ≥ 0.95 where sin²γ/(1+cos²γ) ≥ 0.95, i.e.
        // cos²γ ≤ 0.05/1.95, |γ − 90°| ≤ 9.2°; never ≤ 0.001 at 40..140°.
        let p = SkyParams {
            model: PolarizationModel::Rayleigh,
            ..SkyParams::default()
        };
        let st = stability(0.0, &p, Grid::default()).unwrap();
        assert_eq!(st.pinned_low, 0);
        // sun at the zenith: γ = θ, so θ = 81°, 83°, …, 89° (5 rings × 90 azimuths)
        assert_eq!(st.pinned_high, 5 * 90);
        assert!(st.max_jump < 0.1);
    }

    #[test]
    fn map_order_and_errors() {
        let m = stability_map(
            &SkyParams::default(),
            &[3.0, 4.0],
            &[30.0],
            &[450.0, 500.0],
            Grid {
                zenith_step_deg: 10.0,
                azimuth_step_deg: 30.0,
            },
        )
        .unwrap();
        assert_eq!(m.len(), 4);
        assert_eq!((m[1].turbidity, m[1].wavelength_nm), (3.0, 500.0));
        assert_eq!(m[2].turbidity, 4.0);
        assert!(stability(95.0, &SkyParams::default(), Grid::default()).is_err());
    }
}
