//! Refitting a radial lens to a polynomial, for the programs that have no model of it.
//!
//! COLMAP has no division model (Fitzgibbon 2001), and Blender 5.0's `DIVISION` tracking camera
//! is not Fitzgibbon's either (measured through its Movie Distortion node: see
//! `scripts/check/blender_check.py`). A division lens is radial, q = p · g(|p|), so its
//! distortion over the frame is refitted as Brown–Conrady's radial polynomial,
//! |q| / |p| ≈ 1 + k1 r² + k2 r⁴ + … (r = |p|, the undistorted normalized radius), by linear least
//! squares on radii from the centre out to the frame's farthest corner
//! ([`Intrinsics::undistorted_corner_radius`]). The fit's error is measured in pixels (the
//! larger focal length times the radial error, on a grid four times finer than the fit's) and
//! reported, so an export says how far its refitted lens is from ours.

use nalgebra::{DMatrix, DVector};

use vfxgraph_geometry::camera::Intrinsics;
use vfxgraph_geometry::error::{Result, VisionError};
use vfxgraph_lens::Distortion;

/// Radii the least-squares fit samples between the centre and the frame's corner.
const FIT_SAMPLES: usize = 256;

/// The largest fit error (px) an export accepts before it refuses the refit.
pub const MAX_FIT_ERROR_PX: f64 = 0.05;

/// A radial polynomial fitted to a lens.
#[derive(Clone, Debug, PartialEq)]
pub struct RadialFit {
    /// k1, k2, … of 1 + k1 r² + k2 r⁴ + … .
    pub k: Vec<f64>,
    /// The largest distance (px) between the polynomial's and the lens's image of a point
    /// inside the frame.
    pub max_error_px: f64,
    /// The undistorted normalized radius fitted out to (the frame's corner).
    pub r_max: f64,
}

/// Fits `terms` radial coefficients to the radial lens of `k` over its frame (module docs).
/// Needs the image size; a lens with tangential terms is refused (it is not radial).
pub fn radial_polynomial(k: &Intrinsics, terms: usize) -> Result<RadialFit> {
    let d = &k.distortion;
    if let Distortion::BrownConrady { p1, p2, .. } = d {
        if *p1 != 0.0 || *p2 != 0.0 {
            return Err(VisionError::InvalidInput(format!(
                "a lens with tangential terms (p1 = {p1}, p2 = {p2}) is not radial: no radial refit"
            )));
        }
    }
    let r_max = k
        .undistorted_corner_radius()?
        .ok_or_else(|| VisionError::InvalidInput("refitting a lens needs the image size".into()))?;
    if terms == 0 || !(r_max > 0.0) {
        return Err(VisionError::InvalidInput(format!(
            "a radial refit needs terms > 0 and a frame (got {terms} terms, radius {r_max})"
        )));
    }
    // |q|/|p| − 1 = Σ k_i r^{2i}, from r > 0 (the ratio at r = 0 is 1 for every model).
    let ratio = |r: f64| -> Result<f64> { Ok(d.distort([r, 0.0])?[0] / r) };
    let mut a = DMatrix::zeros(FIT_SAMPLES, terms);
    let mut b = DVector::zeros(FIT_SAMPLES);
    for s in 0..FIT_SAMPLES {
        let r = r_max * (s + 1) as f64 / FIT_SAMPLES as f64;
        let mut rp = 1.0;
        for t in 0..terms {
            rp *= r * r;
            // Weighted by r: the residual in normalized units is r · (ratio error).
            a[(s, t)] = r * rp;
        }
        b[s] = r * (ratio(r)? - 1.0);
    }
    let svd = a.svd(true, true);
    let coef = svd
        .solve(&b, 1e-14)
        .map_err(|e| VisionError::InvalidInput(format!("radial refit failed: {e}")))?;
    let k_fit: Vec<f64> = coef.iter().copied().collect();
    let f = k.f1.abs().max(k.f2.abs());
    let mut worst: f64 = 0.0;
    for s in 1..=4 * FIT_SAMPLES {
        let r = r_max * s as f64 / (4 * FIT_SAMPLES) as f64;
        let mut rho = 1.0;
        let mut rp = 1.0;
        for c in &k_fit {
            rp *= r * r;
            rho += c * rp;
        }
        worst = worst.max(f * (r * rho - r * ratio(r)?).abs());
    }
    Ok(RadialFit {
        k: k_fit,
        max_error_px: worst,
        r_max,
    })
}

/// The refit of [`radial_polynomial`], refused with a clear error when it is farther than
/// [`MAX_FIT_ERROR_PX`] from the lens (`target` names the program for the message).
pub fn radial_polynomial_within(k: &Intrinsics, terms: usize, target: &str) -> Result<RadialFit> {
    let fit = radial_polynomial(k, terms)?;
    if !(fit.max_error_px <= MAX_FIT_ERROR_PX) {
        return Err(VisionError::InvalidInput(format!(
            "{target} has no {} lens model and its best {terms}-term radial polynomial is off by \
             {:.3} px inside the frame (limit {MAX_FIT_ERROR_PX} px): export the undistorted \
             plate or an ST-map instead",
            k.distortion.name(),
            fit.max_error_px
        )));
    }
    Ok(fit)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Point2;

    /// A Brown–Conrady radial lens is refitted exactly (it is a polynomial); a division lens of
    /// a moderate wide angle fits three terms within a few hundredths of a pixel, and the
    /// reported error is the real one (checked on the plate's pixels along the diagonal).
    #[test]
    fn refit_is_exact_for_polynomials_and_measured_for_division() {
        let k = Intrinsics::new(900.0, 900.0, 639.5, 359.5).with_size(1280, 720);
        let brown = k.clone().with_distortion(Distortion::BrownConrady {
            k1: -0.16,
            k2: 0.045,
            k3: 0.0,
            p1: 0.0,
            p2: 0.0,
        });
        let fit = radial_polynomial(&brown, 3).unwrap();
        assert!((fit.k[0] + 0.16).abs() < 1e-12 && (fit.k[1] - 0.045).abs() < 1e-12);
        assert!(fit.k[2].abs() < 1e-11 && fit.max_error_px < 1e-9, "{fit:?}");

        let div = k.with_distortion(Distortion::Division { k1: 0.1, k2: 0.0 });
        let fit = radial_polynomial(&div, 3).unwrap();
        let refit = div.clone().with_distortion(Distortion::BrownConrady {
            k1: fit.k[0],
            k2: fit.k[1],
            k3: fit.k[2],
            p1: 0.0,
            p2: 0.0,
        });
        let mut worst: f64 = 0.0;
        for i in 0..=100 {
            let t = i as f64 / 100.0;
            // A pixel of the plate (distorted) out to the corner, and where the refit images
            // its undistorted position.
            let q = Point2::new(639.5 + t * 640.0, 359.5 + t * 360.0);
            let u = div.undistort_pixel(&q).unwrap();
            worst = worst.max((refit.distort_pixel(&u).unwrap() - q).norm());
        }
        assert!(
            worst <= fit.max_error_px * 1.01 + 1e-12,
            "{worst} vs {fit:?}"
        );
        assert!(
            fit.max_error_px > 1e-4 && fit.max_error_px < MAX_FIT_ERROR_PX,
            "{fit:?}"
        );
        let tangential = div.with_distortion(Distortion::BrownConrady {
            k1: 0.0,
            k2: 0.0,
            k3: 0.0,
            p1: 0.001,
            p2: 0.0,
        });
        assert!(radial_polynomial(&tangential, 3).is_err());
        let strong = Intrinsics::new(600.0, 600.0, 639.5, 359.5)
            .with_size(1280, 720)
            .with_distortion(Distortion::Division { k1: -0.15, k2: 0.0 });
        let e = radial_polynomial_within(&strong, 3, "COLMAP")
            .unwrap_err()
            .to_string();
        assert!(e.contains("COLMAP") && e.contains("ST-map"), "{e}");
    }
}
