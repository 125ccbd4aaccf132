//! Rays and robust ray origins (book §2.6; pbrt-v4 §6.8.6).

use crate::math::Vec3;

/// A ray r(t) = o + t·d with a unit direction (book §2.6).
#[derive(Clone, Copy, Debug)]
pub struct Ray {
    /// Origin.
    pub o: Vec3,
    /// Unit direction.
    pub d: Vec3,
}

impl Ray {
    /// A ray from an origin along a unit direction.
    #[inline]
    pub fn new(o: Vec3, d: Vec3) -> Ray {
        Ray { o, d }
    }
    /// The point at parameter t.
    #[inline]
    pub fn at(&self, t: f64) -> Vec3 {
        self.o + self.d * t
    }
}

/// Relative size of the offset that lifts a ray origin off the surface it leaves.
///
/// Hit points are reconstructed from barycentrics (triangles) or reprojected onto the sphere,
/// so their error is a few ulps of the largest coordinate (≈1e-16 relative in f64); an offset
/// of 1e-9 relative keeps seven orders of magnitude of margin while staying far below any
/// feature size of a real scene.
pub const ORIGIN_OFFSET: f64 = 1e-9;

/// Moves `p` off the surface with geometric normal `ng` to the side of `w`, so a ray leaving
/// along `w` cannot re-hit the surface it starts on (pbrt-v4 `OffsetRayOrigin`, with a
/// scale-relative bound instead of per-operation error terms).
#[inline]
pub fn offset_origin(p: Vec3, ng: Vec3, w: Vec3) -> Vec3 {
    let eps = ORIGIN_OFFSET * (1.0 + p.max_abs());
    if ng.dot(w) < 0.0 {
        p - ng * eps
    } else {
        p + ng * eps
    }
}

/// Perfect specular reflection of `wo` (pointing away from the surface) about `n`
/// (book §9.5.2).
#[inline]
pub fn reflect(wo: Vec3, n: Vec3) -> Vec3 {
    n * (2.0 * wo.dot(n)) - wo
}
