//! The class image: what each pixel sees ([`Class`]: outside the image circle, sky, cloud,
//! obstruction, ground, the sun's disc), exactly per pixel centre.

use super::*;
use crate::image::Image;
use crate::world::{Class, Hit, World};

/// The class of the pixel (col, row) centre, without the sun's disc, in `world` (`None`: the
/// open sky), which is all a pixel's class depends on besides the camera.
pub fn pixel_class_in(world: Option<&World>, cam: &Camera, col: usize, row: usize) -> Class {
    let Some(d) = cam.pixel_direction(col as f64, row as f64) else {
        return Class::Outside;
    };
    let Some(w) = world else {
        return if d.z > 0.0 { Class::Sky } else { Class::Ground };
    };
    if !w.open(col, row) {
        return Class::Obstruction;
    }
    match w.trace(d) {
        Hit::Sky if d.z > 0.0 => {
            if w.clouds().opacity(d) >= 0.5 {
                Class::Cloud
            } else {
                Class::Sky
            }
        }
        Hit::Sky | Hit::Ground => Class::Ground,
        _ => Class::Obstruction,
    }
}

/// The class of every pixel ([`Class`] codes), with the sun's disc where it is drawn
/// (`sun_disc`) and seen.
pub fn class_image(sky: &Sky, cam: &Camera, sun_disc: bool) -> Image<u8> {
    class_image_every(sky, cam, sun_disc, 1)
}

/// The class of every `stride`-th pixel in each direction (columns and rows 0, stride,
/// 2 stride, …): an image of ⌈width / stride⌉ x ⌈height / stride⌉ pixels, [`class_image`] for
/// stride 1.
pub fn class_image_every(sky: &Sky, cam: &Camera, sun_disc: bool, stride: usize) -> Image<u8> {
    let world = sky.surroundings().map(|w| w.world());
    let mut out = class_image_in(world, cam, stride);
    if sun_disc {
        let s = stride.max(1);
        let w = cam.intrinsics.width;
        for (k, _) in sun_disc_pixels(sky, cam) {
            let (r, c) = (k / w, k % w);
            if r % s == 0 && c % s == 0 {
                out.data[(r / s) * out.width + c / s] = Class::Sun as u8;
            }
        }
    }
    out
}

/// [`class_image_every`] without the sun's disc, in `world` (`None`: the open sky): no sky
/// needed.
pub fn class_image_in(world: Option<&World>, cam: &Camera, stride: usize) -> Image<u8> {
    let s = stride.max(1);
    let (w, h) = (cam.intrinsics.width, cam.intrinsics.height);
    let ws = w.div_ceil(s);
    let mut out: Image<u8> = Image::new(ws, h.div_ceil(s));
    out.data
        .par_chunks_mut(ws.max(1))
        .enumerate()
        .for_each(|(r, row)| {
            for (c, v) in row.iter_mut().enumerate() {
                *v = pixel_class_in(world, cam, c * s, r * s) as u8;
            }
        });
    out
}

/// Most pixels a frame's class fractions count ([`class_stride`]).
pub const CLASS_SAMPLES: usize = 16_384;

/// The stride of a `width` x `height` frame's class fractions: the smallest `s` with at most
/// [`CLASS_SAMPLES`] pixels on every `s`-th column and row (1 up to 128 x 128, 18 on the full
/// sensor).
///
/// ```
/// use psns::render::class_stride;
/// assert_eq!((class_stride(128, 128), class_stride(129, 128), class_stride(2448, 2048)), (1, 2, 18));
/// ```
pub fn class_stride(width: usize, height: usize) -> usize {
    (1..)
        .find(|s| width.div_ceil(*s) * height.div_ceil(*s) <= CLASS_SAMPLES)
        .expect("a stride as large as the frame counts one pixel")
}

/// The fraction of the pixels of a class image in each class ([`Class::ALL`] order): what
/// `psns render` writes as `derived.class_fractions`.
pub fn fractions(class: &Image<u8>) -> [f64; 6] {
    let mut counts = [0usize; 6];
    for &c in &class.data {
        counts[c as usize] += 1;
    }
    let n = class.data.len().max(1) as f64;
    counts.map(|k| k as f64 / n)
}
