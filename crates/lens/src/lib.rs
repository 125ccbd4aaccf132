//! Lens distortion: the models real cameras are solved and composited with (an addition to the
//! book, whose cameras are ideal pinholes, §2.7).
//!
//! A model maps *undistorted* normalized coordinates p = (X/Z, Y/Z) — where an ideal pinhole
//! would image the point — to the *distorted* normalized coordinates q the lens images it at;
//! pixels are then K·q. Models:
//! - [`Distortion::BrownConrady`]: OpenCV's (and Blender's BROWN, Nuke's) radial k1, k2, k3 and
//!   tangential p1, p2 on normalized coordinates (Brown 1966, "Decentering distortion of
//!   lenses"; Conrady 1919): with r² = |p|², ρ = 1 + k1 r² + k2 r⁴ + k3 r⁶,
//!   q = ρ p + (2 p1 x y + p2 (r² + 2x²), p1 (r² + 2y²) + 2 p2 x y). Forward in closed form;
//!   inverse by Newton's method on the 2×2 system.
//! - [`Distortion::Division`]: Fitzgibbon's division model (CVPR 2001, "Simultaneous linear
//!   estimation of multiple view geometry and lens distortion"): the
//!   *undistorted* point from the distorted one, p = q / (1 + k1 |q|² + k2 |q|⁴) — closed form in
//!   that direction, which is why wide-angle solvers like it; forward by Newton's method on the
//!   radius (the model is radial, so q = p · |q|/|p|). Blender's tracking camera calls a
//!   different model DIVISION (measured in bpy 5.0.1: a polynomial of the undistorted radius),
//!   so the Blender export writes a division lens as its polynomial refit (`export::lens_fit`).
//!
//! Jacobians (of q with respect to p and to the parameters) are analytic — for the division
//! model through the implicit function theorem — and tested against finite differences. A model
//! is only valid where its radial curve is monotonic: [`Distortion::check`] refuses parameters
//! that fold the image over inside a given radius, so an inverse that does not exist is an error,
//! not NaN cameras.
//!
//! A leaf crate (nalgebra and serde only) so that the camera crates (geometry, bundle adjustment, matchmove, exports; re-exported
//! as `vfxgraph_geometry::lens`) and the render crate (rays through the lens) share one type.

#![warn(missing_docs)]
// `!(x > 0.0)` is used on purpose: it is also true for NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use nalgebra::{Matrix2, Vector2};
use serde::{Deserialize, Serialize};

/// Why a lens cannot be used: bad parameters, or a point outside the region where the model
/// is invertible. The message names the model, its parameters and the point.
#[derive(Clone, Debug, PartialEq)]
pub struct LensError(pub String);

impl std::fmt::Display for LensError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for LensError {}

/// Result alias of this crate.
pub type Result<T> = std::result::Result<T, LensError>;

/// Newton steps of the inverses before they report non-convergence.
const MAX_NEWTON_STEPS: usize = 30;

/// Convergence of the inverses: the step, relative to 1 + |point| (normalized units: 1e-12 of
/// a 1000 px focal length is 1e-9 px).
const NEWTON_TOLERANCE: f64 = 1e-12;

/// A lens distortion model on normalized coordinates (module docs). JSON:
/// `{"model": "none"}`, `{"model": "brown_conrady", "k1": …, "k2": …, "k3": …, "p1": …, "p2": …}`,
/// `{"model": "division", "k1": …, "k2": …}` (absent coefficients are 0).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(tag = "model", rename_all = "snake_case")]
pub enum Distortion {
    /// The ideal pinhole: q = p.
    #[default]
    None,
    /// OpenCV's radial–tangential model (k1, k2, p1, p2, k3 in OpenCV's order of
    /// `distCoeffs`).
    BrownConrady {
        /// r² coefficient.
        #[serde(default)]
        k1: f64,
        /// r⁴ coefficient.
        #[serde(default)]
        k2: f64,
        /// r⁶ coefficient.
        #[serde(default)]
        k3: f64,
        /// First tangential coefficient.
        #[serde(default)]
        p1: f64,
        /// Second tangential coefficient.
        #[serde(default)]
        p2: f64,
    },
    /// Fitzgibbon's division model, p = q / (1 + k1 |q|² + k2 |q|⁴).
    Division {
        /// |q|² coefficient.
        #[serde(default)]
        k1: f64,
        /// |q|⁴ coefficient.
        #[serde(default)]
        k2: f64,
    },
}

impl Distortion {
    /// The model's parameters in a fixed order: Brown–Conrady (k1, k2, k3, p1, p2), division
    /// (k1, k2), none ().
    pub fn params(&self) -> Vec<f64> {
        match *self {
            Distortion::None => vec![],
            Distortion::BrownConrady { k1, k2, k3, p1, p2 } => vec![k1, k2, k3, p1, p2],
            Distortion::Division { k1, k2 } => vec![k1, k2],
        }
    }

    /// The same model with parameters `v` (in [`Distortion::params`] order and length).
    pub fn with_params(&self, v: &[f64]) -> Result<Distortion> {
        if v.len() != self.params().len() {
            return Err(LensError(format!(
                "a {} lens has {} parameters, {} given",
                self.name(),
                self.params().len(),
                v.len()
            )));
        }
        Ok(match self {
            Distortion::None => Distortion::None,
            Distortion::BrownConrady { .. } => Distortion::BrownConrady {
                k1: v[0],
                k2: v[1],
                k3: v[2],
                p1: v[3],
                p2: v[4],
            },
            Distortion::Division { .. } => Distortion::Division { k1: v[0], k2: v[1] },
        })
    }

    /// The model's name as in JSON.
    pub fn name(&self) -> &'static str {
        match self {
            Distortion::None => "none",
            Distortion::BrownConrady { .. } => "brown_conrady",
            Distortion::Division { .. } => "division",
        }
    }

    /// Whether this is the ideal pinhole (every parameter zero counts as one).
    pub fn is_identity(&self) -> bool {
        self.params().iter().all(|&v| v == 0.0)
    }

    /// Distorted normalized coordinates of the undistorted `p` (module docs). For the division
    /// model this is the Newton inverse of its closed form; it fails where it does not converge
    /// (outside the radius the model is monotonic in: see [`Distortion::check`]).
    pub fn distort(&self, p: [f64; 2]) -> Result<[f64; 2]> {
        match *self {
            Distortion::None => Ok(p),
            Distortion::BrownConrady { .. } => Ok(self.brown(p).0),
            Distortion::Division { k1, k2 } => {
                let rp = p[0].hypot(p[1]);
                if rp == 0.0 {
                    return Ok(p);
                }
                let rq = division_radius(k1, k2, rp)?;
                Ok([p[0] * rq / rp, p[1] * rq / rp])
            }
        }
    }

    /// Undistorted normalized coordinates of the distorted `q`: closed form for the division
    /// model, Newton's method for Brown–Conrady (an error when it does not converge).
    pub fn undistort(&self, q: [f64; 2]) -> Result<[f64; 2]> {
        match *self {
            Distortion::None => Ok(q),
            Distortion::Division { k1, k2 } => {
                let r2 = q[0] * q[0] + q[1] * q[1];
                let s = 1.0 + k1 * r2 + k2 * r2 * r2;
                if !(s > 0.0) {
                    return Err(not_invertible(self, q));
                }
                Ok([q[0] / s, q[1] / s])
            }
            Distortion::BrownConrady { .. } => {
                let mut p = Vector2::new(q[0], q[1]);
                let target = Vector2::new(q[0], q[1]);
                for _ in 0..MAX_NEWTON_STEPS {
                    let (d, j) = self.brown([p.x, p.y]);
                    let f = Vector2::new(d[0], d[1]) - target;
                    let step = j.try_inverse().ok_or_else(|| not_invertible(self, q))? * f;
                    p -= step;
                    if !(p.x.is_finite() && p.y.is_finite()) {
                        break;
                    }
                    if step.norm() <= NEWTON_TOLERANCE * (1.0 + p.norm()) {
                        return Ok([p.x, p.y]);
                    }
                }
                Err(not_invertible(self, q))
            }
        }
    }

    /// ∂q/∂p, the Jacobian of [`Distortion::distort`] at the undistorted `p`.
    pub fn jacobian_point(&self, p: [f64; 2]) -> Result<Matrix2<f64>> {
        match *self {
            Distortion::None => Ok(Matrix2::identity()),
            Distortion::BrownConrady { .. } => Ok(self.brown(p).1),
            Distortion::Division { k1, k2 } => {
                let q = self.distort(p)?;
                division_dq(k1, k2, q).map(|(dq_dp, _)| dq_dp)
            }
        }
    }

    /// ∂q/∂θ, the Jacobian of [`Distortion::distort`] at the undistorted `p` with respect to
    /// the parameters θ (2 × [`Distortion::params`]`.len()`, in that order).
    pub fn jacobian_params(&self, p: [f64; 2]) -> Result<nalgebra::DMatrix<f64>> {
        let [x, y] = p;
        let r2 = x * x + y * y;
        match *self {
            Distortion::None => Ok(nalgebra::DMatrix::zeros(2, 0)),
            Distortion::BrownConrady { .. } => Ok(nalgebra::DMatrix::from_row_slice(
                2,
                5,
                &[
                    x * r2,
                    x * r2 * r2,
                    x * r2 * r2 * r2,
                    2.0 * x * y,
                    r2 + 2.0 * x * x,
                    y * r2,
                    y * r2 * r2,
                    y * r2 * r2 * r2,
                    r2 + 2.0 * y * y,
                    2.0 * x * y,
                ],
            )),
            Distortion::Division { k1, k2 } => {
                let q = self.distort(p)?;
                let (_, dq_dk) = division_dq(k1, k2, q)?;
                Ok(nalgebra::DMatrix::from_column_slice(2, 2, dq_dk.as_slice()))
            }
        }
    }

    /// The largest undistorted normalized radius of a `width`×`height` frame's outer corners
    /// (pixel edges, where a pixel's footprint reaches), a little beyond (×1.02): how far out the
    /// lens must be invertible and monotonic ([`Distortion::check`]) for every pixel.
    /// `normalize` maps a pixel to its distorted normalized point (K⁻¹x). An error names the
    /// corner the lens cannot undistort.
    pub fn frame_radius(
        &self,
        width: f64,
        height: f64,
        normalize: impl Fn([f64; 2]) -> [f64; 2],
    ) -> Result<f64> {
        let (w, h) = (width, height);
        let mut r: f64 = 0.0;
        for (x, y) in [
            (-0.5, -0.5),
            (w - 0.5, -0.5),
            (-0.5, h - 0.5),
            (w - 0.5, h - 0.5),
        ] {
            let p = self.undistort(normalize([x, y])).map_err(|e| {
                LensError(format!(
                    "the {} lens cannot be inverted at the frame's corner ({x}, {y}): {e}",
                    self.name()
                ))
            })?;
            r = r.max(p[0].hypot(p[1]));
        }
        Ok(r * 1.02)
    }

    /// Checks the model is usable out to the undistorted normalized radius `r_max` (the image's
    /// corners, say): finite parameters and a radial curve that keeps increasing there, so
    /// distinct points stay distinct and the inverse exists. The radial part is checked on a fine
    /// grid of radii; Brown–Conrady's tangential terms are small by construction and are checked
    /// only through the Jacobian's determinant along the image's diagonals.
    pub fn check(&self, r_max: f64) -> Result<()> {
        let params = self.params();
        if params.iter().any(|v| !v.is_finite()) || !(r_max.is_finite() && r_max >= 0.0) {
            return Err(LensError(format!(
                "{} lens: parameters {params:?} and radius {r_max} must be finite",
                self.name()
            )));
        }
        const STEPS: usize = 512;
        for i in 1..=STEPS {
            let r = r_max * i as f64 / STEPS as f64;
            let ok = match *self {
                Distortion::None => true,
                Distortion::BrownConrady { k1, k2, k3, .. } => {
                    let r2 = r * r;
                    let slope = 1.0 + 3.0 * k1 * r2 + 5.0 * k2 * r2 * r2 + 7.0 * k3 * r2 * r2 * r2;
                    let diag = std::f64::consts::FRAC_1_SQRT_2 * r;
                    slope > 0.0
                        && [[diag, diag], [diag, -diag], [-diag, diag], [-diag, -diag]]
                            .iter()
                            .all(|&p| self.brown(p).1.determinant() > 0.0)
                }
                Distortion::Division { k1, k2 } => division_radius(k1, k2, r).is_ok(),
            };
            if !ok {
                return Err(LensError(format!(
                    "{} lens {params:?} folds over at normalized radius {r:.3} (inside the \
                     frame's {r_max:.3}): the radial curve stops increasing, so the image cannot \
                     be undistorted",
                    self.name()
                )));
            }
        }
        Ok(())
    }

    /// Brown–Conrady's forward map and its Jacobian ∂q/∂p (zero parameters for other models).
    fn brown(&self, p: [f64; 2]) -> ([f64; 2], Matrix2<f64>) {
        let Distortion::BrownConrady { k1, k2, k3, p1, p2 } = *self else {
            return (p, Matrix2::identity());
        };
        let [x, y] = p;
        let r2 = x * x + y * y;
        let rho = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
        // dρ/d(r²).
        let drho = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2);
        let q = [
            x * rho + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
            y * rho + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y,
        ];
        let j = Matrix2::new(
            rho + 2.0 * x * x * drho + 2.0 * p1 * y + 6.0 * p2 * x,
            2.0 * x * y * drho + 2.0 * p1 * x + 2.0 * p2 * y,
            2.0 * x * y * drho + 2.0 * p1 * x + 2.0 * p2 * y,
            rho + 2.0 * y * y * drho + 6.0 * p1 * y + 2.0 * p2 * x,
        );
        (q, j)
    }
}

fn not_invertible(d: &Distortion, q: [f64; 2]) -> LensError {
    LensError(format!(
        "{} lens {:?}: no undistorted point for ({:.4}, {:.4}) — outside the radius where the \
         model is monotonic",
        d.name(),
        d.params(),
        q[0],
        q[1]
    ))
}

/// The distorted radius rq of the division model with rq / (1 + k1 rq² + k2 rq⁴) = rp, by
/// Newton's method from rq = rp, on the branch through the origin (where the curve increases).
fn division_radius(k1: f64, k2: f64, rp: f64) -> Result<f64> {
    let mut r = rp;
    for _ in 0..MAX_NEWTON_STEPS {
        let r2 = r * r;
        let s = 1.0 + k1 * r2 + k2 * r2 * r2;
        let slope = (1.0 - k1 * r2 - 3.0 * k2 * r2 * r2) / (s * s);
        if !(s > 0.0 && slope > 0.0) {
            break;
        }
        let step = (r / s - rp) / slope;
        r -= step;
        if !(r.is_finite() && r >= 0.0) {
            break;
        }
        if step.abs() <= NEWTON_TOLERANCE * (1.0 + r) {
            let r2 = r * r;
            let s = 1.0 + k1 * r2 + k2 * r2 * r2;
            if s > 0.0 && 1.0 - k1 * r2 - 3.0 * k2 * r2 * r2 > 0.0 {
                return Ok(r);
            }
            break;
        }
    }
    Err(LensError(format!(
        "division lens [{k1}, {k2}]: no distorted radius images the undistorted radius {rp:.4} \
         (the model folds over before it)"
    )))
}

/// The division model's Jacobians at the distorted point q, through the implicit function
/// theorem on u(q) = q / s(q) − p = 0: ∂q/∂p = (∂u/∂q)⁻¹ and ∂q/∂k = −(∂u/∂q)⁻¹ ∂u/∂k.
fn division_dq(k1: f64, k2: f64, q: [f64; 2]) -> Result<(Matrix2<f64>, Matrix2<f64>)> {
    let qv = Vector2::new(q[0], q[1]);
    let r2 = qv.norm_squared();
    let s = 1.0 + k1 * r2 + k2 * r2 * r2;
    let ds_dq = qv * (2.0 * k1 + 4.0 * k2 * r2);
    let du_dq = Matrix2::identity() / s - qv * ds_dq.transpose() / (s * s);
    let inv = du_dq.try_inverse().ok_or_else(|| {
        LensError(format!(
            "division lens [{k1}, {k2}] is singular at ({:.4}, {:.4})",
            q[0], q[1]
        ))
    })?;
    let du_dk = Matrix2::from_columns(&[-qv * r2 / (s * s), -qv * r2 * r2 / (s * s)]);
    Ok((inv, -inv * du_dk))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The lens of `blender_plate_dev/distorted` (its README), and a wide-angle division lens.
    fn lenses() -> [Distortion; 3] {
        [
            Distortion::BrownConrady {
                k1: -0.16,
                k2: 0.045,
                k3: 0.0,
                p1: 0.0008,
                p2: -0.0005,
            },
            Distortion::BrownConrady {
                k1: 0.08,
                k2: -0.02,
                k3: 0.004,
                p1: -0.001,
                p2: 0.002,
            },
            Distortion::Division {
                k1: -0.25,
                k2: 0.02,
            },
        ]
    }

    /// Points over a 960×540 frame with f = 920 (normalized radius up to 0.6), corners included.
    fn grid() -> Vec<[f64; 2]> {
        let mut v = Vec::new();
        for i in 0..=16 {
            for j in 0..=9 {
                v.push([
                    (i as f64 * 60.0 - 479.5) / 920.0,
                    (j as f64 * 60.0 - 269.5) / 920.0,
                ]);
            }
        }
        v
    }

    #[test]
    fn undistort_inverts_distort_over_the_frame() {
        for d in lenses() {
            d.check(0.6).unwrap();
            let mut worst = 0.0f64;
            for p in grid() {
                let q = d.distort(p).unwrap();
                let back = d.undistort(q).unwrap();
                worst = worst.max((back[0] - p[0]).hypot(back[1] - p[1]) * 920.0);
            }
            // In pixels of a 920 px focal length.
            assert!(worst < 1e-8, "{d:?}: round trip off by {worst} px");
        }
    }

    #[test]
    fn jacobians_match_finite_differences() {
        let h = 1e-7;
        for d in lenses() {
            for p in grid() {
                let j = d.jacobian_point(p).unwrap();
                for c in 0..2 {
                    let mut a = p;
                    let mut b = p;
                    a[c] += h;
                    b[c] -= h;
                    let (qa, qb) = (d.distort(a).unwrap(), d.distort(b).unwrap());
                    for r in 0..2 {
                        let fd = (qa[r] - qb[r]) / (2.0 * h);
                        assert!((fd - j[(r, c)]).abs() < 1e-6, "{d:?} ∂q{r}/∂p{c} at {p:?}");
                    }
                }
                let jp = d.jacobian_params(p).unwrap();
                let theta = d.params();
                assert_eq!(jp.shape(), (2, theta.len()));
                for c in 0..theta.len() {
                    let (mut ta, mut tb) = (theta.clone(), theta.clone());
                    ta[c] += h;
                    tb[c] -= h;
                    let qa = d.with_params(&ta).unwrap().distort(p).unwrap();
                    let qb = d.with_params(&tb).unwrap().distort(p).unwrap();
                    for r in 0..2 {
                        let fd = (qa[r] - qb[r]) / (2.0 * h);
                        assert!((fd - jp[(r, c)]).abs() < 1e-6, "{d:?} ∂q{r}/∂θ{c} at {p:?}");
                    }
                }
            }
        }
    }

    /// OpenCV's `projectPoints` formula evaluated by hand for one point: the model's convention
    /// is OpenCV's (coefficients on normalized coordinates, tangential terms as in its docs).
    #[test]
    fn brown_conrady_is_opencvs_formula() {
        let d = lenses()[0];
        let (x, y) = (0.3, -0.2);
        let r2: f64 = x * x + y * y;
        let rho = 1.0 - 0.16 * r2 + 0.045 * r2 * r2;
        let want = [
            x * rho + 2.0 * 0.0008 * x * y - 0.0005 * (r2 + 2.0 * x * x),
            y * rho + 0.0008 * (r2 + 2.0 * y * y) - 2.0 * 0.0005 * x * y,
        ];
        assert_eq!(d.distort([x, y]).unwrap(), want);
    }

    #[test]
    fn division_is_closed_form_from_the_distorted_side() {
        let d = Distortion::Division {
            k1: -0.25,
            k2: 0.02,
        };
        let q = [0.4, 0.3];
        let r2: f64 = 0.25;
        let s = 1.0 - 0.25 * r2 + 0.02 * r2 * r2;
        assert_eq!(d.undistort(q).unwrap(), [0.4 / s, 0.3 / s]);
    }

    #[test]
    fn a_lens_that_folds_over_inside_the_frame_is_an_error() {
        // ρ r = r − 0.9 r³ stops increasing at r = 1/√2.7 ≈ 0.61.
        let fold = Distortion::BrownConrady {
            k1: -0.9,
            k2: 0.0,
            k3: 0.0,
            p1: 0.0,
            p2: 0.0,
        };
        assert!(fold.check(0.5).is_ok());
        let e = fold.check(0.8).unwrap_err().to_string();
        assert!(e.contains("folds over"), "{e}");
        // The division model's undistorted radius q/(1 + 4q²) peaks at 1/4 (at q = 1/2).
        let div = Distortion::Division { k1: 4.0, k2: 0.0 };
        assert!(div.check(0.2).is_ok());
        assert!(div.check(0.3).is_err());
        assert!(div.distort([0.3, 0.0]).is_err());
        let nan = Distortion::Division {
            k1: f64::NAN,
            k2: 0.0,
        };
        assert!(nan.check(0.5).is_err());
    }

    #[test]
    fn json_names_the_model() {
        let d: Distortion =
            serde_json::from_str(r#"{"model": "brown_conrady", "k1": -0.16, "p2": 0.001}"#)
                .unwrap();
        assert_eq!(
            d,
            Distortion::BrownConrady {
                k1: -0.16,
                k2: 0.0,
                k3: 0.0,
                p1: 0.0,
                p2: 0.001
            }
        );
        let back: Distortion = serde_json::from_str(&serde_json::to_string(&d).unwrap()).unwrap();
        assert_eq!(back, d);
        assert!(serde_json::from_str::<Distortion>(r#"{"model": "fisheye"}"#).is_err());
        assert!(Distortion::None.is_identity());
    }
}
