//! Every constant of the matchmove in one value ([`MatchmoveOptions`]), gathered from the
//! stages' own options, with the book's values as defaults.

use serde::{Deserialize, Serialize};

use crate::fragment::RefineOptions;
use crate::fragments::FragmentOptions;
use crate::global::GlobalOptions;
use crate::junction::ScaleOptions;
use crate::lens::LensOptions;
use crate::pair::PairOptions;
use crate::parallax::MotionOptions;

/// Every constant of the matchmove, with the book's values as defaults.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, vfxgraph_params::Options)]
#[serde(default)]
pub struct MatchmoveOptions {
    /// Fragment cutting (§7.11).
    #[param(flatten)]
    pub fragments: FragmentOptions,
    /// Best-pair search (§7.2–7.6).
    #[param(flatten)]
    pub pair: PairOptions,
    /// Refinement cycles (§7.9).
    #[param(flatten)]
    pub refine: RefineOptions,
    /// Scale search between fragments (§7.12).
    #[param(flatten)]
    pub scale: ScaleOptions,
    /// finish with a robust bundle adjustment of the whole sequence
    ///
    /// Not in the book; `None` skips it.
    #[param(toggle = "global_adjust")]
    pub global: Option<GlobalOptions>,
    /// The lens: what of the focal length and distortion is solved (`matchmove_with_lens`;
    /// `matchmove` itself ignores it and takes K as exact and the tracks as a pinhole's).
    #[param(flatten)]
    pub lens: LensOptions,
    /// The camera's motion: general, or a nodal pan (the `tripod` solve), or detected.
    #[param(flatten)]
    pub motion: MotionOptions,
    /// Seed of every random choice (RANSAC samples); each fragment derives its own stream.
    #[param(skip)]
    pub seed: u64,
    /// score the cameras against every track into the report
    ///
    /// The book-style score of [`crate::score`].
    pub score: bool,
}

impl Default for MatchmoveOptions {
    fn default() -> Self {
        MatchmoveOptions {
            fragments: FragmentOptions::default(),
            pair: PairOptions::default(),
            refine: RefineOptions::default(),
            scale: ScaleOptions::default(),
            global: Some(GlobalOptions::default()),
            lens: LensOptions::default(),
            motion: MotionOptions::default(),
            seed: 0,
            score: true,
        }
    }
}
