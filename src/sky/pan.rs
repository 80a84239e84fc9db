//! Neutral points that move with the sun: Pan et al.'s measured law (Opt. Express 31:15189, 2023).
//!
//! Pan, Wang, Yang, Pu, Wang, Bao & Gao regressed the angular distances of the Babinet point
//! (above the sun) and the Brewster point (below it) on the solar elevation e (degrees), from
//! all-sky polarization images over e = 0…64° (their eqs. (25), (26)):
//!
//! * Babinet: δ_Ba = 42.53 − 0.56 e;
//! * Brewster: δ_Br = 37.34 + 0.49 e for e ≤ 27°, 56.84 − 0.25 e above.
//!
//! The Brewster fit is piecewise: its branches differ by 0.48° at 27° (50.57° below, 50.09°
//! above; the breakpoint takes the lower branch), a step in the law itself that moves the AOP
//! near the Brewster point by a fraction of a degree as the sun passes 27°.
//!
//! **Outside the fit** psns holds the distances at the values of the nearest end of the
//! measured range: below e = 0 (a sun below the horizon is not rendered) the e = 0 values, above
//! e = 64° the e = 64° values, Babinet 6.69° and Brewster 40.84°. The distances therefore stay
//! continuous and the Babinet point stays above the sun up to e = 90°. Extrapolating the lines,
//! as pyskylumos 0.1.3 does, would take the Babinet distance through zero at e = 75.95° and
//! put the "Babinet" point below the sun.

/// Solar elevations covered by the fit, degrees.
pub const FIT_RANGE_DEG: (f64, f64) = (0.0, 64.0);
/// Elevation where the Brewster fit changes branch, degrees.
pub const BREWSTER_BREAK_DEG: f64 = 27.0;

/// The solar elevation the law uses: `elevation_deg` clamped to [`FIT_RANGE_DEG`].
#[inline]
pub fn law_elevation(elevation_deg: f64) -> f64 {
    elevation_deg.clamp(FIT_RANGE_DEG.0, FIT_RANGE_DEG.1)
}

/// Babinet distance above the sun, degrees, at solar elevation `elevation_deg` (eq. (26),
/// held constant outside 0…64°).
///
/// ```
/// use psns::sky::pan::babinet_deg;
/// assert!((babinet_deg(0.0) - 42.53).abs() < 1e-12);
/// assert!((babinet_deg(64.0) - 6.69).abs() < 1e-12);
/// assert_eq!(babinet_deg(80.0), babinet_deg(64.0));
/// ```
pub fn babinet_deg(elevation_deg: f64) -> f64 {
    42.53 - 0.56 * law_elevation(elevation_deg)
}

/// Brewster distance below the sun, degrees, at solar elevation `elevation_deg` (eq. (25),
/// held constant outside 0…64°).
///
/// ```
/// use psns::sky::pan::brewster_deg;
/// assert!((brewster_deg(27.0) - 50.57).abs() < 1e-12);
/// assert!((brewster_deg(64.0) - 40.84).abs() < 1e-12);
/// ```
pub fn brewster_deg(elevation_deg: f64) -> f64 {
    let e = law_elevation(elevation_deg);
    if e <= BREWSTER_BREAK_DEG {
        37.34 + 0.49 * e
    } else {
        56.84 - 0.25 * e
    }
}

/// (Babinet, Brewster) distances, degrees, for a sun at zenith angle `sun_zenith_deg`.
pub fn distances(sun_zenith_deg: f64) -> (f64, f64) {
    let e = 90.0 - sun_zenith_deg;
    (babinet_deg(e), brewster_deg(e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn law_is_continuous_but_for_the_brewster_break() {
        let mut prev = distances(90.0);
        for i in 1..=9000 {
            let z = 90.0 - i as f64 * 0.01;
            let d = distances(z);
            let e = 90.0 - z;
            let step_br = (d.1 - prev.1).abs();
            assert!((d.0 - prev.0).abs() <= 0.56 * 0.01 + 1e-9);
            if (e - 27.01).abs() < 1e-6 {
                // the published fit's own step
                assert!((step_br - (0.48 + 0.25 * 0.01)).abs() < 1e-9, "{step_br}");
            } else {
                assert!(step_br <= 0.49 * 0.01 + 1e-9, "{e}: {step_br}");
            }
            prev = d;
        }
    }
}
