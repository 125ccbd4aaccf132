//! What a solve knows of the lens and what it solves of it ([`LensOptions`]: focal length,
//! distortion, principal point; an addition to the book, whose K comes from a prior
//! calibration, §7.1, and whose camera is an ideal pinhole, §2.7), and tracks undistorted by a
//! lens ([`undistort_tracks`]): the pinhole that the book's pipeline solves.

use serde::{Deserialize, Serialize};
use vfxgraph_geometry::camera::Intrinsics;
use vfxgraph_geometry::error::{Result, VisionError};
use vfxgraph_klt::Tracks;
use vfxgraph_lens::Distortion;
use vfxgraph_params::{Choice, Options};

/// What the solve knows of the focal length.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Choice)]
#[serde(rename_all = "lowercase")]
pub enum FocalMode {
    /// The intrinsics' focal length is exact: held.
    Known,
    /// The intrinsics' focal length is a starting value: refined with the cameras.
    Refine,
    /// No focal length is known: estimated from the tracks, then refined.
    Unknown,
}

/// Which distortion the solve estimates.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Choice)]
#[serde(rename_all = "lowercase")]
pub enum DistortionMode {
    /// None is estimated: the intrinsics' own distortion (a pinhole if they carry none) is held.
    None,
    /// Brown–Conrady k1 (OpenCV's model; k2 held).
    K1,
    /// Brown–Conrady k1 and k2.
    K1k2,
    /// Brown–Conrady k1, k2 and the tangential p1, p2 (OpenCV's model; k3 held).
    Brown,
    /// Fitzgibbon's one-parameter division model (wide angles).
    Division,
}

/// Where the principal point is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Choice)]
#[serde(rename_all = "lowercase")]
pub enum PrincipalPoint {
    /// Held: the intrinsics' (the image's centre without intrinsics).
    Centre,
    /// Refined with the lens, from the intrinsics' (or the centre).
    Refine,
}

/// The lens part of a matchmove.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Options)]
#[serde(default)]
pub struct LensOptions {
    /// the focal length: known (held), refine (from the intrinsics) or unknown (estimated)
    pub focal: FocalMode,
    /// the lens distortion solved with the cameras
    ///
    /// `none` holds the intrinsics' own distortion (none for a pinhole); `k1`, `k1k2`:
    /// Brown–Conrady radial terms (OpenCV's model); `brown`: with the tangential p1, p2;
    /// `division`: Fitzgibbon's model.
    pub distortion: DistortionMode,
    /// the principal point: centre (held) or refine (solved with the lens)
    pub principal_point: PrincipalPoint,
    /// rounds of undistort → pinhole solve → lens adjustment, when the lens is solved
    #[param(range = 1..=5)]
    pub lens_rounds: usize,
    /// a focal length per frame (a zooming lens), smoothed by `zoom_smoothness`
    ///
    /// The intrinsics' focal length is the first frame's: held with `focal: known` (what a
    /// shot that orbits or dollies needs: there the absolute focal length of a zoom is not
    /// determined), solved with `refine`; `unknown` estimates it. Needs `distortion: none`
    /// (the intrinsics' own lens is held).
    pub zoom: bool,
    /// the zoom's smoothness: σ of the focal length's second difference, px per frame²
    ///
    /// A frame whose focal length leaves the line through its neighbours' by σ costs what
    /// one observation 1 px off does; a steady zoom (a linear ramp) costs nothing.
    #[param(range = 1e-3..=1e4)]
    pub zoom_smoothness: f64,
    /// image width, px (0: the intrinsics', else the frames the tracks were measured on)
    #[param(range = 0..=100_000)]
    pub width: usize,
    /// image height, px (0: the intrinsics', else the tracked frames')
    #[param(range = 0..=100_000)]
    pub height: usize,
}

impl Default for LensOptions {
    fn default() -> Self {
        LensOptions {
            focal: FocalMode::Known,
            distortion: DistortionMode::None,
            principal_point: PrincipalPoint::Centre,
            lens_rounds: 1,
            zoom: false,
            zoom_smoothness: 1.0,
            width: 0,
            height: 0,
        }
    }
}

impl LensOptions {
    /// The intrinsics the solve starts from: `k` (when given) with the image size of the
    /// options where set; without `k`, a camera of that size with its principal point at the
    /// centre, which only `focal: unknown` can solve. The size is the options', else `k`'s,
    /// else `tracked` (the frames the tracks were measured on, [`Tracks::image_size`]).
    pub fn initial_intrinsics(
        &self,
        k: Option<&Intrinsics>,
        tracked: Option<[u32; 2]>,
    ) -> Result<Intrinsics> {
        let size = (self.width > 0 && self.height > 0)
            .then_some((self.width, self.height))
            .or_else(|| k.and_then(|k| Some((k.width? as usize, k.height? as usize))))
            .or_else(|| tracked.map(|[w, h]| (w as usize, h as usize)));
        let mut k = match (k, size) {
            (Some(k), _) => k.clone(),
            (None, Some((w, h))) => {
                if self.focal != FocalMode::Unknown {
                    return Err(VisionError::InvalidInput(
                        "without intrinsics the focal length is unknown: set focal: unknown".into(),
                    ));
                }
                let (w, h) = (w as f64, h as f64);
                Intrinsics::new(w.max(h), w.max(h), (w - 1.0) / 2.0, (h - 1.0) / 2.0)
            }
            (None, None) => {
                return Err(VisionError::InvalidInput(
                    "no intrinsics and no image size (the tracks do not record one): connect the \
                     intrinsics, or set focal: unknown with width and height"
                        .into(),
                ))
            }
        };
        if let Some((w, h)) = size {
            let (w, h) = (u32::try_from(w), u32::try_from(h));
            if let (Ok(w), Ok(h)) = (w, h) {
                k = k.with_size(w, h);
            }
        }
        Ok(k)
    }

    /// Whether anything of the lens is solved (otherwise `matchmove_with_lens` is the book's
    /// matchmove on the undistorted tracks).
    pub fn solves_lens(&self) -> bool {
        self.focal != FocalMode::Known
            || self.distortion != DistortionMode::None
            || self.principal_point == PrincipalPoint::Refine
    }

    /// The lens whose parameters the adjustment refines, from the intrinsics' own distortion,
    /// and the held flags of the block `[f, k1, k2, p1, p2, cx, cy]`.
    pub fn block(&self, k: &Intrinsics) -> Result<(Distortion, crate::adjust::Held)> {
        let f_held = self.focal == FocalMode::Known;
        let own = k.distortion;
        let (lens, k1_held, k2_held) = match self.distortion {
            DistortionMode::None => (own, true, true),
            DistortionMode::K1 | DistortionMode::K1k2 | DistortionMode::Brown => {
                let lens = match own {
                    Distortion::BrownConrady { .. } => own,
                    Distortion::None => Distortion::BrownConrady {
                        k1: 0.0,
                        k2: 0.0,
                        k3: 0.0,
                        p1: 0.0,
                        p2: 0.0,
                    },
                    Distortion::Division { .. } => {
                        return Err(VisionError::InvalidInput(format!(
                            "distortion: {} solves a Brown–Conrady lens, but the intrinsics \
                             carry a division one",
                            self.distortion.choice()
                        )))
                    }
                };
                (lens, false, self.distortion == DistortionMode::K1)
            }
            DistortionMode::Division => {
                let lens =
                    match own {
                        Distortion::Division { .. } => own,
                        Distortion::None => Distortion::Division { k1: 0.0, k2: 0.0 },
                        Distortion::BrownConrady { .. } => return Err(VisionError::InvalidInput(
                            "distortion: division, but the intrinsics carry a Brown–Conrady lens"
                                .into(),
                        )),
                    };
                (lens, false, true)
            }
        };
        let p_held = self.distortion != DistortionMode::Brown;
        let c_held = self.principal_point == PrincipalPoint::Centre;
        Ok((
            lens,
            [f_held, k1_held, k2_held, p_held, p_held, c_held, c_held],
        ))
    }
}

/// Fewest tracks (seen in 3 frames or more) a distortion solve accepts: the lens's radial
/// curve needs points spread over the frame, and fewer make k1, k2 noise.
pub const MIN_LENS_TRACKS: usize = 30;

/// The tracks as an ideal pinhole with the same K would see them (every observation through
/// [`Intrinsics::undistort_pixel`]); the tracks themselves when `k` is a pinhole.
pub fn undistort_tracks(tracks: &Tracks, k: &Intrinsics) -> Result<Tracks> {
    let mut out = tracks.clone();
    if k.is_pinhole() {
        return Ok(out);
    }
    for t in &mut out.tracks {
        for p in &mut t.points {
            let u = k
                .undistort_pixel(&nalgebra::Point2::new(p[0], p[1]))
                .map_err(|e| {
                    VisionError::InvalidInput(format!(
                        "track {} at ({:.1}, {:.1}): the lens cannot undistort it: {e}",
                        t.id, p[0], p[1]
                    ))
                })?;
            *p = [u.x, u.y];
        }
    }
    Ok(out)
}
