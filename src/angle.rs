//! Angle types that carry their reference axis, so conventions cannot be mixed up silently.
//!
//! * [`SensorAngle`]: an axial angle (period 180°) in the focal plane, measured from +x (increasing
//!   column) toward +y (increasing row, i.e. down on a displayed image), wrapped to [0°, 180°).
//!   AoP/AoLP images, the polarizer pass axes of the mosaic and the demosaic output all use it.
//! * [`CompassAzimuth`]: a direction on the horizon, degrees from north, clockwise seen from above,
//!   wrapped to [0°, 360°).

/// Axial angle in the sensor plane, degrees from +x (columns) toward +y (rows, down), in [0, 180).
///
/// ```
/// use psns::angle::SensorAngle;
/// assert_eq!(SensorAngle::from_deg(-30.0).deg(), 150.0);
/// assert_eq!(SensorAngle::from_deg(180.0).deg(), 0.0);
/// // from a Stokes pair: AoLP = ½ atan2(S2, S1)
/// let a = SensorAngle::from_stokes(0.0, 1.0);
/// assert!((a.deg() - 45.0).abs() < 1e-12);
/// // axial difference is at most 90°
/// assert!((SensorAngle::from_deg(179.0).diff(SensorAngle::from_deg(1.0)) - 2.0).abs() < 1e-12);
/// ```
#[derive(Clone, Copy, Debug, PartialEq, PartialOrd)]
pub struct SensorAngle(f64);

impl SensorAngle {
    /// Wraps any angle in degrees to [0, 180).
    #[inline]
    pub fn from_deg(deg: f64) -> Self {
        // |deg| < 180 (every AoLP from an atan2): rem_euclid's fmod returns deg itself, so this is
        // its value without the call
        if (0.0..180.0).contains(&deg) {
            return SensorAngle(deg);
        }
        if deg > -180.0 && deg < 0.0 {
            let a = deg + 180.0;
            return SensorAngle(if a >= 180.0 { 0.0 } else { a });
        }
        let mut a = deg.rem_euclid(180.0);
        if a >= 180.0 {
            a = 0.0; // rem_euclid can round up to the modulus
        }
        SensorAngle(a)
    }

    /// Angle of linear polarization of a sensor-frame Stokes pair, ½ atan2(S2, S1).
    #[inline]
    pub fn from_stokes(s1: f64, s2: f64) -> Self {
        Self::from_deg(0.5 * s2.atan2(s1).to_degrees())
    }

    /// Degrees in [0, 180).
    #[inline]
    pub fn deg(self) -> f64 {
        self.0
    }

    /// Radians in [0, π).
    #[inline]
    pub fn rad(self) -> f64 {
        self.0.to_radians()
    }

    /// Smallest axial difference |a − b| mod 180, in [0, 90].
    #[inline]
    pub fn diff(self, other: SensorAngle) -> f64 {
        let d = (self.0 - other.0).rem_euclid(180.0);
        d.min(180.0 - d)
    }
}

/// Compass azimuth: degrees from north, clockwise seen from above, in [0, 360).
///
/// ```
/// use psns::angle::CompassAzimuth;
/// assert_eq!(CompassAzimuth::from_deg(-90.0).deg(), 270.0);
/// // unit vector in ENU (x east, y north): azimuth 90° points east
/// let (e, n) = CompassAzimuth::from_deg(90.0).east_north();
/// assert!((e - 1.0).abs() < 1e-12 && n.abs() < 1e-12);
/// ```
#[derive(Clone, Copy, Debug, PartialEq, PartialOrd)]
pub struct CompassAzimuth(f64);

impl CompassAzimuth {
    /// Wraps any angle in degrees to [0, 360).
    #[inline]
    pub fn from_deg(deg: f64) -> Self {
        let mut a = deg.rem_euclid(360.0);
        if a >= 360.0 {
            a = 0.0;
        }
        CompassAzimuth(a)
    }

    /// Degrees in [0, 360).
    #[inline]
    pub fn deg(self) -> f64 {
        self.0
    }

    /// (east, north) components of the horizontal unit vector: (sin A, cos A).
    #[inline]
    pub fn east_north(self) -> (f64, f64) {
        let a = self.0.to_radians();
        (a.sin(), a.cos())
    }
}

/// Wraps an axial angle in degrees to (−90, 90], the convention of the spec's reference tables.
///
/// ```
/// assert_eq!(psns::angle::wrap_pm90(-90.0), 90.0);
/// assert_eq!(psns::angle::wrap_pm90(100.0), -80.0);
/// ```
#[inline]
pub fn wrap_pm90(deg: f64) -> f64 {
    let a = SensorAngle::from_deg(deg).deg(); // [0, 180)
    if a > 90.0 {
        a - 180.0
    } else {
        a
    }
}

/// Unit view vector in ENU for zenith angle θ and compass azimuth A (degrees):
/// v = (sin θ sin A, sin θ cos A, cos θ).
///
/// ```
/// let v = psns::angle::direction(90.0, 0.0);
/// assert!((v.y - 1.0).abs() < 1e-12); // north on the horizon
/// ```
pub fn direction(zenith_deg: f64, azimuth_deg: f64) -> glam::DVec3 {
    let (st, ct) = zenith_deg.to_radians().sin_cos();
    let (sa, ca) = azimuth_deg.to_radians().sin_cos();
    glam::DVec3::new(st * sa, st * ca, ct)
}

/// Zenith angle and compass azimuth (degrees) of a unit ENU vector; azimuth in [0, 360).
pub fn zenith_azimuth_deg(v: glam::DVec3) -> (f64, f64) {
    let z = v.z.clamp(-1.0, 1.0).acos().to_degrees();
    let a = CompassAzimuth::from_deg(v.x.atan2(v.y).to_degrees()).deg();
    (z, a)
}

#[cfg(test)]
mod tests {
    use super::SensorAngle;

    /// The wrap as it was written before the fast path: rem_euclid, 180 folded to 0.
    fn reference(deg: f64) -> f64 {
        let a = deg.rem_euclid(180.0);
        if a >= 180.0 {
            0.0
        } else {
            a
        }
    }

    #[test]
    fn from_deg_is_rem_euclid_bit_for_bit() {
        let mut vals = vec![
            0.0,
            -0.0,
            1e-300,
            -1e-300,
            -1e-20,
            -f64::EPSILON,
            90.0,
            -90.0,
            179.999_999_999_999_97,
            180.0,
            -180.0,
            -179.999_999_999_999_97,
            359.5,
            -725.25,
            1e17,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ];
        // a dense sweep of (−360, 360) with awkward fractions
        vals.extend((-720_000..720_000).map(|k| k as f64 * 0.000_5 + 1e-9 * (k % 7) as f64));
        for v in vals {
            let (got, want) = (SensorAngle::from_deg(v).deg(), reference(v));
            assert_eq!(got.to_bits(), want.to_bits(), "{v:e}: {got:e} vs {want:e}");
        }
        assert!(SensorAngle::from_deg(f64::NAN).deg().is_nan());
    }
}
