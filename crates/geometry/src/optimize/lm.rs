//! Levenberg–Marquardt for small dense nonlinear least squares (book §3.3.2).
//!
//! Minimizes g(x) = ½‖f(x)‖². Each step solves (JᵀJ + μD)h = −Jᵀf (book eq. 3.21) with
//! Marquardt's scaling D = diag(JᵀJ), which makes the damping insensitive to the very different
//! units of the parameters (focal lengths in pixels, angles in radians). μ follows Nielsen's
//! gain-ratio rule. The Jacobian is analytic when the problem provides one, otherwise it is
//! computed by central differences.

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

/// A nonlinear least-squares problem: residuals f(x) ∈ Rᵐ of parameters x ∈ Rⁿ.
pub trait LeastSquaresProblem {
    /// The residual vector f(x). Non-finite entries mark x as infeasible (the step is rejected).
    fn residuals(&self, x: &DVector<f64>) -> DVector<f64>;

    /// The Jacobian ∂f/∂x (m × n), or `None` to let the solver use central differences.
    fn jacobian(&self, x: &DVector<f64>) -> Option<DMatrix<f64>> {
        let _ = x;
        None
    }
}

/// Options of [`levenberg_marquardt`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LmOptions {
    /// Maximum number of iterations (accepted or rejected steps).
    pub max_iterations: usize,
    /// Stop when the relative decrease of the cost in an accepted step is below this.
    pub ftol: f64,
    /// Stop when the step is below `xtol · (‖x‖ + xtol)`.
    pub xtol: f64,
    /// Stop when ‖Jᵀf‖∞ is below this.
    pub gtol: f64,
    /// Initial damping relative to max diag(JᵀJ).
    pub initial_damping: f64,
}

impl Default for LmOptions {
    fn default() -> Self {
        LmOptions {
            max_iterations: 100,
            ftol: 1e-12,
            xtol: 1e-12,
            gtol: 1e-12,
            initial_damping: 1e-3,
        }
    }
}

/// Why the solver stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum LmTermination {
    /// Gradient small enough.
    Gradient,
    /// Step small enough.
    Step,
    /// Cost decrease small enough.
    Cost,
    /// Iteration limit reached.
    MaxIterations,
    /// No step could decrease the cost (damping overflowed).
    Stalled,
}

/// Summary of a Levenberg–Marquardt run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LmReport {
    /// Iterations done.
    pub iterations: usize,
    /// ½‖f‖² at the start.
    pub initial_cost: f64,
    /// ½‖f‖² at the end.
    pub final_cost: f64,
    /// Why it stopped.
    pub termination: LmTermination,
}

fn cost(r: &DVector<f64>) -> f64 {
    if r.iter().all(|v| v.is_finite()) {
        0.5 * r.norm_squared()
    } else {
        f64::INFINITY
    }
}

/// Central-difference Jacobian of `problem` at `x`.
pub fn numeric_jacobian<P: LeastSquaresProblem + ?Sized>(
    problem: &P,
    x: &DVector<f64>,
    m: usize,
) -> DMatrix<f64> {
    let n = x.len();
    let mut j = DMatrix::zeros(m, n);
    let mut xp = x.clone();
    for k in 0..n {
        let h = 1e-6 * x[k].abs().max(1e-3);
        let orig = xp[k];
        xp[k] = orig + h;
        let fp = problem.residuals(&xp);
        xp[k] = orig - h;
        let fm = problem.residuals(&xp);
        xp[k] = orig;
        j.set_column(k, &((fp - fm) / (2.0 * h)));
    }
    j
}

/// Minimize ½‖f(x)‖² from `x0` (book §3.3.2). Returns the best parameters found and a report;
/// it never returns parameters with a larger cost than `x0`.
pub fn levenberg_marquardt<P: LeastSquaresProblem + ?Sized>(
    problem: &P,
    x0: DVector<f64>,
    options: &LmOptions,
) -> (DVector<f64>, LmReport) {
    let n = x0.len();
    let mut x = x0;
    let mut r = problem.residuals(&x);
    let m = r.len();
    let mut c = cost(&r);
    let initial_cost = c;
    let jac = |x: &DVector<f64>| {
        problem
            .jacobian(x)
            .unwrap_or_else(|| numeric_jacobian(problem, x, m))
    };
    let mut report = LmReport {
        iterations: 0,
        initial_cost,
        final_cost: c,
        termination: LmTermination::MaxIterations,
    };
    if !c.is_finite() || n == 0 || m == 0 {
        report.termination = LmTermination::Stalled;
        return (x, report);
    }
    let mut j = jac(&x);
    let mut jtj = j.transpose() * &j;
    let mut g = j.transpose() * &r;
    let mut mu = options.initial_damping;
    let mut nu = 2.0;
    let mut iterations = 0;
    let termination = loop {
        if g.amax() <= options.gtol {
            break LmTermination::Gradient;
        }
        if iterations >= options.max_iterations {
            break LmTermination::MaxIterations;
        }
        iterations += 1;
        let mut a = jtj.clone();
        for k in 0..n {
            let d = jtj[(k, k)].max(1e-12 * jtj.diagonal().amax()).max(1e-300);
            a[(k, k)] += mu * d;
        }
        let h = match a.cholesky() {
            Some(ch) => ch.solve(&(-&g)),
            None => {
                mu *= nu;
                nu *= 2.0;
                if mu > 1e32 {
                    break LmTermination::Stalled;
                }
                continue;
            }
        };
        if h.norm() <= options.xtol * (x.norm() + options.xtol) {
            break LmTermination::Step;
        }
        let x_new = &x + &h;
        let r_new = problem.residuals(&x_new);
        let c_new = cost(&r_new);
        // Predicted decrease of the linear model: −hᵀg − ½hᵀJᵀJh.
        let predicted = -(h.dot(&g)) - 0.5 * h.dot(&(&jtj * &h));
        let rho = if predicted > 0.0 {
            (c - c_new) / predicted
        } else {
            -1.0
        };
        if c_new.is_finite() && rho > 0.0 {
            let decrease = c - c_new;
            x = x_new;
            r = r_new;
            c = c_new;
            j = jac(&x);
            jtj = j.transpose() * &j;
            g = j.transpose() * &r;
            mu *= (1.0 / 3.0f64).max(1.0 - (2.0 * rho - 1.0).powi(3));
            nu = 2.0;
            if decrease <= options.ftol * c.max(1e-300) {
                break LmTermination::Cost;
            }
        } else {
            mu *= nu;
            nu *= 2.0;
            if mu > 1e32 {
                break LmTermination::Stalled;
            }
        }
    };
    report.iterations = iterations;
    report.final_cost = c;
    report.termination = termination;
    (x, report)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rosenbrock as least squares: f = (10(y − x²), 1 − x).
    struct Rosenbrock {
        analytic: bool,
    }

    impl LeastSquaresProblem for Rosenbrock {
        fn residuals(&self, p: &DVector<f64>) -> DVector<f64> {
            DVector::from_vec(vec![10.0 * (p[1] - p[0] * p[0]), 1.0 - p[0]])
        }
        fn jacobian(&self, p: &DVector<f64>) -> Option<DMatrix<f64>> {
            self.analytic
                .then(|| DMatrix::from_row_slice(2, 2, &[-20.0 * p[0], 10.0, -1.0, 0.0]))
        }
    }

    #[test]
    fn rosenbrock_analytic_and_numeric() {
        for analytic in [true, false] {
            let (x, rep) = levenberg_marquardt(
                &Rosenbrock { analytic },
                DVector::from_vec(vec![-1.2, 1.0]),
                &LmOptions::default(),
            );
            assert!(
                (x[0] - 1.0).abs() < 1e-8 && (x[1] - 1.0).abs() < 1e-8,
                "{x:?} {rep:?}"
            );
            assert!(rep.final_cost < 1e-16);
        }
    }

    /// Exponential fit y = a exp(b t) with different parameter scales.
    struct ExpFit {
        t: Vec<f64>,
        y: Vec<f64>,
    }

    impl LeastSquaresProblem for ExpFit {
        fn residuals(&self, p: &DVector<f64>) -> DVector<f64> {
            DVector::from_iterator(
                self.t.len(),
                self.t
                    .iter()
                    .zip(&self.y)
                    .map(|(t, y)| p[0] * (p[1] * t).exp() - y),
            )
        }
    }

    #[test]
    fn exponential_fit_with_mixed_scales() {
        let t: Vec<f64> = (0..20).map(|i| i as f64 * 0.1).collect();
        let y = t.iter().map(|t| 1500.0 * (-0.7 * t).exp()).collect();
        let (x, _) = levenberg_marquardt(
            &ExpFit { t, y },
            DVector::from_vec(vec![1000.0, 0.0]),
            &LmOptions::default(),
        );
        assert!(
            (x[0] - 1500.0).abs() < 1e-6 && (x[1] + 0.7).abs() < 1e-9,
            "{x:?}"
        );
    }
}
