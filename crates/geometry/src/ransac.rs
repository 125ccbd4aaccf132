//! RANSAC (book §3.6, Fischler & Bolles 1981), written once and generic over an [`Estimator`]
//! in the manner of COLMAP: the estimator knows its minimal sample, fits models to a sample and
//! measures a residual; [`ransac`] only samples, scores and refits.
//!
//! Beyond the book's fixed iteration count, the number of iterations adapts to the best inlier
//! ratio w found so far: N = log(1 − p) / log(1 − wˢ) for confidence p and sample size s
//! (Hartley & Zisserman §4.7.1). Each new best model is refitted on its consensus set (LO-RANSAC,
//! Chum et al. 2003), and the winner is refitted again on its final consensus set, which is then
//! recomputed with the refitted model.

use nalgebra::{Matrix2, Point2, Vector2};
use rand::Rng;
use serde::{Deserialize, Serialize};

use crate::error::{Result, VisionError};

/// A model estimator for [`ransac`].
pub trait Estimator {
    /// One datum (a correspondence, a point…).
    type Datum;
    /// The estimated model.
    type Model: Clone;
    /// Size of a minimal sample.
    const MIN_SAMPLES: usize;

    /// Models fitted to the data at `sample` (a minimal sample in the loop). May return none
    /// (degenerate sample) or several (e.g. several roots).
    fn estimate(&self, data: &[Self::Datum], sample: &[usize]) -> Vec<Self::Model>;

    /// The residual of one datum under a model, in the unit of the threshold (e.g. pixels).
    fn residual(&self, model: &Self::Model, datum: &Self::Datum) -> f64;

    /// Refit on a consensus set (more than the minimal sample). Defaults to the first model of
    /// [`Estimator::estimate`] on the whole set; estimators override it with a nonlinear refinement.
    fn refit(
        &self,
        data: &[Self::Datum],
        inliers: &[usize],
        model: &Self::Model,
    ) -> Option<Self::Model> {
        let _ = model;
        self.estimate(data, inliers).into_iter().next()
    }
}

/// Parameters of [`ransac`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RansacParams {
    /// Residual threshold under which a datum is an inlier.
    pub threshold: f64,
    /// Probability p of drawing at least one outlier-free sample, used for the adaptive count.
    pub confidence: f64,
    /// Hard cap on the number of iterations.
    pub max_iterations: usize,
    /// Minimum number of iterations, whatever the inlier ratio.
    pub min_iterations: usize,
    /// Refit on the consensus set (then recompute the consensus) this many times; 0 disables.
    pub refit_rounds: usize,
    /// Local optimization (LO-RANSAC, Chum, Matas & Kittler 2003): each time a sample gives a new
    /// best model, refit it on its consensus set and keep the refit when it scores better. Noisy
    /// minimal samples under-count the inliers; the refit recovers them, so the adaptive count
    /// stops much earlier.
    pub local_optimization: bool,
}

impl Default for RansacParams {
    fn default() -> Self {
        RansacParams {
            threshold: 2.0,
            confidence: 0.999,
            max_iterations: 10_000,
            min_iterations: 20,
            refit_rounds: 2,
            local_optimization: true,
        }
    }
}

impl RansacParams {
    /// Default parameters with the given inlier threshold.
    pub fn with_threshold(threshold: f64) -> Self {
        RansacParams {
            threshold,
            ..Default::default()
        }
    }
}

/// Output of [`ransac`].
#[derive(Clone, Debug, PartialEq)]
pub struct RansacResult<M> {
    /// The model (refitted on the consensus set when enabled).
    pub model: M,
    /// Inlier flag of every datum under `model`.
    pub inliers: Vec<bool>,
    /// Number of inliers.
    pub num_inliers: usize,
    /// Iterations of the sampling loop actually run.
    pub iterations: usize,
}

/// Iterations needed to draw an all-inlier sample of size `s` with probability `p` when the
/// inlier ratio is `w`.
pub fn adaptive_iterations(w: f64, s: usize, p: f64) -> usize {
    if w >= 1.0 {
        return 1;
    }
    let ws = w.powi(s as i32);
    if ws <= 0.0 {
        return usize::MAX;
    }
    let denom = (1.0 - ws).ln();
    if denom >= 0.0 {
        return usize::MAX;
    }
    let n = (1.0 - p).ln() / denom;
    if n.is_finite() && n < usize::MAX as f64 {
        n.ceil().max(1.0) as usize
    } else {
        usize::MAX
    }
}

fn consensus<E: Estimator>(
    est: &E,
    data: &[E::Datum],
    model: &E::Model,
    threshold: f64,
) -> (Vec<bool>, usize, f64) {
    let mut flags = vec![false; data.len()];
    let mut count = 0;
    let mut score = 0.0;
    for (i, d) in data.iter().enumerate() {
        let r = est.residual(model, d);
        if r.is_finite() && r <= threshold {
            flags[i] = true;
            count += 1;
            score += r * r;
        }
    }
    (flags, count, score)
}

/// Robust estimation by RANSAC (book §3.6.1) with an adaptive iteration count and a refit on
/// the consensus set. `rng` is the caller's seeded generator (e.g. `rand_pcg::Pcg64`), so the
/// result is reproducible.
pub fn ransac<E, R>(
    est: &E,
    data: &[E::Datum],
    params: &RansacParams,
    rng: &mut R,
) -> Result<RansacResult<E::Model>>
where
    E: Estimator,
    R: Rng + ?Sized,
{
    let n = data.len();
    let s = E::MIN_SAMPLES;
    if n < s {
        return Err(VisionError::TooFewPoints { needed: s, got: n });
    }
    if !(params.threshold > 0.0 && params.confidence > 0.0 && params.confidence < 1.0) {
        return Err(VisionError::InvalidInput(
            "RANSAC needs threshold > 0 and 0 < confidence < 1".into(),
        ));
    }
    let mut best: Option<(E::Model, Vec<bool>, usize, f64)> = None;
    let mut needed = params.max_iterations;
    let mut iterations = 0;
    while iterations < needed.max(params.min_iterations).min(params.max_iterations) {
        iterations += 1;
        let sample = rand::seq::index::sample(rng, n, s).into_vec();
        for model in est.estimate(data, &sample) {
            let (flags, count, score) = consensus(est, data, &model, params.threshold);
            let better = match &best {
                None => true,
                Some((_, _, c, sc)) => count > *c || (count == *c && score < *sc),
            };
            if better {
                let (mut model, mut flags, mut count, mut score) = (model, flags, count, score);
                if params.local_optimization && count > s {
                    let idx: Vec<usize> = (0..n).filter(|&i| flags[i]).collect();
                    if let Some(lo) = est.refit(data, &idx, &model) {
                        let (f2, c2, s2) = consensus(est, data, &lo, params.threshold);
                        if c2 > count || (c2 == count && s2 < score) {
                            (model, flags, count, score) = (lo, f2, c2, s2);
                        }
                    }
                }
                needed = adaptive_iterations(count as f64 / n as f64, s, params.confidence);
                best = Some((model, flags, count, score));
            }
        }
    }
    let (mut model, mut flags, mut count, _) = match best {
        Some(b) if b.2 >= s => b,
        other => {
            return Err(VisionError::NoConsensus {
                best: other.map_or(0, |b| b.2),
                total: n,
                needed: s,
            })
        }
    };
    for _ in 0..params.refit_rounds {
        let idx: Vec<usize> = (0..n).filter(|&i| flags[i]).collect();
        let Some(refit) = est.refit(data, &idx, &model) else {
            break;
        };
        let (f2, c2, _) = consensus(est, data, &refit, params.threshold);
        if c2 < count.min(idx.len()) || c2 < s {
            break;
        }
        let unchanged = f2 == flags;
        model = refit;
        flags = f2;
        count = c2;
        if unchanged {
            break;
        }
    }
    Ok(RansacResult {
        model,
        inliers: flags,
        num_inliers: count,
        iterations,
    })
}

/// A line n·p + c = 0 with ‖n‖ = 1.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Line2 {
    /// Unit normal.
    pub normal: Vector2<f64>,
    /// Offset.
    pub c: f64,
}

/// The book's RANSAC example (§3.6.2): a straight line through 2D points. Two points define a
/// candidate; the residual is the distance to the line (the "tubular neighbourhood"); the refit
/// is the orthogonal (total) least-squares line of the inliers.
#[derive(Clone, Copy, Debug, Default)]
pub struct LineEstimator;

impl Estimator for LineEstimator {
    type Datum = Point2<f64>;
    type Model = Line2;
    const MIN_SAMPLES: usize = 2;

    fn estimate(&self, data: &[Point2<f64>], sample: &[usize]) -> Vec<Line2> {
        if sample.len() == 2 {
            let (p, q) = (data[sample[0]], data[sample[1]]);
            let d = q - p;
            let len = d.norm();
            if len == 0.0 {
                return vec![];
            }
            let normal = Vector2::new(-d.y, d.x) / len;
            return vec![Line2 {
                normal,
                c: -normal.dot(&p.coords),
            }];
        }
        // Total least squares: the normal is the least-variance direction of the scatter matrix.
        let m = sample.len() as f64;
        let mean = sample
            .iter()
            .fold(Vector2::zeros(), |a, &i| a + data[i].coords)
            / m;
        let mut s = Matrix2::zeros();
        for &i in sample {
            let d = data[i].coords - mean;
            s += d * d.transpose();
        }
        let eig = s.symmetric_eigen();
        let k = if eig.eigenvalues[0] <= eig.eigenvalues[1] {
            0
        } else {
            1
        };
        let normal = eig.eigenvectors.column(k).into_owned().normalize();
        vec![Line2 {
            normal,
            c: -normal.dot(&mean),
        }]
    }

    fn residual(&self, line: &Line2, p: &Point2<f64>) -> f64 {
        (line.normal.dot(&p.coords) + line.c).abs()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_pcg::Pcg64;

    #[test]
    fn adaptive_count() {
        assert_eq!(adaptive_iterations(1.0, 8, 0.99), 1);
        let n = adaptive_iterations(0.5, 2, 0.99);
        assert_eq!(n, 17); // log(0.01)/log(0.75) = 16.01
        assert_eq!(adaptive_iterations(0.0, 2, 0.99), usize::MAX);
    }

    #[test]
    fn line_with_outliers() {
        let mut rng = Pcg64::seed_from_u64(7);
        let mut pts = Vec::new();
        for i in 0..70 {
            let x = i as f64 * 0.1;
            let noise = rng.random_range(-0.01..0.01);
            pts.push(Point2::new(x, 0.5 * x - 1.0 + noise));
        }
        for _ in 0..30 {
            pts.push(Point2::new(
                rng.random_range(0.0..7.0),
                rng.random_range(-5.0..5.0),
            ));
        }
        let res = ransac(
            &LineEstimator,
            &pts,
            &RansacParams::with_threshold(0.03),
            &mut Pcg64::seed_from_u64(1),
        )
        .unwrap();
        let slope = -res.model.normal.x / res.model.normal.y;
        let intercept = -res.model.c / res.model.normal.y;
        assert!(
            (slope - 0.5).abs() < 2e-3 && (intercept + 1.0).abs() < 1e-2,
            "{slope} {intercept}"
        );
        assert!(res.inliers[..70].iter().filter(|&&b| b).count() >= 68);
        assert!(res.num_inliers <= 75);
        assert!(res.iterations < 200, "adaptive count: {}", res.iterations);
        // Same seed, same result.
        let again = ransac(
            &LineEstimator,
            &pts,
            &RansacParams::with_threshold(0.03),
            &mut Pcg64::seed_from_u64(1),
        )
        .unwrap();
        assert_eq!(res, again);
    }

    #[test]
    fn too_few_points() {
        let pts = vec![Point2::new(0.0, 0.0)];
        let e = ransac(
            &LineEstimator,
            &pts,
            &RansacParams::default(),
            &mut Pcg64::seed_from_u64(1),
        );
        assert!(matches!(
            e,
            Err(VisionError::TooFewPoints { needed: 2, got: 1 })
        ));
    }
}
