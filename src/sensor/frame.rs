//! A raw frame and how to ask for one: [`RawFrame`], [`Radiance`], [`FramePath`],
//! [`FrameOptions`].

use super::*;

/// One emulated raw frame with its ground truth.
#[derive(Clone, Debug)]
pub struct RawFrame {
    /// Raw mosaic codes at `bit_depth` (LSB-aligned).
    pub codes: Image<u16>,
    /// Output bit depth.
    pub bit_depth: u8,
    /// Black level in output DN.
    pub black_level_dn: f64,
    /// Exposure used, µs.
    pub exposure_us: f64,
    /// Analog gain, dB.
    pub gain_db: f64,
    /// System gain in output DN per electron (0 for the PSNS presets).
    pub dn_per_electron: f64,
    /// Noise-free Stokes (S0, S1, S2) of an ideal pixel at every pixel's own position, output DN
    /// above the black level.
    pub truth: StokesImage,
    /// Saturated pixels per mosaic position (0,0), (0,1), (1,0), (1,1): at the maximum code, or with
    /// the full well reached (which reads a few DN below the top code after read noise and DSNU).
    pub saturated: [u32; 4],
    /// The exposure came from auto-exposure.
    pub auto_exposed: bool,
    /// Auto-exposure hit the 20 µs..10 s limits.
    pub exposure_clipped: bool,
    /// Unrounded, unclipped output values (output DN) when the `quantize` stage is off.
    pub analog: Option<Image<f32>>,
    /// CRC-32 (IEEE, as [`crc32fast`]) of the codes as little-endian u16 bytes (a stream's
    /// Mono16 payload), when [`FastSink::CodesCrc32`] asked for it: taken band by band while
    /// the codes were in cache. `None` otherwise. It describes `codes` as the frame was made
    /// (it is stale once a caller changes them).
    pub codes_crc32: Option<u32>,
    /// With a lead ([`FrameOptions::lead`]): the whole buffer, its first `lead` elements as they
    /// were given, then the codes (`codes` is then 0 × 0). `None` without a lead.
    pub lead_buffer: Option<Vec<u16>>,
}

/// Above this share of saturated pixels the front-ends warn ([`saturation_warning`]): render,
/// a stream's first frame, a dataset build's summary, and `psns heading` without an estimate.
pub const SATURATION_WARN_FRACTION: f64 = 0.01;

impl RawFrame {
    /// Saturated pixels of the frame ([`Self::saturated`] over the four mosaic positions).
    pub fn saturated_pixels(&self) -> u64 {
        self.saturated.iter().map(|&n| n as u64).sum()
    }
}

/// `saturated` of `pixels` as a share (0 for an empty frame).
pub fn saturated_fraction(saturated: u64, pixels: u64) -> f64 {
    if pixels == 0 {
        0.0
    } else {
        saturated as f64 / pixels as f64
    }
}

/// The warning for a frame with more than [`SATURATION_WARN_FRACTION`] of its `pixels`
/// saturated (`None` otherwise): a saturated pixel carries no polarization.
///
/// ```
/// use psns::sensor::saturation_warning;
/// assert!(saturation_warning(1, 1000).is_none());
/// assert!(saturation_warning(500, 1000).unwrap().contains("50.0 % of the pixels are saturated"));
/// ```
pub fn saturation_warning(saturated: u64, pixels: u64) -> Option<String> {
    let f = saturated_fraction(saturated, pixels);
    (f > SATURATION_WARN_FRACTION).then(|| {
        format!(
            "{:.1} % of the pixels are saturated ({saturated} of {pixels}): they carry no \
             polarization; shorten the exposure or lower the gain (--exposure-us, --gain-db), \
             or use --auto-exposure",
            100.0 * f
        )
    })
}

/// What the fast path also makes of a frame, band by band while the codes are in cache
/// ([`FrameOptions::sink`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FastSink {
    /// Only the codes.
    None,
    /// [`RawFrame::codes_crc32`] (on a big-endian machine it stays `None`).
    CodesCrc32,
}

/// Where a frame's sensor-frame Stokes radiance (W m⁻² sr⁻¹ nm⁻¹) comes from.
#[derive(Clone, Copy)]
pub enum Radiance<'a> {
    /// Whole planes: any path, and the ground truth.
    Planes(&'a StokesImage),
    /// Rows on demand (a [`crate::render::SkyGrid`], no full-size planes): the fast path and
    /// the PSNS presets; no ground truth.
    Rows(&'a dyn StokesRows),
}

/// The path from radiance to codes ([`FrameOptions::path`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FramePath {
    /// Counter-based noise, Cornish–Fisher shot noise above 16 e⁻, read noise folded in, an f32
    /// kernel ([`fast`]); the camera model without crosstalk ([`Sensor::fast_capable`]).
    Fast,
    /// The bit-stable reference: exact Poisson draws from per-row ChaCha8 streams, every stage.
    Exact,
}

/// How [`Sensor::frame`] makes a frame. The PSNS presets have one model of their own and take
/// it whichever path is asked.
#[derive(Clone, Debug)]
pub struct FrameOptions {
    /// The path.
    pub path: FramePath,
    /// Also the ground truth ([`RawFrame::truth`]; needs [`Radiance::Planes`]).
    pub truth: bool,
    /// A codes buffer to reuse (a stream's previous frame: no allocation and no page faults).
    pub codes: Vec<u16>,
    /// What the fast path also makes of the codes.
    pub sink: FastSink,
    /// Elements of `codes` kept in front of the frame's codes (zeros where the buffer is
    /// shorter): room for a message header before the pixels, e.g. a ROS 2 `Image`'s CDR
    /// prefix, so that the pixels need no copy. With a lead > 0 the frame comes back in
    /// [`RawFrame::lead_buffer`].
    pub lead: usize,
}

impl FrameOptions {
    /// The fast path, no truth.
    pub fn fast() -> Self {
        FrameOptions {
            path: FramePath::Fast,
            truth: false,
            codes: Vec::new(),
            sink: FastSink::None,
            lead: 0,
        }
    }

    /// The exact path, no truth.
    pub fn exact() -> Self {
        FrameOptions {
            path: FramePath::Exact,
            ..Self::fast()
        }
    }

    /// With the ground truth.
    pub fn with_truth(mut self) -> Self {
        self.truth = true;
        self
    }

    /// Into the buffer `codes`.
    pub fn into_codes(mut self, codes: Vec<u16>) -> Self {
        self.codes = codes;
        self
    }

    /// Into the buffer `codes` after its first `lead` elements ([`FrameOptions::lead`]).
    pub fn into_codes_after(mut self, codes: Vec<u16>, lead: usize) -> Self {
        self.codes = codes;
        self.lead = lead;
        self
    }

    /// Also making what `sink` asks for.
    pub fn with_sink(mut self, sink: FastSink) -> Self {
        self.sink = sink;
        self
    }
}

/// The buffer of a frame's codes: `lead` elements kept (zeros where `buf` is shorter), then
/// `n` elements for the codes (a reused buffer is not cleared: the kernels write every code).
pub(crate) fn codes_buffer(mut buf: Vec<u16>, lead: usize, n: usize) -> Vec<u16> {
    buf.resize(lead + n, 0);
    buf
}

/// [`RawFrame::codes`] and [`RawFrame::lead_buffer`] of a filled [`codes_buffer`].
pub(crate) fn split_lead(
    buf: Vec<u16>,
    lead: usize,
    w: usize,
    h: usize,
) -> (Image<u16>, Option<Vec<u16>>) {
    if lead == 0 {
        (Image::from_vec(w, h, buf), None)
    } else {
        (Image::from_vec(0, 0, Vec::new()), Some(buf))
    }
}

impl RawFrame {
    /// DoLP = |S_lin|/S0 (0 where S0 ≤ 0) and AoLP = ½ atan2(S2, S1) in degrees, [0, 180), of the
    /// ground truth.
    pub fn truth_dolp_aolp(&self) -> (Image<f32>, Image<f32>) {
        dolp_aolp_f64(&self.truth)
    }
}

/// [`RawFrame::truth_dolp_aolp`] of a Stokes image.
pub(super) fn dolp_aolp_f64(t: &StokesImage) -> (Image<f32>, Image<f32>) {
    let (w, h) = (t.width(), t.height());
    let mut dolp = Image::new(w, h);
    let mut aolp = Image::new(w, h);
    (
        dolp.data.par_chunks_mut(w),
        aolp.data.par_chunks_mut(w),
        t.s0.data.par_chunks(w),
        t.s1.data.par_chunks(w),
        t.s2.data.par_chunks(w),
    )
        .into_par_iter()
        .for_each(|(dolp, aolp, s0, s1, s2)| dolp_aolp_row(s0, s1, s2, dolp, aolp));
    (dolp, aolp)
}

crate::simd::simd_dispatch! {
    /// [`dolp_aolp_row_body`] built for the best instruction set the CPU has.
    pub(super) fn dolp_aolp_row = dolp_aolp_row_body(s0: &[f32], s1: &[f32], s2: &[f32], dolp: &mut [f32], aolp: &mut [f32])
}

/// One row of [`RawFrame::truth_dolp_aolp`], in f64 with [`crate::vmath`]'s hypot and atan2
/// (within 2 ulp of libm's, so the f32 results are libm's but for a rare last-bit rounding; the
/// per-pixel libm calls took about 5 % of `render --raw`'s CPU time).
#[inline(always)]
pub(super) fn dolp_aolp_row_body(
    s0: &[f32],
    s1: &[f32],
    s2: &[f32],
    dolp: &mut [f32],
    aolp: &mut [f32],
) {
    let n = dolp.len();
    let (s0, s1, s2, aolp) = (&s0[..n], &s1[..n], &s2[..n], &mut aolp[..n]);
    for k in 0..n {
        let (s0, s1, s2) = (s0[k] as f64, s1[k] as f64, s2[k] as f64);
        let d = crate::vmath::hypot(s1, s2) / s0;
        dolp[k] = if s0 > 0.0 { d as f32 } else { 0.0 };
        // ½ atan2 in degrees lies in [-90, 90]: into [0, 180) as SensorAngle::from_deg does
        let a = 0.5 * crate::vmath::atan2(s2, s1).to_degrees();
        let w = a + 180.0;
        let w = if w >= 180.0 { 0.0 } else { w };
        aolp[k] = if a < 0.0 { w } else { a } as f32;
    }
}
