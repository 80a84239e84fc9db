//! IMX250MZR sensor emulation: sensor-frame Stokes radiance at every pixel centre → raw mosaic
//! codes plus noise-free ground truth (`sensor.md`).
//!
//! Pipeline of the camera model (`sensor.md` §6), each stage switchable in [`Stages`]:
//!
//! 1. optics ([`optics`]): relative illumination RI, lens and filter transmission, π/(4N²), pixel
//!    area, band width, photon energy → photons/s per unit radiance;
//! 2. polarizer ([`polarizer`]): partial polarizer with ER(λ_c) and a fixed-pattern orientation
//!    error δ_k, evaluated at the pixel's own pass axis (no superpixel shortcut);
//! 3. mean electrons μ_k = t · η · photons, times the PRNU gain g_k; optional 3 × 3 crosstalk;
//! 4. dark current I_d(T)·t, shot noise Poisson(μ + I_d t) (exact), full-well clip, DSNU, read
//!    noise N(0, σ_d²) ([`noise`]);
//! 5. gain, black level, ADC ([`adc`]).
//!
//! The ground truth ([`RawFrame::truth`]) is the Stokes vector in output DN above the black level
//! that an ideal pixel would see: same optics, RI, filter, T∥, QE, exposure and gain, but an ideal
//! polarizer (ER = ∞, δ = 0), no PRNU and no noise, so that such a pixel at angle a reads
//! (S0 + S1 cos 2a + S2 sin 2a)/2.
//!
//! The PSNS presets ([`presets`], `sensor.md` §9) bypass the camera model: I_k = κ · ½(S0 + S1 cos
//! 2θ_k + S2 sin 2θ_k), optionally times RI, plus Gaussian noise and ellipse clouds.
//!
//! Randomness: fixed-pattern maps and temporal noise come from per-row ChaCha8 streams
//! ([`noise`]), so frames do not depend on the number of rayon threads.

pub mod adc;
pub mod emva;
mod exact;
pub mod fast;
pub mod mosaic;
pub mod noise;
pub mod normal;
pub mod optics;
pub mod packing;
pub mod polarizer;
pub mod presets;
pub mod spectral;

use crate::camera::Intrinsics;
use crate::error::{check_range, Error, Result};
use crate::image::{Image, StokesImage, StokesRows};
use mosaic::MosaicLayout;
use optics::RelativeIllumination;
use polarizer::ErTable;
pub use presets::{Preset, PsnsModel};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use spectral::Spectral;

mod config;
mod frame;
#[cfg(test)]
mod tests;

pub use config::*;
pub use frame::*;

/// A prepared camera: configuration, intrinsics and the fixed-pattern maps of one camera seed.
/// Build once, then render any number of frames with [`Sensor::frame`].
#[derive(Clone, Debug)]
pub struct Sensor {
    cfg: SensorConfig,
    intrinsics: Intrinsics,
    seed: u64,
    /// RI per pixel, `None` when off (= 1).
    ri: Option<Vec<f32>>,
    /// The polarizer orientation error is modelled (else nominal angles).
    oriented: bool,
    /// Per-pixel (cos 2θ_k, sin 2θ_k) with the orientation error, built on first use by
    /// [`Self::axis_map`].
    axis: std::sync::OnceLock<Vec<[f32; 2]>>,
    /// PRNU gain g_k; `None` = 1.
    prnu: Option<Vec<f32>>,
    /// DSNU offset in e⁻; `None` = 0.
    dsnu: Option<Vec<f32>>,
    /// Photons/s per unit radiance on an on-axis pixel before the polarizer.
    photon_rate: f64,
    /// The fast path's per-pixel coefficients, built on first use.
    fast: std::sync::OnceLock<fast::FastStatics>,
}

/// The value of `cell`, built by `f` if it is still empty. `f` runs outside the cell's lock: the
/// per-camera maps are built with rayon, and a thread waiting in a rayon join may run a sibling
/// job that asks for the same map; inside `OnceLock::get_or_init` that nested call would
/// deadlock. Here two callers may both build the map once (same value, the later one dropped).
fn get_or_build<T>(cell: &std::sync::OnceLock<T>, f: impl FnOnce() -> T) -> &T {
    if let Some(v) = cell.get() {
        return v;
    }
    let _ = cell.set(f());
    cell.get().expect("set above or by another caller")
}

impl Sensor {
    /// Validates and builds the fixed-pattern maps of camera `seed`.
    pub fn new(cfg: &SensorConfig, intrinsics: &Intrinsics, seed: u64) -> Result<Self> {
        intrinsics.validate()?;
        let (w, h) = (intrinsics.width, intrinsics.height);
        cfg.validate(w, h)?;
        let st = &cfg.stages;
        // the stage switch always applies; a PSNS model also has its own falloff switch
        let eff = cfg.effective_ri();
        let ri = (eff != RelativeIllumination::None).then(|| eff.map(intrinsics));
        let camera = cfg.psns.is_none();
        // the exact path's per-pixel axis map is built on first use: the fast path never needs it
        let oriented = camera && st.polarizer_orientation && cfg.orientation_sigma_deg > 0.0;
        let prnu = (camera && st.prnu && cfg.prnu > 0.0)
            .then(|| noise::gaussian_map(w, h, seed, noise::MAP_PRNU, 1.0, cfg.prnu));
        let dsnu = (camera && st.dsnu && cfg.dsnu_e > 0.0)
            .then(|| noise::gaussian_map(w, h, seed, noise::MAP_DSNU, 0.0, cfg.dsnu_e));
        let photon_rate = optics::photon_rate_per_radiance(
            cfg.f_number,
            cfg.lens_transmission,
            cfg.filter_transmission,
            cfg.filter_width_nm,
            cfg.filter_center_nm,
            intrinsics.pixel_pitch_um,
        )?;
        Ok(Sensor {
            cfg: cfg.clone(),
            intrinsics: *intrinsics,
            seed,
            ri,
            oriented,
            axis: std::sync::OnceLock::new(),
            prnu,
            dsnu,
            photon_rate,
            fast: std::sync::OnceLock::new(),
        })
    }

    /// The configuration.
    pub fn config(&self) -> &SensorConfig {
        &self.cfg
    }

    /// The intrinsics (frame size, focal length, pitch).
    pub fn intrinsics(&self) -> &Intrinsics {
        &self.intrinsics
    }

    /// The camera seed.
    pub fn seed(&self) -> u64 {
        self.seed
    }

    /// Photons/s per unit radiance on an on-axis pixel before the polarizer.
    pub fn photon_rate_per_radiance(&self) -> f64 {
        self.photon_rate
    }

    /// The relative-illumination map (row-major), if active.
    pub fn ri_map(&self) -> Option<&[f32]> {
        self.ri.as_deref()
    }

    /// The PRNU gain map (row-major), if active.
    pub fn prnu_map(&self) -> Option<&[f32]> {
        self.prnu.as_deref()
    }

    /// The DSNU map in e⁻ (row-major), if active.
    pub fn dsnu_map(&self) -> Option<&[f32]> {
        self.dsnu.as_deref()
    }

    /// Per-pixel (cos 2θ_k, sin 2θ_k) with the orientation error (row-major), `None` when the
    /// error is off (nominal angles). Built on first call: only the exact path reads it.
    fn axis_map(&self) -> Option<&[[f32; 2]]> {
        if !self.oriented {
            return None;
        }
        let m = get_or_build(&self.axis, || {
            let (w, h) = (self.intrinsics.width, self.intrinsics.height);
            let cfg = &self.cfg;
            let delta = noise::gaussian_map(
                w,
                h,
                self.seed,
                noise::MAP_ORIENTATION,
                0.0,
                cfg.orientation_sigma_deg,
            );
            let mut out = vec![[0f32; 2]; w * h];
            out.par_chunks_mut(w).enumerate().for_each(|(r, row)| {
                for (c, v) in row.iter_mut().enumerate() {
                    let th = (cfg.layout.angle_deg(r, c) + delta[r * w + c] as f64).to_radians();
                    let (s, co) = (2.0 * th).sin_cos();
                    *v = [co as f32, s as f32];
                }
            });
            out
        });
        Some(m)
    }

    /// Per-pixel pass-axis angle θ_k in degrees, [0, 180), including the orientation error.
    /// The first call builds the per-pixel map (with rayon; see `get_or_build`).
    pub fn pass_axis_deg(&self, row: usize, col: usize) -> f64 {
        match self.axis_map() {
            Some(a) => {
                let [c, s] = a[row * self.intrinsics.width + col];
                crate::angle::SensorAngle::from_deg(0.5 * (s as f64).atan2(c as f64).to_degrees())
                    .deg()
            }
            None => self.cfg.layout.angle_deg(row, col),
        }
    }

    #[inline]
    fn ri_at(&self, k: usize) -> f64 {
        self.ri.as_ref().map_or(1.0, |m| m[k] as f64)
    }

    #[inline]
    fn axis_at(&self, axis: Option<&[[f32; 2]]>, row: usize, col: usize) -> (f64, f64) {
        match axis {
            Some(a) => {
                let [c, s] = a[row * self.intrinsics.width + col];
                (c as f64, s as f64)
            }
            None => nominal_axis(&self.cfg.layout, row, col),
        }
    }

    fn check_rows(&self, src: &dyn StokesRows) -> Result<()> {
        let (w, h) = (self.intrinsics.width, self.intrinsics.height);
        if src.width() != w || src.height() != h {
            return Err(Error::Invalid(format!(
                "the scene is {}x{}, the sensor is {w}x{h}",
                src.width(),
                src.height()
            )));
        }
        Ok(())
    }

    fn check_input(&self, stokes: &StokesImage) -> Result<()> {
        let (w, h) = (self.intrinsics.width, self.intrinsics.height);
        for (n, im) in [("S0", &stokes.s0), ("S1", &stokes.s1), ("S2", &stokes.s2)] {
            if im.width != w || im.height != h || im.data.len() != w * h {
                return Err(Error::Invalid(format!(
                    "{n} plane is {}x{}, the sensor is {w}x{h}",
                    im.width, im.height
                )));
            }
        }
        Ok(())
    }

    /// Noise-free electron rate (e⁻/s) of every pixel before crosstalk: η · photons · RI · g_k ·
    /// partial-polarizer reading. Non-finite input counts as no light.
    pub fn electron_rate(&self, stokes: &StokesImage) -> Result<Vec<f64>> {
        self.check_input(stokes)?;
        let (a, b, base) = self.rate_coefficients();
        let w = self.intrinsics.width;
        let axis = self.axis_map();
        let mut out = vec![0f64; w * self.intrinsics.height];
        out.par_chunks_mut(w).enumerate().for_each(|(r, row)| {
            for (c, v) in row.iter_mut().enumerate() {
                *v = self.rate_at(stokes, axis, r, c, a, b, base);
            }
        });
        Ok(out)
    }

    /// Polarizer coefficients (a, b) and η · photon rate shared by every pixel's electron rate.
    fn rate_coefficients(&self) -> (f64, f64, f64) {
        let cfg = &self.cfg;
        let er = if cfg.stages.polarizer_er {
            cfg.er_table.at(cfg.filter_center_nm)
        } else {
            f64::INFINITY
        };
        let (a, b) = polarizer::coefficients(cfg.pass_transmission_at_filter(), er);
        (a, b, cfg.qe_at_filter() * self.photon_rate)
    }

    /// Electron rate of pixel (r, c); the one formula behind [`Sensor::electron_rate`] and the
    /// fused single-pass frame path, so both give the same bits.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn rate_at(
        &self,
        stokes: &StokesImage,
        axis: Option<&[[f32; 2]]>,
        r: usize,
        c: usize,
        a: f64,
        b: f64,
        base: f64,
    ) -> f64 {
        let k = r * self.intrinsics.width + c;
        let (s0, s1, s2) = finite3(stokes, k);
        let (co, si) = self.axis_at(axis, r, c);
        let g = self.prnu.as_ref().map_or(1.0, |m| m[k] as f64);
        base * self.ri_at(k) * g * polarizer::reading(s0, s1, s2, co, si, a, b)
    }

    /// Exposure for this scene: the fixed value, or auto-exposure (`sensor.md` §5).
    pub fn exposure_for(&self, stokes: &StokesImage, rate: &[f64]) -> ExposureChoice {
        self.exposure_from_sky_rates(|| {
            rate.iter()
                .zip(&stokes.s0.data)
                .filter(|(_, &s0)| s0 > 0.0 && s0.is_finite())
                .map(|(&r, _)| r)
                .collect()
        })
    }

    /// [`Self::exposure_for`] given the electron rates of the sky pixels (S0 > 0), made only
    /// when auto-exposure needs them.
    fn exposure_from_sky_rates(&self, sky_rates: impl FnOnce() -> Vec<f64>) -> ExposureChoice {
        match self.cfg.exposure {
            Exposure::Fixed { us } => ExposureChoice {
                us,
                auto: false,
                clipped: false,
            },
            Exposure::Auto {
                percentile,
                fraction,
            } => {
                let mut sky = sky_rates();
                let p = if sky.is_empty() {
                    0.0
                } else {
                    let n = sky.len();
                    let i = ((percentile / 100.0 * n as f64).ceil() as usize).clamp(1, n) - 1;
                    *sky.select_nth_unstable_by(i, |x, y| x.total_cmp(y)).1
                };
                let wanted = if p > 0.0 {
                    1e6 * fraction * self.cfg.full_well_e / p
                } else {
                    f64::INFINITY
                };
                let line = self.cfg.line_time_us();
                let lo = (MIN_EXPOSURE_US / line).ceil();
                let hi = (MAX_EXPOSURE_US / line).floor();
                let n = (wanted / line).round();
                ExposureChoice {
                    us: n.clamp(lo, hi) * line,
                    auto: true,
                    clipped: !(n >= lo && n <= hi),
                }
            }
        }
    }

    /// True when [`FramePath::Fast`] models this configuration: the camera model (not a PSNS
    /// preset) without crosstalk, with the ADC on, all gain analog, under 2³² pixels.
    pub fn fast_capable(&self) -> bool {
        let c = &self.cfg;
        c.psns.is_none()
            && !(c.stages.crosstalk && c.crosstalk > 0.0)
            && c.stages.quantize
            && c.digital_gain_above_db.is_none_or(|th| c.gain_db <= th)
            && ((self.intrinsics.width * self.intrinsics.height) as u64) < (1u64 << 32)
    }

    /// The fast path's per-pixel coefficients (built on first call, ~16 bytes per pixel).
    pub fn fast_statics(&self) -> &fast::FastStatics {
        get_or_build(&self.fast, || fast::FastStatics::new(self))
    }

    /// Frame `frame_index` of this camera from `radiance`, by the path and with what `opts`
    /// ask: the one way to make a raw frame.
    ///
    /// The fast path errors when [`Self::fast_capable`] is false; the exact path and the
    /// ground truth need [`Radiance::Planes`].
    pub fn frame(
        &self,
        radiance: Radiance<'_>,
        frame_index: u64,
        opts: FrameOptions,
    ) -> Result<RawFrame> {
        let FrameOptions {
            path,
            truth,
            codes,
            sink,
            lead,
        } = opts;
        match (radiance, self.cfg.psns.is_some(), path) {
            (Radiance::Planes(st), true, _) | (Radiance::Planes(st), false, FramePath::Exact) => {
                self.render(st, frame_index, truth, codes, lead)
            }
            (_, _, _) if truth => Err(Error::Invalid(
                "the ground truth needs the radiance as whole planes".into(),
            )),
            (Radiance::Rows(src), true, _) => {
                self.check_rows(src)?;
                presets::psns_frame(
                    self,
                    presets::PsnsSource::Rows(src),
                    frame_index,
                    false,
                    codes,
                    lead,
                )
            }
            (Radiance::Rows(src), false, FramePath::Fast) => {
                self.frame_fast(src, frame_index, codes, sink, lead)
            }
            (Radiance::Planes(st), false, FramePath::Fast) => {
                self.frame_fast(st, frame_index, codes, sink, lead)
            }
            (Radiance::Rows(_), false, FramePath::Exact) => Err(Error::Invalid(
                "the exact path needs the radiance as whole planes".into(),
            )),
        }
    }

    /// [`FramePath::Fast`]: no ground truth (`truth` is 0 × 0); `sink` as asked (the same codes
    /// either way); the codes after `lead` elements of `codes` ([`FrameOptions::lead`]).
    fn frame_fast(
        &self,
        src: &dyn StokesRows,
        frame_index: u64,
        codes: Vec<u16>,
        sink: FastSink,
        lead: usize,
    ) -> Result<RawFrame> {
        self.check_rows(src)?;
        let (w, h) = (self.intrinsics.width, self.intrinsics.height);
        if !self.fast_capable() {
            return Err(Error::Invalid(
                "this sensor configuration needs the exact path (--exact)".into(),
            ));
        }
        let cfg = &self.cfg;
        let st = &cfg.stages;
        let statics = self.fast_statics();
        let ExposureChoice {
            us: t_us,
            auto,
            clipped,
        } = self.exposure_from_sky_rates(|| {
            let (rate, sky) = fast::rates(self, statics, src);
            rate.into_iter()
                .zip(sky)
                .filter(|(_, s)| *s)
                .map(|(r, _)| r)
                .collect()
        });
        let t = t_us * 1e-6;
        let kg = adc::system_gain(cfg.k0, cfg.gain_db);
        let scale = adc::output_scale(cfg.bit_depth);
        let fc = fast::FrameConsts {
            t,
            dark_e: if st.dark {
                cfg.dark_current_at_temperature() * t
            } else {
                0.0
            },
            fwc: cfg.full_well_e,
            fwc_clip: st.fwc_clip,
            shot: st.shot,
            sigma_read: if st.read { cfg.read_noise_e } else { 0.0 },
            kg: kg * scale,
            black: cfg.black_level_dn * scale,
            max: adc::max_code(cfg.bit_depth),
            shot_key: normal::NoiseKey::new(self.seed, frame_index, noise::STAGE_SHOT),
            read_key: normal::NoiseKey::new(self.seed, frame_index, noise::STAGE_READ),
        };
        let out = fast::render_codes(self, statics, src, &fc, codes, lead, sink);
        let (codes, lead_buffer) = frame::split_lead(out.codes, lead, w, h);
        Ok(RawFrame {
            codes,
            lead_buffer,
            bit_depth: cfg.bit_depth,
            black_level_dn: cfg.black_level_dn * scale,
            exposure_us: t_us,
            gain_db: cfg.gain_db,
            dn_per_electron: kg * scale,
            truth: StokesImage::zeros(0, 0),
            saturated: out.saturated,
            auto_exposed: auto,
            exposure_clipped: clipped,
            analog: None,
            codes_crc32: out.crc32,
        })
    }

    /// Noise-free electron rate (e⁻/s) of every pixel as the fast path computes it (the
    /// counterpart of [`Self::electron_rate`], for comparing the two paths).
    pub fn electron_rate_fast(&self, src: &dyn StokesRows) -> Result<Vec<f64>> {
        self.check_rows(src)?;
        Ok(fast::rates(self, self.fast_statics(), src).0)
    }

    /// Ground truth of a frame made by [`Self::frame`] (either path) with exposure
    /// `exposure_us`: the Stokes vector in output DN above the black level of an ideal pixel.
    pub fn truth_for(&self, stokes: &StokesImage, exposure_us: f64) -> StokesImage {
        let cfg = &self.cfg;
        let (scale, kg) = (
            adc::output_scale(cfg.bit_depth),
            adc::system_gain(cfg.k0, cfg.gain_db),
        );
        let t = exposure_us * 1e-6;
        self.truth(
            stokes,
            scale
                * kg
                * t
                * cfg.qe_at_filter()
                * self.photon_rate
                * cfg.pass_transmission_at_filter(),
        )
    }

    /// [`FramePath::Exact`] from planes, or a PSNS preset's frame from planes; with the ground
    /// truth when `want_truth`; into `codes` after its first `lead` elements.
    fn render(
        &self,
        stokes: &StokesImage,
        frame_index: u64,
        want_truth: bool,
        codes: Vec<u16>,
        lead: usize,
    ) -> Result<RawFrame> {
        self.check_input(stokes)?;
        if self.cfg.psns.is_some() {
            return presets::psns_frame(
                self,
                presets::PsnsSource::Planes(stokes),
                frame_index,
                want_truth,
                codes,
                lead,
            );
        }
        let cfg = &self.cfg;
        let st = &cfg.stages;
        let (w, h) = (self.intrinsics.width, self.intrinsics.height);
        let has_crosstalk = st.crosstalk && cfg.crosstalk > 0.0;
        // Auto-exposure and crosstalk need the whole rate image first; otherwise each pixel's rate
        // is computed inside the noise loop (same formula, same bits, no 8-byte-per-pixel buffer).
        let (rate, t_us, auto, clipped) = match cfg.exposure {
            Exposure::Fixed { us } if !has_crosstalk => (None, us, false, false),
            _ => {
                let mut rate = self.electron_rate(stokes)?;
                let ExposureChoice {
                    us: t_us,
                    auto,
                    clipped,
                } = self.exposure_for(stokes, &rate);
                if has_crosstalk {
                    rate = crosstalk(&rate, w, h, cfg.crosstalk);
                }
                (Some(rate), t_us, auto, clipped)
            }
        };
        let (pa, pb, pbase) = self.rate_coefficients();
        let axis = self.axis_map(); // built here, before the parallel loop, if still unbuilt
        let t = t_us * 1e-6;
        let kg = adc::system_gain(cfg.k0, cfg.gain_db);
        // analog part before the ADC and an optional digital part after a 12-bit ADC
        let (g_analog, g_digital) = match cfg.digital_gain_above_db {
            Some(th) if cfg.gain_db > th => (th, cfg.gain_db - th),
            _ => (cfg.gain_db, 0.0),
        };
        let scale = adc::output_scale(cfg.bit_depth);
        let black = cfg.black_level_dn;
        let fc = exact::ExactConsts {
            t,
            dark_e: if st.dark {
                cfg.dark_current_at_temperature() * t
            } else {
                0.0
            },
            pa,
            pb,
            pbase,
            shot: st.shot,
            fwc_clip: st.fwc_clip,
            fwc: cfg.full_well_e,
            read_sigma: (st.read && cfg.read_noise_e > 0.0).then_some(cfg.read_noise_e),
            digital: (g_digital > 0.0).then(|| {
                (
                    adc::system_gain(cfg.k0, g_analog),
                    10f64.powf(g_digital / 20.0),
                )
            }),
            quantize: st.quantize,
            kg,
            black,
            scale,
            max: adc::max_code(cfg.bit_depth),
        };
        // no clearing: the kernel writes every code
        let mut buf = frame::codes_buffer(codes, lead, w * h);
        let codes = &mut buf[lead..];
        let mut analog = (!st.quantize).then(|| vec![0f32; w * h]);
        let seed = self.seed;
        let layout = &cfg.layout;
        let row_sat = |r: usize,
                       row: &mut [u16],
                       an: Option<&mut [f32]>,
                       buf: &mut exact::RowBufs|
         -> [u32; 4] {
            let span = r * w..(r + 1) * w;
            let inp = exact::RowIn {
                s: [
                    &stokes.s0.data[span.clone()],
                    &stokes.s1.data[span.clone()],
                    &stokes.s2.data[span.clone()],
                ],
                rate: rate.as_ref().map(|v| &v[span.clone()]),
                ri: self.ri.as_ref().map(|v| &v[span.clone()]),
                prnu: self.prnu.as_ref().map(|v| &v[span.clone()]),
                axis: axis.map(|v| &v[span.clone()]),
                nominal: [nominal_axis(layout, r, 0), nominal_axis(layout, r, 1)],
                dsnu: self.dsnu.as_ref().map(|v| &v[span.clone()]),
            };
            let mut rs = crate::rng::frame_stream(seed, frame_index, noise::STAGE_SHOT, r as u64);
            let mut rr = crate::rng::frame_stream(seed, frame_index, noise::STAGE_READ, r as u64);
            let [even, odd] = exact::row_kernel(&fc, &inp, &mut rs, &mut rr, buf, row, an);
            let mut sat = [0u32; 4];
            sat[(r & 1) << 1] = even;
            sat[((r & 1) << 1) | 1] = odd;
            sat
        };
        // per-thread row buffers of the kernel's passes
        let bufs = || exact::RowBufs::new(w);
        let sat_rows: Vec<[u32; 4]> = match analog.as_mut() {
            None => codes
                .par_chunks_mut(w)
                .enumerate()
                .map_init(bufs, |buf, (r, row)| row_sat(r, row, None, buf))
                .collect(),
            Some(an) => codes
                .par_chunks_mut(w)
                .zip(an.par_chunks_mut(w))
                .enumerate()
                .map_init(bufs, |buf, (r, (row, a))| row_sat(r, row, Some(a), buf))
                .collect(),
        };
        let mut saturated = [0u32; 4];
        for s in &sat_rows {
            for i in 0..4 {
                saturated[i] += s[i];
            }
        }
        let truth = if want_truth {
            self.truth_for(stokes, t_us)
        } else {
            StokesImage::zeros(0, 0)
        };
        let (codes, lead_buffer) = frame::split_lead(buf, lead, w, h);
        Ok(RawFrame {
            codes,
            lead_buffer,
            bit_depth: cfg.bit_depth,
            black_level_dn: black * scale,
            exposure_us: t_us,
            gain_db: cfg.gain_db,
            dn_per_electron: kg * scale,
            truth,
            saturated,
            auto_exposed: auto,
            exposure_clipped: clipped,
            analog: analog.map(|a| Image::from_vec(w, h, a)),
            codes_crc32: None,
        })
    }

    /// Ground truth: `gain` · RI · S at every pixel (non-finite input → 0).
    pub(crate) fn truth(&self, stokes: &StokesImage, gain: f64) -> StokesImage {
        let (w, h) = (self.intrinsics.width, self.intrinsics.height);
        let mut out = StokesImage::zeros(w, h);
        out.par_rows(|r, a, b, c| {
            for i in 0..w {
                let k = r * w + i;
                let (x0, x1, x2) = finite3(stokes, k);
                let g = gain * self.ri_at(k);
                a[i] = (g * x0) as f32;
                b[i] = (g * x1) as f32;
                c[i] = (g * x2) as f32;
            }
        });
        out
    }

    /// The float image of the ideal model with no noise, no fixed patterns, an ideal polarizer and
    /// no rounding or clipping: black + K₀10^(g/20)·μ_k in output DN, RI as configured, exposure as
    /// configured (auto-exposure evaluated on the ideal model).
    pub fn float_image(&self, stokes: &StokesImage) -> Result<Image<f32>> {
        self.check_input(stokes)?;
        let mut cfg = self.cfg.clone();
        let ri = cfg.stages.ri;
        cfg.stages = Stages {
            ri,
            ..Stages::none()
        };
        cfg.psns = None;
        let ideal = Sensor::new(&cfg, &self.intrinsics, self.seed)?;
        let rate = ideal.electron_rate(stokes)?;
        let t_us = ideal.exposure_for(stokes, &rate).us;
        let f = adc::system_gain(cfg.k0, cfg.gain_db) * adc::output_scale(cfg.bit_depth);
        let b = cfg.black_level_dn * adc::output_scale(cfg.bit_depth);
        let t = t_us * 1e-6;
        let (w, h) = (self.intrinsics.width, self.intrinsics.height);
        Ok(Image::from_vec(
            w,
            h,
            rate.iter().map(|&r| (b + f * r * t) as f32).collect(),
        ))
    }
}

#[inline]
fn finite3(s: &StokesImage, k: usize) -> (f64, f64, f64) {
    let f = |v: f32| if v.is_finite() { v as f64 } else { 0.0 };
    (f(s.s0.data[k]), f(s.s1.data[k]), f(s.s2.data[k]))
}

/// (cos 2θ, sin 2θ) of the nominal pass axis; exact for the four layout angles.
#[inline]
pub(crate) fn nominal_axis(layout: &MosaicLayout, row: usize, col: usize) -> (f64, f64) {
    match layout.channel(row, col) {
        0 => (1.0, 0.0),
        1 => (0.0, 1.0),
        2 => (-1.0, 0.0),
        _ => (0.0, -1.0),
    }
}

/// 3 × 3 crosstalk of a row-major image: each pixel keeps 1 − c and gives c/6 to each edge and
/// c/12 to each corner neighbour; mirrored at the borders.
pub fn crosstalk(img: &[f64], w: usize, h: usize, c: f64) -> Vec<f64> {
    let mut out = vec![0f64; w * h];
    let idx = |i: isize, n: usize| -> usize {
        let n = n as isize;
        (if i < 0 {
            -i
        } else if i >= n {
            2 * n - 2 - i
        } else {
            i
        })
        .clamp(0, n - 1) as usize
    };
    out.par_chunks_mut(w).enumerate().for_each(|(r, row)| {
        for (col, v) in row.iter_mut().enumerate() {
            let mut edge = 0.0;
            let mut corner = 0.0;
            for dr in -1isize..=1 {
                for dc in -1isize..=1 {
                    if dr == 0 && dc == 0 {
                        continue;
                    }
                    let rr = idx(r as isize + dr, h);
                    let cc = idx(col as isize + dc, w);
                    let x = img[rr * w + cc];
                    if dr == 0 || dc == 0 {
                        edge += x;
                    } else {
                        corner += x;
                    }
                }
            }
            *v = (1.0 - c) * img[r * w + col] + c / 6.0 * edge + c / 12.0 * corner;
        }
    });
    out
}

/// Uniform flat-field scene (EMVA 1288): radiance S0 = `radiance` (W m⁻² sr⁻¹ nm⁻¹), degree
/// `dolp` in [0, 1] and angle `aolp_deg` (sensor frame) of linear polarization everywhere.
pub fn flat_field(
    width: usize,
    height: usize,
    radiance: f64,
    dolp: f64,
    aolp_deg: f64,
) -> Result<StokesImage> {
    check_range("flat-radiance", radiance, 0.0, 1e6)?;
    check_range("flat-dolp", dolp, 0.0, 1.0)?;
    check_range("flat-aolp", aolp_deg, -360.0, 360.0)?;
    let a = 2.0 * aolp_deg.to_radians();
    let (s1, s2) = (radiance * dolp * a.cos(), radiance * dolp * a.sin());
    let mk = |v: f64| Image::from_vec(width, height, vec![v as f32; width * height]);
    Ok(StokesImage {
        s0: mk(radiance),
        s1: mk(s1),
        s2: mk(s2),
    })
}
