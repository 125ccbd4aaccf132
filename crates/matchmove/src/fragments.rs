//! Fragments (book §7.11): the sequence cut into pieces short enough for features to survive
//! through them and long enough to have parallax.
//!
//! A fragment starts at a base frame and takes frames until it has more than `min_frames` frames
//! AND the mean displacement, since the base frame, of the features tracked since then reaches
//! `min_displacement` pixels. Consecutive fragments share one frame (the last of one is the
//! first of the next). Only features tracked through the whole fragment belong to it.
//!
//! Two additions to the book: a fragment is also cut early when fewer than `min_features`
//! features would survive through it (the book's rule can starve a fragment on footage that
//! loses features fast), and the last fragment — shorter than the rule asks, which the book
//! throws away — is kept and solved too.

use serde::{Deserialize, Serialize};
use vfxgraph_geometry::error::{Result, VisionError};
use vfxgraph_klt::Tracks;
use vfxgraph_params::Options;

use crate::structure::through;

/// The cutting rule's constants.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Options)]
#[serde(default)]
pub struct FragmentOptions {
    /// a fragment has more frames than this (§7.11)
    ///
    /// Book: 60.
    #[param(range = 2..=100_000)]
    pub min_frames: usize,
    /// …and its features moved this much since its base frame, px (§7.11)
    ///
    /// On average, pixels (book: 20).
    #[param(range = 0.0..=1e5)]
    pub min_displacement: f64,
    /// cut a fragment early rather than keep fewer features through it
    #[param(range = 6..=100_000)]
    pub min_features: usize,
}

impl Default for FragmentOptions {
    fn default() -> Self {
        FragmentOptions {
            min_frames: 60,
            min_displacement: 20.0,
            min_features: 30,
        }
    }
}

/// One fragment: frame indices `first..=last` and the tracks seen in all of them.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Fragment {
    /// First frame index (into `Tracks::frames`).
    pub first: usize,
    /// Last frame index, inclusive.
    pub last: usize,
    /// Indices (into `Tracks::tracks`) of the tracks observed in every frame of the fragment.
    pub features: Vec<usize>,
    /// The remainder at the end of the sequence, shorter than the rule asks.
    pub is_last: bool,
}

impl Fragment {
    /// Number of frames.
    pub fn len(&self) -> usize {
        self.last - self.first + 1
    }

    /// Whether the fragment has no frames (never true for a built fragment).
    pub fn is_empty(&self) -> bool {
        false
    }
}

/// Tracks seen in every frame of `first..=last`.
fn features_through(tracks: &Tracks, first: usize, last: usize) -> Vec<usize> {
    tracks
        .tracks
        .iter()
        .enumerate()
        .filter(|(_, t)| through(t, first, last).is_some())
        .map(|(i, _)| i)
        .collect()
}

/// The fragment of frames `first..=last` with the tracks seen in all of them.
pub(crate) fn fragment_of(tracks: &Tracks, first: usize, last: usize, is_last: bool) -> Fragment {
    Fragment {
        first,
        last,
        features: features_through(tracks, first, last),
        is_last,
    }
}

/// Mean displacement between frames `a` and `b` of the given tracks, pixels.
pub(crate) fn mean_displacement(tracks: &Tracks, features: &[usize], a: usize, b: usize) -> f64 {
    if features.is_empty() {
        return 0.0;
    }
    let s: f64 = features
        .iter()
        .map(|&i| {
            let t = &tracks.tracks[i];
            let (pa, pb) = (t.points[a - t.first], t.points[b - t.first]);
            ((pa[0] - pb[0]).powi(2) + (pa[1] - pb[1]).powi(2)).sqrt()
        })
        .sum();
    s / features.len() as f64
}

/// Cuts the sequence into fragments (book §7.11, with the additions of the module docs).
pub fn split_fragments(tracks: &Tracks, options: &FragmentOptions) -> Result<Vec<Fragment>> {
    let n = tracks.frames.len();
    if options.min_frames < 2 {
        return Err(VisionError::InvalidInput(
            "fragments need min_frames ≥ 2".into(),
        ));
    }
    let mut out = Vec::new();
    let mut base = 0usize;
    while base + 1 < n {
        let mut cut = None;
        let mut prev_features = features_through(tracks, base, base);
        for e in base + 1..n {
            let feats: Vec<usize> = prev_features
                .iter()
                .copied()
                .filter(|&i| tracks.tracks[i].end() > e)
                .collect();
            if feats.len() < options.min_features && e > base + 1 {
                // Starving: end the fragment at the previous frame.
                cut = Some((e - 1, std::mem::take(&mut prev_features)));
                break;
            }
            let long = e - base + 1 > options.min_frames;
            if long && mean_displacement(tracks, &feats, base, e) >= options.min_displacement {
                cut = Some((e, feats));
                break;
            }
            prev_features = feats;
        }
        match cut {
            Some((last, features)) => {
                out.push(Fragment {
                    first: base,
                    last,
                    features,
                    is_last: false,
                });
                base = last;
            }
            None => {
                out.push(Fragment {
                    first: base,
                    last: n - 1,
                    features: prev_features,
                    is_last: true,
                });
                break;
            }
        }
    }
    if out.is_empty() {
        return Err(VisionError::InvalidInput(
            "the sequence is too short to cut into fragments".into(),
        ));
    }
    Ok(out)
}
