//! Golden-section minimization of a unimodal function on an interval (book §3.1).

use super::Minimum1d;
use crate::error::{Result, VisionError};

/// Minimize a unimodal `f` on `[a, b]` by the golden-section search of book §3.1: interior
/// points u = a + α(b − a), v = a + β(b − a) with α = (3 − √5)/2, β = (√5 − 1)/2; one of them is
/// reused at each step (Theorem 3.1). Stops when the interval is shorter than `tol` or after
/// `max_iter` steps and returns (u + v)/2.
pub fn golden_section_minimize<F>(
    mut f: F,
    a: f64,
    b: f64,
    tol: f64,
    max_iter: usize,
) -> Result<Minimum1d>
where
    F: FnMut(f64) -> f64,
{
    if !(a.is_finite() && b.is_finite() && a < b) {
        return Err(VisionError::InvalidInput(format!(
            "need a finite interval a < b, got [{a}, {b}]"
        )));
    }
    let alpha = (3.0 - 5f64.sqrt()) / 2.0;
    let beta = (5f64.sqrt() - 1.0) / 2.0;
    let (mut a, mut b) = (a, b);
    let mut u = a + alpha * (b - a);
    let mut v = a + beta * (b - a);
    let mut fu = f(u);
    let mut fv = f(v);
    let mut evaluations = 2;
    let mut iterations = 0;
    while b - a > tol && iterations < max_iter {
        iterations += 1;
        if fu < fv {
            // [v, b] holds no minimum.
            b = v;
            v = u;
            fv = fu;
            u = a + alpha * (b - a);
            fu = f(u);
        } else {
            // [a, u] holds no minimum.
            a = u;
            u = v;
            fu = fv;
            v = a + beta * (b - a);
            fv = f(v);
        }
        evaluations += 1;
    }
    let x = 0.5 * (u + v);
    let fx = f(x);
    Ok(Minimum1d {
        x,
        fx,
        iterations,
        evaluations: evaluations + 1,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_parabola_minimum() {
        let m =
            golden_section_minimize(|x| (x - 1.234).powi(2) + 3.0, -10.0, 10.0, 1e-9, 200).unwrap();
        assert!((m.x - 1.234).abs() < 1e-6);
        assert!((m.fx - 3.0).abs() < 1e-12);
    }

    #[test]
    fn rejects_bad_interval() {
        assert!(golden_section_minimize(|x| x, 1.0, 0.0, 1e-6, 10).is_err());
        assert!(golden_section_minimize(|x| x, f64::NAN, 0.0, 1e-6, 10).is_err());
    }
}
