//! The book's chapter 6 tracker run with OpenCV's own `goodFeaturesToTrack` and
//! `calcOpticalFlowPyrLK` — what the book used — in place of ours (only with the `opencv`
//! cargo feature), to cross-check our KLT: [`track_sequence_opencv`].
//!
//! The sequence logic is [`Tracker`](super::Tracker)'s (book 6.5): N feature slots, disposal
//! of lost windows, refill of lost slots with the best new corners at least `min_distance`
//! from live features (OpenCV's idiom: a mask with a disc of that radius cleared around each
//! live feature and, as in our tracker, a `border` margin), stable ids with a new id per
//! refill. Frames are tracked as 8-bit gray: the luminance on a 0–255 sRGB-encoded scale,
//! rounded (OpenCV's LK takes 8-bit images).
//!
//! [`TrackerOptions`], as OpenCV takes them:
//! - `features` → `maxCorners` (of the free slots), `quality` → `qualityLevel`,
//!   `min_distance` → `minDistance` (and the mask discs), block size 3, no Harris.
//! - `window` → `winSize` (window × window; an even value is used as the next odd one, as in
//!   ours), `levels` → `maxLevel`, `iterations` and `epsilon` → the `TermCriteria`
//!   (COUNT + EPS; OpenCV compares the squared step with ε², i.e. a step shorter than ε
//!   pixels, as ours), `minEigThreshold` 1e-4 (OpenCV's default, = our 0.1).
//! - `max_residual` → a threshold on OpenCV's `err`, which is the *mean absolute* difference
//!   of the window (gray levels) where ours is the RMS: the same number is a slightly looser
//!   test here (mean |d| ≤ RMS).
//! - `fb_threshold` → no OpenCV parameter: a second `calcOpticalFlowPyrLK` from the new frame
//!   back to the old one (started at the old positions, `OPTFLOW_USE_INITIAL_FLOW`), lost
//!   when it misses the start by more than the threshold — what ours does.
//! - `border`, `replace_lost`: the sequence logic above.
//!
//! End reasons: OpenCV's status 0 is `left_image` when its last position lies outside the
//! image and `singular` otherwise (it does not say which); `residual`, `forward_backward` and
//! the `border` margin as ours. OpenCV works per feature, so the result does not depend on
//! its thread count. The `klt_track_opencv` node runs it; its tests cross-check the two.

use opencv::core::{
    Mat, Point, Point2f, Scalar, Size, TermCriteria, TermCriteria_Type, Vector, CV_8UC1,
};
use opencv::imgproc;
use opencv::prelude::*;
use opencv::video;

use super::{GrayImage, LostReason, TrackerOptions, Tracks};

/// An 8-bit single-channel OpenCV image of a gray image (0–255, rounded).
fn to_mat(img: &GrayImage) -> Result<Mat, String> {
    let bytes: Vec<u8> = img
        .data
        .iter()
        .map(|&v| v.round().clamp(0.0, 255.0) as u8)
        .collect();
    let m = Mat::new_rows_cols_with_data::<u8>(img.height as i32, img.width as i32, &bytes)
        .map_err(|e| e.to_string())?;
    m.try_clone().map_err(|e| e.to_string())
}

fn cv<T>(r: opencv::Result<T>) -> Result<T, String> {
    r.map_err(|e| format!("OpenCV: {e}"))
}

/// OpenCV's LK output: new positions, statuses (1 = found), window errors.
type LkOut = (Vector<Point2f>, Vector<u8>, Vector<f32>);

/// The book's sequence tracker (6.2–6.5) with OpenCV's corners and LK.
struct CvTracker {
    params: TrackerOptions,
    prev: Option<Mat>,
    size: (usize, usize),
    tracks: Tracks,
    live: Vec<Option<usize>>,
    /// The previous frame's measured noise (`noise_factor` > 0), as `klt_track`.
    prev_sigma: f32,
}

impl CvTracker {
    fn new(params: TrackerOptions) -> Result<CvTracker, String> {
        params.lk.validate().map_err(|e| e.to_string())?;
        if params.max_residual.is_nan()
            || params.fb_threshold.is_some_and(|t| t.is_nan() || t < 0.0)
            || !(params.border >= 0.0 && params.border < 1e6)
        {
            return Err("max_residual, fb_threshold and border must be numbers ≥ 0".into());
        }
        let slots = params.corners.max_corners;
        Ok(CvTracker {
            params,
            prev: None,
            size: (0, 0),
            tracks: Tracks {
                frames: Vec::new(),
                slots,
                image_size: None,
                tracks: Vec::new(),
            },
            live: vec![None; slots],
            prev_sigma: 0.0,
        })
    }

    fn live_points(&self) -> Vector<Point2f> {
        self.tracks
            .last_points(&self.live)
            .map(|p| Point2f::new(p[0] as f32, p[1] as f32))
            .collect()
    }

    /// Fills empty slots with OpenCV's best corners away from the border and from live
    /// features (book 6.4–6.5).
    fn refill(&mut self, img: &Mat, fi: usize) -> Result<(), String> {
        let free: Vec<usize> = (0..self.live.len())
            .filter(|&s| self.live[s].is_none())
            .collect();
        if free.is_empty() {
            return Ok(());
        }
        let (w, h) = self.size;
        let b = self.params.border.ceil() as usize;
        let mut mask = cv(Mat::new_rows_cols_with_default(
            h as i32,
            w as i32,
            CV_8UC1,
            Scalar::all(0.0),
        ))?;
        {
            let data = cv(mask.data_bytes_mut())?;
            for (i, v) in data.iter_mut().enumerate() {
                let (x, y) = (i % w, i / w);
                let inside = b <= 1 || (x >= b && y >= b && x + b < w && y + b < h);
                *v = if inside { 255 } else { 0 };
            }
        }
        let cp = &self.params.corners;
        let radius = cp.min_distance.ceil() as i32;
        if radius > 0 {
            for p in self.live_points() {
                let c = Point::new(p.x.round() as i32, p.y.round() as i32);
                cv(imgproc::circle(
                    &mut mask,
                    c,
                    radius,
                    Scalar::all(0.0),
                    -1,
                    imgproc::LINE_8,
                    0,
                ))?;
            }
        }
        let mut corners = Vector::<Point2f>::new();
        cv(imgproc::good_features_to_track(
            img,
            &mut corners,
            free.len() as i32,
            cp.quality.max(1e-12) as f64,
            cp.min_distance as f64,
            &mask,
            cp.block_size as i32,
            false,
            0.04,
        ))?;
        for (slot, c) in free.into_iter().zip(corners) {
            self.live[slot] = Some(self.tracks.start(slot, fi, [c.x as f64, c.y as f64]));
        }
        Ok(())
    }

    /// OpenCV's pyramidal LK of `pts` from `a` to `b`; `init` starts the search there.
    fn lk(
        &self,
        a: &Mat,
        b: &Mat,
        pts: &Vector<Point2f>,
        init: Option<&Vector<Point2f>>,
    ) -> Result<LkOut, String> {
        let lk = &self.params.lk;
        let win = 2 * lk.half_window() as i32 + 1;
        let criteria = cv(TermCriteria::new(
            TermCriteria_Type::COUNT as i32 + TermCriteria_Type::EPS as i32,
            lk.max_iterations as i32,
            lk.epsilon as f64,
        ))?;
        let mut next = init.cloned().unwrap_or_default();
        let (mut status, mut err) = (Vector::<u8>::new(), Vector::<f32>::new());
        let flags = if init.is_some() {
            video::OPTFLOW_USE_INITIAL_FLOW
        } else {
            0
        };
        cv(video::calc_optical_flow_pyr_lk(
            a,
            b,
            pts,
            &mut next,
            &mut status,
            &mut err,
            Size::new(win, win),
            lk.levels as i32,
            criteria,
            flags,
            lk.min_eigen as f64 * 1e-3,
        ))?;
        Ok((next, status, err))
    }

    fn push(&mut self, frame: i64, gray: &GrayImage) -> Result<(), String> {
        let img = to_mat(gray)?;
        let sigma = if self.params.noise_factor > 0.0 {
            super::noise_sigma(gray)
        } else {
            0.0
        };
        let max_residual = self.params.residual_threshold(self.prev_sigma, sigma);
        self.prev_sigma = sigma;
        let size = (gray.width, gray.height);
        let fi = self.tracks.frames.len();
        if let Some(prev) = self.prev.take() {
            if size != self.size {
                return Err(format!(
                    "frame size {size:?} differs from the sequence's {:?}",
                    self.size
                ));
            }
            let slots: Vec<usize> = (0..self.live.len())
                .filter(|&s| self.live[s].is_some())
                .collect();
            let pts = self.live_points();
            let mut lost: Vec<Option<LostReason>> = vec![None; pts.len()];
            let mut pos: Vec<[f64; 2]> = vec![[0.0; 2]; pts.len()];
            if !pts.is_empty() {
                let (next, status, err) = self.lk(&prev, &img, &pts, None)?;
                let m = self.params.border;
                let (w, h) = (size.0 as f32, size.1 as f32);
                for k in 0..pts.len() {
                    let p = next.get(k).map_err(|e| e.to_string())?;
                    pos[k] = [p.x as f64, p.y as f64];
                    let outside = !(p.x >= 0.0 && p.y >= 0.0 && p.x <= w - 1.0 && p.y <= h - 1.0);
                    if status.get(k).unwrap_or(0) == 0 {
                        lost[k] = Some(if outside {
                            LostReason::LeftImage
                        } else {
                            LostReason::Singular
                        });
                    } else if p.x < m || p.y < m || p.x > w - 1.0 - m || p.y > h - 1.0 - m {
                        lost[k] = Some(LostReason::LeftImage);
                    } else if err.get(k).unwrap_or(f32::INFINITY) > max_residual {
                        lost[k] = Some(LostReason::Residual);
                    }
                }
                if let Some(fb) = self.params.fb_threshold {
                    let (back, bstatus, _) = self.lk(&img, &prev, &next, Some(&pts))?;
                    for (k, l) in lost.iter_mut().enumerate() {
                        if l.is_none() {
                            let b = back.get(k).unwrap_or_default();
                            let p = pts.get(k).unwrap_or_default();
                            let d = (b.x - p.x).hypot(b.y - p.y);
                            if bstatus.get(k).unwrap_or(0) == 0 || d.is_nan() || d > fb {
                                *l = Some(LostReason::ForwardBackward);
                            }
                        }
                    }
                }
            }
            for ((slot, reason), p) in slots.into_iter().zip(lost).zip(pos) {
                let Some(k) = self.live[slot] else { continue };
                if self.tracks.tracks[k].advance(fi, p, reason) {
                    self.live[slot] = None;
                }
            }
            self.tracks.frames.push(frame);
            if self.params.replace_lost {
                self.refill(&img, fi)?;
            }
        } else {
            if gray.width == 0 || gray.height == 0 {
                return Err("bad image: empty frame".into());
            }
            self.size = size;
            self.tracks.image_size = u32::try_from(size.0)
                .ok()
                .zip(u32::try_from(size.1).ok())
                .map(|(w, h)| [w, h]);
            self.tracks.frames.push(frame);
            self.refill(&img, fi)?;
        }
        self.prev = Some(img);
        Ok(())
    }
}

/// Tracks a whole sequence with OpenCV's corners and LK (book 6.2–6.5), as
/// [`track_sequence`](super::track_sequence) does with ours.
pub fn track_sequence_opencv(
    frames: &[(i64, &GrayImage)],
    params: &TrackerOptions,
    mut progress: impl FnMut(f32),
) -> Result<Tracks, String> {
    let mut t = CvTracker::new(params.clone())?;
    for (k, (f, img)) in frames.iter().enumerate() {
        t.push(*f, img)?;
        progress((k + 1) as f32 / frames.len() as f32);
    }
    Ok(t.tracks)
}
