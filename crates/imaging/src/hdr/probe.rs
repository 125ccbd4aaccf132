//! Light probe (mirror ball) → equirectangular conversion (book 10.7; Debevec 1998, "Rendering
//! Synthetic Objects into Real Scenes", §3: a mirrored sphere photographed from afar sees the
//! whole environment).
//!
//! # Conventions
//!
//! - **Probe.** The photograph holds the ball as a disc of centre `(cx, cy)` and radius `r`
//!   pixels (pixel coordinates with the top-left pixel's centre at (0, 0), y down), seen by an
//!   orthographic camera looking along **−z** with **+y** up and +x to the right. A ball point
//!   at normalised disc coordinates `(s, t) = ((x − cx)/r, (y − cy)/r)` has the normal
//!   `N = (s, −t, √(1 − s² − t²))` and reflects the view direction `(0, 0, −1)` into
//!   `D = (2 N_z N_x, 2 N_z N_y, 2 N_z² − 1)`; conversely `N = unit(D + (0, 0, 1))`.
//!   The disc centre sees +z (behind the camera); the rim sees −z (behind the ball), where the
//!   mapping is singular and resolution is poorest.
//! - **Equirect.** The layout of `vfxgraph_render::dome::Dome::y_up`: longitude across, latitude
//!   down, top row +y, centre column −z, +x at `3w/4`; texel `(i, j)` is the direction at
//!   `θ = π (j + ½)/h`, `φ = π (1 − 2 (i + ½)/w)`, `D = (−sin θ sin φ, cos θ, −sin θ cos φ)`.

use rayon::prelude::*;

use super::HdrError;
use crate::Image;

/// Where the ball is in the probe photograph.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProbeCircle {
    /// Centre x, pixels.
    pub cx: f64,
    /// Centre y, pixels.
    pub cy: f64,
    /// Radius, pixels.
    pub radius: f64,
}

impl ProbeCircle {
    /// The disc inscribed in an image cropped to the ball (the usual light-probe layout).
    pub fn inscribed(width: usize, height: usize) -> ProbeCircle {
        ProbeCircle {
            cx: (width as f64 - 1.0) / 2.0,
            cy: (height as f64 - 1.0) / 2.0,
            radius: width.min(height) as f64 / 2.0,
        }
    }
}

/// The unwrapping of a probe photograph: where the ball is and the output width.
#[derive(Clone, Debug, PartialEq, vfxgraph_params::Options)]
#[param(check)]
pub struct ProbeOptions {
    /// [cx, cy, radius] of the ball in pixels; [] = the disc inscribed in the image
    pub circle: Vec<f64>,
    /// output width (height = width / 2)
    #[param(range = 2..=65536)]
    pub width: usize,
}

impl Default for ProbeOptions {
    fn default() -> Self {
        ProbeOptions {
            circle: Vec::new(),
            width: 1024,
        }
    }
}

impl ProbeOptions {
    /// `circle` is empty or three numbers.
    pub fn check(&self) -> Result<(), String> {
        match self.circle.len() {
            0 | 3 => Ok(()),
            n => Err(format!("circle needs [cx, cy, radius], got {n} numbers")),
        }
    }

    /// The ball in a `width × height` probe photograph: `circle`, or the inscribed disc.
    pub fn circle_in(&self, width: usize, height: usize) -> ProbeCircle {
        match self.circle[..] {
            [cx, cy, radius] => ProbeCircle { cx, cy, radius },
            _ => ProbeCircle::inscribed(width, height),
        }
    }
}

/// The unit direction of texel `(i, j)` of a `w × h` equirectangular image (see the module
/// conventions).
pub fn equirect_direction(i: f64, j: f64, w: usize, h: usize) -> [f64; 3] {
    let theta = std::f64::consts::PI * (j + 0.5) / h as f64;
    let phi = std::f64::consts::PI * (1.0 - 2.0 * (i + 0.5) / w as f64);
    let (st, ct) = theta.sin_cos();
    [-st * phi.sin(), ct, -st * phi.cos()]
}

/// The probe-image position `(x, y)` that reflects world direction `d` (unit), for the ball
/// `circle`.
pub fn probe_position(d: [f64; 3], circle: &ProbeCircle) -> (f64, f64) {
    let h = [d[0], d[1], d[2] + 1.0];
    let n = (h[0] * h[0] + h[1] * h[1] + h[2] * h[2]).sqrt();
    let (s, t) = if n < 1e-12 {
        (1.0, 0.0) // straight behind the ball: any rim point
    } else {
        (h[0] / n, -h[1] / n)
    };
    (circle.cx + circle.radius * s, circle.cy + circle.radius * t)
}

/// Resamples a mirror-ball light probe into a `width × width/2` equirectangular image (bilinear
/// lookups; book 10.7). Channels are kept. Errors: an empty probe, a zero width, or a circle that
/// is not finite and positive.
pub fn probe_to_equirect(
    probe: &Image,
    circle: &ProbeCircle,
    width: usize,
) -> Result<Image, HdrError> {
    if probe.is_empty() || width < 2 {
        return Err(HdrError::InvalidArgument(
            "the probe is empty or the output width is below 2".into(),
        ));
    }
    if ![circle.cx, circle.cy, circle.radius]
        .iter()
        .all(|v| v.is_finite())
        || circle.radius <= 0.0
    {
        return Err(HdrError::InvalidArgument(format!(
            "probe circle {circle:?} must be finite with a positive radius"
        )));
    }
    let (w, h) = (width, (width / 2).max(1));
    let c_n = probe.channels;
    let mut out = Image::try_new(w, h, c_n)?;
    out.data
        .par_chunks_mut(w * c_n)
        .enumerate()
        .for_each(|(j, row)| {
            for i in 0..w {
                let d = equirect_direction(i as f64, j as f64, w, h);
                let (x, y) = probe_position(d, circle);
                bilinear(probe, x, y, &mut row[i * c_n..(i + 1) * c_n]);
            }
        });
    Ok(out)
}

/// Bilinear sample at pixel-centre coordinates, clamped to the image.
fn bilinear(img: &Image, x: f64, y: f64, out: &mut [f32]) {
    let (w, h) = (img.width as f64, img.height as f64);
    let x = x.clamp(0.0, w - 1.0);
    let y = y.clamp(0.0, h - 1.0);
    let (x0, y0) = (x.floor() as usize, y.floor() as usize);
    let (x1, y1) = ((x0 + 1).min(img.width - 1), (y0 + 1).min(img.height - 1));
    let (fx, fy) = ((x - x0 as f64) as f32, (y - y0 as f64) as f32);
    for (c, o) in out.iter_mut().enumerate() {
        *o = img.get(x0, y0, c) * (1.0 - fx) * (1.0 - fy)
            + img.get(x1, y0, c) * fx * (1.0 - fy)
            + img.get(x0, y1, c) * (1.0 - fx) * fy
            + img.get(x1, y1, c) * fx * fy;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A smooth environment: RGB = (D + 1) / 2.
    fn env(d: [f64; 3]) -> [f32; 3] {
        d.map(|v| ((v + 1.0) / 2.0) as f32)
    }

    #[test]
    fn a_rendered_mirror_ball_unwraps_to_its_environment() {
        // Render the ball: each disc pixel shows env(reflection of the view ray).
        let n = 257;
        let circle = ProbeCircle::inscribed(n, n);
        let probe = Image::from_fn(n, n, 3, |x, y, c| {
            let s = (x as f64 - circle.cx) / circle.radius;
            let t = (y as f64 - circle.cy) / circle.radius;
            let r2 = s * s + t * t;
            if r2 >= 1.0 {
                return 0.0;
            }
            let nz = (1.0 - r2).sqrt();
            let nn = [s, -t, nz];
            let d = [2.0 * nz * nn[0], 2.0 * nz * nn[1], 2.0 * nz * nz - 1.0];
            env(d)[c]
        });
        let eq = probe_to_equirect(&probe, &circle, 128).unwrap();
        assert_eq!((eq.width, eq.height), (128, 64));
        let mut errs = Vec::new();
        for j in 0..64 {
            for i in 0..128 {
                let d = equirect_direction(i as f64, j as f64, 128, 64);
                if d[2] < -0.7 {
                    continue; // near the rim: singular, poorly resolved
                }
                for (c, want) in env(d).iter().enumerate() {
                    errs.push((eq.get(i, j, c) - want).abs());
                }
            }
        }
        errs.sort_by(f32::total_cmp);
        let p99 = errs[errs.len() * 99 / 100];
        assert!(p99 < 0.02, "99th percentile error {p99}");
        // Layout: the top row is +y, the centre column −z, +x at 3w/4.
        let d = equirect_direction(95.5, 31.5, 128, 64);
        assert!((d[0] - 1.0).abs() < 1e-3, "{d:?}");
        assert!(equirect_direction(0.0, 0.0, 128, 64)[1] > 0.99);
        let bad = ProbeCircle {
            radius: 0.0,
            ..circle
        };
        assert!(probe_to_equirect(&probe, &bad, 128).is_err());
        assert!(probe_to_equirect(&probe, &circle, 1).is_err());
    }
}
