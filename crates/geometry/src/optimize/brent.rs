//! Brent's minimization on an interval (book §3.1: the improved golden section that GSL uses and
//! chapter 7 calls for the scale between fragments). Golden-section steps safeguard successive
//! parabolic interpolation (R. P. Brent, *Algorithms for Minimization without Derivatives*, 1973).

use super::Minimum1d;
use crate::error::{Result, VisionError};

/// Minimize `f` on `[a, b]` to a relative tolerance `tol` (absolute floor 1e-12) with at most
/// `max_iter` iterations. The start point is the golden-section point of the interval.
pub fn brent_minimize<F>(mut f: F, a: f64, b: f64, tol: f64, max_iter: usize) -> Result<Minimum1d>
where
    F: FnMut(f64) -> f64,
{
    if !(a.is_finite() && b.is_finite() && a < b) {
        return Err(VisionError::InvalidInput(format!(
            "need a finite interval a < b, got [{a}, {b}]"
        )));
    }
    const CGOLD: f64 = 0.381_966_011_250_105_1;
    const ZEPS: f64 = 1e-12;
    let (mut a, mut b) = (a, b);
    let mut x = a + CGOLD * (b - a);
    let (mut w, mut v) = (x, x);
    let mut fx = f(x);
    let (mut fw, mut fv) = (fx, fx);
    let mut evaluations = 1;
    let mut d: f64 = 0.0;
    let mut e: f64 = 0.0;
    let mut iterations = 0;
    while iterations < max_iter {
        iterations += 1;
        let xm = 0.5 * (a + b);
        let tol1 = tol * x.abs() + ZEPS;
        let tol2 = 2.0 * tol1;
        if (x - xm).abs() <= tol2 - 0.5 * (b - a) {
            break;
        }
        let mut golden = true;
        if e.abs() > tol1 {
            // Parabola through x, w, v.
            let r = (x - w) * (fx - fv);
            let mut q = (x - v) * (fx - fw);
            let mut p = (x - v) * q - (x - w) * r;
            q = 2.0 * (q - r);
            if q > 0.0 {
                p = -p;
            }
            q = q.abs();
            let etemp = e;
            e = d;
            if p.abs() < (0.5 * q * etemp).abs() && p > q * (a - x) && p < q * (b - x) {
                d = p / q;
                let u = x + d;
                if u - a < tol2 || b - u < tol2 {
                    d = tol1.copysign(xm - x);
                }
                golden = false;
            }
        }
        if golden {
            e = if x >= xm { a - x } else { b - x };
            d = CGOLD * e;
        }
        let u = if d.abs() >= tol1 {
            x + d
        } else {
            x + tol1.copysign(d)
        };
        let fu = f(u);
        evaluations += 1;
        if fu <= fx {
            if u >= x {
                a = x;
            } else {
                b = x;
            }
            v = w;
            fv = fw;
            w = x;
            fw = fx;
            x = u;
            fx = fu;
        } else {
            if u < x {
                a = u;
            } else {
                b = u;
            }
            if fu <= fw || w == x {
                v = w;
                fv = fw;
                w = u;
                fw = fu;
            } else if fu <= fv || v == x || v == w {
                v = u;
                fv = fu;
            }
        }
    }
    Ok(Minimum1d {
        x,
        fx,
        iterations,
        evaluations,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::optimize::golden_section_minimize;

    #[test]
    fn finds_minimum_faster_than_golden_section() {
        let f = |x: f64| (x - 0.7).powi(2) * (1.0 + x * x) + (x - 0.7).powi(4);
        let b = brent_minimize(f, -3.0, 5.0, 1e-10, 200).unwrap();
        let g = golden_section_minimize(f, -3.0, 5.0, 1e-9, 200).unwrap();
        assert!((b.x - 0.7).abs() < 1e-7, "{b:?}");
        assert!((g.x - 0.7).abs() < 1e-7);
        assert!(
            b.evaluations < g.evaluations,
            "{} vs {}",
            b.evaluations,
            g.evaluations
        );
    }

    #[test]
    fn non_smooth_function() {
        let b = brent_minimize(|x| (x - 2.0).abs(), 0.0, 10.0, 1e-10, 500).unwrap();
        assert!((b.x - 2.0).abs() < 1e-7);
    }
}
