//! `klt_track_opencv` (only with the `opencv` cargo feature): the book's chapter 6 tracker run
//! with OpenCV's own `goodFeaturesToTrack` and `calcOpticalFlowPyrLK` — what the book used —
//! in place of ours, behind the same params, ports and `tracks` artifact as `klt_track`, to
//! cross-check our KLT inside a graph.
//!
//! The sequence logic is `klt_track`'s (vfxgraph-vision's `Tracker`, book 6.5): N feature
//! slots, disposal of lost windows, refill of lost slots with the best new corners at least
//! `min_distance` from live features (OpenCV's idiom: a mask with a disc of that radius
//! cleared around each live feature and, as in `klt_track`, a `border` margin), stable ids
//! with a new id per refill. Frames are tracked as 8-bit gray: `klt_track`'s luminance on a
//! 0–255 sRGB-encoded scale, rounded (OpenCV's LK takes 8-bit images).
//!
//! Params, as OpenCV takes them:
//! - `features` → `maxCorners` (of the free slots), `quality` → `qualityLevel`,
//!   `min_distance` → `minDistance` (and the mask discs), block size 3, no Harris.
//! - `window` → `winSize` (window × window; an even value is used as the next odd one, as in
//!   `klt_track`), `levels` → `maxLevel`, `iterations` and `epsilon` → the `TermCriteria`
//!   (COUNT + EPS; OpenCV compares the squared step with ε², i.e. a step shorter than ε
//!   pixels, as ours), `minEigThreshold` 1e-4 (OpenCV's default, = `klt_track`'s 0.1).
//! - `max_residual` → a threshold on OpenCV's `err`, which is the *mean absolute* difference
//!   of the window (gray levels) where ours is the RMS: the same number is a slightly looser
//!   test here (mean |d| ≤ RMS).
//! - `fb_threshold` → no OpenCV parameter: a second `calcOpticalFlowPyrLK` from the new frame
//!   back to the old one (started at the old positions, `OPTFLOW_USE_INITIAL_FLOW`), lost
//!   when it misses the start by more than the threshold — what `klt_track` does.
//! - `border`, `replace_lost`: the sequence logic above.
//!
//! End reasons: OpenCV's status 0 is `left_image` when its last position lies outside the
//! image and `singular` otherwise (it does not say which); `residual`, `forward_backward` and
//! the `border` margin as in `klt_track`. OpenCV works per feature, so the result does not
//! depend on its thread count.

use opencv::core::{
    Mat, Point, Point2f, Scalar, Size, TermCriteria, TermCriteria_Type, Vector, CV_8UC1,
};
use opencv::imgproc;
use opencv::prelude::*;
use opencv::video;
use vfxgraph_engine::{Context, NodeError, Registry};
use vfxgraph_vision::klt::{GrayImage, LostReason, Track, TrackEnd, TrackerParams, Tracks};

use crate::tracking::{gray_frames, klt_spec, TracksArt};
use crate::FnNode;

/// Registers `klt_track_opencv`.
pub fn register(r: &mut Registry) {
    r.register_node(FnNode::new(
        klt_spec(
            "klt_track_opencv",
            &TrackerParams {
                drift_correction: None,
                ..TrackerParams::default()
            },
            "klt_track with OpenCV's goodFeaturesToTrack + calcOpticalFlowPyrLK (what the book \
             used) in place of ours, same params and output, to cross-check klt_track in a \
             graph. Differences: max_residual is compared with OpenCV's mean absolute window \
             difference (ours: RMS); fb_threshold is a second, backward OpenCV LK call; frames \
             are tracked as 8-bit gray. Only in a build with the `opencv` cargo feature.",
        ),
        run_klt_track_opencv,
    ));
}

fn run_klt_track_opencv(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let mut params: TrackerParams = ctx.options()?;
    if params.drift_correction.is_some() {
        return Err(NodeError::msg(
            "klt_track_opencv: drift_correction is only implemented by klt_track (OpenCV's \
             tracker has no first-window monitoring); set it to 0 or use klt_track",
        ));
    }
    let grays = gray_frames(ctx)?;
    let refs: Vec<(i64, &GrayImage)> = grays.iter().map(|(f, g)| (*f, g)).collect();
    if let Some((_, g)) = refs.first() {
        params.corners.max_corners = params.feature_slots(g.width, g.height);
    }
    let tracks = track_sequence_opencv(&refs, &params, |x| ctx.progress(x))
        .map_err(|e| NodeError::msg(format!("klt_track_opencv: {e}")))?;
    ctx.output("tracks", TracksArt(tracks));
    Ok(())
}

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
    params: TrackerParams,
    prev: Option<Mat>,
    size: (usize, usize),
    tracks: Tracks,
    live: Vec<Option<usize>>,
    /// The previous frame's measured noise (`noise_factor` > 0), as `klt_track`.
    prev_sigma: f32,
}

impl CvTracker {
    fn new(params: TrackerParams) -> Result<CvTracker, String> {
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
                tracks: Vec::new(),
            },
            live: vec![None; slots],
            prev_sigma: 0.0,
        })
    }

    fn live_points(&self) -> Vector<Point2f> {
        self.live
            .iter()
            .flatten()
            .map(|&k| {
                let p = self.tracks.tracks[k]
                    .points
                    .last()
                    .copied()
                    .unwrap_or_default();
                Point2f::new(p[0] as f32, p[1] as f32)
            })
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
            let id = self.tracks.tracks.len() as u64;
            self.live[slot] = Some(self.tracks.tracks.len());
            self.tracks.tracks.push(Track {
                id,
                slot,
                first: fi,
                points: vec![[c.x as f64, c.y as f64]],
                lost: None,
            });
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
            vfxgraph_vision::klt::noise_sigma(gray)
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
                let t = &mut self.tracks.tracks[k];
                match reason {
                    None => t.points.push(p),
                    Some(reason) => {
                        let at = if p[0].is_finite() && p[1].is_finite() {
                            p
                        } else {
                            t.points.last().copied().unwrap_or_default()
                        };
                        t.lost = Some(TrackEnd {
                            frame: fi,
                            at,
                            reason,
                        });
                        self.live[slot] = None;
                    }
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
            self.tracks.frames.push(frame);
            self.refill(&img, fi)?;
        }
        self.prev = Some(img);
        Ok(())
    }
}

/// Tracks a whole sequence with OpenCV's corners and LK (book 6.2–6.5), as
/// `vfxgraph_vision::klt::track_sequence` does with ours.
pub fn track_sequence_opencv(
    frames: &[(i64, &GrayImage)],
    params: &TrackerParams,
    mut progress: impl FnMut(f32),
) -> Result<Tracks, String> {
    let mut t = CvTracker::new(params.clone())?;
    for (k, (f, img)) in frames.iter().enumerate() {
        t.push(*f, img)?;
        progress((k + 1) as f32 / frames.len() as f32);
    }
    Ok(t.tracks)
}

#[cfg(test)]
mod tests {
    use vfxgraph_engine::{InputValue, ParamValue, Value};
    use vfxgraph_imaging::{read_image, Image};
    use vfxgraph_vision::formats::flo::read_flo;

    use super::*;
    use crate::artifacts::ImageArt;
    use crate::testing::{params, spec};

    /// Runs a tracking node on `(frame, image)` pairs with `set` params over the book's
    /// tracker (no noise-adaptive threshold, forward–backward check or drift correction: what
    /// both nodes implement alike).
    fn track(node: &str, frames: &[(i64, Image)], set: &[(&str, ParamValue)]) -> Tracks {
        let dir = tempfile::tempdir().unwrap();
        let s = spec(node);
        let mut all = vec![
            ("noise_factor", ParamValue::Float(0.0)),
            ("fb_threshold", ParamValue::Float(0.0)),
            ("drift_correction", ParamValue::Float(0.0)),
        ];
        all.extend_from_slice(set);
        let p = params(&s, &all);
        let seq: Vec<(i64, Value)> = frames
            .iter()
            .map(|(f, img)| (*f, Value::new(ImageArt(img.clone()))))
            .collect();
        let mut ctx = Context::for_test(
            &s,
            &p,
            dir.path(),
            None,
            vec![("frames", InputValue::Sequence(seq))],
        );
        let run = if node == "klt_track_opencv" {
            run_klt_track_opencv
        } else {
            crate::tracking::run_klt_track
        };
        run(&mut ctx).unwrap();
        ctx.take_output::<TracksArt>("tracks").unwrap().0
    }

    /// A textured frame whose content moves by (−1.5, −0.75) px per frame (klt_track's test).
    fn moving(k: usize) -> Image {
        let (dx, dy) = (1.5 * k as f32, 0.75 * k as f32);
        Image::from_fn(160, 120, 3, |x, y, _| {
            let (x, y) = (x as f32 + dx, y as f32 + dy);
            0.3 + 0.2 * (x * 0.21).sin() * (y * 0.17).cos() + 0.15 * ((x - 1.3 * y) * 0.09).sin()
        })
    }

    /// The same params (names, types, defaults) and ports, but for the default drift
    /// correction: 1 px in `klt_track`, 0 here (OpenCV's tracker has none, and the node refuses
    /// any other value).
    #[test]
    fn same_params_and_ports_as_klt_track() {
        let (a, b) = (spec("klt_track"), spec("klt_track_opencv"));
        let params = |s: &vfxgraph_engine::NodeSpec| -> Vec<String> {
            s.params
                .iter()
                .map(|p| match p.name {
                    "drift_correction" => format!("{} {:?}", p.name, p.ty),
                    _ => format!("{} {:?} {:?}", p.name, p.ty, p.default),
                })
                .collect()
        };
        assert_eq!(params(&a), params(&b));
        let drift = |s: &vfxgraph_engine::NodeSpec| {
            s.params
                .iter()
                .find(|p| p.name == "drift_correction")
                .and_then(|p| p.default.clone())
        };
        assert_eq!(drift(&a), Some(ParamValue::Float(1.0)));
        assert_eq!(drift(&b), Some(ParamValue::Float(0.0)));
        let ports = |v: &[vfxgraph_engine::PortSpec]| -> Vec<String> {
            v.iter()
                .map(|p| format!("{} {} {}", p.name, p.ty, p.sequence))
                .collect()
        };
        assert_eq!(ports(&a.inputs), ports(&b.inputs));
        assert_eq!(ports(&a.outputs), ports(&b.outputs));
        assert_eq!(a.mode, b.mode);
    }

    /// Known motion: every step of every track is the content's motion; features that leave
    /// the image are reported lost there and their slots refilled.
    #[test]
    fn known_motion_disposal_and_refill() {
        let frames: Vec<(i64, Image)> = (0..8).map(|k| (20 + k as i64, moving(k))).collect();
        let t = track(
            "klt_track_opencv",
            &frames,
            &[("features", ParamValue::Int(40))],
        );
        t.validate().unwrap();
        assert_eq!(t.frames, (20..28).collect::<Vec<i64>>());
        assert_eq!(t.slots, 40);
        assert!(t.tracks.iter().filter(|t| t.first == 0).count() >= 30);
        let mut steps = 0;
        for tr in &t.tracks {
            for w in tr.points.windows(2) {
                assert!((w[1][0] - w[0][0] + 1.5).abs() < 0.1, "{tr:?}");
                assert!((w[1][1] - w[0][1] + 0.75).abs() < 0.1, "{tr:?}");
                steps += 1;
            }
        }
        assert!(steps >= 150, "{steps} steps");
        // Content moves up-left: features reaching the 10 px border there are lost, where
        // they were, and replaced by new tracks.
        let lost: Vec<_> = t.tracks.iter().filter_map(|t| t.lost).collect();
        assert!(!lost.is_empty());
        for l in &lost {
            assert_eq!(l.reason, LostReason::LeftImage, "{l:?}");
            assert!(l.at[0] < 10.0 || l.at[1] < 10.0, "{l:?}");
        }
        assert!(t.tracks.len() >= 40 + lost.len().min(40) / 2, "no refill");
        // Every frame keeps its slots filled (refill respects min_distance from live ones).
        for f in 0..t.frames.len() {
            let obs = t.observations(f);
            for (i, (_, p)) in obs.iter().enumerate() {
                for (_, q) in &obs[..i] {
                    assert!((p[0] - q[0]).hypot(p[1] - q[1]) >= 9.0, "frame {f}");
                }
            }
        }
    }

    /// The cross-check on real motion with ground truth: Middlebury RubberWhale frames 10→11,
    /// the corner settings of the KLT accuracy test (500, quality 0.01, distance 10). Each
    /// tracker's median end-point error against the ground-truth flow, on its own corners and
    /// on the corners both found.
    #[test]
    fn rubberwhale_cross_check_against_ground_truth() {
        // Absent: a notice (a failure under CI=true); present but undecodable: a failure.
        let Some(dir) = vfxgraph_testdata::path("middlebury_flow_RubberWhale") else {
            return;
        };
        let load = |n: &str| read_image(&dir.join(n)).unwrap();
        let (a, b) = (load("frame10.png"), load("frame11.png"));
        let flow = read_flo(&dir.join("flow10.flo")).unwrap();
        let frames = vec![(10, a), (11, b)];
        let set = [
            ("features", ParamValue::Int(500)),
            ("quality", ParamValue::Float(0.01)),
            ("min_distance", ParamValue::Float(10.0)),
        ];
        let ours = track("klt_track", &frames, &set);
        let cv = track("klt_track_opencv", &frames, &set);
        // (start, end-point error or None when lost) of every corner of frame 0 with known flow.
        let epe = |t: &Tracks| -> Vec<([f64; 2], Option<f64>)> {
            t.tracks
                .iter()
                .filter(|t| t.first == 0)
                .filter_map(|t| {
                    let p = t.points[0];
                    let [u, v] = flow.at(p[0] as usize, p[1] as usize)?;
                    let e = t
                        .at(1)
                        .map(|q| (q[0] - p[0] - u as f64).hypot(q[1] - p[1] - v as f64));
                    Some((p, e))
                })
                .collect()
        };
        let median = |mut v: Vec<f64>| {
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        };
        let stats = |e: &[([f64; 2], Option<f64>)]| {
            let tracked: Vec<f64> = e.iter().filter_map(|x| x.1).collect();
            (tracked.len() as f64 / e.len() as f64, median(tracked))
        };
        let (eo, ec) = (epe(&ours), epe(&cv));
        let ((fo, mo), (fc, mc)) = (stats(&eo), stats(&ec));
        // Corners both detectors found (within 0.5 px), tracked by both.
        let mut both = (Vec::new(), Vec::new());
        let mut shared = 0;
        for (p, e) in &ec {
            if let Some((_, f)) = eo
                .iter()
                .find(|(q, _)| (p[0] - q[0]).hypot(p[1] - q[1]) < 0.5)
            {
                shared += 1;
                if let (Some(x), Some(y)) = (f, e) {
                    both.0.push(*x);
                    both.1.push(*y);
                }
            }
        }
        let n_both = both.0.len();
        let (bo, bc) = (median(both.0), median(both.1));
        eprintln!(
            "RubberWhale: klt_track {} corners, {:.1} % tracked, median EPE {mo:.4} px; \
             klt_track_opencv {} corners, {:.1} % tracked, median EPE {mc:.4} px; \
             {shared} corners in common, on the {n_both} tracked by both: ours {bo:.4}, \
             OpenCV {bc:.4}",
            eo.len(),
            100.0 * fo,
            ec.len(),
            100.0 * fc,
        );
        assert!(eo.len() >= 400 && ec.len() >= 400);
        assert!(fo >= 0.95 && fc >= 0.95, "tracked {fo} / {fc}");
        // The detectors agree on most corners (same score, same selection rule).
        assert!(shared as f64 >= 0.8 * ec.len() as f64, "{shared} shared");
        // OpenCV is as accurate as the KLT test asks of ours, and the two agree.
        // README: 0.0467 / 0.0472 px; the bound within 2× of them.
        assert!(
            mc <= 0.09 && mo <= 0.09,
            "median EPE ours {mo}, OpenCV {mc}"
        );
        assert!((mo - mc).abs() <= 0.01, "median EPE ours {mo}, OpenCV {mc}");
        assert!(
            (bo - bc).abs() <= 0.01,
            "on common corners: ours {bo}, OpenCV {bc}"
        );
    }

    /// Identical tracks whatever OpenCV's thread count, and from run to run.
    #[test]
    fn deterministic_for_any_thread_count() {
        let frames: Vec<(i64, Image)> = (0..5).map(|k| (k as i64, moving(k))).collect();
        let set = [
            ("features", ParamValue::Int(60)),
            ("fb_threshold", ParamValue::Float(0.5)),
        ];
        // OpenCV's default thread count first (TBB keeps a lower limit once set).
        let before = opencv::core::get_num_threads().unwrap();
        let many = track("klt_track_opencv", &frames, &set);
        let again = track("klt_track_opencv", &frames, &set);
        opencv::core::set_num_threads(1).unwrap();
        let one = track("klt_track_opencv", &frames, &set);
        opencv::core::set_num_threads(before).unwrap();
        eprintln!("OpenCV threads: {before}, then 1");
        assert!(one.tracks.len() >= 50);
        assert_eq!(one, many);
        assert_eq!(many, again);
    }

    #[test]
    fn bad_input_is_an_error_not_a_panic() {
        let dir = tempfile::tempdir().unwrap();
        let s = spec("klt_track_opencv");
        let p = params(&s, &[]);
        let seq = vec![
            (0, Value::new(ImageArt(moving(0)))),
            (1, Value::new(ImageArt(Image::new(10, 10, 3)))),
        ];
        let mut ctx = Context::for_test(
            &s,
            &p,
            dir.path(),
            None,
            vec![("frames", InputValue::Sequence(seq))],
        );
        let e = run_klt_track_opencv(&mut ctx).unwrap_err();
        assert!(
            e.message.contains("klt_track_opencv") && e.message.contains("size"),
            "{e}"
        );
        // A tiny frame (smaller than the window and the border): no corners, no panic.
        let seq = vec![
            (0, Value::new(ImageArt(Image::new(4, 4, 3)))),
            (1, Value::new(ImageArt(Image::new(4, 4, 3)))),
        ];
        let mut ctx = Context::for_test(
            &s,
            &p,
            dir.path(),
            None,
            vec![("frames", InputValue::Sequence(seq))],
        );
        let r = run_klt_track_opencv(&mut ctx);
        if let Err(e) = r {
            assert!(e.message.contains("klt_track_opencv"), "{e}");
        }
    }
}
