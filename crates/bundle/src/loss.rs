//! Robust losses (Triggs et al. 2000, section 3.3; Ceres' `LossFunction`) as values.
//!
//! A loss ρ acts on the squared residual norm s = ‖r‖² of one observation; the cost is
//! ½·Σ ρ(sᵢ). The `scale` is in pixels: residuals below it are treated (almost) quadratically.

use serde::{Deserialize, Serialize};
use vfxgraph_params::Choice;

/// A robust loss by name, as a node's param chooses it; [`RobustLoss::at`] gives it a scale.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Choice)]
#[serde(rename_all = "lowercase")]
pub enum RobustLoss {
    /// Plain least squares.
    None,
    /// Huber's loss.
    Huber,
    /// Cauchy's loss.
    Cauchy,
}

impl RobustLoss {
    /// The loss with scale `scale` px.
    pub fn at(self, scale: f64) -> Loss {
        match self {
            RobustLoss::None => Loss::Trivial,
            RobustLoss::Huber => Loss::Huber { scale },
            RobustLoss::Cauchy => Loss::Cauchy { scale },
        }
    }
}

/// A robust loss with its scale in pixels (Ceres' `HuberLoss(a)`, `CauchyLoss(a)`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Loss {
    /// ρ(s) = s: plain least squares.
    #[default]
    Trivial,
    /// ρ(s) = s for s ≤ a², 2a√s − a² otherwise.
    Huber {
        /// a, in pixels.
        scale: f64,
    },
    /// ρ(s) = a²·log(1 + s/a²).
    Cauchy {
        /// a, in pixels.
        scale: f64,
    },
}

impl Loss {
    /// Parses `none|trivial|huber[:a]|cauchy[:a]` (default scale 1 px), for command lines.
    pub fn parse(text: &str) -> Option<Loss> {
        let (name, scale) = match text.split_once([':', '=']) {
            Some((n, s)) => (
                n,
                s.parse::<f64>()
                    .ok()
                    .filter(|v| v.is_finite() && *v > 0.0)?,
            ),
            None => (text, 1.0),
        };
        match name.to_ascii_lowercase().as_str() {
            "none" | "trivial" | "l2" => Some(Loss::Trivial),
            "huber" => Some(Loss::Huber { scale }),
            "cauchy" => Some(Loss::Cauchy { scale }),
            _ => None,
        }
    }

    /// (ρ(s), ρ'(s), ρ''(s)) at the squared norm s (Ceres' `LossFunction::Evaluate`).
    pub fn evaluate(&self, s: f64) -> [f64; 3] {
        match *self {
            Loss::Trivial => [s, 1.0, 0.0],
            Loss::Huber { scale } => {
                let b = scale * scale;
                if s > b {
                    let r = s.sqrt();
                    [2.0 * scale * r - b, scale / r, -0.5 * scale / (s * r)]
                } else {
                    [s, 1.0, 0.0]
                }
            }
            Loss::Cauchy { scale } => {
                let b = scale * scale;
                let c = 1.0 / b;
                let sum = 1.0 + s * c;
                let inv = 1.0 / sum;
                [b * sum.ln(), inv, -c * inv * inv]
            }
        }
    }

    /// Triggs' correction (Triggs et al. 2000, sec. 4.3; Ceres' `Corrector`): returns
    /// `(residual_scale, alpha_sq_norm, jacobian_scale)` such that the corrected residual is
    /// `residual_scale·r` and the corrected Jacobian is `jacobian_scale·(J − alpha_sq_norm·r·rᵀJ)`,
    /// so that Gauss–Newton on the corrected terms sees ρ's curvature.
    pub fn corrector(&self, s: f64) -> (f64, f64, f64) {
        if let Loss::Trivial = self {
            return (1.0, 0.0, 1.0);
        }
        let rho = self.evaluate(s);
        let sqrt_rho1 = rho[1].sqrt();
        if s == 0.0 || rho[2] <= 0.0 {
            return (sqrt_rho1, 0.0, sqrt_rho1);
        }
        let d = 1.0 + 2.0 * s * rho[2] / rho[1];
        let alpha = 1.0 - d.max(0.0).sqrt();
        (sqrt_rho1 / (1.0 - alpha), alpha / s, sqrt_rho1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn derivatives_match_finite_differences() {
        for loss in [Loss::Huber { scale: 2.0 }, Loss::Cauchy { scale: 1.5 }] {
            for s in [0.3, 2.0, 9.0, 30.0] {
                let h = 1e-6;
                let [_, d1, d2] = loss.evaluate(s);
                let fd1 = (loss.evaluate(s + h)[0] - loss.evaluate(s - h)[0]) / (2.0 * h);
                let fd2 = (loss.evaluate(s + h)[1] - loss.evaluate(s - h)[1]) / (2.0 * h);
                assert!((d1 - fd1).abs() < 1e-6, "{loss:?} s={s}");
                assert!((d2 - fd2).abs() < 1e-6, "{loss:?} s={s}");
            }
        }
    }

    #[test]
    fn parse_names() {
        assert_eq!(Loss::parse("huber:2"), Some(Loss::Huber { scale: 2.0 }));
        assert_eq!(Loss::parse("cauchy"), Some(Loss::Cauchy { scale: 1.0 }));
        assert_eq!(Loss::parse("none"), Some(Loss::Trivial));
        assert_eq!(Loss::parse("huber:nan"), None);
        assert_eq!(Loss::parse("tukey"), None);
    }
}
