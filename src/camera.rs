//! Pinhole camera: pixel rays, attitude and the projection of the sky's E-vector onto the sensor.
//!
//! Frames (`sky.md` §1, §7): world ENU n (x east, y north, z up); solar-azimuth frame a (y toward
//! the sun's azimuth, z up); camera frame c with +z the optical axis, +x increasing column, +y
//! increasing row (image down). Attitude is yaw ψ, pitch ϑ, roll φ with
//! C_r^c = R_y(φ) R_x(ϑ) R_z(ψ) (PSNS eqs. (11)–(13)); v_c = C_r^c v_r. At zero attitude the camera
//! looks at the zenith with +x toward x_r and +y toward y_r, so the image is the sky seen from
//! below (a mirror of a map). C_n^c = C_a^c R_z(A_s), i.e. ψ_n = ψ_a + A_s.

use crate::error::{check_positive, check_range, Error, Result};
use glam::{DMat3, DQuat, DVec3};
use serde::{Deserialize, Serialize};

/// Reference frame of a yaw/pitch/roll attitude.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum AttitudeFrame {
    /// Solar-azimuth frame a: yaw measured from the sun's azimuth.
    #[default]
    Solar,
    /// East-North-Up: yaw measured from north.
    Enu,
}

/// Camera orientation.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum Attitude {
    /// Yaw ψ, pitch ϑ, roll φ in degrees relative to `frame`.
    Euler {
        /// Reference frame.
        frame: AttitudeFrame,
        /// Yaw ψ, degrees.
        yaw_deg: f64,
        /// Pitch ϑ, degrees.
        pitch_deg: f64,
        /// Roll φ, degrees.
        roll_deg: f64,
    },
    /// Hamilton quaternion (w, x, y, z) rotating camera-frame vectors into `frame`.
    Quaternion {
        /// Reference frame.
        frame: AttitudeFrame,
        /// w, x, y, z.
        wxyz: [f64; 4],
    },
}

impl Default for Attitude {
    fn default() -> Self {
        Attitude::Euler {
            frame: AttitudeFrame::Solar,
            yaw_deg: 0.0,
            pitch_deg: 0.0,
            roll_deg: 0.0,
        }
    }
}

/// R_z(ψ) of `sky.md` §7 (a frame rotation about z).
pub fn rot_z(a: f64) -> DMat3 {
    let (s, c) = a.sin_cos();
    DMat3::from_cols(
        DVec3::new(c, s, 0.0),
        DVec3::new(-s, c, 0.0),
        DVec3::new(0.0, 0.0, 1.0),
    )
}

/// R_x(ϑ) of `sky.md` §7.
pub fn rot_x(a: f64) -> DMat3 {
    let (s, c) = a.sin_cos();
    DMat3::from_cols(
        DVec3::new(1.0, 0.0, 0.0),
        DVec3::new(0.0, c, -s),
        DVec3::new(0.0, s, c),
    )
}

/// R_y(φ) of `sky.md` §7.
pub fn rot_y(a: f64) -> DMat3 {
    let (s, c) = a.sin_cos();
    DMat3::from_cols(
        DVec3::new(c, 0.0, s),
        DVec3::new(0.0, 1.0, 0.0),
        DVec3::new(-s, 0.0, c),
    )
}

/// C_r^c = R_y(φ) R_x(ϑ) R_z(ψ), angles in degrees.
pub fn euler_matrix(yaw_deg: f64, pitch_deg: f64, roll_deg: f64) -> DMat3 {
    rot_y(roll_deg.to_radians()) * rot_x(pitch_deg.to_radians()) * rot_z(yaw_deg.to_radians())
}

/// How far from 1 a quaternion's norm may be: four decimals, as users type them
/// (`0.7071,0,0,0.7071` has norm 0.99999). Within it the quaternion is normalised.
pub const QUATERNION_TOLERANCE: f64 = 1e-3;

impl Attitude {
    /// The same attitude with a quaternion scaled to unit norm (Euler angles unchanged).
    pub fn normalized(&self) -> Self {
        match *self {
            Attitude::Quaternion { frame, wxyz } => {
                let n = wxyz.iter().map(|v| v * v).sum::<f64>().sqrt();
                Attitude::Quaternion {
                    frame,
                    wxyz: wxyz.map(|v| v / n),
                }
            }
            e => e,
        }
    }

    /// ENU attitude from yaw/pitch/roll in degrees.
    pub fn enu(yaw_deg: f64, pitch_deg: f64, roll_deg: f64) -> Self {
        Attitude::Euler {
            frame: AttitudeFrame::Enu,
            yaw_deg,
            pitch_deg,
            roll_deg,
        }
    }

    /// Solar-frame attitude from yaw/pitch/roll in degrees.
    pub fn solar(yaw_deg: f64, pitch_deg: f64, roll_deg: f64) -> Self {
        Attitude::Euler {
            frame: AttitudeFrame::Solar,
            yaw_deg,
            pitch_deg,
            roll_deg,
        }
    }

    /// Checks the angle ranges (yaw −720..720 like a sun azimuth, pitch and roll −360..360)
    /// and quaternions (norm within [`QUATERNION_TOLERANCE`] of 1; such a quaternion is used
    /// normalised).
    pub fn validate(&self) -> Result<()> {
        match *self {
            Attitude::Euler {
                yaw_deg,
                pitch_deg,
                roll_deg,
                ..
            } => {
                check_range("yaw", yaw_deg, -720.0, 720.0)?;
                check_range("pitch", pitch_deg, -360.0, 360.0)?;
                check_range("roll", roll_deg, -360.0, 360.0)?;
            }
            Attitude::Quaternion { wxyz, .. } => {
                let n = wxyz.iter().map(|v| v * v).sum::<f64>().sqrt();
                if !n.is_finite() || (n - 1.0).abs() > QUATERNION_TOLERANCE {
                    let f = |v: f64| crate::error::num(v);
                    return Err(Error::Invalid(format!(
                        "quaternion {},{},{},{} is not a unit quaternion (norm {n:.6}; allowed 1 +- 0.001)",
                        f(wxyz[0]), f(wxyz[1]), f(wxyz[2]), f(wxyz[3])
                    )));
                }
            }
        }
        Ok(())
    }

    /// C_n^c: the matrix taking ENU vectors into the camera frame, for a sun at compass azimuth
    /// `sun_azimuth_deg` (used only by solar-frame attitudes).
    pub fn enu_to_camera(&self, sun_azimuth_deg: f64) -> DMat3 {
        let (frame, c_r_c) = match *self {
            Attitude::Euler {
                frame,
                yaw_deg,
                pitch_deg,
                roll_deg,
            } => (frame, euler_matrix(yaw_deg, pitch_deg, roll_deg)),
            Attitude::Quaternion { frame, wxyz } => {
                let q = DQuat::from_xyzw(wxyz[1], wxyz[2], wxyz[3], wxyz[0]).normalize();
                (frame, DMat3::from_quat(q).transpose())
            }
        };
        match frame {
            AttitudeFrame::Enu => c_r_c,
            AttitudeFrame::Solar => c_r_c * rot_z(sun_azimuth_deg.to_radians()),
        }
    }
}

/// Camera-to-ENU rotation (C_n^c)ᵀ as a Hamilton quaternion [w, x, y, z] (the stream's attitude).
pub fn camera_to_enu_quaternion(enu_to_camera: &DMat3) -> [f64; 4] {
    let q = DQuat::from_mat3(&enu_to_camera.transpose()).normalize();
    let q = if q.w < 0.0 { -q } else { q };
    [q.w, q.x, q.y, q.z]
}

/// Pinhole intrinsics. Pixel (col, row) are 0-based; the pixel centre of column c is at c.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Intrinsics {
    /// Columns n_x (default 2448).
    pub width: usize,
    /// Rows n_y (default 2048).
    pub height: usize,
    /// Focal length f in mm (default 4).
    pub focal_length_mm: f64,
    /// Pixel pitch in µm (default 3.45).
    pub pixel_pitch_um: f64,
    /// Principal point (column, row), 0-based pixels; `None` = exact image centre ((n − 1)/2).
    pub principal_point: Option<[f64; 2]>,
}

impl Default for Intrinsics {
    fn default() -> Self {
        Intrinsics {
            width: 2448,
            height: 2048,
            focal_length_mm: 4.0,
            pixel_pitch_um: 3.45,
            principal_point: None,
        }
    }
}

impl Intrinsics {
    /// The default optics (4 mm, 3.45 µm, centred principal point) with another sensor size, i.e. a
    /// centred window of the default camera (smaller sizes see a smaller field).
    ///
    /// ```
    /// let i = psns::camera::Intrinsics::with_size(64, 48);
    /// assert_eq!((i.width, i.height, i.focal_length_mm), (64, 48, 4.0));
    /// ```
    pub fn with_size(width: usize, height: usize) -> Self {
        Intrinsics {
            width,
            height,
            ..Intrinsics::default()
        }
    }

    /// Checks that sizes, focal length and pitch are positive and finite.
    pub fn validate(&self) -> Result<()> {
        if self.width == 0 || self.width > 65_536 {
            return Err(Error::range("width", self.width as f64, "1..65536"));
        }
        if self.height == 0 || self.height > 65_536 {
            return Err(Error::range("height", self.height as f64, "1..65536"));
        }
        check_positive("focal-length", self.focal_length_mm)?;
        check_positive("pixel-pitch", self.pixel_pitch_um)?;
        // beyond these the ray arithmetic overflows or the frame cannot be allocated
        check_range("focal-length", self.focal_length_mm, 0.01, 10_000.0)?;
        check_range("pixel-pitch", self.pixel_pitch_um, 0.1, 1000.0)?;
        if self.width * self.height > 100_000_000 {
            return Err(Error::range(
                "width x height",
                (self.width * self.height) as f64,
                "at most 100000000 pixels",
            ));
        }
        if let Some([x, y]) = self.principal_point {
            check_range("principal-point x", x, -1e6, 1e6)?;
            check_range("principal-point y", y, -1e6, 1e6)?;
        }
        Ok(())
    }

    /// Principal point (column, row), 0-based.
    pub fn principal(&self) -> (f64, f64) {
        match self.principal_point {
            Some([x, y]) => (x, y),
            None => (
                (self.width as f64 - 1.0) / 2.0,
                (self.height as f64 - 1.0) / 2.0,
            ),
        }
    }

    /// Focal length in pixels, f / pitch.
    pub fn focal_px(&self) -> f64 {
        self.focal_length_mm * 1000.0 / self.pixel_pitch_um
    }

    /// Unnormalised ray in the camera frame through the 0-based sub-pixel position (col, row),
    /// in pixel units: (col − c0, row − r0, f/pitch).
    #[inline]
    pub fn ray(&self, col: f64, row: f64) -> DVec3 {
        let (c0, r0) = self.principal();
        DVec3::new(col - c0, row - r0, self.focal_px())
    }

    /// Field angle ϕ (radians) between the optical axis and the ray of (col, row).
    pub fn field_angle(&self, col: f64, row: f64) -> f64 {
        let d = self.ray(col, row);
        (d.x.hypot(d.y)).atan2(d.z)
    }

    /// Pixel position (col, row) of a camera-frame direction, or `None` if it points backward.
    pub fn project(&self, d_c: DVec3) -> Option<(f64, f64)> {
        if d_c.z <= 0.0 {
            return None;
        }
        let (c0, r0) = self.principal();
        let f = self.focal_px();
        Some((c0 + f * d_c.x / d_c.z, r0 + f * d_c.y / d_c.z))
    }
}

/// A posed camera: intrinsics plus C_n^c.
#[derive(Clone, Copy, Debug)]
pub struct Camera {
    /// Intrinsics.
    pub intrinsics: Intrinsics,
    /// C_n^c, ENU → camera.
    pub enu_to_camera: DMat3,
}

impl Camera {
    /// A camera with intrinsics and attitude; `sun_azimuth_deg` resolves solar-frame attitudes.
    pub fn new(intrinsics: Intrinsics, attitude: &Attitude, sun_azimuth_deg: f64) -> Result<Self> {
        intrinsics.validate()?;
        attitude.validate()?;
        Ok(Camera {
            intrinsics,
            enu_to_camera: attitude.enu_to_camera(sun_azimuth_deg),
        })
    }

    /// Unit ENU view direction of the 0-based sub-pixel position (col, row).
    #[inline]
    pub fn pixel_direction(&self, col: f64, row: f64) -> DVec3 {
        (self.enu_to_camera.transpose() * self.intrinsics.ray(col, row)).normalize()
    }

    /// Sensor AOP (degrees, [0, 180), from +x toward +y) of an ENU E-vector.
    #[inline]
    pub fn sensor_aop_deg(&self, e_enu: DVec3) -> f64 {
        let e = self.enu_to_camera * e_enu;
        crate::angle::SensorAngle::from_deg(e.y.atan2(e.x).to_degrees()).deg()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sky::zenith_azimuth_deg;

    #[test]
    fn centre_pixel_looks_at_zenith_and_corners_match_spec() {
        let cam = Camera::new(Intrinsics::default(), &Attitude::enu(0.0, 0.0, 0.0), 200.0).unwrap();
        let (z, _) = zenith_azimuth_deg(cam.pixel_direction(1223.5, 1023.5));
        assert!(z.abs() < 1e-9);
        // sky.md §9 camera table
        let (z, a) = zenith_azimuth_deg(cam.pixel_direction(0.0, 0.0));
        assert!(
            (z - 53.989).abs() < 1e-3 && (a - 230.086).abs() < 1e-3,
            "{z} {a}"
        );
        let (z, a) = zenith_azimuth_deg(cam.pixel_direction(2447.0, 2047.0));
        assert!(
            (z - 53.989).abs() < 1e-3 && (a - 50.086).abs() < 1e-3,
            "{z} {a}"
        );
        let cam = Camera::new(
            Intrinsics::default(),
            &Attitude::enu(30.0, 10.0, -5.0),
            200.0,
        )
        .unwrap();
        let (z, a) = zenith_azimuth_deg(cam.pixel_direction(1223.5, 1023.5));
        assert!(
            (z - 11.169).abs() < 1e-3 && (a - 236.740).abs() < 1e-3,
            "{z} {a}"
        );
        let (z, a) = zenith_azimuth_deg(cam.pixel_direction(0.0, 0.0));
        assert!(
            (z - 64.315).abs() < 1e-3 && (a - 257.963).abs() < 1e-3,
            "{z} {a}"
        );
    }

    #[test]
    fn solar_and_enu_attitudes_agree_through_eq13() {
        for &(yaw, pitch, roll, az) in &[
            (0.0, 0.0, 0.0, 200.0),
            (30.0, 10.0, -5.0, 123.0),
            (-170.0, 45.0, 20.0, 359.0),
        ] {
            let a = Attitude::solar(yaw, pitch, roll).enu_to_camera(az);
            let n = Attitude::enu(yaw + az, pitch, roll).enu_to_camera(az);
            assert!((a - n).abs().to_cols_array().iter().all(|v| *v < 1e-12));
        }
    }

    #[test]
    fn quaternion_attitude_matches_euler() {
        let m = Attitude::enu(30.0, 10.0, -5.0).enu_to_camera(0.0);
        let q = camera_to_enu_quaternion(&m);
        let m2 = Attitude::Quaternion {
            frame: AttitudeFrame::Enu,
            wxyz: q,
        }
        .enu_to_camera(0.0);
        assert!((m - m2).abs().to_cols_array().iter().all(|v| *v < 1e-12));
    }

    #[test]
    fn image_y_axis_heading_is_yaw() {
        // Row 2 of C_r^c is the image +y axis: (cos ϑ sin ψ, cos ϑ cos ψ, sin ϑ).
        let m = euler_matrix(30.0, 10.0, 0.0);
        let y = m.row(1);
        let (p, h) = (10f64.to_radians(), 30f64.to_radians());
        assert!((y - DVec3::new(p.cos() * h.sin(), p.cos() * h.cos(), p.sin())).length() < 1e-12);
    }

    #[test]
    fn project_inverts_ray() {
        let i = Intrinsics::default();
        let cam = Camera::new(i, &Attitude::enu(12.0, -7.0, 3.0), 0.0).unwrap();
        for &(c, r) in &[(0.0, 0.0), (100.25, 2000.5), (2447.0, 3.0)] {
            let d = cam.pixel_direction(c, r);
            let (c2, r2) = i.project(cam.enu_to_camera * d).unwrap();
            assert!((c - c2).abs() < 1e-8 && (r - r2).abs() < 1e-8);
        }
    }

    #[test]
    fn bad_quaternion_is_rejected() {
        let a = Attitude::Quaternion {
            frame: AttitudeFrame::Enu,
            wxyz: [1.0, 1.0, 0.0, 0.0],
        };
        assert!(a.validate().is_err());
    }
}
