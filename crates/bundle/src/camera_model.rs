//! The intrinsics block of a bundle-adjustment problem ([`Intrinsics`]: its parameters, held
//! flags, fixed flag) and the camera models it parameterises ([`CameraModel`]: the book's
//! pinhole, BAL's camera, the project's pinhole through a lens).

use serde::{Deserialize, Serialize};

/// Most parameters of an intrinsics block (the radial–tangential lens's
/// `[f, k1, k2, p1, p2, cx, cy]`, [`CameraModel::Radial`]).
pub const INTRINSICS: usize = 7;

/// The camera model of an intrinsics block; it fixes the meaning of its parameters (three, or
/// seven for [`CameraModel::Radial`]) and of the pixel coordinates of the observations.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum CameraModel {
    /// The project's model (book 4.2, ARCHITECTURE.md, Conventions): x ~ K(RX + t), camera looking down +z,
    /// pixels with origin at the top-left pixel centre and y down. Parameters `[f, cx, cy]`;
    /// K = [[f, skew, cx], [0, aspect·f, cy], [0, 0, 1]] with `aspect` and `skew` held constant.
    Pinhole {
        /// fy / fx, held constant (1 for square pixels).
        aspect: f64,
        /// K[0][1], held constant (0 for a zero-skew camera).
        skew: f64,
    },
    /// The BAL / Bundler model (Agarwal et al. 2010): P = RX + t, p = −P.xy / P.z,
    /// predicted = f·(1 + k1‖p‖² + k2‖p‖⁴)·p, pixels centred on the principal point with y up,
    /// camera looking down −z. Parameters `[f, k1, k2]`.
    Bal,
    /// The project's pinhole frame seen through a lens ([`vfxgraph_lens`]): with p = (X/Z, Y/Z)
    /// and q = d(p) the lens's distorted point, the pixel is
    /// `(f·qx + skew·qy + cx, aspect·f·qy + cy)`. Parameters `[f, k1, k2, p1, p2, cx, cy]`: the
    /// focal length, Brown–Conrady's radial k1, k2 and tangential p1, p2 (its k3 held from
    /// `lens`) — or the division model's k1, k2 (p1, p2 zero and held) — and the principal
    /// point. This is what a matchmove with an unknown lens refines, as Blender's and libmv's
    /// camera solvers do; `held` says which of the seven stay.
    Radial {
        /// fy / fx, held constant.
        aspect: f64,
        /// K[0][1], held constant.
        skew: f64,
        /// The lens model; its k1, k2 (and Brown–Conrady's p1, p2) are replaced by the block's
        /// parameters, the rest held.
        lens: vfxgraph_lens::Distortion,
    },
}

impl CameraModel {
    /// The lens of a [`CameraModel::Radial`] block whose parameters are `params`
    /// (`[f, k1, k2, p1, p2, cx, cy]`; the identity for the other models).
    pub fn lens_with(&self, params: &[f64; INTRINSICS]) -> vfxgraph_lens::Distortion {
        use vfxgraph_lens::Distortion;
        let [_, k1, k2, p1, p2, ..] = *params;
        match *self {
            CameraModel::Radial { lens, .. } => match lens {
                Distortion::None => Distortion::BrownConrady {
                    k1,
                    k2,
                    k3: 0.0,
                    p1,
                    p2,
                },
                Distortion::BrownConrady { k3, .. } => {
                    Distortion::BrownConrady { k1, k2, k3, p1, p2 }
                }
                Distortion::Division { .. } => Distortion::Division { k1, k2 },
            },
            _ => Distortion::None,
        }
    }

    /// Number of parameters of a block of this model.
    pub fn num_params(&self) -> usize {
        match self {
            CameraModel::Pinhole { .. } | CameraModel::Bal => 3,
            CameraModel::Radial { .. } => INTRINSICS,
        }
    }
}

/// An intrinsics parameter block: a camera model and its parameters.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Intrinsics {
    /// What the parameters mean.
    pub model: CameraModel,
    /// `[f, cx, cy]` for [`CameraModel::Pinhole`], `[f, k1, k2]` for [`CameraModel::Bal`]
    /// (the rest zero), `[f, k1, k2, p1, p2, cx, cy]` for [`CameraModel::Radial`].
    pub params: [f64; INTRINSICS],
    /// Held constant during the solve.
    pub fixed: bool,
    /// Parameters held constant when the block is free (e.g. k2 of a k1-only lens solve);
    /// those past the model's [`CameraModel::num_params`] are ignored.
    pub held: [bool; INTRINSICS],
}

impl Intrinsics {
    /// A square-pixel, zero-skew pinhole block `[f, cx, cy]`.
    pub fn pinhole(f: f64, cx: f64, cy: f64, fixed: bool) -> Self {
        Intrinsics {
            model: CameraModel::Pinhole {
                aspect: 1.0,
                skew: 0.0,
            },
            params: [f, cx, cy, 0.0, 0.0, 0.0, 0.0],
            fixed,
            held: [false; INTRINSICS],
        }
    }

    /// A BAL block `[f, k1, k2]`.
    pub fn bal(f: f64, k1: f64, k2: f64, fixed: bool) -> Self {
        Intrinsics {
            model: CameraModel::Bal,
            params: [f, k1, k2, 0.0, 0.0, 0.0, 0.0],
            fixed,
            held: [false; INTRINSICS],
        }
    }

    /// A [`CameraModel::Radial`] block `[f, k1, k2, p1, p2, cx, cy]` of a camera with
    /// principal point `(cx, cy)`, square pixels and zero skew, free (p1, p2 held for a
    /// division lens).
    pub fn radial(f: f64, cx: f64, cy: f64, lens: vfxgraph_lens::Distortion) -> Self {
        use vfxgraph_lens::Distortion;
        let (k1, k2, p1, p2) = match lens {
            Distortion::None => (0.0, 0.0, 0.0, 0.0),
            Distortion::BrownConrady { k1, k2, p1, p2, .. } => (k1, k2, p1, p2),
            Distortion::Division { k1, k2 } => (k1, k2, 0.0, 0.0),
        };
        let division = matches!(lens, Distortion::Division { .. });
        Intrinsics {
            model: CameraModel::Radial {
                aspect: 1.0,
                skew: 0.0,
                lens,
            },
            params: [f, k1, k2, p1, p2, cx, cy],
            fixed: false,
            held: [false, false, false, division, division, false, false],
        }
    }

    /// Number of parameters of the block ([`CameraModel::num_params`]).
    pub fn num_params(&self) -> usize {
        self.model.num_params()
    }

    /// Whether parameter `u` stays constant in a solve (the block is fixed, or `u` is held).
    pub fn is_held(&self, u: usize) -> bool {
        self.fixed || self.held[u]
    }

    /// Number of parameters the solve changes (0 when fixed).
    pub fn num_free(&self) -> usize {
        (0..self.num_params()).filter(|&u| !self.is_held(u)).count()
    }
}
