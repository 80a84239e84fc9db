//! The sky with a world around the camera ([`crate::world`]): what a view ray sees when a
//! building, a tree, the skyline or a cloud is in the way, lit by this sky.

use super::{Sky, SkySample};
use crate::world::optics::{self, Light, Lighting};
use crate::world::{clouds::CLOUD_BRIGHTNESS, Hit, World};
use glam::DVec3;

/// A [`World`] lit by one sky: the irradiance on its surfaces and its clouds' radiance.
#[derive(Clone, Debug)]
pub struct Surroundings {
    world: World,
    lighting: Lighting,
    cloud_radiance: f64,
    /// False: rays that see the sky see it without the clouds in front of it (the fast path
    /// lays the clouds over its interpolated sky itself); reflections keep theirs.
    direct_clouds: bool,
}

/// What a view ray needs from the sky after [`Surroundings::look`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Look {
    /// What the ray meets.
    pub hit: Hit,
    /// The direction to sample the clear sky in: the ray itself (sky) or its mirror image
    /// (glass) when that is above the horizon; None when no sky is seen.
    pub sample: Option<DVec3>,
}

impl Surroundings {
    /// Lights `world` by `sky`.
    pub fn new(sky: &Sky, world: World) -> Self {
        let hw = sky.hosek();
        let sun_irradiance = if sky.sun_visible() {
            // 2π ∫ L(γ) sin γ dγ over the disc, midpoint rule
            const N: usize = 64;
            let r = crate::sky::hosek::SUN_RADIUS_RAD;
            let dg = r / N as f64;
            (0..N)
                .map(|k| {
                    let g = (k as f64 + 0.5) * dg;
                    hw.sun_radiance(g) * g.sin() * dg
                })
                .sum::<f64>()
                * std::f64::consts::TAU
        } else {
            0.0
        };
        let lighting = Lighting::new(
            |v| sky.sample(v).radiance,
            sky.sun().vector(),
            sun_irradiance,
            sky.params().albedo,
        );
        let cloud_radiance = CLOUD_BRIGHTNESS * sky.sample(DVec3::Z).radiance;
        Surroundings {
            world,
            lighting,
            cloud_radiance,
            direct_clouds: true,
        }
    }

    /// These surroundings with the clouds in front of the sky left out (reflected clouds
    /// kept): what the fast path's nodes see before it lays the clouds over them.
    pub fn without_direct_clouds(&self) -> Self {
        Surroundings {
            direct_clouds: false,
            ..self.clone()
        }
    }

    /// Radiance of a thick cloud.
    pub fn cloud_radiance(&self) -> f64 {
        self.cloud_radiance
    }

    /// The opacity of the clouds in front of the sky along the unit ray `d` (0 where the ray
    /// meets anything else first or the ground).
    pub fn direct_opacity(&self, d: DVec3) -> f64 {
        match self.world.trace(d) {
            Hit::Sky if d.z > 0.0 => self.world.clouds().opacity(d),
            _ => 0.0,
        }
    }

    /// The same lighting around `world` (the same world, its clouds elsewhere).
    pub fn with_world(&self, world: World) -> Self {
        Surroundings {
            world,
            lighting: self.lighting.clone(),
            cloud_radiance: self.cloud_radiance,
            direct_clouds: self.direct_clouds,
        }
    }

    /// The world.
    pub fn world(&self) -> &World {
        &self.world
    }

    /// The irradiance on the world's surfaces.
    pub fn lighting(&self) -> &Lighting {
        &self.lighting
    }

    /// What the unit ENU view ray `d` meets, and where the sky must be sampled for it.
    #[inline]
    pub fn look(&self, d: DVec3) -> Look {
        let hit = self.world.trace(d);
        let sample = match hit {
            Hit::Sky if d.z > 0.0 => Some(d),
            Hit::Glass { normal, .. } => {
                let r = optics::mirror(d, normal);
                (r.z > 0.0).then_some(r)
            }
            _ => None,
        };
        Look { hit, sample }
    }

    /// The clear sky `s` sampled along `v` as seen through the clouds.
    #[inline]
    fn through_clouds(&self, v: DVec3, s: &SkySample) -> Light {
        let a = self.world.clouds().opacity(v);
        if a == 0.0 {
            return Light {
                radiance: s.radiance,
                dop: s.dop,
                e: s.e,
            };
        }
        let pol = (1.0 - a) * s.radiance * s.dop;
        let l = (1.0 - a) * s.radiance + a * self.cloud_radiance;
        Light {
            radiance: l,
            dop: if l > 0.0 { pol / l } else { 0.0 },
            e: s.e,
        }
    }

    /// The light along the view ray `d` after [`Self::look`] gave `look`, with `s` the clear sky
    /// sampled at `look.sample` (ignored when that is None); None for the ground.
    #[inline]
    pub fn shade(
        &self,
        d: DVec3,
        look: &Look,
        s: &SkySample,
        ground_radiance: f64,
    ) -> Option<Light> {
        match (look.hit, look.sample) {
            (Hit::Sky, Some(v)) if self.direct_clouds => Some(self.through_clouds(v, s)),
            (Hit::Sky, Some(_)) => Some(Light {
                radiance: s.radiance,
                dop: s.dop,
                e: s.e,
            }),
            (Hit::Sky, None) | (Hit::Ground, _) => None,
            (Hit::Glass { normal, index }, v) => {
                let incoming = match v {
                    Some(v) => self.through_clouds(v, s),
                    None => Light {
                        radiance: ground_radiance,
                        dop: 0.0,
                        e: optics::horizontal_across(d),
                    },
                };
                Some(optics::glass(d, normal, index, incoming))
            }
            (Hit::Diffuse { normal, albedo }, _) => Some(Light {
                radiance: albedo * self.lighting.irradiance(normal) / std::f64::consts::PI,
                dop: 0.0,
                e: optics::horizontal_across(d),
            }),
            (Hit::Foliage, _) => Some(Light {
                radiance: crate::world::FOLIAGE_ALBEDO * self.lighting.horizontal()
                    / std::f64::consts::PI,
                dop: optics::FOLIAGE_DOP,
                e: optics::horizontal_across(d),
            }),
        }
    }

    /// The fraction of the sun's light that reaches the camera along the unit ray `d`: 0 behind
    /// anything solid, 1 − opacity through a cloud.
    pub fn sun_transmission(&self, d: DVec3) -> f64 {
        match self.world.trace(d) {
            Hit::Sky => 1.0 - self.world.clouds().opacity(d),
            _ => 0.0,
        }
    }
}
