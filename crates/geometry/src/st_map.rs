//! ST-maps: a lens warp as an image, in Nuke's STMap convention (not in the book).
//!
//! Nuke's STMap node (Nuke Reference Guide, "STMap") moves pixels by a UV image: output pixel
//! (x, y)'s red and green channels hold the position to sample the source at, normalized to
//! 0–1 over the *source's* size, with the origin at the bottom-left corner: s = 0 at the source's
//! left edge and 1 at its right edge, t = 0 at its bottom edge and 1 at its top. In this
//! project's pixel-centre convention (y down, pixel (0, 0) the top-left pixel's centre;
//! ARCHITECTURE.md, "Conventions") a source position (sx, sy) is therefore
//!
//!   s = (sx + ½) / W_src,   t = 1 − (sy + ½) / H_src,
//!
//! so the centre of the source's top-left pixel is (½ / W, 1 − ½ / H). The map is written as a
//! float (32-bit) EXR — half floats would round positions by up to 0.25 px at 2K — with blue 0;
//! positions with no source (the overscan's corners beyond the plate) hold s = t = −1, outside
//! 0–1, which STMap and OpenCV's `remap` with a constant border both show as black.
//!
//! Both directions of a [`LensWarp`]: **undistort** (the size of the undistorted image,
//! normalized by the plate's size: apply it to the plate) and **redistort** (the plate's size,
//! normalized by the undistorted image's size: apply it to a pinhole render with K′ to see it
//! through the lens). These are the maps a compositor uses instead of a LensDistortion node;
//! OpenCV's `remap` with map_x = s·W − ½, map_y = (1 − t)·H − ½ applies them the same way
//! (scripts/check/st_map_remap.py checks that against our `undistort`).

use vfxgraph_imaging::Image;

use crate::undistort::{LensWarp, UndistortOptions};

/// Which warp an ST-map encodes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, vfxgraph_params::Choice)]
pub enum StMapDirection {
    /// Plate → undistorted image: sized as the undistorted image, sampling the plate.
    #[default]
    Undistort,
    /// Undistorted image → plate: sized as the plate, sampling the undistorted image.
    Redistort,
}

/// The ST-map's options.
#[derive(Clone, Debug, Default, PartialEq, vfxgraph_params::Options)]
pub struct StMapOptions {
    /// `undistort`: the map that undistorts the plate; `redistort`: the map that puts a pinhole
    /// render through the lens
    pub direction: StMapDirection,
    /// How the undistorted image is framed (as `undistort`'s, so the maps fit its output).
    #[param(flatten)]
    pub framing: UndistortOptions,
}

/// The value an ST-map holds where the warp has no source position.
pub const NO_SOURCE: f32 = -1.0;

/// The (s, t) of source position `p` in a `w`×`h` source (module docs).
pub fn st_of_position(p: [f64; 2], (w, h): (usize, usize)) -> [f64; 2] {
    [(p[0] + 0.5) / w as f64, 1.0 - (p[1] + 0.5) / h as f64]
}

/// The source position of (s, t) in a `w`×`h` source (inverse of [`st_of_position`]).
pub fn position_of_st(st: [f64; 2], (w, h): (usize, usize)) -> [f64; 2] {
    [st[0] * w as f64 - 0.5, (1.0 - st[1]) * h as f64 - 0.5]
}

/// The ST-map of `warp` in `direction`: an RGB image (R = s, G = t, B = 0).
pub fn st_map(warp: &LensWarp, direction: StMapDirection) -> Image {
    let (out_size, src_size) = match direction {
        StMapDirection::Undistort => (warp.undistorted_size(), warp.plate_size()),
        StMapDirection::Redistort => (warp.plate_size(), warp.undistorted_size()),
    };
    let (w, h) = out_size;
    let mut img = Image::new(w, h, 3);
    use rayon::prelude::*;
    img.data
        .par_chunks_mut(w * 3)
        .enumerate()
        .for_each(|(y, row)| {
            for x in 0..w {
                let at = [x as f64, y as f64];
                let src = match direction {
                    StMapDirection::Undistort => warp.plate_of_undistorted(at),
                    StMapDirection::Redistort => warp.undistorted_of_plate(at).ok(),
                };
                let [s, t] = src.map_or([NO_SOURCE as f64; 2], |p| st_of_position(p, src_size));
                row[x * 3] = s as f32;
                row[x * 3 + 1] = t as f32;
            }
        });
    img
}

/// `src` warped by an ST-map (bilinear, as [`crate::undistort::warp`]; positions outside 0–1 are
/// black): what Nuke's STMap node does.
pub fn apply_st_map(src: &Image, map: &Image) -> Image {
    let size = (src.width, src.height);
    crate::undistort::warp(src, map.width, map.height, |x, y| {
        let st = [map.get(x, y, 0) as f64, map.get(x, y, 1) as f64];
        (st[0] >= 0.0 && st[1] >= 0.0).then(|| position_of_st(st, size))
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::undistort::tests::dev_lens;

    /// The convention's fixed points: the source's top-left pixel centre, its bottom-left and
    /// top-right corners.
    #[test]
    fn nuke_convention_origin_bottom_left() {
        let size = (960, 540);
        assert_eq!(
            st_of_position([0.0, 0.0], size),
            [0.5 / 960.0, 1.0 - 0.5 / 540.0]
        );
        assert_eq!(st_of_position([-0.5, 539.5], size), [0.0, 0.0]);
        assert_eq!(st_of_position([959.5, -0.5], size), [1.0, 1.0]);
        let p = [123.25, 456.75];
        let back = position_of_st(st_of_position(p, size), size);
        assert!((back[0] - p[0]).abs() < 1e-12 && (back[1] - p[1]).abs() < 1e-12);
    }

    /// An ST-map applied to the plate is our `undistort` (the map holds its positions to f32
    /// precision, ~1e-4 px), and the redistort map applied to that gives back the plate's
    /// interior up to two bilinear resamplings.
    #[test]
    fn applying_the_maps_is_the_warp() {
        let warp = LensWarp::new(&dev_lens(), &UndistortOptions::default()).unwrap();
        let plate = Image::from_fn(960, 540, 3, |x, y, c| {
            let (x, y) = (x as f32, y as f32);
            ((x * 0.05 + c as f32).sin() * (y * 0.04).cos() + 1.0) * 0.5
        });
        let und = warp.undistort(&plate).unwrap();
        let map = st_map(&warp, StMapDirection::Undistort);
        assert_eq!((map.width, map.height), warp.undistorted_size());
        let via_map = apply_st_map(&plate, &map);
        let d = via_map.max_abs_diff(&und).unwrap();
        assert!(d < 1e-4, "ST-map vs undistort: {d}");
        let back = apply_st_map(&und, &st_map(&warp, StMapDirection::Redistort));
        let mut worst: f32 = 0.0;
        for y in 20..520 {
            for x in 20..940 {
                for c in 0..3 {
                    worst = worst.max((back.get(x, y, c) - plate.get(x, y, c)).abs());
                }
            }
        }
        // Two bilinear resamplings of a pattern with a ~125 px period.
        assert!(worst < 0.01, "redistorted undistorted plate off by {worst}");
    }
}
