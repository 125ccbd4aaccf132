//! Shapes: spheres and triangles, their ray intersections and bounds (book §2.6, §9.11;
//! pbrt-v4 ch. 6).

use serde::{Deserialize, Serialize};

use crate::math::Vec3;
use crate::ray::Ray;

/// An axis-aligned bounding box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// Lower corner.
    pub min: Vec3,
    /// Upper corner.
    pub max: Vec3,
}

impl Aabb {
    /// The empty box (min = +∞, max = −∞).
    pub const EMPTY: Aabb = Aabb {
        min: Vec3::new(f64::INFINITY, f64::INFINITY, f64::INFINITY),
        max: Vec3::new(f64::NEG_INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY),
    };
    /// The union with another box.
    #[inline]
    pub fn union(self, o: Aabb) -> Aabb {
        Aabb {
            min: self.min.min(o.min),
            max: self.max.max(o.max),
        }
    }
    /// The union with a point.
    #[inline]
    pub fn grow(self, p: Vec3) -> Aabb {
        Aabb {
            min: self.min.min(p),
            max: self.max.max(p),
        }
    }
    /// Surface area (0 for an empty box).
    #[inline]
    pub fn area(self) -> f64 {
        let d = self.max - self.min;
        if d.x < 0.0 || d.y < 0.0 || d.z < 0.0 {
            return 0.0;
        }
        2.0 * (d.x * d.y + d.y * d.z + d.z * d.x)
    }
    /// The centre.
    #[inline]
    pub fn centroid(self) -> Vec3 {
        (self.min + self.max) * 0.5
    }
}

/// A sphere (S3D `sphere{center, radius}`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Sphere {
    /// Centre.
    pub center: Vec3,
    /// Radius (> 0).
    pub radius: f64,
}

impl Sphere {
    /// The nearest intersection with t in (0, t_max). Uses the numerically careful form of
    /// Haines et al., "Precision improvements for ray/sphere intersection" (Ray Tracing Gems
    /// ch. 7) for a unit direction.
    #[inline]
    pub fn intersect(&self, ray: &Ray, t_max: f64) -> Option<f64> {
        let f = ray.o - self.center;
        let b = -f.dot(ray.d);
        let l = f + ray.d * b;
        let r2 = self.radius * self.radius;
        let disc = r2 - l.length_squared();
        if disc < 0.0 {
            return None;
        }
        let c = f.length_squared() - r2;
        let q = b + disc.sqrt().copysign(b);
        let (t0, t1) = if q == 0.0 {
            (0.0, 0.0)
        } else {
            let (a, b) = (c / q, q);
            if a < b {
                (a, b)
            } else {
                (b, a)
            }
        };
        if t0 > 0.0 && t0 < t_max {
            Some(t0)
        } else if t1 > 0.0 && t1 < t_max {
            Some(t1)
        } else {
            None
        }
    }
    /// Bounds.
    pub fn bounds(&self) -> Aabb {
        let r = Vec3::new(self.radius, self.radius, self.radius);
        Aabb {
            min: self.center - r,
            max: self.center + r,
        }
    }
}

/// A triangle stored as a vertex and two edges, with its unit geometric normal
/// e1 × e2 / |e1 × e2| (counter-clockwise vertices face the normal).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Triangle {
    /// First vertex.
    pub p0: Vec3,
    /// p1 − p0.
    pub e1: Vec3,
    /// p2 − p0.
    pub e2: Vec3,
    /// Unit geometric normal.
    pub n: Vec3,
    /// Area.
    pub area: f64,
}

impl Triangle {
    /// A triangle from its vertices; `None` if it is degenerate (zero area) or not finite.
    pub fn new(p0: Vec3, p1: Vec3, p2: Vec3) -> Option<Triangle> {
        let (e1, e2) = (p1 - p0, p2 - p0);
        let c = e1.cross(e2);
        let len = c.length();
        let scale = e1.length() * e2.length();
        if !(len.is_finite() && p0.is_finite()) || len <= 1e-14 * scale || len == 0.0 {
            return None;
        }
        Some(Triangle {
            p0,
            e1,
            e2,
            n: c / len,
            area: 0.5 * len,
        })
    }
    /// Möller–Trumbore intersection with t in (0, t_max): (t, b1, b2), the point being
    /// p0 + b1 e1 + b2 e2.
    #[inline]
    pub fn intersect(&self, ray: &Ray, t_max: f64) -> Option<(f64, f64, f64)> {
        let pvec = ray.d.cross(self.e2);
        let det = self.e1.dot(pvec);
        if det == 0.0 || !det.is_finite() {
            return None;
        }
        let inv = 1.0 / det;
        let tvec = ray.o - self.p0;
        let u = tvec.dot(pvec) * inv;
        if !(0.0..=1.0).contains(&u) {
            return None;
        }
        let qvec = tvec.cross(self.e1);
        let v = ray.d.dot(qvec) * inv;
        if v < 0.0 || u + v > 1.0 {
            return None;
        }
        let t = self.e2.dot(qvec) * inv;
        if t > 0.0 && t < t_max {
            Some((t, u, v))
        } else {
            None
        }
    }
    /// The point with barycentrics (b1, b2) on edges e1, e2.
    #[inline]
    pub fn point(&self, b1: f64, b2: f64) -> Vec3 {
        self.p0 + self.e1 * b1 + self.e2 * b2
    }
    /// Bounds.
    pub fn bounds(&self) -> Aabb {
        Aabb::EMPTY
            .grow(self.p0)
            .grow(self.p0 + self.e1)
            .grow(self.p0 + self.e2)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sphere_hits_near_and_far_roots() {
        let s = Sphere {
            center: Vec3::new(0.0, 0.0, 10.0),
            radius: 2.0,
        };
        let r = Ray::new(Vec3::ZERO, Vec3::new(0.0, 0.0, 1.0));
        assert!((s.intersect(&r, f64::INFINITY).unwrap() - 8.0).abs() < 1e-12);
        assert!(s.intersect(&r, 7.9).is_none());
        let inside = Ray::new(Vec3::new(0.0, 0.0, 10.0), Vec3::new(0.0, 0.0, 1.0));
        assert!((s.intersect(&inside, f64::INFINITY).unwrap() - 2.0).abs() < 1e-12);
        let miss = Ray::new(Vec3::new(0.0, 2.0001, 0.0), Vec3::new(0.0, 0.0, 1.0));
        assert!(s.intersect(&miss, f64::INFINITY).is_none());
        // Far away: the careful form keeps precision.
        let far = Sphere {
            center: Vec3::new(0.0, 0.0, 1e7),
            radius: 1.0,
        };
        let t = far.intersect(&r, f64::INFINITY).unwrap();
        assert!((t - (1e7 - 1.0)).abs() < 1e-6);
    }

    #[test]
    fn triangle_hits_and_degenerates() {
        let t = Triangle::new(
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(1.0, 0.0, 1.0),
            Vec3::new(0.0, 1.0, 1.0),
        )
        .unwrap();
        assert_eq!(t.n, Vec3::new(0.0, 0.0, 1.0));
        assert!((t.area - 0.5).abs() < 1e-15);
        let r = Ray::new(Vec3::new(0.25, 0.25, 0.0), Vec3::new(0.0, 0.0, 1.0));
        let (tt, b1, b2) = t.intersect(&r, f64::INFINITY).unwrap();
        assert!((tt - 1.0).abs() < 1e-15 && (b1 - 0.25).abs() < 1e-15 && (b2 - 0.25).abs() < 1e-15);
        let r = Ray::new(Vec3::new(0.75, 0.75, 0.0), Vec3::new(0.0, 0.0, 1.0));
        assert!(t.intersect(&r, f64::INFINITY).is_none());
        let p = Vec3::new(1.0, 1.0, 1.0);
        assert!(Triangle::new(p, p, Vec3::ZERO).is_none());
        assert!(Triangle::new(Vec3::ZERO, p, p * 2.0).is_none(), "collinear");
        assert!(Triangle::new(Vec3::new(f64::NAN, 0.0, 0.0), p, Vec3::ZERO).is_none());
    }
}
