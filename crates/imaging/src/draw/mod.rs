//! Plots and overlays drawn into images for a person to look at (no text: axes are implied by
//! grid lines at round values), and plots of reports as SVG ([`svg`]).

pub mod svg;

use crate::hdr::{ResponseCurve, LEVELS};
use crate::Image;

/// The size of a plot.
#[derive(Clone, Debug, PartialEq, vfxgraph_params::Options)]
pub struct PlotOptions {
    /// pixels
    #[param(range = 64..=8192)]
    pub width: usize,
    /// pixels
    #[param(range = 64..=8192)]
    pub height: usize,
}

impl Default for PlotOptions {
    fn default() -> Self {
        PlotOptions {
            width: 640,
            height: 480,
        }
    }
}

/// Draws the response curve figure of Debevec & Malik 1997 (Fig. 2): pixel value z up against
/// log exposure g(z) across, one line per channel (red, green, blue; black for one channel), on
/// white with a grid at every unit of ln exposure and every 32 codes.
pub fn plot_response(curve: &ResponseCurve, o: &PlotOptions) -> Image {
    let (w, h) = (o.width, o.height);
    let mut img = Image::from_fn(w, h, 3, |_, _, _| 1.0);
    let (lo, hi) = curve
        .curves()
        .iter()
        .flatten()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    let (lo, hi) = (lo.floor(), hi.ceil().max(lo.floor() + 1.0));
    let m = 24.0;
    let (pw, ph) = (w as f64 - 2.0 * m, h as f64 - 2.0 * m);
    let to_px = |g: f64, z: f64| (m + (g - lo) / (hi - lo) * pw, m + (1.0 - z / 255.0) * ph);
    let dot = |img: &mut Image, x: f64, y: f64, col: [f32; 3], r: i64| {
        for dy in -r..=r {
            for dx in -r..=r {
                let (xi, yi) = (x.round() as i64 + dx, y.round() as i64 + dy);
                if xi >= 0 && yi >= 0 && (xi as usize) < w && (yi as usize) < h {
                    img.pixel_mut(xi as usize, yi as usize)
                        .copy_from_slice(&col);
                }
            }
        }
    };
    // Grid: every unit of ln exposure, every 32 codes; the frame darker.
    let grey = [0.75f32; 3];
    let mut g = lo;
    while g <= hi + 1e-9 {
        let (x, _) = to_px(g, 0.0);
        for yi in 0..(ph as usize) {
            dot(&mut img, x, m + yi as f64, grey, 0);
        }
        g += 1.0;
    }
    for z in (0..=256).step_by(32) {
        let (_, y) = to_px(lo, z.min(255) as f64);
        for xi in 0..(pw as usize) {
            dot(&mut img, m + xi as f64, y, grey, 0);
        }
    }
    let colours: [[f32; 3]; 4] = [
        [0.8, 0.0, 0.0],
        [0.0, 0.5, 0.0],
        [0.0, 0.0, 0.8],
        [0.2, 0.2, 0.2],
    ];
    let single = curve.channels() == 1;
    for (c, gc) in curve.curves().iter().enumerate() {
        let col = if single { [0.0; 3] } else { colours[c] };
        for z in 0..LEVELS - 1 {
            let (x0, y0) = to_px(gc[z], z as f64);
            let (x1, y1) = to_px(gc[z + 1], (z + 1) as f64);
            let steps = ((x1 - x0).abs().max((y1 - y0).abs()).ceil() as usize).max(1);
            for s in 0..=steps {
                let t = s as f64 / steps as f64;
                dot(&mut img, x0 + t * (x1 - x0), y0 + t * (y1 - y0), col, 1);
            }
        }
    }
    img
}

/// Sets pixel (`x`, `y`)'s colour channels to `c`; outside the image, nothing.
pub fn plot(img: &mut Image, x: i64, y: i64, c: [f32; 3]) {
    if x >= 0 && y >= 0 && (x as usize) < img.width && (y as usize) < img.height {
        img.pixel_mut(x as usize, y as usize)[..3].copy_from_slice(&c);
    }
}

/// A one-pixel line from `a` to `b` (pixel centres at integers), clipped to the image.
pub fn line(img: &mut Image, a: [f64; 2], b: [f64; 2], c: [f32; 3]) {
    let n = ((b[0] - a[0]).abs().max((b[1] - a[1]).abs()).ceil() as i64).clamp(1, 100_000);
    for k in 0..=n {
        let t = k as f64 / n as f64;
        let x = a[0] + (b[0] - a[0]) * t;
        let y = a[1] + (b[1] - a[1]) * t;
        plot(img, x.round() as i64, y.round() as i64, c);
    }
}

/// A cross of arms `r` pixels long centred on pixel (`x`, `y`).
pub fn cross(img: &mut Image, x: i64, y: i64, r: i64, c: [f32; 3]) {
    for d in -r..=r {
        plot(img, x + d, y, c);
        plot(img, x, y + d, c);
    }
}

/// The outline of a square of half side `r` centred on pixel (`x`, `y`).
pub fn square(img: &mut Image, x: i64, y: i64, r: i64, c: [f32; 3]) {
    for d in -r..=r {
        for (dx, dy) in [(d, -r), (d, r), (-r, d), (r, d)] {
            plot(img, x + dx, y + dy, c);
        }
    }
}

/// A bright, fully saturated colour (linear RGB) from an id: the same id, the same colour.
pub fn id_colour(id: u64) -> [f32; 3] {
    let h = (id.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 40) as f32 / (1u64 << 24) as f32;
    let h6 = h * 6.0;
    let x = 1.0 - (h6 % 2.0 - 1.0).abs();
    let (r, g, b) = match h6 as u32 {
        0 => (1.0, x, 0.0),
        1 => (x, 1.0, 0.0),
        2 => (0.0, 1.0, x),
        3 => (0.0, x, 1.0),
        4 => (x, 0.0, 1.0),
        _ => (1.0, 0.0, x),
    };
    [r, g, b]
}
