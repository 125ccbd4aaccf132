//! The whole-sequence KLT tracker (book 6.2–6.5; the book's chapter 6.7 program): Shi–Tomasi
//! corners in the first frame, pyramidal Lucas–Kanade from each frame to the next, disposal
//! of windows that leave the image, become singular, or whose residual exceeds a threshold
//! (and, optionally, that fail a forward–backward check or whose drift correction no longer
//! aligns them, module `drift`), and replacement of each lost feature by a new corner that
//! keeps the minimum distance to the live ones.
//!
//! Pyramids are built once per frame; features are tracked in parallel (rayon). The result
//! does not depend on the number of threads.

use super::corners::{good_features_to_track, CornerOptions};
use super::drift::{AlignFailure, Template};
use super::lucas_kanade::{track_points, LkOptions, LkResult};
use super::pyramid::{GrayImage, Pyramid};
use super::tracks::{LostReason, Tracks};
use super::KltError;
use rayon::prelude::*;

/// Parameters of the sequence tracker (book 6.4–6.5). Defaults: a feature count from the frame
/// size (the book's 150 for frames up to 440 × 440 px), minimum distance 10, quality 1e-5, OpenCV's LK defaults, a residual threshold of 12 gray
/// levels RMS raised to 3 × the frame pair's measured noise, lost features replaced, and —
/// not in the book, so that grainy footage tracks as well as clean — a 1 px forward–backward
/// check and 1 px drift correction. [`TrackerOptions::book`] is the book's tracker.
#[derive(Clone, Debug, PartialEq, vfxgraph_params::Options)]
pub struct TrackerOptions {
    /// Corner detection; `max_corners` is the number of feature slots (the book's N), 0 = from
    /// the frame size ([`TrackerOptions::feature_slots`]).
    #[param(flatten)]
    pub corners: CornerOptions,
    /// Pyramidal Lucas–Kanade.
    #[param(flatten)]
    pub lk: LkOptions,
    /// a feature whose window RMS residual (0–255 gray levels) exceeds this is lost
    ///
    /// Book 6.5; infinity disables the test.
    #[param(range = 0.0..=1e9)]
    pub max_residual: f32,
    /// …or this many times the frame pair's measured noise √(σa² + σb²) when larger (grainy
    /// footage); 0 = max_residual only (the book)
    ///
    /// The residual threshold of a step from frame a to frame b is at least this many times
    /// √(σa² + σb²), the frames' measured noise ([`super::noise::noise_sigma`]): the RMS
    /// difference of two windows that match except for noise. On clean footage (σ ≈ 2)
    /// 3 × √2 σ stays below 12 and nothing changes.
    #[param(range = 0.0..=1e6)]
    pub noise_factor: f32,
    /// forward–backward check: lost if tracking back misses the start by more than this many
    /// pixels; 0 = off
    ///
    /// If set, each tracked feature is tracked back and lost when it does not come back
    /// within this many pixels of where it started.
    #[param(range = 0.0..=1e9)]
    pub fb_threshold: Option<f32>,
    /// refill lost slots with new corners (book 6.5)
    pub replace_lost: bool,
    /// no corners closer than this to the edge; features closer are lost
    ///
    /// Margin in pixels: corners are not detected closer than this to the image edge, and a
    /// feature closer than that is lost as having left the image. Near the edge part of the
    /// window lies outside the image, where LK sees no gradient (as OpenCV), so the feature is
    /// followed on a partial window. With the default (10, the half window of the default LK
    /// window) every window lies wholly inside the image, the book's definition of a window
    /// (6.1).
    #[param(range = 0.0..=10_000.0)]
    pub border: f32,
    /// re-align each step to the feature's first window; a feature that moves more than this
    /// many pixels is lost (no drift along long tracks); 0 = off, the book's frame-to-frame
    /// tracker
    ///
    /// Drift correction ([`super::drift`]): each step's position is re-aligned to the
    /// feature's first window and moved there when that moves it less than this many pixels;
    /// otherwise the window no longer looks like the feature and the track is lost
    /// ([`LostReason::Drift`]). `None`: frame-to-frame only, the book's tracker.
    #[param(range = 0.0..=1e3)]
    pub drift_correction: Option<f32>,
    /// LK window of noisy footage (its first frame pairs track worse than a fifth of a pixel);
    /// 0 = keep `window`
    ///
    /// When the median forward–backward distance of the first [`NOISY_PAIRS`] frame pairs
    /// exceeds [`NOISY_FB`] px the footage is noisy: tracking starts again from the first
    /// frame with this window where it is larger than `window` (a larger window averages more
    /// pixels, so noise moves it less) and with `spread_factor`. Needs the forward–backward
    /// check.
    #[param(range = 0..=255)]
    pub noisy_window: usize,
    /// on noisy footage the forward–backward and drift bounds grow to this many times the frame
    /// pair's median distance where that is larger; 0 = fixed bounds
    ///
    /// Noisy as for `noisy_window`. See [`SPREAD_FACTOR`], the default.
    #[param(range = 0.0..=100.0)]
    pub spread_factor: f32,
}

impl Default for TrackerOptions {
    fn default() -> Self {
        TrackerOptions {
            corners: CornerOptions {
                max_corners: 0,
                ..CornerOptions::default()
            },
            lk: LkOptions::default(),
            max_residual: 12.0,
            noise_factor: 3.0,
            fb_threshold: Some(1.0),
            replace_lost: true,
            border: 10.0,
            drift_correction: Some(1.0),
            noisy_window: 31,
            spread_factor: SPREAD_FACTOR,
        }
    }
}

impl TrackerOptions {
    /// The book's tracker (6.7): 150 features, the fixed residual threshold of 12 gray levels,
    /// frame-to-frame LK only (no forward–backward check, no drift correction).
    pub fn book() -> TrackerOptions {
        TrackerOptions {
            corners: CornerOptions::default(),
            noise_factor: 0.0,
            fb_threshold: None,
            drift_correction: None,
            noisy_window: 0,
            spread_factor: 0.0,
            ..TrackerOptions::default()
        }
    }

    /// The number of feature slots for frames of `width × height`: `corners.max_corners`, or
    /// when that is 0, one feature per [`AUTO_FEATURE_AREA`] pixels (a 36 × 36 block), at least
    /// the book's 150. More features average more of a grainy plate's noise out of the solve:
    /// on the 960 × 540 Blender dev plate (400 features) the known-K solve's worst rotation
    /// error is 0.052–0.056° for 350–800 features against 0.06–0.11° for 150–300.
    pub fn feature_slots(&self, width: usize, height: usize) -> usize {
        match self.corners.max_corners {
            0 => ((width * height) as f64 / AUTO_FEATURE_AREA as f64)
                .round()
                .max(150.0) as usize,
            n => n,
        }
    }

    /// The residual threshold of a step between frames of noise `sigma_a` and `sigma_b`.
    pub fn residual_threshold(&self, sigma_a: f32, sigma_b: f32) -> f32 {
        let adaptive = self.noise_factor * sigma_a.hypot(sigma_b);
        if adaptive > self.max_residual {
            adaptive
        } else {
            self.max_residual
        }
    }
}

/// Frame area per feature when the feature count is chosen from the frame size
/// ([`TrackerOptions::feature_slots`]).
pub const AUTO_FEATURE_AREA: usize = 36 * 36;

/// Footage whose first frame's measured noise ([`super::noise::noise_sigma`], 0–255 gray
/// levels) is above this is grainy: drift correction aligns its windows on frames smoothed by a
/// σ = 1 px binomial filter. Smoothing trades fine texture for noise: on the Blender dev plate
/// (σ ≈ 10) it halves the alignment's steps and lowers the tracks' error against the true
/// cameras; on our clean renders (σ ≈ 2–3) it only blurs the texture (the demo plate's solve:
/// 0.103° smoothed against 0.057°).
pub const GRAINY_SIGMA: f32 = 5.0;

/// The default [`TrackerOptions::spread_factor`]: on noisy footage a feature is lost by the
/// forward–backward check or drift correction only beyond this many times the frame pair's
/// median forward–backward distance (or median drift-correction move) when that exceeds the
/// fixed bound. The median measures how precisely the footage tracks on the features
/// themselves; for distances spread as the length of a 2-D Gaussian error the 99th percentile
/// is 2.6 × the median, so 3 × loses features that jumped, not the precision the footage
/// allows. Only on noisy footage ([`NOISY_FB`]): the drift-correction moves of the Blender dev
/// plate have a median of 0.33 px, and the fixed 1 px bound there ends features whose window
/// changed (its solve: 0.012° with the fixed bound, 0.017° with the spread's).
pub const SPREAD_FACTOR: f32 = 3.0;

/// The median over the first [`NOISY_PAIRS`] frame pairs of each pair's median
/// forward–backward distance (px) above which footage is noisy: tracked with
/// [`TrackerOptions::noisy_window`] and [`TrackerOptions::spread_factor`]. Clean renders track to 0.01–0.05 px with the 21 px window,
/// the Cycles grain of the Blender dev plate (σ ≈ 10 gray levels) to 0.14 px, where the larger
/// window solves worse (its windows straddle more depth and perspective: 0.069° against
/// 0.037°); 4-sample renders of a dark room corner (σ ≈ 25) to 0.25–0.6 px, where it solves
/// better (on eight such plates the worst rotation error falls from 0.12–1.7° to 0.05–1.6°).
pub const NOISY_FB: f32 = 0.2;

/// How many first frame pairs decide whether footage is noisy ([`NOISY_FB`]): the first pair's
/// spread reads high (its fresh corners include noise peaks that the checks then end).
pub const NOISY_PAIRS: usize = 3;

/// Incremental tracker: push frames in order, then [`Tracker::finish`] (book 6.2–6.5).
pub struct Tracker {
    params: TrackerOptions,
    prev: Option<Pyramid>,
    /// The pyramid of two frames ago, whose memory the next frame reuses.
    spare: Option<Pyramid>,
    tracks: Tracks,
    /// Per slot, the index into `tracks.tracks` of its live track.
    live: Vec<Option<usize>>,
    /// Per track, its first window (with drift correction).
    templates: Vec<Option<Template>>,
    /// The previous frame's measured noise (with `noise_factor` > 0).
    prev_sigma: f32,
    /// Drift correction aligns smoothed frames (the first frame's noise is above
    /// [`GRAINY_SIGMA`]).
    smooth: bool,
    /// The refill's mask of the pixels inside the border, built once for the frame size.
    border_mask: Option<(usize, usize, Vec<bool>)>,
    /// The first frames, kept while the shot may still switch to the noisy window.
    early: Vec<(i64, GrayImage)>,
    /// The median forward–backward distance of each of the first frame pairs.
    early_spread: Vec<f32>,
    /// The first frame pairs tracked worse than [`NOISY_FB`]: the shot is tracked with the
    /// noisy window and bounds that follow the spread.
    noisy: bool,
}

impl Tracker {
    /// A tracker with these parameters (checked).
    pub fn new(params: TrackerOptions) -> Result<Tracker, KltError> {
        params.lk.validate()?;
        if params.max_residual.is_nan()
            || !(params.noise_factor >= 0.0 && params.noise_factor < 1e6)
            || params.fb_threshold.is_some_and(|t| t.is_nan() || t < 0.0)
            || !(params.border >= 0.0 && params.border < 1e6)
            || !(params.spread_factor >= 0.0 && params.spread_factor <= 100.0)
            || params
                .drift_correction
                .is_some_and(|d| !(d > 0.0 && d.is_finite()))
        {
            return Err(KltError::BadParam(
                "max_residual, noise_factor, fb_threshold, border and spread_factor must be numbers ≥ 0".into(),
            ));
        }
        let slots = params.corners.max_corners;
        Ok(Tracker {
            params,
            prev: None,
            spare: None,
            tracks: Tracks {
                frames: Vec::new(),
                slots,
                image_size: None,
                tracks: Vec::new(),
            },
            live: vec![None; slots],
            templates: Vec::new(),
            prev_sigma: 0.0,
            smooth: false,
            border_mask: None,
            early: Vec::new(),
            early_spread: Vec::new(),
            noisy: false,
        })
    }

    /// Positions of the live features, by slot.
    fn live_points(&self) -> Vec<[f32; 2]> {
        self.tracks
            .last_points(&self.live)
            .map(|p| [p[0] as f32, p[1] as f32])
            .collect()
    }

    /// Fills empty slots with the best corners of `img` that keep the minimum distance to the
    /// live features (book 6.4–6.5).
    fn refill(
        &mut self,
        img: &GrayImage,
        drift_img: &GrayImage,
        fi: usize,
    ) -> Result<(), KltError> {
        let free: Vec<usize> = (0..self.live.len())
            .filter(|&s| self.live[s].is_none())
            .collect();
        if free.is_empty() {
            return Ok(());
        }
        let existing = self.live_points();
        let cp = CornerOptions {
            max_corners: free.len(),
            ..self.params.corners.clone()
        };
        let b = self.params.border.ceil() as usize;
        let (w, h) = (img.width, img.height);
        if b > 1 && !matches!(&self.border_mask, Some((mw, mh, _)) if (*mw, *mh) == (w, h)) {
            let mask = (0..w * h)
                .map(|i| {
                    let (x, y) = (i % w, i / w);
                    x >= b && y >= b && x + b < w && y + b < h
                })
                .collect();
            self.border_mask = Some((w, h, mask));
        }
        let mask = self
            .border_mask
            .as_ref()
            .filter(|_| b > 1)
            .map(|m| &m.2[..]);
        let corners = good_features_to_track(img, &cp, mask, &existing)?;
        for (slot, c) in free.into_iter().zip(corners) {
            self.templates
                .push(self.params.drift_correction.and_then(|_| {
                    Template::capture(drift_img, [c.x, c.y], self.params.lk.half_window())
                }));
            self.live[slot] = Some(self.tracks.start(slot, fi, [c.x as f64, c.y as f64]));
        }
        Ok(())
    }

    /// Adds the next frame (its number and image).
    pub fn push(&mut self, frame: i64, img: &GrayImage) -> Result<(), KltError> {
        let lk = &self.params.lk;
        let mut pyr = match self.spare.take() {
            Some(p) => p,
            None => Pyramid { levels: Vec::new() },
        };
        pyr.rebuild(img, lk.levels, lk.pad())?;
        let fi = self.tracks.frames.len();
        if !self.watch_noise() {
            self.early = Vec::new();
        } else if fi < NOISY_PAIRS {
            self.early.push((frame, img.clone()));
        }
        let sigma = if self.params.noise_factor > 0.0
            || (fi == 0 && self.params.drift_correction.is_some())
        {
            super::noise::noise_sigma(img)
        } else {
            0.0
        };
        // With `noise_factor` 0 the threshold ignores σ, so measuring it only for the first
        // frame's grain test changes nothing there.
        let max_residual = self.params.residual_threshold(self.prev_sigma, sigma);
        if fi == 0 {
            // Grainy footage is aligned on smoothed frames (module `drift`); decided once from
            // the first frame so that every template and frame of the shot is treated alike.
            self.smooth = sigma > GRAINY_SIGMA;
            let slots = self.params.feature_slots(img.width, img.height);
            self.params.corners.max_corners = slots;
            self.tracks.slots = slots;
            self.tracks.image_size = u32::try_from(img.width)
                .ok()
                .zip(u32::try_from(img.height).ok())
                .map(|(w, h)| [w, h]);
            self.live = vec![None; slots];
        }
        // Drift correction aligns windows of the frame smoothed by a σ = 1 px binomial filter
        // (module `drift`).
        let smoothed = self
            .params
            .drift_correction
            .is_some_and(|_| self.smooth)
            .then(|| img.binomial_smoothed());
        let drift_img = smoothed.as_ref().unwrap_or(img);
        self.prev_sigma = sigma;
        if let Some(prev) = &self.prev {
            if prev.size() != pyr.size() {
                return Err(KltError::SizeMismatch {
                    expected: prev.size(),
                    found: pyr.size(),
                });
            }
            let slots: Vec<usize> = (0..self.live.len())
                .filter(|&s| self.live[s].is_some())
                .collect();
            let pts = self.live_points();
            let mut res = track_points(prev, &pyr, &pts, None, lk)?;
            let m = self.params.border;
            let (w, h) = (img.width as f32, img.height as f32);
            for r in res.iter_mut() {
                let [x, y] = r.pos;
                if r.lost.is_none() && (x < m || y < m || x > w - 1.0 - m || y > h - 1.0 - m) {
                    r.lost = Some(LostReason::LeftImage);
                }
                if r.lost.is_none() && r.residual > max_residual {
                    r.lost = Some(LostReason::Residual);
                }
            }
            if let Some(fb) = self.params.fb_threshold {
                let fwd: Vec<[f32; 2]> = res.iter().map(|r| r.pos).collect();
                let back = track_points(&pyr, prev, &fwd, Some(&pts), lk)?;
                let d: Vec<Option<f32>> = res
                    .iter()
                    .zip(&back)
                    .zip(&pts)
                    .map(|((r, b), p)| {
                        let d = (b.pos[0] - p[0]).hypot(b.pos[1] - p[1]);
                        (r.lost.is_none() && b.lost.is_none() && d.is_finite()).then_some(d)
                    })
                    .collect();
                let spread = median(d.iter().flatten().copied());
                if self.watch_noise() {
                    self.early_spread.push(spread);
                    if self.early_spread.len() == NOISY_PAIRS
                        && median(self.early_spread.iter().copied()) > NOISY_FB
                    {
                        // The shot tracks worse than a fifth of a pixel: start again as noisy
                        // footage.
                        return self.restart_as_noisy(frame, img);
                    }
                }
                let fb = self.spread_bound(fb, spread);
                for (r, d) in res.iter_mut().zip(d) {
                    if r.lost.is_none() && !d.is_some_and(|d| d <= fb) {
                        r.lost = Some(LostReason::ForwardBackward);
                    }
                }
            }
            if let Some(bound) = self.params.drift_correction {
                let ks: Vec<Option<usize>> = slots.iter().map(|&s| self.live[s]).collect();
                let templates = &self.templates;
                type Aligned = Result<([f32; 2], f32, nalgebra::Matrix3<f64>), AlignFailure>;
                let aligned: Vec<Option<Aligned>> = res
                    .par_iter()
                    .zip(&ks)
                    .map(|(r, k)| {
                        let t = templates[(*k)?].as_ref()?;
                        if r.lost.is_some() {
                            return None;
                        }
                        Some(t.align(drift_img, r.pos, 20))
                    })
                    .collect();
                let moved = |r: &LkResult, q: [f32; 2]| (q[0] - r.pos[0]).hypot(q[1] - r.pos[1]);
                let spread = median(res.iter().zip(&aligned).filter_map(|(r, a)| match a {
                    Some(Ok((q, _, _))) => Some(moved(r, *q)),
                    _ => None,
                }));
                let bound = self.spread_bound(bound, spread);
                let accepted: Vec<Option<(usize, nalgebra::Matrix3<f64>)>> = res
                    .iter_mut()
                    .zip(&ks)
                    .zip(aligned)
                    .map(|((r, k), a)| {
                        // A window the template no longer aligns to within the bound has
                        // lost its feature (module `drift`): the track ends. One at the
                        // image's edge cannot be aligned, and keeps its frame-to-frame step.
                        match a? {
                            Ok((q, residual, warp))
                                if moved(r, q) < bound && residual <= max_residual =>
                            {
                                r.pos = q;
                                Some(((*k)?, warp))
                            }
                            Err(AlignFailure::LeftImage) => None,
                            _ => {
                                r.lost = Some(LostReason::Drift);
                                None
                            }
                        }
                    })
                    .collect();
                // Each accepted template updates itself (and, for its first frames, averages
                // the frame's window in): in parallel, by track.
                let mut warps = vec![None; self.templates.len()];
                for (k, warp) in accepted.into_iter().flatten() {
                    warps[k] = Some(warp);
                }
                self.templates
                    .par_iter_mut()
                    .zip(warps)
                    .for_each(|(t, warp)| {
                        if let (Some(t), Some(warp)) = (t.as_mut(), warp) {
                            t.accept(warp, drift_img);
                        }
                    });
            }
            for (slot, r) in slots.into_iter().zip(res) {
                let Some(k) = self.live[slot] else { continue };
                let pos = [r.pos[0] as f64, r.pos[1] as f64];
                if self.tracks.tracks[k].advance(fi, pos, r.lost) {
                    self.live[slot] = None;
                }
            }
            self.tracks.frames.push(frame);
            if self.params.replace_lost {
                self.refill(img, drift_img, fi)?;
            }
        } else {
            self.tracks.frames.push(frame);
            self.refill(img, drift_img, fi)?;
        }
        self.spare = self.prev.replace(pyr);
        Ok(())
    }

    /// A forward–backward or drift `bound` raised to [`TrackerOptions::spread_factor`] × the
    /// frame pair's median distance `spread`, on noisy footage only.
    fn spread_bound(&self, bound: f32, spread: f32) -> f32 {
        if self.noisy {
            bound.max(self.params.spread_factor * spread)
        } else {
            bound
        }
    }

    /// Whether the first frame pairs are still being measured for the switch to
    /// [`TrackerOptions::noisy_window`].
    fn watch_noise(&self) -> bool {
        !self.noisy
            && (self.params.noisy_window > self.params.lk.window || self.params.spread_factor > 0.0)
            && self.params.fb_threshold.is_some()
            && self.early_spread.len() < NOISY_PAIRS
    }

    /// Tracks the shot again from its first frame as noisy footage (with
    /// [`TrackerOptions::noisy_window`] and [`TrackerOptions::spread_factor`]); `img`
    /// is the frame after the first [`NOISY_PAIRS`] pairs, which were tracked and measured to
    /// decide it.
    fn restart_as_noisy(&mut self, frame: i64, img: &GrayImage) -> Result<(), KltError> {
        let early = std::mem::take(&mut self.early);
        let mut params = self.params.clone();
        params.lk.window = params.lk.window.max(params.noisy_window);
        *self = Tracker::new(params)?;
        self.noisy = true;
        for (f, im) in &early {
            self.push(*f, im)?;
        }
        self.push(frame, img)
    }

    /// The tracks so far.
    pub fn tracks(&self) -> &Tracks {
        &self.tracks
    }

    /// Ends the sequence and returns the tracks.
    pub fn finish(self) -> Tracks {
        self.tracks
    }
}

/// Tracks a whole sequence of (frame number, image) pairs (book 6.2–6.5); `progress` is
/// called with the fraction done after each frame. An empty sequence gives empty tracks.
pub fn track_sequence(
    frames: &[(i64, &GrayImage)],
    params: &TrackerOptions,
    mut progress: impl FnMut(f32),
) -> Result<Tracks, KltError> {
    let mut t = Tracker::new(params.clone())?;
    for (k, (f, img)) in frames.iter().enumerate() {
        t.push(*f, img)?;
        progress((k + 1) as f32 / frames.len() as f32);
    }
    Ok(t.finish())
}

/// [`track_sequence`] over `n` frames produced one at a time by `load(k)` = (frame number,
/// image): frame k + 1 is loaded (decoded, converted) while frame k is tracked, and at most
/// two are held, so a long plate never sits in memory whole.
pub fn track_loaded<E: From<KltError> + Send>(
    n: usize,
    load: impl Fn(usize) -> Result<(i64, GrayImage), E> + Sync,
    params: &TrackerOptions,
    mut progress: impl FnMut(f32),
) -> Result<Tracks, E> {
    let mut t = Tracker::new(params.clone())?;
    let mut next = (n > 0).then(|| load(0));
    for k in 0..n {
        let (f, img) = next.take().expect("frame k was loaded")?;
        let (pushed, loaded) = rayon::join(|| t.push(f, &img), || (k + 1 < n).then(|| load(k + 1)));
        pushed?;
        next = loaded;
        progress((k + 1) as f32 / n as f32);
    }
    Ok(t.finish())
}

/// The median of `v` (0 when empty).
fn median(v: impl Iterator<Item = f32>) -> f32 {
    let mut v: Vec<f32> = v.collect();
    if v.is_empty() {
        return 0.0;
    }
    let mid = v.len() / 2;
    *v.select_nth_unstable_by(mid, f32::total_cmp).1
}
