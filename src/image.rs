//! A plain row-major image buffer: row 0 at the top, `data[row * width + col]`.

/// Row-major image, rows top to bottom, no padding.
#[derive(Clone, Debug, PartialEq)]
pub struct Image<T> {
    /// Number of columns.
    pub width: usize,
    /// Number of rows.
    pub height: usize,
    /// Pixels, `data[row * width + col]`.
    pub data: Vec<T>,
}

/// `x.round().clamp(0.0, hi) as u32` (NaN to 0) without libm's `round`, a call on the baseline
/// x86-64 target (no SSE4.1), and without branches, so row loops vectorise: clipped first, the
/// truncation and the fraction are exact. For 0 ≤ hi < 2³². The ADC's rounding
/// (`sensor::adc::quantize`), the polarizer images and the views all use it.
///
/// ```
/// use psns::image::round_clamp;
/// assert_eq!(round_clamp(2.5, 255.0), 3);
/// assert_eq!(round_clamp(0.499_999_999_999_999_94, 255.0), 0);
/// assert_eq!(round_clamp(-3.0, 255.0), 0);
/// assert_eq!(round_clamp(f64::NAN, 255.0), 0);
/// assert_eq!(round_clamp(1e9, 65_535.0), 65_535);
/// ```
#[inline(always)]
pub fn round_clamp(x: f64, hi: f64) -> u32 {
    let x = x.max(0.0).min(hi); // max ignores NaN: NaN becomes 0
    let t = x as u32;
    t + (x - t as f64 >= 0.5) as u32
}

impl<T: Clone + Default> Image<T> {
    /// A `width` x `height` image filled with `T::default()`.
    pub fn new(width: usize, height: usize) -> Self {
        Image {
            width,
            height,
            data: vec![T::default(); width * height],
        }
    }
}

impl<T> Image<T> {
    /// Wraps a buffer; panics if its length is not `width * height`.
    pub fn from_vec(width: usize, height: usize, data: Vec<T>) -> Self {
        assert_eq!(
            data.len(),
            width * height,
            "buffer size does not match image size"
        );
        Image {
            width,
            height,
            data,
        }
    }

    /// The pixel at (row, col).
    #[inline]
    pub fn get(&self, row: usize, col: usize) -> &T {
        &self.data[row * self.width + col]
    }

    /// Mutable pixel at (row, col).
    #[inline]
    pub fn get_mut(&mut self, row: usize, col: usize) -> &mut T {
        &mut self.data[row * self.width + col]
    }

    /// One row as a slice.
    #[inline]
    pub fn row(&self, row: usize) -> &[T] {
        &self.data[row * self.width..(row + 1) * self.width]
    }
}

/// Sensor-frame Stokes planes (S0, S1, S2) at every pixel centre, same size.
///
/// Angles of S1/S2 are referred to the sensor frame: +x = columns, +y = rows (down), so
/// AoLP = ½ atan2(S2, S1) is measured from +x toward +y.
#[derive(Clone, Debug, PartialEq)]
pub struct StokesImage {
    /// Total intensity.
    pub s0: Image<f32>,
    /// 0°/90° difference.
    pub s1: Image<f32>,
    /// 45°/135° difference.
    pub s2: Image<f32>,
}

impl StokesImage {
    /// Zero Stokes planes of the given size.
    pub fn zeros(width: usize, height: usize) -> Self {
        StokesImage {
            s0: Image::new(width, height),
            s1: Image::new(width, height),
            s2: Image::new(width, height),
        }
    }
    /// Columns.
    pub fn width(&self) -> usize {
        self.s0.width
    }
    /// Rows.
    pub fn height(&self) -> usize {
        self.s0.height
    }
    /// Fills the three planes row by row, rows in parallel: `f(row, s0, s1, s2)`.
    pub fn par_rows(&mut self, f: impl Fn(usize, &mut [f32], &mut [f32], &mut [f32]) + Sync) {
        use rayon::prelude::*;
        let w = self.width().max(1);
        let StokesImage { s0, s1, s2 } = self;
        s0.data
            .par_chunks_mut(w)
            .zip(s1.data.par_chunks_mut(w))
            .zip(s2.data.par_chunks_mut(w))
            .enumerate()
            .for_each(|(r, ((a, b), c))| f(r, a, b, c));
    }
}

/// A source of sensor-frame Stokes radiance one row at a time: a whole [`StokesImage`], or a
/// coarse grid interpolated on the fly (`render::SkyGrid`), so a frame never needs the three
/// full planes in memory.
pub trait StokesRows: Sync {
    /// Columns.
    fn width(&self) -> usize;
    /// Rows.
    fn height(&self) -> usize;
    /// Writes row `r` of S0, S1, S2 into the three slices (each `width()` long), finite values
    /// (non-finite input counts as no light: 0).
    fn fill_row(&self, r: usize, s0: &mut [f32], s1: &mut [f32], s2: &mut [f32]);
}

impl StokesRows for StokesImage {
    fn width(&self) -> usize {
        self.s0.width
    }
    fn height(&self) -> usize {
        self.s0.height
    }
    fn fill_row(&self, r: usize, s0: &mut [f32], s1: &mut [f32], s2: &mut [f32]) {
        for (o, i) in [(s0, &self.s0), (s1, &self.s1), (s2, &self.s2)] {
            for (o, &v) in o.iter_mut().zip(i.row(r)) {
                *o = if v.is_finite() { v } else { 0.0 };
            }
        }
    }
}

/// A raw mosaic sample type. Bit depth does not matter: values are used as they are.
pub trait RawPixel: Copy + Send + Sync + 'static {
    /// The sample as f32 (exact for u8 and u16).
    fn to_f32(self) -> f32;
}

impl RawPixel for u8 {
    #[inline(always)]
    fn to_f32(self) -> f32 {
        self as f32
    }
}
impl RawPixel for u16 {
    #[inline(always)]
    fn to_f32(self) -> f32 {
        self as f32
    }
}
impl RawPixel for f32 {
    #[inline(always)]
    fn to_f32(self) -> f32 {
        self
    }
}
