//! The weight of each track in the global adjustment's outlier rounds (weighted least squares,
//! Triggs et al. 2000 §3.2; the reweighting of IRLS): tracks are not equally accurate, and
//! giving each the weight of its accuracy, rather than one each, keeps the many mediocre tracks
//! of grainy footage from bending the path.
//!
//! A track's weight is `σ_ref / σ_t · √((1 − ρ_t)/(1 + ρ_t))`, at most [`MAX_TRACK_WEIGHT`]:
//!
//! - **Its noise σ_t**, estimated from its residuals after the previous adjustment:
//!   √(Σ|e|² / d_t) on d_t = 2n − 3 degrees of freedom (a point has 3 parameters). On grainy
//!   footage a corner on a sharp texture holds within a tenth of a pixel where one on a soft
//!   edge slides by one. (Smyth's empirical-Bayes moderation of the variances — each track's
//!   shrunk towards a prior fitted to all of them, Smyth 2004 §6.2 — was tried for the short
//!   tracks' scattered estimates: on the dev plates it fitted 1.5–2.6 prior degrees of freedom,
//!   i.e. it hardly shrank, and it was no better — the distorted dev plate 0.097° against
//!   0.092°, the worst of 12 seeded synthetic shots 0.165° against 0.126° — so the plain
//!   estimate stays.)
//! - **The correlation ρ_t of its residuals along it**: the lag-one correlation of its
//!   residual vectors over consecutive inlier frames, Σ eⱼ·eⱼ₊₁ / Σ|eⱼ|², clamped to
//!   0–[`MAX_RESIDUAL_CORRELATION`]. A static point's residuals are white; a track that slides
//!   (a T-junction, an edge, a window that drifts) leaves residuals that change slowly along
//!   it — largest at its ends, small in the middle where its point was fitted — and its n
//!   observations carry the information of about n(1 − ρ)/(1 + ρ) independent ones (the
//!   variance inflation of an AR(1) series). Measured with `examples/track_accuracy.rs` on the
//!   Blender dev plate, most of the tracks over 1 px against the true cameras are of this kind
//!   (2–3 px at both ends, near 0 in the middle), and their residuals after a solve are small
//!   enough that the noise alone does not discount them.
//!
//! σ_ref is the median σ_t, so the typical track keeps weight 1 (the robust loss's scale stays
//! in pixels). Over 12 seeded synthetic shots through a lens (5 % drifting tracks, 0.1 and
//! 0.5 px noise, focal length and Brown–Conrady lens unknown) the weighting lowered the worst
//! rotation error in 10 (`matchmove::tests::track_weighting_beats_the_unweighted_adjustment`).

use nalgebra::Vector3;
use rayon::prelude::*;
use vfxgraph_geometry::camera::{Intrinsics, Pose};
use vfxgraph_klt::Tracks;

/// Largest weight of a track: a short track whose few residuals happen to be small does not
/// outweigh the typical track by more than this.
pub const MAX_TRACK_WEIGHT: f64 = 4.0;

/// Largest lag-one correlation of a track's residuals counted (its information then shrinks
/// to √(0.05/1.95) ≈ 0.16 of its length's, not to nothing).
pub const MAX_RESIDUAL_CORRELATION: f64 = 0.95;

/// One track's residual statistics after an adjustment.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrackResiduals {
    /// Sum of squared residuals over its inlier observations, px².
    pub sum_squares: f64,
    /// Degrees of freedom, 2n − 3 for n inlier observations.
    pub dof: f64,
    /// Lag-one correlation of its residual vectors, clamped to 0–[`MAX_RESIDUAL_CORRELATION`].
    pub correlation: f64,
}

/// Per track, the weight of its observations in the next adjustment (module docs); tracks
/// without a point or with fewer than two inlier observations get 0.
pub(crate) fn track_weights(
    tracks: &Tracks,
    k: &Intrinsics,
    poses: &[Option<Pose>],
    points: &[Option<Vector3<f64>>],
    flags: &[Vec<bool>],
) -> Vec<f64> {
    let stats: Vec<Option<TrackResiduals>> = (0..tracks.tracks.len())
        .into_par_iter()
        .map(|ti| {
            let x = points[ti]?;
            let t = &tracks.tracks[ti];
            let projected = t.points.iter().enumerate().map(|(j, o)| {
                let p = flags[ti][j]
                    .then(|| crate::structure::project(k, poses[t.first + j].as_ref()?, &x))
                    .flatten()?;
                Some([p[0] - o[0], p[1] - o[1]])
            });
            residual_statistics(projected)
        })
        .collect();
    weights(&stats)
}

/// The statistics of one track's residual vectors in frame order (`None`: not an inlier, which
/// breaks the run the correlation is taken over); `None` under two inliers.
pub fn residual_statistics(
    residuals: impl IntoIterator<Item = Option<[f64; 2]>>,
) -> Option<TrackResiduals> {
    let (mut ss, mut lag, mut n) = (0.0, 0.0, 0usize);
    let mut prev: Option<[f64; 2]> = None;
    for e in residuals {
        let Some(e) = e else {
            prev = None;
            continue;
        };
        ss += e[0] * e[0] + e[1] * e[1];
        n += 1;
        if let Some(q) = prev {
            lag += e[0] * q[0] + e[1] * q[1];
        }
        prev = Some(e);
    }
    if n < 2 {
        return None;
    }
    let correlation = if ss > 0.0 {
        (lag / ss).clamp(0.0, MAX_RESIDUAL_CORRELATION)
    } else {
        0.0
    };
    Some(TrackResiduals {
        sum_squares: ss,
        dof: (2 * n - 3) as f64,
        correlation,
    })
}

/// The weights of [`track_weights`] from the tracks' residual statistics (all 1 when no track
/// has any).
pub fn weights(stats: &[Option<TrackResiduals>]) -> Vec<f64> {
    let sigma: Vec<Option<f64>> = stats
        .iter()
        .map(|s| s.map(|r| (r.sum_squares / r.dof).sqrt()))
        .collect();
    let mut sorted: Vec<f64> = sigma.iter().flatten().copied().collect();
    sorted.sort_by(f64::total_cmp);
    let Some(&reference) = sorted.get(sorted.len() / 2) else {
        // No track to measure: the unweighted adjustment (as before the weighting).
        return vec![1.0; stats.len()];
    };
    stats
        .iter()
        .zip(&sigma)
        .map(|(s, sigma)| match (s, sigma) {
            (Some(r), Some(sigma)) if *sigma > 0.0 => {
                let independent = ((1.0 - r.correlation) / (1.0 + r.correlation)).sqrt();
                (independent * reference / sigma).min(MAX_TRACK_WEIGHT)
            }
            (Some(_), Some(_)) => MAX_TRACK_WEIGHT,
            _ => 0.0,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64;

    use super::*;

    /// A track of `n` observations whose residuals are Gaussian of `sigma` px per coordinate,
    /// white along the track, drawn by a seeded generator. As after fitting its point, the sum
    /// of squares has 2n − 3 degrees of freedom: it sums the first 2n − 3 coordinates.
    fn track(rng: &mut Pcg64, n: usize, sigma: f64) -> TrackResiduals {
        // Box–Muller: two Gaussians from two uniforms.
        let mut pair = || {
            let (u, v): (f64, f64) = (rng.random(), rng.random());
            let r = sigma * (-2.0 * (1.0 - u).ln()).sqrt();
            let a = 2.0 * std::f64::consts::PI * v;
            [r * a.cos(), r * a.sin()]
        };
        let e: Vec<[f64; 2]> = (0..n).map(|_| pair()).collect();
        let mut r = residual_statistics(e.iter().map(|&v| Some(v))).unwrap();
        r.sum_squares = e.iter().flatten().take(2 * n - 3).map(|x| x * x).sum();
        r
    }

    /// Two populations of tracks (0.2 and 0.8 px, 40 observations each): a precise track
    /// outweighs a noisy one about 4×, the ratio of their noise.
    #[test]
    fn tracks_of_different_accuracy_are_weighted_by_it() {
        let mut rng = Pcg64::seed_from_u64(11);
        let stats: Vec<_> = (0..400)
            .map(|i| Some(track(&mut rng, 40, if i % 2 == 0 { 0.2 } else { 0.8 })))
            .collect();
        let w = weights(&stats);
        let mean = |parity: usize| {
            let v: Vec<f64> = w.iter().skip(parity).step_by(2).copied().collect();
            v.iter().sum::<f64>() / v.len() as f64
        };
        let ratio = mean(0) / mean(1);
        assert!(
            (3.3..4.4).contains(&ratio),
            "precise / noisy weight {ratio}"
        );
    }

    /// A track that slides (residuals drifting linearly from −1 to 1 px along it) is
    /// discounted by its correlation: its weight is a fraction of a white track's of the same
    /// RMS.
    #[test]
    fn a_sliding_track_is_discounted() {
        let n = 30;
        let slide = residual_statistics((0..n).map(|j| {
            let s = -1.0 + 2.0 * j as f64 / (n - 1) as f64;
            Some([s, 0.0])
        }))
        .unwrap();
        assert!(slide.correlation > 0.85, "ρ {}", slide.correlation);
        let white = TrackResiduals {
            correlation: 0.0,
            ..slide
        };
        let w = weights(&[Some(slide), Some(white)]);
        assert!(w[0] < 0.3 * w[1], "{w:?}");
        // No statistics, no weight; a run broken by an outlier restarts the correlation.
        assert_eq!(weights(&[None, Some(white)])[0], 0.0);
        let broken = residual_statistics([Some([1.0, 0.0]), None, Some([1.0, 0.0])]).unwrap();
        assert_eq!(broken.correlation, 0.0);
    }
}
