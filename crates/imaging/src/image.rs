//! The image buffer that flows through vfxgraph.

use rayon::prelude::*;

use crate::color;
use crate::error::ImageError;

/// The largest number of samples (width × height × channels) an image may hold: 2³⁰, i.e. 4 GiB
/// of `f32`. Decoders check file headers against it before allocating, so a forged header cannot
/// exhaust memory.
pub const MAX_SAMPLES: usize = 1 << 30;

/// Images with at least this many samples are processed in parallel by [`Image::map`] and friends.
const PARALLEL_THRESHOLD: usize = 1 << 15;

/// Linear-light `f32` image, row-major, interleaved channels.
///
/// Channel layouts: 1 = gray, 2 = gray + alpha, 3 = RGB, 4 = RGBA (the decoders of [`crate::io`]
/// produce only 1, 3 or 4). Sample `(x, y, c)` is at `data[(y * width + x) * channels + c]`; pixel
/// `(0, 0)` is the top-left one, x grows to the right and y downwards (ARCHITECTURE.md, "Conventions"). Colour
/// channels are linear light (scene-referred, may exceed 1 or be negative); alpha is straight
/// (not premultiplied) coverage.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Number of columns.
    pub width: usize,
    /// Number of rows.
    pub height: usize,
    /// Samples per pixel (1–4, see the type's documentation).
    pub channels: usize,
    /// `width * height * channels` samples, row by row from the top.
    pub data: Vec<f32>,
}

impl Image {
    /// A black (all-zero) image. Panics if the dimensions overflow or exceed [`MAX_SAMPLES`]; use
    /// [`Image::try_new`] for sizes that come from outside the program.
    pub fn new(width: usize, height: usize, channels: usize) -> Image {
        match Image::try_new(width, height, channels) {
            Ok(img) => img,
            Err(e) => panic!("Image::new: {e}"),
        }
    }

    /// A black (all-zero) image, or [`ImageError::InvalidDimensions`] when `channels` is not 1–4 or
    /// the sample count overflows or exceeds [`MAX_SAMPLES`]. A zero width or height is allowed
    /// (an empty image).
    pub fn try_new(width: usize, height: usize, channels: usize) -> Result<Image, ImageError> {
        let n = sample_count(width, height, channels)?;
        Ok(Image {
            width,
            height,
            channels,
            data: vec![0.0; n],
        })
    }

    /// Wrap existing samples, checking that `data.len() == width * height * channels` and that
    /// `channels` is 1–4.
    pub fn from_vec(
        width: usize,
        height: usize,
        channels: usize,
        data: Vec<f32>,
    ) -> Result<Image, ImageError> {
        let n = sample_count(width, height, channels)?;
        if data.len() != n {
            return Err(ImageError::InvalidDimensions(format!(
                "{width}x{height}x{channels} needs {n} samples, got {}",
                data.len()
            )));
        }
        Ok(Image {
            width,
            height,
            channels,
            data,
        })
    }

    /// An image whose sample `(x, y, c)` is `f(x, y, c)`. Panics on dimensions [`Image::new`]
    /// rejects.
    pub fn from_fn(
        width: usize,
        height: usize,
        channels: usize,
        f: impl Fn(usize, usize, usize) -> f32,
    ) -> Image {
        let mut img = Image::new(width, height, channels);
        for y in 0..height {
            for x in 0..width {
                for c in 0..channels {
                    img.data[(y * width + x) * channels + c] = f(x, y, c);
                }
            }
        }
        img
    }

    /// Index of sample `(x, y, c)` in [`Image::data`].
    #[inline]
    pub fn index(&self, x: usize, y: usize, c: usize) -> usize {
        debug_assert!(x < self.width && y < self.height && c < self.channels);
        (y * self.width + x) * self.channels + c
    }

    /// Sample `(x, y, c)`. Panics when out of bounds.
    #[inline]
    pub fn get(&self, x: usize, y: usize, c: usize) -> f32 {
        assert!(
            x < self.width && y < self.height && c < self.channels,
            "sample ({x}, {y}, {c}) outside {}x{}x{}",
            self.width,
            self.height,
            self.channels
        );
        self.data[self.index(x, y, c)]
    }

    /// Set sample `(x, y, c)` to `v`. Panics when out of bounds.
    #[inline]
    pub fn set(&mut self, x: usize, y: usize, c: usize, v: f32) {
        assert!(
            x < self.width && y < self.height && c < self.channels,
            "sample ({x}, {y}, {c}) outside {}x{}x{}",
            self.width,
            self.height,
            self.channels
        );
        let i = self.index(x, y, c);
        self.data[i] = v;
    }

    /// The `channels` samples of pixel `(x, y)`. Panics when out of bounds.
    #[inline]
    pub fn pixel(&self, x: usize, y: usize) -> &[f32] {
        assert!(
            x < self.width && y < self.height,
            "pixel ({x}, {y}) outside image"
        );
        let i = (y * self.width + x) * self.channels;
        &self.data[i..i + self.channels]
    }

    /// Mutable samples of pixel `(x, y)`. Panics when out of bounds.
    #[inline]
    pub fn pixel_mut(&mut self, x: usize, y: usize) -> &mut [f32] {
        assert!(
            x < self.width && y < self.height,
            "pixel ({x}, {y}) outside image"
        );
        let i = (y * self.width + x) * self.channels;
        &mut self.data[i..i + self.channels]
    }

    /// Row `y` (`width * channels` samples).
    pub fn row(&self, y: usize) -> &[f32] {
        let n = self.width * self.channels;
        &self.data[y * n..(y + 1) * n]
    }

    /// Number of pixels (`width * height`).
    pub fn pixel_count(&self) -> usize {
        self.width * self.height
    }

    /// True when the image has no pixels.
    pub fn is_empty(&self) -> bool {
        self.width == 0 || self.height == 0
    }

    /// True for the layouts with an alpha channel (2 and 4 channels).
    pub fn has_alpha(&self) -> bool {
        self.channels == 2 || self.channels == 4
    }

    /// Number of colour (non-alpha) channels: 1 for gray layouts, 3 for RGB layouts.
    pub fn color_channels(&self) -> usize {
        match self.channels {
            1 | 2 => 1,
            3 | 4 => 3,
            n => n,
        }
    }

    /// Apply `f` to every sample, alpha included (in parallel for large images).
    pub fn map(&self, f: impl Fn(f32) -> f32 + Sync) -> Image {
        let data = if self.data.len() >= PARALLEL_THRESHOLD {
            self.data.par_iter().map(|&v| f(v)).collect()
        } else {
            self.data.iter().map(|&v| f(v)).collect()
        };
        Image {
            data,
            ..self.shallow()
        }
    }

    /// Apply `f` to every colour sample, leaving alpha untouched (in parallel for large images).
    pub fn map_color(&self, f: impl Fn(f32) -> f32 + Sync) -> Image {
        let mut out = self.clone();
        let cc = self.color_channels();
        out.for_each_pixel_mut(|px| {
            for v in &mut px[..cc] {
                *v = f(*v);
            }
        });
        out
    }

    /// Apply `f` to every pixel's samples in place (in parallel for large images).
    pub fn for_each_pixel_mut(&mut self, f: impl Fn(&mut [f32]) + Sync + Send) {
        let ch = self.channels.max(1);
        if self.data.len() >= PARALLEL_THRESHOLD {
            self.data.par_chunks_mut(ch).for_each(f);
        } else {
            self.data.chunks_mut(ch).for_each(f);
        }
    }

    /// The image with every pixel replaced by `f(pixel)`, which returns `out_channels` samples
    /// written into the given slice (in parallel for large images).
    pub fn map_pixels(&self, out_channels: usize, f: impl Fn(&[f32], &mut [f32]) + Sync) -> Image {
        let mut out = Image::new(self.width, self.height, out_channels);
        let ch = self.channels.max(1);
        if out_channels == 0 {
            return out;
        }
        if self.data.len() >= PARALLEL_THRESHOLD {
            out.data
                .par_chunks_mut(out_channels)
                .zip(self.data.par_chunks(ch))
                .for_each(|(o, i)| f(i, o));
        } else {
            out.data
                .chunks_mut(out_channels)
                .zip(self.data.chunks(ch))
                .for_each(|(o, i)| f(i, o));
        }
        out
    }

    /// Rec. 709 luminance as a 1-channel image (gray stays as it is; alpha is dropped).
    pub fn luminance(&self) -> Image {
        let cc = self.color_channels();
        self.map_pixels(1, |p, o| {
            o[0] = if cc == 3 {
                color::luminance(p[0], p[1], p[2])
            } else {
                p[0]
            }
        })
    }

    /// The image as 3-channel RGB: gray is replicated, alpha is dropped.
    pub fn to_rgb(&self) -> Image {
        let cc = self.color_channels();
        self.map_pixels(3, |p, o| {
            if cc == 3 {
                o.copy_from_slice(&p[..3]);
            } else {
                o.fill(p[0]);
            }
        })
    }

    /// The image as 4-channel RGBA: gray is replicated, a missing alpha becomes 1.
    pub fn to_rgba(&self) -> Image {
        let cc = self.color_channels();
        let alpha = self.has_alpha();
        self.map_pixels(4, |p, o| {
            if cc == 3 {
                o[..3].copy_from_slice(&p[..3]);
            } else {
                o[..3].fill(p[0]);
            }
            o[3] = if alpha { p[cc] } else { 1.0 };
        })
    }

    /// The colour channels only (gray → 1 channel, RGB(A) → 3 channels).
    pub fn without_alpha(&self) -> Image {
        if !self.has_alpha() {
            return self.clone();
        }
        let cc = self.color_channels();
        self.map_pixels(cc, |p, o| o.copy_from_slice(&p[..cc]))
    }

    /// The alpha channel as a 1-channel image, if there is one.
    pub fn alpha(&self) -> Option<Image> {
        if !self.has_alpha() {
            return None;
        }
        let a = self.channels - 1;
        Some(self.map_pixels(1, |p, o| o[0] = p[a]))
    }

    /// The image mirrored top to bottom.
    pub fn flipped_vertically(&self) -> Image {
        let n = self.width * self.channels;
        let mut data = Vec::with_capacity(self.data.len());
        for y in (0..self.height).rev() {
            data.extend_from_slice(&self.data[y * n..(y + 1) * n]);
        }
        Image {
            data,
            ..self.shallow()
        }
    }

    /// Smallest and largest finite sample, ignoring NaN and ±∞ (`None` when there is none).
    pub fn finite_range(&self) -> Option<(f32, f32)> {
        let mut range: Option<(f32, f32)> = None;
        for &v in self.data.iter().filter(|v| v.is_finite()) {
            range = Some(match range {
                None => (v, v),
                Some((lo, hi)) => (lo.min(v), hi.max(v)),
            });
        }
        range
    }

    /// Largest absolute difference between corresponding samples of two images of equal shape
    /// (`None` when the shapes differ). NaN samples equal only NaN samples.
    pub fn max_abs_diff(&self, other: &Image) -> Option<f32> {
        if (self.width, self.height, self.channels) != (other.width, other.height, other.channels) {
            return None;
        }
        let mut m = 0.0f32;
        for (&a, &b) in self.data.iter().zip(&other.data) {
            if a.is_nan() || b.is_nan() {
                if a.is_nan() != b.is_nan() {
                    return Some(f32::INFINITY);
                }
            } else if a != b {
                m = m.max((a - b).abs());
            }
        }
        Some(m)
    }

    fn shallow(&self) -> Image {
        Image {
            width: self.width,
            height: self.height,
            channels: self.channels,
            data: Vec::new(),
        }
    }
}

/// `width * height * channels`, checked for overflow, the channel range and [`MAX_SAMPLES`].
pub(crate) fn sample_count(
    width: usize,
    height: usize,
    channels: usize,
) -> Result<usize, ImageError> {
    if !(1..=4).contains(&channels) {
        return Err(ImageError::InvalidDimensions(format!(
            "{channels} channels (1 to 4 supported)"
        )));
    }
    width
        .checked_mul(height)
        .and_then(|n| n.checked_mul(channels))
        .filter(|&n| n <= MAX_SAMPLES)
        .ok_or_else(|| {
            ImageError::InvalidDimensions(format!(
                "{width}x{height}x{channels} exceeds the limit of {MAX_SAMPLES} samples"
            ))
        })
}

/// An image of one colour plus a horizontal ramp (`constant`): test patterns, backgrounds.
#[derive(Clone, Debug, PartialEq, vfxgraph_params::Options)]
pub struct ConstantOptions {
    /// pixels
    #[param(range = 1..=65536)]
    pub width: usize,
    /// pixels
    #[param(range = 1..=65536)]
    pub height: usize,
    /// linear RGB
    pub color: [f64; 3],
    /// added × x/width
    #[param(range = -1e6..=1e6)]
    pub ramp: f64,
}

impl Default for ConstantOptions {
    fn default() -> Self {
        ConstantOptions {
            width: 64,
            height: 64,
            color: [0.18; 3],
            ramp: 0.0,
        }
    }
}

/// The RGB image of `o`: `color + ramp × x / width` on every channel.
pub fn constant(o: &ConstantOptions) -> Result<Image, ImageError> {
    let (w, h) = (o.width, o.height);
    Image::try_new(w, h, 3)?;
    Ok(Image::from_fn(w, h, 3, |x, _, c| {
        (o.color[c] + o.ramp * x as f64 / w as f64) as f32
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layout_is_row_major_interleaved() {
        let img = Image::from_fn(3, 2, 3, |x, y, c| (100 * y + 10 * x + c) as f32);
        assert_eq!(img.data.len(), 18);
        assert_eq!(img.get(2, 1, 1), 121.0);
        assert_eq!(img.data[(3 + 2) * 3 + 1], 121.0);
        assert_eq!(img.pixel(1, 1), &[110.0, 111.0, 112.0]);
        assert_eq!(img.row(1)[0], 100.0);
        let mut m = img.clone();
        m.set(0, 1, 2, -5.0);
        assert_eq!(m.get(0, 1, 2), -5.0);
        assert_eq!(m.pixel(0, 1)[2], -5.0);
    }

    #[test]
    fn from_vec_checks_length_and_channels() {
        assert!(Image::from_vec(2, 2, 3, vec![0.0; 12]).is_ok());
        assert!(matches!(
            Image::from_vec(2, 2, 3, vec![0.0; 11]),
            Err(ImageError::InvalidDimensions(_))
        ));
        assert!(matches!(
            Image::from_vec(1, 1, 0, vec![]),
            Err(ImageError::InvalidDimensions(_))
        ));
        assert!(matches!(
            Image::from_vec(1, 1, 5, vec![0.0; 5]),
            Err(ImageError::InvalidDimensions(_))
        ));
        assert!(matches!(
            Image::try_new(usize::MAX, 2, 1),
            Err(ImageError::InvalidDimensions(_))
        ));
        assert!(matches!(
            Image::try_new(1 << 20, 1 << 20, 1),
            Err(ImageError::InvalidDimensions(_))
        ));
        assert!(Image::try_new(0, 5, 3).unwrap().is_empty());
    }

    #[test]
    fn map_parallel_and_serial_agree() {
        let big = Image::from_fn(300, 200, 3, |x, y, c| (x + y + c) as f32);
        let mapped = big.map(|v| v * 2.0 + 1.0);
        for (a, b) in big.data.iter().zip(&mapped.data) {
            assert_eq!(*b, a * 2.0 + 1.0);
        }
        let small = Image::from_fn(3, 2, 4, |x, _, c| (x * c) as f32);
        let m = small.map_color(|v| v + 1.0);
        assert_eq!(m.get(2, 0, 3), small.get(2, 0, 3), "alpha untouched");
        assert_eq!(m.get(2, 0, 2), small.get(2, 0, 2) + 1.0);
    }

    #[test]
    fn channel_conversions() {
        let rgb = Image::from_vec(1, 1, 3, vec![1.0, 0.5, 0.25]).unwrap();
        let lum = rgb.luminance();
        assert_eq!(lum.channels, 1);
        assert!((lum.data[0] - (0.2126 + 0.5 * 0.7152 + 0.25 * 0.0722)).abs() < 1e-6);
        let rgba = rgb.to_rgba();
        assert_eq!(rgba.data, vec![1.0, 0.5, 0.25, 1.0]);
        assert_eq!(rgba.to_rgb(), rgb);
        assert_eq!(rgba.alpha().unwrap().data, vec![1.0]);
        assert_eq!(rgba.without_alpha(), rgb);
        let ga = Image::from_vec(1, 1, 2, vec![0.3, 0.7]).unwrap();
        assert_eq!(ga.to_rgba().data, vec![0.3, 0.3, 0.3, 0.7]);
        assert_eq!(ga.to_rgb().data, vec![0.3, 0.3, 0.3]);
        assert_eq!(ga.luminance().data, vec![0.3]);
    }

    #[test]
    fn flip_and_ranges() {
        let img = Image::from_fn(2, 3, 1, |_, y, _| y as f32);
        let f = img.flipped_vertically();
        assert_eq!(f.get(0, 0, 0), 2.0);
        assert_eq!(f.flipped_vertically(), img);
        let mut n = img.clone();
        n.data[0] = f32::NAN;
        n.data[1] = f32::INFINITY;
        assert_eq!(n.finite_range(), Some((1.0, 2.0)));
        assert_eq!(n.max_abs_diff(&n), Some(0.0));
        assert_eq!(img.max_abs_diff(&n), Some(f32::INFINITY));
    }
}
