//! The bundle adjustment problem as data (Ceres' design; Triggs et al. 2000, section 2).
//!
//! Parameter blocks are camera poses (axis–angle rotation ω and translation t, so a point X maps to
//! `R(ω)X + t`), intrinsics blocks (shared by several cameras or one per camera) and 3D points.
//! Observations reference them by index. Every block has a `fixed` flag; the [`Gauge`] says how
//! the 7-dof similarity ambiguity is removed.

use nalgebra::{Vector2, Vector3};
use serde::{Deserialize, Serialize};

use super::camera_model::{CameraModel, Intrinsics};
use super::error::BundleError;

/// A camera pose block: X ↦ R(rotation)·X + translation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraPose {
    /// Axis–angle ω (book 4.5.2).
    pub rotation: Vector3<f64>,
    /// t.
    pub translation: Vector3<f64>,
    /// Index of this camera's intrinsics block in [`Problem::intrinsics`].
    pub intrinsics: usize,
    /// Held constant during the solve.
    pub fixed: bool,
}

impl CameraPose {
    /// A pose from a rotation matrix and translation (X ↦ R·X + t), with intrinsics block
    /// `intrinsics`, free.
    pub fn from_rt(r: &nalgebra::Matrix3<f64>, t: &Vector3<f64>, intrinsics: usize) -> Self {
        CameraPose {
            rotation: super::rotation::matrix_to_angle_axis(r),
            translation: *t,
            intrinsics,
            fixed: false,
        }
    }

    /// The rotation matrix R(ω) (book 4.5.2).
    pub fn rotation_matrix(&self) -> nalgebra::Matrix3<f64> {
        super::rotation::angle_axis_to_matrix(&self.rotation)
    }

    /// The camera centre c = −Rᵀt.
    pub fn centre(&self) -> Vector3<f64> {
        camera_centre(self)
    }
}

/// A 3D point block.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Point {
    /// World coordinates.
    pub position: Vector3<f64>,
    /// Held constant during the solve.
    pub fixed: bool,
}

/// One measured projection of a point in a camera (pixel coordinates in the camera model's frame).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Observation {
    /// Index into [`Problem::cameras`].
    pub camera: usize,
    /// Index into [`Problem::points`].
    pub point: usize,
    /// The measured pixel.
    pub pixel: Vector2<f64>,
    /// The residual's weight: `predicted − pixel` is multiplied by it (with its Jacobians),
    /// so an observation of noise σ weighted σ_ref/σ counts as one of noise σ_ref — weighted
    /// least squares for tracks of unequal accuracy (Triggs et al. 2000, section 3.2).
    /// 1 is plain least squares in pixels; it must be positive and finite.
    pub weight: f64,
}

/// One term `coefficient · x` of a [`Prior`], x being parameter `param` of intrinsics block
/// `intrinsics`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PriorTerm {
    /// Index into [`Problem::intrinsics`].
    pub intrinsics: usize,
    /// Index into that block's [`Intrinsics::params`].
    pub param: usize,
    /// The term's coefficient.
    pub coefficient: f64,
}

/// A linear prior on intrinsics parameters: the residual `Σ cᵢ·xᵢ − target`, added to the cost
/// as `½·r²` beside the observations' (not robustified). Its coefficients carry its weight, in
/// the observations' units: a residual of 1 costs what an observation 1 px off does. A zooming
/// lens's smoothness is such a prior, `(f₍ᵢ₋₁₎ − 2fᵢ + f₍ᵢ₊₁₎)/σ` between the focal lengths of
/// neighbouring frames (Triggs et al. 2000, section 3.4: priors as extra residuals). Terms on
/// held parameters or fixed blocks add to the residual, not to the solve.
#[derive(Debug, Clone, PartialEq)]
pub struct Prior {
    /// The terms.
    pub terms: Vec<PriorTerm>,
    /// The value the combination should have.
    pub target: f64,
}

/// The smoothness prior of a zoom over `n` frames' intrinsics blocks (block i = frame i):
/// `(fᵢ₋₁ − 2fᵢ + fᵢ₊₁)/σ` for every interior frame (the matchmove's zooming lens).
pub fn zoom_priors(n: usize, sigma: f64) -> Vec<Prior> {
    (1..n.saturating_sub(1))
        .map(|i| Prior {
            terms: [(i - 1, 1.0), (i, -2.0), (i + 1, 1.0)]
                .map(|(b, c)| PriorTerm {
                    intrinsics: b,
                    param: 0,
                    coefficient: c / sigma,
                })
                .to_vec(),
            target: 0.0,
        })
        .collect()
}

impl Prior {
    /// The residual at the problem's current parameters.
    pub fn residual(&self, intrinsics: &[Intrinsics]) -> f64 {
        self.terms
            .iter()
            .map(|t| t.coefficient * intrinsics[t.intrinsics].params[t.param])
            .sum::<f64>()
            - self.target
    }
}

/// How the similarity gauge (3 rotation, 3 translation, 1 scale) is fixed
/// (Triggs et al. 2000, section 9; Hartley & Zisserman 18.1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum Gauge {
    /// Nothing beyond the blocks' own `fixed` flags; LM's damping handles the null space.
    /// This is what Ceres' `bundle_adjuster` does on BAL files.
    #[default]
    Free,
    /// Hold the first camera's pose constant and, for scale, the component of the second
    /// camera's translation in which the baseline `R₁(c₀ − c₁)` is largest (the other two
    /// components and its rotation stay free). Under a similarity that keeps camera 0, that
    /// component scales with the scene, so holding it removes exactly the scale freedom.
    FixFirstCameraAndScale,
    /// A camera that only rotates (a nodal pan, the matchmove's tripod solve): every camera
    /// centre held at the origin (all translations held, so t = 0) and the first camera's
    /// rotation held. The points are then directions: a point moved along its ray projects
    /// the same in every camera, a null direction of its own block that LM's damping handles.
    RotationOnly,
}

/// A bundle adjustment problem: blocks and the observations that tie them.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Problem {
    /// Camera pose blocks.
    pub cameras: Vec<CameraPose>,
    /// Intrinsics blocks (one per camera, or shared).
    pub intrinsics: Vec<Intrinsics>,
    /// Point blocks.
    pub points: Vec<Point>,
    /// Observations.
    pub observations: Vec<Observation>,
    /// Gauge fixing.
    pub gauge: Gauge,
    /// Linear priors on intrinsics parameters (a zoom's smoothness); usually none.
    pub priors: Vec<Prior>,
}

fn finite3(v: &Vector3<f64>) -> bool {
    v.iter().all(|x| x.is_finite())
}

impl Problem {
    /// Checks indices and finiteness; every solve calls it first. NaN or infinity anywhere gives
    /// [`BundleError::NonFinite`], a dangling index [`BundleError::IndexOutOfRange`].
    pub fn validate(&self) -> Result<(), BundleError> {
        for (i, k) in self.intrinsics.iter().enumerate() {
            let consts_ok = match k.model {
                CameraModel::Pinhole { aspect, skew } => aspect.is_finite() && skew.is_finite(),
                CameraModel::Bal => true,
                CameraModel::Radial { aspect, skew, lens } => {
                    [aspect, skew].iter().all(|v| v.is_finite())
                        && lens.params().iter().all(|v| v.is_finite())
                }
            };
            if !consts_ok || k.params.iter().any(|p| !p.is_finite()) {
                return Err(BundleError::NonFinite {
                    what: format!("intrinsics {i}"),
                });
            }
        }
        for (i, c) in self.cameras.iter().enumerate() {
            if !finite3(&c.rotation) || !finite3(&c.translation) {
                return Err(BundleError::NonFinite {
                    what: format!("camera {i} pose"),
                });
            }
            if c.intrinsics >= self.intrinsics.len() {
                return Err(BundleError::IndexOutOfRange {
                    what: format!(
                        "camera {i} uses intrinsics {} of {}",
                        c.intrinsics,
                        self.intrinsics.len()
                    ),
                });
            }
        }
        for (i, p) in self.points.iter().enumerate() {
            if !finite3(&p.position) {
                return Err(BundleError::NonFinite {
                    what: format!("point {i}"),
                });
            }
        }
        for (i, o) in self.observations.iter().enumerate() {
            if o.camera >= self.cameras.len() || o.point >= self.points.len() {
                return Err(BundleError::IndexOutOfRange {
                    what: format!("observation {i} (camera {}, point {})", o.camera, o.point),
                });
            }
            let weight_ok = o.weight > 0.0 && o.weight.is_finite();
            if !(o.pixel.iter().all(|x| x.is_finite()) && weight_ok) {
                return Err(BundleError::NonFinite {
                    what: format!("observation {i} pixel"),
                });
            }
        }
        for (i, p) in self.priors.iter().enumerate() {
            for t in &p.terms {
                let Some(k) = self.intrinsics.get(t.intrinsics) else {
                    return Err(BundleError::IndexOutOfRange {
                        what: format!(
                            "prior {i} uses intrinsics {} of {}",
                            t.intrinsics,
                            self.intrinsics.len()
                        ),
                    });
                };
                if t.param >= k.num_params() {
                    return Err(BundleError::IndexOutOfRange {
                        what: format!(
                            "prior {i} uses parameter {} of intrinsics {} ({} parameters)",
                            t.param,
                            t.intrinsics,
                            k.num_params()
                        ),
                    });
                }
            }
            let finite = p.target.is_finite() && p.terms.iter().all(|t| t.coefficient.is_finite());
            if !finite {
                return Err(BundleError::NonFinite {
                    what: format!("prior {i}"),
                });
            }
        }
        if self.observations.is_empty() {
            return Err(BundleError::InvalidProblem("no observations".into()));
        }
        Ok(())
    }

    /// Number of free scalar parameters after the `fixed` flags and the gauge.
    pub fn num_free_parameters(&self) -> usize {
        let masks = self.pose_masks();
        let poses: usize = self
            .cameras
            .iter()
            .zip(&masks)
            .filter(|(c, _)| !c.fixed)
            .map(|(_, m)| m.iter().filter(|f| !**f).count())
            .sum();
        let intr: usize = self.intrinsics.iter().map(Intrinsics::num_free).sum();
        let pts = self.points.iter().filter(|p| !p.fixed).count() * 3;
        poses + intr + pts
    }

    /// Per-camera masks of pose components held constant by the gauge (`true` = held),
    /// in the order `[ω₀, ω₁, ω₂, t₀, t₁, t₂]`.
    pub fn pose_masks(&self) -> Vec<[bool; 6]> {
        let mut masks = vec![[false; 6]; self.cameras.len()];
        if self.gauge == Gauge::RotationOnly {
            for (i, m) in masks.iter_mut().enumerate() {
                *m = [i == 0, i == 0, i == 0, true, true, true];
            }
            return masks;
        }
        if let (Gauge::FixFirstCameraAndScale, true) = (self.gauge, self.cameras.len() >= 2) {
            masks[0] = [true; 6];
            let c0 = camera_centre(&self.cameras[0]);
            let c1 = camera_centre(&self.cameras[1]);
            let r1 = super::rotation::angle_axis_to_matrix(&self.cameras[1].rotation);
            let b = r1 * (c0 - c1);
            let k = b.iamax();
            masks[1][3 + k] = true;
        } else if let Gauge::FixFirstCameraAndScale = self.gauge {
            if let Some(m) = masks.first_mut() {
                *m = [true; 6];
            }
        }
        masks
    }

    /// Predicted pixel of observation `i` at the current parameters.
    pub fn predict(&self, i: usize) -> Vector2<f64> {
        let o = &self.observations[i];
        let c = &self.cameras[o.camera];
        let k = &self.intrinsics[c.intrinsics];
        super::residual::project(
            k,
            &c.rotation,
            &c.translation,
            &self.points[o.point].position,
        )
    }

    /// ½·Σ‖w·(predicted − observed)‖² + ½·Σ r²(priors) without a robust loss (Ceres' cost
    /// with a trivial loss).
    pub fn cost(&self) -> f64 {
        0.5 * (0..self.observations.len())
            .map(|i| {
                let o = &self.observations[i];
                ((self.predict(i) - o.pixel) * o.weight).norm_squared()
            })
            .sum::<f64>()
            + self.prior_cost()
    }

    /// ½·Σ r² over the priors.
    pub fn prior_cost(&self) -> f64 {
        0.5 * self
            .priors
            .iter()
            .map(|p| p.residual(&self.intrinsics).powi(2))
            .sum::<f64>()
    }
}

/// Camera centre c = −Rᵀt of a pose.
pub fn camera_centre(c: &CameraPose) -> Vector3<f64> {
    let r = super::rotation::angle_axis_to_matrix(&c.rotation);
    -(r.transpose() * c.translation)
}
