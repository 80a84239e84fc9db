//! Camera: pixel rays (rectilinear or one of four fisheye projections), attitude, and how the sky's
//! E-vector reaches the sensor (the paper's pinhole projection, or an ideal rotationally
//! symmetric lens); `camera.md`.
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
    Solar,
    /// East-North-Up: yaw measured from north (the compass heading `psns heading` reports).
    #[default]
    Enu,
}

crate::names::name_table!(AttitudeFrame {
    Solar => "solar",
    Enu => "enu",
});

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
            frame: AttitudeFrame::Enu,
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

/// How a field angle θ (between a ray and the optical axis) maps to the image radius r, with
/// f the focal length (`camera.md` §1). Rectilinear is the pinhole r = f tan θ; the four fisheyes
/// image a 180° field whose rim (θ = 90°) is the image circle, outside which pixels get no light.
///
/// ```
/// use psns::camera::Projection;
/// let p: Projection = "equidistant".parse().unwrap();
/// assert_eq!(p, Projection::Equidistant);
/// // r/f = θ: 90° lands at π/2 focal lengths, and back
/// assert!((p.radius(90f64.to_radians()).unwrap() - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
/// assert!((p.field_angle(0.5).unwrap() - 0.5).abs() < 1e-12);
/// assert_eq!(p.field_angle(1.6), None); // outside the image circle
/// assert_eq!(Projection::Rectilinear.radius(90f64.to_radians()), None);
/// assert!("fisheye".parse::<Projection>().unwrap_err().to_string().contains("rectilinear, equidistant"));
/// ```
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Projection {
    /// r = f tan θ (pinhole, distortion-free; the default). Field below 90°.
    #[default]
    Rectilinear,
    /// r = f θ (equal angles, equal radii).
    Equidistant,
    /// r = 2 f sin(θ/2) (equal solid angles, equal areas).
    Equisolid,
    /// r = 2 f tan(θ/2) (conformal).
    Stereographic,
    /// r = f sin θ.
    Orthographic,
}

crate::names::name_table!(Projection {
    Rectilinear => "rectilinear",
    Equidistant => "equidistant",
    Equisolid => "equisolid",
    Stereographic => "stereographic",
    Orthographic => "orthographic",
});

impl Projection {
    /// Normalised image radius ρ = r/f of the field angle θ (radians), `None` outside the field
    /// (rectilinear: θ ≥ 90°; fisheyes: θ > 90°, outside the image circle).
    #[inline]
    pub fn radius(self, theta: f64) -> Option<f64> {
        let half_pi = std::f64::consts::FRAC_PI_2;
        if theta.is_nan()
            || theta < 0.0
            || theta > half_pi
            || (self == Projection::Rectilinear && theta >= half_pi)
        {
            return None;
        }
        Some(match self {
            Projection::Rectilinear => theta.tan(),
            Projection::Equidistant => theta,
            Projection::Equisolid => 2.0 * (0.5 * theta).sin(),
            Projection::Stereographic => 2.0 * (0.5 * theta).tan(),
            Projection::Orthographic => theta.sin(),
        })
    }

    /// Field angle θ (radians) of the normalised image radius ρ = r/f, `None` outside the image
    /// circle (θ > 90°; never for rectilinear).
    #[inline]
    pub fn field_angle(self, rho: f64) -> Option<f64> {
        if rho.is_nan() || rho < 0.0 {
            return None;
        }
        if let Some(rim) = self.rim_radius() {
            if rho > rim {
                return None;
            }
        }
        Some(match self {
            Projection::Rectilinear => rho.atan(),
            Projection::Equidistant => rho,
            Projection::Equisolid => 2.0 * (0.5 * rho).min(1.0).asin(),
            Projection::Stereographic => 2.0 * (0.5 * rho).atan(),
            Projection::Orthographic => rho.min(1.0).asin(),
        })
    }

    /// Normalised radius r/f of the image circle (θ = 90°); `None` for rectilinear (no circle).
    pub fn rim_radius(self) -> Option<f64> {
        match self {
            Projection::Rectilinear => None,
            Projection::Equidistant => Some(std::f64::consts::FRAC_PI_2),
            Projection::Equisolid => Some(std::f64::consts::SQRT_2),
            Projection::Stereographic => Some(2.0),
            Projection::Orthographic => Some(1.0),
        }
    }

    /// dρ/dθ, the radial magnification relative to f at field angle θ (radians, below 90°).
    pub fn radial_scale(self, theta: f64) -> f64 {
        match self {
            Projection::Rectilinear => 1.0 / (theta.cos() * theta.cos()),
            Projection::Equidistant => 1.0,
            Projection::Equisolid => (0.5 * theta).cos(),
            Projection::Stereographic => 1.0 / ((0.5 * theta).cos() * (0.5 * theta).cos()),
            Projection::Orthographic => theta.cos(),
        }
    }

    /// ρ/sin θ, the tangential (sagittal) magnification relative to f (1 on the axis).
    pub fn tangential_scale(self, theta: f64) -> f64 {
        if theta < 1e-9 {
            return 1.0;
        }
        match self {
            Projection::Rectilinear => 1.0 / theta.cos(),
            _ => self.radius(theta).unwrap_or(0.0) / theta.sin(),
        }
    }
}

impl std::fmt::Display for Projection {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Projection {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        Projection::from_name(s).ok_or_else(|| {
            Error::Invalid(format!(
                "projection '{s}' is unknown (allowed {})",
                Projection::names()
            ))
        })
    }
}

/// Which polarization reaches the sensor (`camera.md` §2). Write the ray's unit direction d at
/// field angle θ, its meridional unit vector m (in the plane of d and the optical axis,
/// ⟂ d, pointing away from the axis) and sagittal unit vector s = ẑ × d/|ẑ × d|, and the
/// E-vector e = a m + b s. On the sensor, ρ̂ is the radial and φ̂ the tangential image
/// direction of the pixel.
///
/// - `Pinhole`: the paper's eqs. (19)–(20), e projected along the optical axis onto the focal
///   plane: (e_x, e_y) = a cos θ ρ̂ + b φ̂.
/// - `Ideal`: a rotationally symmetric, non-polarizing lens keeps each ray's meridional and
///   sagittal components and delivers them along ρ̂ and φ̂ at normal incidence:
///   a ρ̂ + b φ̂ (Richards & Wolf 1959; Chipman, Lam & Young 2018, ch. 11).
///
/// The two agree on the axis; off axis the ideal lens's radial component is larger by 1/cos θ.
///
/// ```
/// use glam::DVec3;
/// use psns::camera::Lens;
/// // a ray 60° off axis toward +x, E-vector at 45° between meridional and sagittal
/// let (s, c) = 60f64.to_radians().sin_cos();
/// let d = DVec3::new(s, 0.0, c);
/// let m = DVec3::new(c, 0.0, -s);
/// let e = (m + DVec3::Y) / 2f64.sqrt();
/// let deg = |l: Lens| l.sensor_angle(d, e).to_degrees();
/// assert!((deg(Lens::Ideal) - 45.0).abs() < 1e-9);
/// assert!((deg(Lens::Pinhole) - 2f64.atan().to_degrees()).abs() < 1e-9); // atan(1 / cos 60°)
/// assert_eq!("ideal".parse::<Lens>().unwrap(), Lens::Ideal);
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Lens {
    /// E-vector projected onto the focal plane (PSNS eqs. (19)–(20)).
    Pinhole,
    /// Meridional → radial, sagittal → tangential (a rotationally symmetric lens).
    Ideal,
}

crate::names::name_table!(Lens {
    Pinhole => "pinhole",
    Ideal => "ideal",
});

impl Lens {
    /// Sensor-plane vector (x, y) of the camera-frame E-vector `e` of a ray with unit
    /// camera-frame direction `d` (its angle is the sensor AOP; its length is not normalised).
    #[inline(always)]
    pub fn sensor_vector(self, d: DVec3, e: DVec3) -> (f64, f64) {
        match self {
            Lens::Pinhole => (e.x, e.y),
            Lens::Ideal => Self::ideal_sensor_vector(d, e, crate::vmath::hypot(d.x, d.y)),
        }
    }

    /// The ideal lens's [`Self::sensor_vector`] given h = √(d_x² + d_y²) (the row evaluator
    /// computes h for a chunk of rays in one loop). Branch-free but for a select.
    #[inline(always)]
    pub fn ideal_sensor_vector(d: DVec3, e: DVec3, h: f64) -> (f64, f64) {
        let (ux, uy) = (d.x / h, d.y / h); // ρ̂; φ̂ = (−uy, ux)
        let a = e.x * d.z * ux + e.y * d.z * uy - e.z * h; // e · m
        let b = -e.x * uy + e.y * ux; // e · s
        if h < 1e-12 {
            (e.x, e.y) // on the axis
        } else {
            (a * ux - b * uy, a * uy + b * ux)
        }
    }

    /// Sensor AOP (radians, from +x toward +y, in (−π, π]) of the E-vector `e` of unit ray `d`.
    #[inline]
    pub fn sensor_angle(self, d: DVec3, e: DVec3) -> f64 {
        let (x, y) = self.sensor_vector(d, e);
        y.atan2(x)
    }

    /// The unit camera-frame E-vector, perpendicular to the ray `d` (any length, z > 0 for the
    /// pinhole), whose sensor AOP is `aop_rad`: the inverse of [`Lens::sensor_angle`].
    pub fn e_vector(self, d: DVec3, aop_rad: f64) -> DVec3 {
        let (s, c) = aop_rad.sin_cos();
        match self {
            Lens::Pinhole => {
                let t = -(d.x * c + d.y * s) / d.z;
                DVec3::new(c, s, t).normalize()
            }
            Lens::Ideal => {
                let d = d.normalize();
                let h = d.x.hypot(d.y);
                if h < 1e-12 {
                    return DVec3::new(c, s, 0.0);
                }
                let (ux, uy) = (d.x / h, d.y / h);
                let (a, b) = (c * ux + s * uy, -c * uy + s * ux);
                let m = DVec3::new(d.z * ux, d.z * uy, -h);
                let sg = DVec3::new(-uy, ux, 0.0);
                a * m + b * sg
            }
        }
    }
}

impl std::fmt::Display for Lens {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Lens {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        Lens::from_name(s).ok_or_else(|| {
            Error::Invalid(format!("lens '{s}' is unknown (allowed {})", Lens::names()))
        })
    }
}

/// Intrinsics. Pixel (col, row) are 0-based; the pixel centre of column c is at c.
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
    /// Projection (default rectilinear).
    #[serde(default)]
    pub projection: Projection,
    /// Polarization transport; `None` = the sensor preset's (scene files: the camera preset's
    /// `ideal`, the PSNS presets' `pinhole`, see `config::RawConfig::lens`; a bare
    /// library `Intrinsics` with `None` is a pinhole, [`Intrinsics::lens`]).
    #[serde(default)]
    pub lens: Option<Lens>,
}

impl Default for Intrinsics {
    fn default() -> Self {
        Intrinsics {
            width: 2448,
            height: 2048,
            focal_length_mm: 4.0,
            pixel_pitch_um: 3.45,
            principal_point: None,
            projection: Projection::Rectilinear,
            lens: None,
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

    /// The lens in force: the configured one, or the pinhole when none is set.
    #[inline]
    pub fn lens(&self) -> Lens {
        self.lens.unwrap_or(Lens::Pinhole)
    }

    /// Ray in the camera frame through the 0-based sub-pixel position (col, row), or `None`
    /// outside a fisheye's image circle. Rectilinear: (col − c0, row − r0, f/pitch), in pixel
    /// units (not normalised); fisheyes: the unit direction at the projection's field angle.
    #[inline]
    pub fn ray(&self, col: f64, row: f64) -> Option<DVec3> {
        let (c0, r0) = self.principal();
        let (x, y) = (col - c0, row - r0);
        let f = self.focal_px();
        if self.projection == Projection::Rectilinear {
            return Some(DVec3::new(x, y, f));
        }
        let r = crate::vmath::hypot(x, y);
        let theta = self.projection.field_angle(r / f)?;
        if r == 0.0 {
            return Some(DVec3::Z);
        }
        let (s, c) = theta.sin_cos();
        Some(DVec3::new(s * x / r, s * y / r, c))
    }

    /// Whether the pixel (col, row) receives light (inside the image circle of a fisheye; always
    /// for rectilinear).
    pub fn in_image_circle(&self, col: f64, row: f64) -> bool {
        self.ray(col, row).is_some()
    }

    /// Field angle ϕ (radians) between the optical axis and the ray of (col, row); π/2 outside a
    /// fisheye's image circle.
    pub fn field_angle(&self, col: f64, row: f64) -> f64 {
        match self.ray(col, row) {
            Some(d) => (d.x.hypot(d.y)).atan2(d.z),
            None => std::f64::consts::FRAC_PI_2,
        }
    }

    /// Pixel position (col, row) of a camera-frame direction, or `None` if it is outside the
    /// field (backward for rectilinear, beyond 90° for fisheyes).
    pub fn project(&self, d_c: DVec3) -> Option<(f64, f64)> {
        let (c0, r0) = self.principal();
        let f = self.focal_px();
        if self.projection == Projection::Rectilinear {
            if d_c.z <= 0.0 {
                return None;
            }
            return Some((c0 + f * d_c.x / d_c.z, r0 + f * d_c.y / d_c.z));
        }
        let h = d_c.x.hypot(d_c.y);
        let rho = self.projection.radius(h.atan2(d_c.z))?;
        if h == 0.0 {
            return Some((c0, r0));
        }
        Some((c0 + f * rho * d_c.x / h, r0 + f * rho * d_c.y / h))
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

    /// Unit ENU view direction of the 0-based sub-pixel position (col, row); `None` outside a
    /// fisheye's image circle.
    #[inline]
    pub fn pixel_direction(&self, col: f64, row: f64) -> Option<DVec3> {
        Some((self.enu_to_camera.transpose() * self.intrinsics.ray(col, row)?).normalize())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::angle::zenith_azimuth_deg;

    #[test]
    fn centre_pixel_looks_at_zenith_and_corners_match_spec() {
        let cam = Camera::new(Intrinsics::default(), &Attitude::enu(0.0, 0.0, 0.0), 200.0).unwrap();
        let (z, _) = zenith_azimuth_deg(cam.pixel_direction(1223.5, 1023.5).unwrap());
        assert!(z.abs() < 1e-9);
        // sky.md §9 camera table
        let (z, a) = zenith_azimuth_deg(cam.pixel_direction(0.0, 0.0).unwrap());
        assert!(
            (z - 53.989).abs() < 1e-3 && (a - 230.086).abs() < 1e-3,
            "{z} {a}"
        );
        let (z, a) = zenith_azimuth_deg(cam.pixel_direction(2447.0, 2047.0).unwrap());
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
        let (z, a) = zenith_azimuth_deg(cam.pixel_direction(1223.5, 1023.5).unwrap());
        assert!(
            (z - 11.169).abs() < 1e-3 && (a - 236.740).abs() < 1e-3,
            "{z} {a}"
        );
        let (z, a) = zenith_azimuth_deg(cam.pixel_direction(0.0, 0.0).unwrap());
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
        for p in Projection::ALL {
            let i = Intrinsics {
                projection: p,
                focal_length_mm: if p == Projection::Rectilinear {
                    4.0
                } else {
                    1.8
                },
                ..Intrinsics::default()
            };
            let cam = Camera::new(i, &Attitude::enu(12.0, -7.0, 3.0), 0.0).unwrap();
            for &(c, r) in &[
                (1000.0, 900.0),
                (1223.5, 1023.5),
                (1500.25, 1200.5),
                (1100.0, 1400.0),
            ] {
                let d = cam.pixel_direction(c, r).unwrap();
                let (c2, r2) = i.project(cam.enu_to_camera * d).unwrap();
                assert!(
                    (c - c2).abs() < 1e-7 && (r - r2).abs() < 1e-7,
                    "{p}: {c},{r}"
                );
            }
        }
    }

    /// A pixel 300 px right of the principal point of a 1.8 mm, 3.45 µm camera looking at the
    /// zenith: its zenith angle by each projection, computed by hand (ρ = 300 / 521.739 =
    /// 0.57500: atan ρ, ρ, 2 asin(ρ/2), 2 atan(ρ/2), asin ρ).
    #[test]
    fn field_angles_by_hand() {
        let want = [
            (Projection::Rectilinear, 29.898_902),
            (Projection::Equidistant, 32.945_073),
            (Projection::Equisolid, 33.416_687),
            (Projection::Stereographic, 32.079_887),
            (Projection::Orthographic, 35.099_632),
        ];
        for (p, deg) in want {
            let i = Intrinsics {
                projection: p,
                focal_length_mm: 1.8,
                ..Intrinsics::default()
            };
            let cam = Camera::new(i, &Attitude::enu(0.0, 0.0, 0.0), 0.0).unwrap();
            let (c0, r0) = i.principal();
            let (z, a) = zenith_azimuth_deg(cam.pixel_direction(c0 + 300.0, r0).unwrap());
            assert!((z - deg).abs() < 1e-5, "{p}: zenith {z}, want {deg}");
            assert!(
                (a - 90.0).abs() < 1e-9,
                "{p}: +x is east at zero ENU attitude ({a})"
            );
            assert!((i.field_angle(c0 + 300.0, r0).to_degrees() - deg).abs() < 1e-5);
        }
    }

    /// The image circle of a 1.8 mm fisheye: θ = 90° at r = f·ρ(90°) (equidistant π/2 f =
    /// 819.5 px, equisolid √2 f = 737.8 px, stereographic 2f = 1043.5 px, orthographic f =
    /// 521.7 px); a pixel just inside has a ray, one just outside none, and the rectilinear camera
    /// has no circle.
    #[test]
    fn image_circle_rim() {
        let f = 1800.0 / 3.45;
        for (p, rim) in [
            (Projection::Equidistant, std::f64::consts::FRAC_PI_2 * f),
            (Projection::Equisolid, std::f64::consts::SQRT_2 * f),
            (Projection::Stereographic, 2.0 * f),
            (Projection::Orthographic, f),
        ] {
            let i = Intrinsics {
                projection: p,
                focal_length_mm: 1.8,
                ..Intrinsics::default()
            };
            let (c0, r0) = i.principal();
            let inside = i.ray(c0, r0 + rim - 0.01).unwrap();
            assert!(inside.z >= 0.0 && inside.z < 1e-2, "{p}: {inside}");
            assert!(i.ray(c0, r0 + rim + 0.01).is_none(), "{p}");
            assert!(
                i.project(DVec3::new(0.0, 1.0, -1e-3)).is_none(),
                "{p}: behind the rim"
            );
        }
        let i = Intrinsics::default();
        assert!(i.ray(-1e5, -1e5).is_some());
    }

    #[test]
    fn names_parse_and_bad_names_list_the_allowed_ones() {
        for p in Projection::ALL {
            assert_eq!(p.name().parse::<Projection>().unwrap(), p);
            assert_eq!(serde_json::to_string(&p).unwrap(), format!("\"{p}\""));
        }
        for l in Lens::ALL {
            assert_eq!(l.to_string().parse::<Lens>().unwrap(), l);
        }
        let e = "thin".parse::<Lens>().unwrap_err().to_string();
        assert!(e.contains("'thin'") && e.contains("pinhole, ideal"), "{e}");
    }

    /// Lens::e_vector inverts Lens::sensor_angle for both lenses, off axis.
    #[test]
    fn lens_e_vector_inverts_sensor_angle() {
        let d = DVec3::new(0.4, -0.7, 0.5).normalize();
        for l in Lens::ALL {
            for deg in [0.0f64, 30.0, 95.0, 150.0] {
                let e = l.e_vector(d, deg.to_radians());
                assert!(
                    e.dot(d).abs() < 1e-12,
                    "{l}: e not perpendicular to the ray"
                );
                let back = l.sensor_angle(d, e).to_degrees();
                let diff = (back - deg).rem_euclid(180.0);
                assert!(diff.min(180.0 - diff) < 1e-9, "{l}: {deg} -> {back}");
            }
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
