//! Undistorting and redistorting images through a lens (not in the book, whose cameras are ideal
//! pinholes, §2.7): the plate as an ideal pinhole with the same focal length would have seen it,
//! and back.
//!
//! A plate taken through a lens `K`, [`crate::lens::Distortion`] images the ray of undistorted
//! normalized point p at the pixel K·distort(p). Its *undistorted* image is the pinhole image
//! K′·p with the same focal lengths and skew; with **overscan** (the default) K′'s principal point
//! and the image size are chosen so that the whole plate's footprint — the undistorted images of
//! its border, sampled at every pixel of its four edges, plus `margin` pixels — fits: nothing of
//! the plate is lost (a barrel lens's corners stretch outwards), and a lens-free K gives back K
//! and the plate's size exactly. Without overscan K′ = K and the size is the plate's (a crop).
//!
//! The two warps are coordinate maps followed by a bilinear lookup (pixel-centre convention,
//! ARCHITECTURE.md, "Conventions"):
//! - undistort: output pixel x′ of the pinhole image samples the plate at K·distort(K′⁻¹x′);
//! - redistort: output pixel x of the plate samples the pinhole image at K′·undistort(K⁻¹x)
//!   (Newton's method, converged to 1e-12 normalized units).
//!
//! They are inverse maps, so undistort ∘ redistort is the identity on coordinates (tested within
//! 0.01 px over the frame). Samples that fall outside the source — the overscan's corners beyond
//! the plate, or beyond the radius the lens was validated to — are 0. The same maps written as
//! images are Nuke's ST-maps ([`crate::st_map`]). Equivalent to OpenCV's
//! `getOptimalNewCameraMatrix` (alpha = 1, keeping every source pixel) + `initUndistortRectifyMap`
//! + `remap`, and to Nuke's LensDistortion node with overscan.

use nalgebra::Point2;
use rayon::prelude::*;
use vfxgraph_imaging::Image;

use crate::camera::Intrinsics;
use crate::error::{Result, VisionError};

/// How the undistorted image is framed.
#[derive(Clone, Debug, PartialEq, vfxgraph_params::Options)]
#[param(check)]
pub struct UndistortOptions {
    /// make the undistorted image as large as the plate's undistorted footprint (nothing is
    /// lost); off: the plate's size and K (the footprint cropped)
    pub overscan: bool,
    /// extra pixels around the footprint on every side (with overscan)
    #[param(range = 0.0..=10000.0)]
    pub margin: f64,
}

impl Default for UndistortOptions {
    fn default() -> Self {
        UndistortOptions {
            overscan: true,
            margin: 0.0,
        }
    }
}

impl UndistortOptions {
    /// The margin must be finite and non-negative.
    pub fn check(&self) -> std::result::Result<(), String> {
        if !(self.margin.is_finite() && self.margin >= 0.0) {
            return Err(format!(
                "margin must be finite and ≥ 0, got {}",
                self.margin
            ));
        }
        Ok(())
    }
}

/// A lens and the pinhole camera of its undistorted images: the two sides of the warps.
#[derive(Clone, Debug, PartialEq)]
pub struct LensWarp {
    /// The plate's intrinsics: K, the lens and the plate's size.
    pub lens: Intrinsics,
    /// The undistorted images' intrinsics: K′ (same focal lengths and skew), no lens, their size.
    pub pinhole: Intrinsics,
    /// The largest undistorted normalized radius of the plate (2 % beyond its corners): points
    /// farther out are outside the plate, and the lens is checked monotonic out to it.
    r_max: f64,
}

fn size_of(k: &Intrinsics, what: &str) -> Result<(usize, usize)> {
    match (k.width, k.height) {
        (Some(w), Some(h)) if w > 0 && h > 0 => Ok((w as usize, h as usize)),
        _ => Err(VisionError::InvalidInput(format!(
            "{what} intrinsics carry no image size (give K with `width` and `height`)"
        ))),
    }
}

impl LensWarp {
    /// The warp of the plate's intrinsics `lens` (which must carry the image size; a pinhole is
    /// allowed and gives the identity) framed by `options`.
    pub fn new(lens: &Intrinsics, options: &UndistortOptions) -> Result<LensWarp> {
        options.check().map_err(VisionError::InvalidInput)?;
        let (w, h) = size_of(lens, "the plate's")?;
        lens.validate()?;
        let r_max = lens.undistorted_corner_radius()?.unwrap_or(0.0);
        let mut pinhole = lens.pinhole();
        if options.overscan && !lens.is_pinhole() {
            // The footprint: the undistorted images of the plate's pixel edges.
            let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
            let (wf, hf) = (w as f64, h as f64);
            let mut add = |x: f64, y: f64| -> Result<()> {
                let p = lens.undistort_pixel(&Point2::new(x, y))?;
                (x0, x1, y0, y1) = (x0.min(p.x), x1.max(p.x), y0.min(p.y), y1.max(p.y));
                Ok(())
            };
            for i in 0..=w {
                add(i as f64 - 0.5, -0.5)?;
                add(i as f64 - 0.5, hf - 0.5)?;
            }
            for j in 0..=h {
                add(-0.5, j as f64 - 0.5)?;
                add(wf - 0.5, j as f64 - 0.5)?;
            }
            let m = options.margin;
            // 1e-9: a lens that changes nothing keeps the plate's size exactly.
            let nw = (x1 - x0 + 2.0 * m - 1e-9).ceil().max(1.0);
            let nh = (y1 - y0 + 2.0 * m - 1e-9).ceil().max(1.0);
            // The footprint's centre goes to the new image's centre.
            pinhole.u0 += (nw - 1.0) / 2.0 - (x0 + x1) / 2.0;
            pinhole.v0 += (nh - 1.0) / 2.0 - (y0 + y1) / 2.0;
            if nw * nh > 1e9 {
                return Err(VisionError::InvalidInput(format!(
                    "the undistorted image would be {nw}×{nh} pixels: the {} lens stretches the \
                     plate too far",
                    lens.distortion.name()
                )));
            }
            pinhole.width = Some(nw as u32);
            pinhole.height = Some(nh as u32);
        }
        Ok(LensWarp {
            lens: lens.clone(),
            pinhole,
            r_max,
        })
    }

    /// Where the undistorted image's pixel position `x` samples the plate (undistort's map);
    /// `None` beyond the plate's undistorted radius (the overscan's outer corners).
    pub fn plate_of_undistorted(&self, x: [f64; 2]) -> Option<[f64; 2]> {
        if self.lens.is_pinhole() {
            // K′ = K: the identity, exactly.
            return Some(x);
        }
        let p = self.pinhole.unproject(&Point2::new(x[0], x[1]));
        let (px, py) = (p.x / p.z, p.y / p.z);
        if !self.lens.is_pinhole() && px.hypot(py) > self.r_max {
            return None;
        }
        let q = self.lens.pixel_of_normalized([px, py]).ok()?;
        Some([q.x, q.y])
    }

    /// Where the plate's pixel position `x` samples the undistorted image (redistort's map).
    pub fn undistorted_of_plate(&self, x: [f64; 2]) -> Result<[f64; 2]> {
        if self.lens.is_pinhole() {
            return Ok(x);
        }
        let p = self.lens.normalized_of_pixel(&Point2::new(x[0], x[1]))?;
        let (k, s) = (&self.pinhole, p);
        Ok([k.f1 * s[0] + k.s * s[1] + k.u0, k.f2 * s[1] + k.v0])
    }

    /// The plate's size.
    pub fn plate_size(&self) -> (usize, usize) {
        size_of(&self.lens, "").expect("checked in new")
    }

    /// The undistorted images' size.
    pub fn undistorted_size(&self) -> (usize, usize) {
        size_of(&self.pinhole, "").expect("set in new")
    }

    /// The plate as the pinhole [`LensWarp::pinhole`] sees it (size: the undistorted size).
    pub fn undistort(&self, plate: &Image) -> Result<Image> {
        check_size(plate, self.plate_size(), "plate (undistort's input)")?;
        let (w, h) = self.undistorted_size();
        Ok(warp(plate, w, h, |x, y| {
            self.plate_of_undistorted([x as f64, y as f64])
        }))
    }

    /// An undistorted (pinhole K′) image seen through the lens again (size: the plate's).
    pub fn redistort(&self, undistorted: &Image) -> Result<Image> {
        check_size(
            undistorted,
            self.undistorted_size(),
            "undistorted image (redistort's input)",
        )?;
        let (w, h) = self.plate_size();
        Ok(warp(undistorted, w, h, |x, y| {
            self.undistorted_of_plate([x as f64, y as f64]).ok()
        }))
    }
}

fn check_size(img: &Image, (w, h): (usize, usize), what: &str) -> Result<()> {
    if (img.width, img.height) != (w, h) {
        return Err(VisionError::InvalidInput(format!(
            "the {what} is {}×{} but the lens's image is {w}×{h}",
            img.width, img.height
        )));
    }
    Ok(())
}

/// A `w`×`h` image whose pixel (x, y) is `src` sampled bilinearly at `map(x, y)` (pixel-centre
/// convention; clamped to the edge within the source's outer pixel edges, 0 beyond or where the
/// map has no position).
pub fn warp(
    src: &Image,
    w: usize,
    h: usize,
    map: impl Fn(usize, usize) -> Option<[f64; 2]> + Sync,
) -> Image {
    let c = src.channels;
    let mut out = Image::new(w, h, c);
    out.data
        .par_chunks_mut((w * c).max(1))
        .enumerate()
        .for_each(|(y, row)| {
            for x in 0..w {
                if let Some(s) = map(x, y) {
                    bilinear(src, s, &mut row[x * c..(x + 1) * c]);
                }
            }
        });
    out
}

/// `src` at position `s`, bilinear, written to `out` (left 0 outside the source's pixel edges).
pub fn bilinear(src: &Image, s: [f64; 2], out: &mut [f32]) {
    let (w, h) = (src.width as f64, src.height as f64);
    if !(s[0] >= -0.5 && s[0] <= w - 0.5 && s[1] >= -0.5 && s[1] <= h - 0.5) {
        return;
    }
    let x = s[0].clamp(0.0, w - 1.0);
    let y = s[1].clamp(0.0, h - 1.0);
    let (x0, y0) = (x.floor() as usize, y.floor() as usize);
    let (x1, y1) = ((x0 + 1).min(src.width - 1), (y0 + 1).min(src.height - 1));
    let (fx, fy) = ((x - x0 as f64) as f32, (y - y0 as f64) as f32);
    for (k, o) in out.iter_mut().enumerate() {
        let a = src.get(x0, y0, k) * (1.0 - fx) + src.get(x1, y0, k) * fx;
        let b = src.get(x0, y1, k) * (1.0 - fx) + src.get(x1, y1, k) * fx;
        *o = a * (1.0 - fy) + b * fy;
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::lens::Distortion;

    /// The lens of `blender_plate_dev/distorted` (its README) on its 960×540 frame.
    pub(crate) fn dev_lens() -> Intrinsics {
        Intrinsics::new(920.0, 920.0, 479.5, 269.5)
            .with_size(960, 540)
            .with_distortion(Distortion::BrownConrady {
                k1: -0.16,
                k2: 0.045,
                k3: 0.0,
                p1: 0.0008,
                p2: -0.0005,
            })
    }

    /// Every pixel of the plate (and its outer edges), through redistort's map then
    /// undistort's: back where it started (the goal: 0.01 px; Newton's tolerance gives
    /// 3.5e-13–4.7e-13 px, bound 1e-12). Also a wide-angle division lens and a pincushion lens.
    #[test]
    fn undistort_after_redistort_is_the_identity_over_the_frame() {
        let lenses = [
            dev_lens(),
            dev_lens().with_distortion(Distortion::Division {
                k1: -0.25,
                k2: 0.02,
            }),
            dev_lens().with_distortion(Distortion::BrownConrady {
                k1: 0.08,
                k2: -0.02,
                k3: 0.004,
                p1: -0.001,
                p2: 0.002,
            }),
        ];
        for lens in lenses {
            let warp = LensWarp::new(&lens, &UndistortOptions::default()).unwrap();
            let mut worst: f64 = 0.0;
            for j in 0..=540 {
                for i in 0..=960 {
                    let x = [i as f64 - 0.5, j as f64 - 0.5];
                    let u = warp.undistorted_of_plate(x).unwrap();
                    let back = warp.plate_of_undistorted(u).unwrap();
                    worst = worst.max((back[0] - x[0]).hypot(back[1] - x[1]));
                }
            }
            eprintln!("{:?}: worst round trip {worst:.2e} px", lens.distortion);
            assert!(worst < 1e-12, "{:?}: {worst} px", lens.distortion);
        }
    }

    /// Overscan keeps the whole plate: every plate pixel edge lands inside the undistorted image,
    /// and the undistorted image is larger than the plate for the dev plate's barrel lens (its
    /// corners stretch out by ≈ 30 px); a lens-free K gives back K and the size exactly.
    #[test]
    fn overscan_keeps_every_plate_pixel() {
        let warp = LensWarp::new(&dev_lens(), &UndistortOptions::default()).unwrap();
        let (w, h) = warp.undistorted_size();
        assert!(w > 960 && h > 540, "{w}×{h}");
        let inside = |x: [f64; 2]| {
            let u = warp.undistorted_of_plate(x).unwrap();
            let eps = 1e-9;
            assert!(
                u[0] >= -0.5 - eps
                    && u[0] <= w as f64 - 0.5 + eps
                    && u[1] >= -0.5 - eps
                    && u[1] <= h as f64 - 0.5 + eps,
                "{x:?} → {u:?} outside {w}×{h}"
            );
        };
        for i in 0..=960 {
            inside([i as f64 - 0.5, -0.5]);
            inside([i as f64 - 0.5, 539.5]);
        }
        for j in 0..=540 {
            inside([-0.5, j as f64 - 0.5]);
            inside([959.5, j as f64 - 0.5]);
        }
        let crop = LensWarp::new(
            &dev_lens(),
            &UndistortOptions {
                overscan: false,
                margin: 0.0,
            },
        )
        .unwrap();
        assert_eq!(crop.undistorted_size(), (960, 540));
        let pin = LensWarp::new(&dev_lens().pinhole(), &UndistortOptions::default()).unwrap();
        assert_eq!(pin.pinhole, dev_lens().pinhole());
        let plate = Image::from_fn(960, 540, 1, |x, y, _| ((x * 7 + y * 13) % 17) as f32);
        assert!(
            pin.undistort(&plate).unwrap() == plate,
            "a pinhole's undistort changes the plate"
        );
    }

    /// A pinhole image of a known point, redistorted, shows it where the lens images the point;
    /// and the undistorted image of a lens render shows it where the pinhole K′ does.
    #[test]
    fn images_move_points_where_the_lens_does() {
        let lens = dev_lens();
        let warp = LensWarp::new(&lens, &UndistortOptions::default()).unwrap();
        let (uw, uh) = warp.undistorted_size();
        // A smooth blob at a known undistorted normalized point near a corner.
        let p = [-0.45, 0.25];
        let k2 = &warp.pinhole;
        let c = [k2.f1 * p[0] + k2.u0, k2.f2 * p[1] + k2.v0];
        let blob = |cx: f64, cy: f64, w, h| {
            Image::from_fn(w, h, 1, move |x, y, _| {
                let d2 = (x as f64 - cx).powi(2) + (y as f64 - cy).powi(2);
                (-d2 / (2.0 * 3.0f64.powi(2))).exp() as f32
            })
        };
        let undistorted = blob(c[0], c[1], uw, uh);
        let plate = warp.redistort(&undistorted).unwrap();
        let want = lens.pixel_of_normalized(p).unwrap();
        let centroid = |img: &Image| {
            let (mut sx, mut sy, mut s) = (0.0, 0.0, 0.0);
            for y in 0..img.height {
                for x in 0..img.width {
                    let v = img.get(x, y, 0) as f64;
                    if v > 0.05 {
                        (sx, sy, s) = (sx + v * x as f64, sy + v * y as f64, s + v);
                    }
                }
            }
            [sx / s, sy / s]
        };
        let got = centroid(&plate);
        let e = (got[0] - want.x).hypot(got[1] - want.y);
        assert!(e < 0.1, "blob at {got:?}, lens images it at {want}: {e} px");
        let back = centroid(&warp.undistort(&blob(want.x, want.y, 960, 540)).unwrap());
        let e = (back[0] - c[0]).hypot(back[1] - c[1]);
        assert!(e < 0.1, "undistorted blob at {back:?}, want {c:?}: {e} px");
    }

    #[test]
    fn bad_input_is_an_error_naming_it() {
        let no_size = Intrinsics::new(920.0, 920.0, 479.5, 269.5);
        let e = LensWarp::new(&no_size, &UndistortOptions::default()).unwrap_err();
        assert!(e.to_string().contains("no image size"), "{e}");
        let warp = LensWarp::new(&dev_lens(), &UndistortOptions::default()).unwrap();
        let e = warp.undistort(&Image::new(10, 10, 3)).unwrap_err();
        assert!(e.to_string().contains("10×10"), "{e}");
        let fold = dev_lens().with_distortion(Distortion::BrownConrady {
            k1: -0.9,
            k2: 0.0,
            k3: 0.0,
            p1: 0.0,
            p2: 0.0,
        });
        assert!(LensWarp::new(&fold, &UndistortOptions::default()).is_err());
    }
}
