//! The perfect mirror (book §9.5.2): a Dirac delta in the reflected direction.

use serde::{Deserialize, Serialize};

use super::BrdfSample;
use crate::math::{Rgb, Vec3};

/// A perfect mirror with reflectance R ∈ [0, 1]³ (book §9.5.2; the `.scn` `se = -1`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Mirror {
    /// Reflectance.
    pub reflectance: Rgb,
}

impl Mirror {
    /// The reflected direction (−wo.x, −wo.y, wo.z), f = R/cos θi, pdf 1 (delta).
    #[inline]
    pub fn sample(&self, wo: Vec3) -> Option<BrdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let wi = Vec3::new(-wo.x, -wo.y, wo.z);
        Some(BrdfSample {
            wi,
            f: self.reflectance / wi.z,
            pdf: 1.0,
            specular: true,
        })
    }
}
