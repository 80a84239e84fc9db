//! The light what hides the sky sends to the camera (`docs/world.md`, with what is approximated):
//!
//! * **Diffuse** (walls, boxes, terrain, trunks): Lambertian and unpolarized, L = ρ E / π, E the
//!   irradiance on the surface from the clear sky (integrated over the half of the sky the surface
//!   faces), the sun (its disc, when the surface faces it) and the ground (albedo of the sky
//!   model, view factor (1 − n_z)/2). Nothing shades anything: a wall facing the sun is sunlit
//!   even when the opposite wall stands between them.
//! * **Glass**: a specular reflector with Fresnel's equations (refractive index n, default
//!   1.52), applied to the Stokes vector of the sky seen in the mirror direction: unpolarized
//!   light comes back with degree (R_s − R_p)/(R_s + R_p), 1 at Brewster's angle
//!   atan n (56.7° for 1.52), its E-vector across the plane of incidence: the facade's angle,
//!   not the sky's. What passes into the building is lost.
//! * **Foliage**: L = ρ_f E_h / π (ρ_f = 0.1, E_h on a horizontal surface), weakly polarized:
//!   degree [`FOLIAGE_DOP`] with a horizontal E-vector (leaves' specular glint, mostly from
//!   above).

use glam::DVec3;

/// Degree of polarization of foliage (leaves reflect weakly polarized light: a few percent
/// over a canopy).
pub const FOLIAGE_DOP: f64 = 0.05;

/// Light along a ray: radiance, degree of linear polarization and the E-vector (a unit vector
/// across the ray; any when the degree is 0).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Light {
    /// Radiance, the sky's units.
    pub radiance: f64,
    /// Degree of linear polarization, 0..1.
    pub dop: f64,
    /// E-vector, unit, across the ray.
    pub e: DVec3,
}

/// Fresnel's amplitude reflection coefficients (r_s, r_p) from air into index `n` at
/// cos(incidence) `cos_i`, with the p-vectors taken as s × k for each beam (so that r_p → +1
/// and r_s → −1 for a perfect conductor).
///
/// ```
/// use psns::world::optics::fresnel;
/// let (rs, rp) = fresnel(1.52f64.atan().cos(), 1.52); // Brewster's angle
/// assert!(rp.abs() < 1e-12 && rs < -0.3);
/// ```
pub fn fresnel(cos_i: f64, n: f64) -> (f64, f64) {
    let cos_i = cos_i.clamp(0.0, 1.0);
    let sin_t = (1.0 - cos_i * cos_i).sqrt() / n;
    let cos_t = (1.0 - sin_t * sin_t).max(0.0).sqrt();
    let rs = (cos_i - n * cos_t) / (cos_i + n * cos_t);
    let rp = (n * cos_i - cos_t) / (n * cos_i + cos_t);
    (rs, rp)
}

/// The mirror direction of the view ray `d` in a surface of outward normal `n`.
#[inline]
pub fn mirror(d: DVec3, n: DVec3) -> DVec3 {
    d - 2.0 * d.dot(n) * n
}

/// The light seen along the view ray `d` (unit, outward from the camera) on glass of outward
/// normal `n` and index `index`, given the light `sky` arriving from the mirror direction
/// [`mirror`]`(d, n)`.
pub fn glass(d: DVec3, n: DVec3, index: f64, sky: Light) -> Light {
    let r = mirror(d, n);
    let (k_in, k_out) = (-r, -d);
    let cos_i = (-d.dot(n)).abs();
    let s = k_in.cross(n);
    let s = if s.length_squared() > 1e-20 {
        s.normalize()
    } else {
        n.any_orthonormal_vector()
    };
    let (p_in, p_out) = (s.cross(k_in), s.cross(k_out));
    let (rs, rp) = fresnel(cos_i, index);
    let (big_rs, big_rp) = (rs * rs, rp * rp);
    let l = sky.radiance;
    let psi = sky.e.dot(p_in).atan2(sky.e.dot(s));
    let (q, u) = (
        l * sky.dop * (2.0 * psi).cos(),
        l * sky.dop * (2.0 * psi).sin(),
    );
    let i2 = 0.5 * ((big_rs + big_rp) * l + (big_rs - big_rp) * q);
    let q2 = 0.5 * ((big_rs - big_rp) * l + (big_rs + big_rp) * q);
    let u2 = rs * rp * u;
    let dop = if i2 > 0.0 {
        (q2.hypot(u2) / i2).min(1.0)
    } else {
        0.0
    };
    let psi2 = 0.5 * u2.atan2(q2);
    Light {
        radiance: i2.max(0.0),
        dop,
        e: psi2.cos() * s + psi2.sin() * p_out,
    }
}

/// The horizontal unit vector across the view ray `d` (foliage's E-vector).
pub fn horizontal_across(d: DVec3) -> DVec3 {
    let h = DVec3::Z.cross(d);
    if h.length_squared() > 1e-20 {
        h.normalize()
    } else {
        DVec3::X
    }
}

/// Azimuth steps of the irradiance table of vertical surfaces.
const VERTICAL_STEPS: usize = 72;

/// Irradiance on the world's surfaces from the clear sky, the sun and the ground, tabulated for
/// vertical surfaces by the azimuth of their normal (every 5°, interpolated linearly) and for a
/// horizontal one.
#[derive(Clone, Debug, PartialEq)]
pub struct Lighting {
    horizontal: f64,
    vertical: [f64; VERTICAL_STEPS],
}

impl Lighting {
    /// Integrates `radiance` (the clear sky along a unit ray above the horizon) over the sky
    /// (2° × 4° cells, midpoint rule), adds the sun (`sun`, unit, with `sun_irradiance` on a
    /// surface facing it; 0 when its disc is not in view) and the ground (albedo
    /// `ground_albedo`, lit by the horizontal irradiance).
    pub fn new(
        radiance: impl Fn(DVec3) -> f64,
        sun: DVec3,
        sun_irradiance: f64,
        ground_albedo: f64,
    ) -> Self {
        const NT: usize = 45;
        const NA: usize = 90;
        let (dt, da) = (
            std::f64::consts::FRAC_PI_2 / NT as f64,
            std::f64::consts::TAU / NA as f64,
        );
        let normals: Vec<DVec3> = (0..VERTICAL_STEPS)
            .map(|k| {
                let a = (k as f64 * 360.0 / VERTICAL_STEPS as f64).to_radians();
                DVec3::new(a.sin(), a.cos(), 0.0)
            })
            .collect();
        let mut vertical = [0.0; VERTICAL_STEPS];
        let mut horizontal = 0.0;
        for i in 0..NT {
            let t = (i as f64 + 0.5) * dt;
            let w0 = t.sin() * dt * da;
            for j in 0..NA {
                let a = (j as f64 + 0.5) * da;
                let v = DVec3::new(t.sin() * a.sin(), t.sin() * a.cos(), t.cos());
                let lw = radiance(v) * w0;
                horizontal += lw * v.z;
                for (e, n) in vertical.iter_mut().zip(&normals) {
                    *e += lw * n.dot(v).max(0.0);
                }
            }
        }
        let sun_h = sun_irradiance * sun.z.max(0.0);
        let ground = ground_albedo * (horizontal + sun_h);
        horizontal += sun_h;
        for (e, n) in vertical.iter_mut().zip(&normals) {
            *e += sun_irradiance * n.dot(sun).max(0.0) + 0.5 * ground;
        }
        Lighting {
            horizontal,
            vertical,
        }
    }

    /// Irradiance on a surface of outward unit normal `n`: exact (to the quadrature) for
    /// vertical and upward surfaces, the only ones the world has; others blend the two.
    pub fn irradiance(&self, n: DVec3) -> f64 {
        let h = n.x.hypot(n.y);
        let mut e = 0.0;
        if h > 0.0 {
            let az = n.x.atan2(n.y).to_degrees().rem_euclid(360.0);
            let x = az * VERTICAL_STEPS as f64 / 360.0;
            let k = (x.floor() as usize).min(VERTICAL_STEPS - 1);
            let f = x - k as f64;
            let v =
                self.vertical[k] + (self.vertical[(k + 1) % VERTICAL_STEPS] - self.vertical[k]) * f;
            e += h * v;
        }
        if n.z > 0.0 {
            e += n.z * self.horizontal;
        }
        e
    }

    /// Irradiance on a horizontal surface facing up.
    pub fn horizontal(&self) -> f64 {
        self.horizontal
    }
}
