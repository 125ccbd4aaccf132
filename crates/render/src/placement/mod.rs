//! Placing the local scene from measured points (book chapter 8 and
//! §10.10): the point-cloud calibration measures a few real points (the ground under the virtual
//! objects); the local scene — the shadow catcher and the objects on it — is built or moved so
//! that it stands on those points.
//!
//! Two tools:
//! - [`Similarity`] and [`umeyama`]: the similarity (scale, rotation, translation) that best
//!   maps anchor points given in a designed scene's own coordinates onto the same points
//!   measured in the solve's frame (Umeyama 1991, least squares with scale), and
//!   [`transform_scene`], which moves a whole [`Scene`] with it — triangles, sphere centres and
//!   radii, lights, the camera, and the dome's `orig`/`south` (rotated only, so the dome stays
//!   oriented to the real world).
//! - [`CatcherFrame`] and [`catcher_polygon`]: a shadow-catcher polygon through marked ground
//!   points (3 points → the parallelogram of the book's `modeling.scn`, A, B, C and
//!   D = B + C − A; more → their polygon, checked planar), and the catcher's own frame (origin
//!   at the first point, x along the first edge, y the plane's normal, unit = the first edge's
//!   length), in which objects are designed independently of the solve's arbitrary scale.
//!
//! [`place`] holds the two operations built on them (`place_scene`, `catcher_from_points`) and
//! their options.

use nalgebra::{Matrix3, Vector3};
use thiserror::Error;

pub mod place;

use crate::camera::Camera;
use crate::math::Vec3;
use crate::scene::{Scene, Shape};

/// Why a placement failed.
#[derive(Debug, Error, PartialEq)]
pub enum PlacementError {
    /// Inputs that cannot be used (counts, non-finite values, degenerate configurations).
    #[error("{0}")]
    Invalid(String),
    /// The points are not on one plane within the tolerance.
    #[error("{0}")]
    NotPlanar(String),
}

type Result<T> = std::result::Result<T, PlacementError>;

fn na(v: Vec3) -> Vector3<f64> {
    Vector3::new(v.x, v.y, v.z)
}

fn v3(v: Vector3<f64>) -> Vec3 {
    Vec3::new(v.x, v.y, v.z)
}

/// A similarity X ↦ s·R·X + t (s > 0, R a rotation).
#[derive(Clone, Debug, PartialEq)]
pub struct Similarity {
    /// Scale s.
    pub scale: f64,
    /// Rotation R.
    pub rotation: Matrix3<f64>,
    /// Translation t.
    pub translation: Vector3<f64>,
}

impl Similarity {
    /// The identity.
    pub fn identity() -> Similarity {
        Similarity {
            scale: 1.0,
            rotation: Matrix3::identity(),
            translation: Vector3::zeros(),
        }
    }

    /// Maps a point.
    pub fn point(&self, p: Vec3) -> Vec3 {
        v3(self.rotation * na(p) * self.scale + self.translation)
    }

    /// Maps a direction (rotation only).
    pub fn direction(&self, d: Vec3) -> Vec3 {
        v3(self.rotation * na(d))
    }

    /// The inverse similarity.
    pub fn inverse(&self) -> Similarity {
        let rt = self.rotation.transpose();
        Similarity {
            scale: 1.0 / self.scale,
            translation: -(rt * self.translation) / self.scale,
            rotation: rt,
        }
    }

    /// The rotation angle of R, degrees.
    pub fn angle_deg(&self) -> f64 {
        ((self.rotation.trace() - 1.0) / 2.0)
            .clamp(-1.0, 1.0)
            .acos()
            .to_degrees()
    }

    /// Maps a camera so it sees the mapped scene as it saw the original: with X' = sRX + T,
    /// K(R_c X + t_c) ∝ K(R_c Rᵀ X' + s t_c − R_c Rᵀ T).
    pub fn camera(&self, c: &Camera) -> Camera {
        let rc = Matrix3::from_fn(|i, j| c.r[i][j]);
        let r2 = rc * self.rotation.transpose();
        let t2 = Vector3::from(c.t) * self.scale - r2 * self.translation;
        Camera {
            r: [
                [r2[(0, 0)], r2[(0, 1)], r2[(0, 2)]],
                [r2[(1, 0)], r2[(1, 1)], r2[(1, 2)]],
                [r2[(2, 0)], r2[(2, 1)], r2[(2, 2)]],
            ],
            t: [t2.x, t2.y, t2.z],
            ..c.clone()
        }
    }
}

/// The result of [`umeyama`]: the similarity and how well it maps the anchors.
#[derive(Clone, Debug, PartialEq)]
pub struct SimilarityFit {
    /// The fitted similarity (source → destination).
    pub similarity: Similarity,
    /// Per anchor: |s·R·x + t − y|, in destination units.
    pub residuals: Vec<f64>,
    /// RMS of the residuals over the RMS distance of the destination points from their
    /// centroid (scale-free; 0 for an exact fit).
    pub relative_rms: f64,
}

/// Centroid and the centred points.
fn centred(p: &[Vector3<f64>]) -> (Vector3<f64>, Vec<Vector3<f64>>) {
    let c = p.iter().sum::<Vector3<f64>>() / p.len() as f64;
    (c, p.iter().map(|x| x - c).collect())
}

/// Whether centred points span at least a line's worth more than a point: the second singular
/// value of their scatter over the first is below `1e-9` → collinear (or coincident).
fn collinear(c: &[Vector3<f64>]) -> bool {
    let m: Matrix3<f64> = c.iter().map(|x| x * x.transpose()).sum();
    let mut s = m.symmetric_eigenvalues();
    s.as_mut_slice()
        .sort_by(|a, b| b.partial_cmp(a).unwrap_or(std::cmp::Ordering::Equal));
    s[0].is_nan() || s[0] <= 0.0 || s[1] <= 1e-9 * s[0]
}

/// The least-squares similarity mapping `src[i]` onto `dst[i]` (Umeyama, "Least-squares
/// estimation of transformation parameters between two point patterns", PAMI 1991): with the
/// cross-covariance Σ = UDVᵀ, R = U·S·Vᵀ (S fixes a reflection), s = tr(DS)/σ²_src,
/// t = μ_dst − s·R·μ_src. Needs ≥ 3 finite, non-collinear pairs.
pub fn umeyama(src: &[Vec3], dst: &[Vec3]) -> Result<SimilarityFit> {
    if src.len() != dst.len() {
        return Err(PlacementError::Invalid(format!(
            "{} anchor points but {} measured points: they must pair one to one",
            src.len(),
            dst.len()
        )));
    }
    if src.len() < 3 {
        return Err(PlacementError::Invalid(format!(
            "a similarity needs at least 3 anchor points, got {}",
            src.len()
        )));
    }
    for (name, pts) in [("anchor", src), ("measured", dst)] {
        if let Some(i) = pts.iter().position(|p| !p.is_finite()) {
            return Err(PlacementError::Invalid(format!(
                "{name} point {i} is not finite ({}, {}, {})",
                pts[i].x, pts[i].y, pts[i].z
            )));
        }
    }
    let xs: Vec<Vector3<f64>> = src.iter().map(|p| na(*p)).collect();
    let ys: Vec<Vector3<f64>> = dst.iter().map(|p| na(*p)).collect();
    let (mx, cx) = centred(&xs);
    let (my, cy) = centred(&ys);
    for (name, c) in [("anchor", &cx), ("measured", &cy)] {
        if collinear(c) {
            return Err(PlacementError::Invalid(format!(
                "the {name} points are collinear (or coincide): a similarity needs 3 points \
                 that span a plane"
            )));
        }
    }
    let n = xs.len() as f64;
    let sigma: Matrix3<f64> = cy
        .iter()
        .zip(&cx)
        .map(|(y, x)| y * x.transpose())
        .sum::<Matrix3<f64>>()
        / n;
    let var_x = cx.iter().map(|x| x.norm_squared()).sum::<f64>() / n;
    let svd = sigma.svd(true, true);
    let (u, vt) = (
        svd.u
            .ok_or_else(|| PlacementError::Invalid("SVD failed".into()))?,
        svd.v_t
            .ok_or_else(|| PlacementError::Invalid("SVD failed".into()))?,
    );
    let mut s = Matrix3::identity();
    if (u.determinant() * vt.determinant()) < 0.0 {
        s[(2, 2)] = -1.0;
    }
    let rotation = u * s * vt;
    let d = svd.singular_values;
    let scale = (d[0] * s[(0, 0)] + d[1] * s[(1, 1)] + d[2] * s[(2, 2)]) / var_x;
    let translation = my - rotation * mx * scale;
    let similarity = Similarity {
        scale,
        rotation,
        translation,
    };
    let residuals: Vec<f64> = src
        .iter()
        .zip(dst)
        .map(|(x, y)| (similarity.point(*x) - *y).length())
        .collect();
    let rms = (residuals.iter().map(|r| r * r).sum::<f64>() / n).sqrt();
    let spread = (cy.iter().map(|y| y.norm_squared()).sum::<f64>() / n).sqrt();
    Ok(SimilarityFit {
        similarity,
        residuals,
        relative_rms: rms / spread,
    })
}

/// The scene moved by a similarity: every object (sphere centres and radii, triangles; the
/// catcher flag and materials kept), every area light, the camera (so it sees the moved scene
/// as it saw the original), and the dome's `orig`/`south` (rotated: the dome is at infinity).
/// Radiance is unchanged: materials and emitted radiance do not depend on scale.
pub fn transform_scene(scene: &Scene, s: &Similarity) -> Scene {
    let mut out = scene.clone();
    let tri = |t: &[Vec3; 3]| [s.point(t[0]), s.point(t[1]), s.point(t[2])];
    for o in &mut out.objects {
        match &mut o.shape {
            Shape::Sphere(sp) => {
                sp.center = s.point(sp.center);
                sp.radius *= s.scale;
            }
            Shape::Triangles { triangles } => {
                for t in triangles.iter_mut() {
                    *t = tri(t);
                }
            }
        }
    }
    for l in &mut out.lights {
        for t in l.triangles.iter_mut() {
            *t = tri(t);
        }
    }
    if let Some(d) = &mut out.dome {
        d.orig = s.direction(d.orig);
        d.south = s.direction(d.south);
    }
    out.camera = scene.camera.as_ref().map(|c| s.camera(c));
    out
}

/// The vertices A, B, C of a scene's first shadow catcher: its first triangle's vertices, in
/// order (the book's `modeling.scn` writes its parallelogram as (A, B, C), (C, B, D) with
/// D = B + C − A). `None` without a triangle catcher.
pub fn first_catcher_vertices(scene: &Scene) -> Option<[Vec3; 3]> {
    scene.catchers().find_map(|o| match &o.shape {
        Shape::Triangles { triangles } => triangles.first().copied(),
        Shape::Sphere(_) => None,
    })
}

/// The frame of a shadow catcher (module docs): `origin` = the first ground point, `x` along
/// the first edge, `y` = the plane's unit normal (the side facing the cameras when known), `z` =
/// x × y; lengths in units of `unit` = the first edge's length. Objects designed in this frame
/// (y up, resting on y = 0) land on the measured ground whatever the solve's scale.
#[derive(Clone, Debug, PartialEq)]
pub struct CatcherFrame {
    /// The first ground point.
    pub origin: Vec3,
    /// Unit vector along the first edge.
    pub x: Vec3,
    /// Unit normal of the ground plane ("up").
    pub y: Vec3,
    /// x × y.
    pub z: Vec3,
    /// The first edge's length (the frame's unit of length).
    pub unit: f64,
}

impl CatcherFrame {
    /// The similarity from catcher-frame coordinates to the world.
    pub fn similarity(&self) -> Similarity {
        let (x, y, z) = (na(self.x), na(self.y), na(self.z));
        Similarity {
            scale: self.unit,
            rotation: Matrix3::from_columns(&[x, y, z]),
            translation: na(self.origin),
        }
    }
}

/// A shadow catcher through ground points: its triangles and its frame.
#[derive(Clone, Debug, PartialEq)]
pub struct CatcherPolygon {
    /// The catcher's triangles.
    pub triangles: Vec<[Vec3; 3]>,
    /// The polygon's corners (after the margin), in order around it.
    pub corners: Vec<Vec3>,
    /// Its frame.
    pub frame: CatcherFrame,
    /// Largest distance of a ground point from the fitted plane, over the polygon's size
    /// (0 for 3 points).
    pub planarity: f64,
}

/// The shadow-catcher polygon through ground points (module docs). 3 points A, B, C → the
/// parallelogram A, B, D = B + C − A, C as the triangles (A, B, C), (C, B, D) of the book's
/// `modeling.scn`; n ≥ 4 points → the polygon of the points ordered by angle around their
/// centroid in the least-squares plane (a fan of triangles from the centroid), refused when a
/// point is farther from the plane than `tolerance` × the polygon's size (its largest distance
/// from the centroid). `margin` grows the polygon about its centroid by that fraction (0 = through
/// the points). `up` (e.g. the mean camera centre minus the centroid) picks the normal's side;
/// without it the normal is (B − A) × (C − A).
pub fn catcher_polygon(
    points: &[Vec3],
    margin: f64,
    tolerance: f64,
    up: Option<Vec3>,
) -> Result<CatcherPolygon> {
    if points.len() < 3 {
        return Err(PlacementError::Invalid(format!(
            "a catcher polygon needs at least 3 ground points, got {}",
            points.len()
        )));
    }
    if let Some(i) = points.iter().position(|p| !p.is_finite()) {
        return Err(PlacementError::Invalid(format!(
            "ground point {i} is not finite ({}, {}, {})",
            points[i].x, points[i].y, points[i].z
        )));
    }
    if !(margin.is_finite() && margin > -1.0) {
        return Err(PlacementError::Invalid(format!(
            "margin {margin} must be a finite fraction > −1"
        )));
    }
    let ps: Vec<Vector3<f64>> = points.iter().map(|p| na(*p)).collect();
    let (centroid, c) = centred(&ps);
    if collinear(&c) {
        return Err(PlacementError::Invalid(
            "the ground points are collinear (or coincide): they do not span a plane".into(),
        ));
    }
    let (a, b) = (ps[0], ps[1]);
    let e1 = b - a;
    // The plane's normal: exact for 3 points, least squares for more.
    let (mut n, planarity) = if ps.len() == 3 {
        (e1.cross(&(ps[2] - a)).normalize(), 0.0)
    } else {
        let m: Matrix3<f64> = c.iter().map(|x| x * x.transpose()).sum();
        let eig = m.symmetric_eigen();
        let k = eig.eigenvalues.imin();
        let mut n: Vector3<f64> = eig.eigenvectors.column(k).into();
        if n.dot(&e1.cross(&(ps[2] - a))) < 0.0 {
            n = -n;
        }
        let size = c.iter().map(|x| x.norm()).fold(0.0, f64::max);
        let off = c.iter().map(|x| x.dot(&n).abs()).fold(0.0, f64::max);
        let planarity = off / size;
        if planarity > tolerance {
            let worst = c
                .iter()
                .map(|x| x.dot(&n).abs())
                .enumerate()
                .fold((0, 0.0), |b, (i, d)| if d > b.1 { (i, d) } else { b });
            return Err(PlacementError::NotPlanar(format!(
                "the {} ground points are not on one plane: point {} is {:.3} × the polygon's \
                 size off the best plane (tolerance {tolerance})",
                ps.len(),
                worst.0,
                worst.1 / size
            )));
        }
        (n, planarity)
    };
    if let Some(u) = up {
        if u.is_finite() && n.dot(&na(u)) < 0.0 {
            n = -n;
        }
    }
    let grow = |p: Vector3<f64>| v3(centroid + (p - centroid) * (1.0 + margin));
    let (corners, triangles) = if ps.len() == 3 {
        let d = ps[1] + ps[2] - ps[0];
        let centroid = (ps[0] + d) / 2.0;
        let grow = |p: Vector3<f64>| v3(centroid + (p - centroid) * (1.0 + margin));
        let (a, b, c, d) = (grow(ps[0]), grow(ps[1]), grow(ps[2]), grow(d));
        (vec![a, b, d, c], vec![[a, b, c], [c, b, d]])
    } else {
        // Order by angle in the plane basis (e1 direction, n × e1).
        let u = (e1 - n * n.dot(&e1)).normalize();
        let w = n.cross(&u);
        let mut order: Vec<usize> = (0..ps.len()).collect();
        let ang = |i: usize| c[i].dot(&w).atan2(c[i].dot(&u));
        order.sort_by(|&i, &j| ang(i).total_cmp(&ang(j)));
        let corners: Vec<Vec3> = order.iter().map(|&i| grow(ps[i])).collect();
        let m = v3(centroid);
        let tris = (0..corners.len())
            .map(|k| [m, corners[k], corners[(k + 1) % corners.len()]])
            .collect();
        (corners, tris)
    };
    let x = e1.normalize();
    // y is the normal; for n ≥ 4 points the first edge may leave the plane slightly: project.
    let x = (x - n * n.dot(&x)).normalize();
    let frame = CatcherFrame {
        origin: points[0],
        x: v3(x),
        y: v3(n),
        z: v3(x.cross(&n)),
        unit: e1.norm(),
    };
    Ok(CatcherPolygon {
        triangles,
        corners,
        frame,
        planarity,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brdf::{Brdf, Lambert};
    use crate::math::Rgb;
    use crate::scene::{AreaLight, DomeSpec, Object};
    use crate::shape::Sphere;
    use rand::{Rng, SeedableRng};

    fn rot(axis: Vector3<f64>, angle: f64) -> Matrix3<f64> {
        *nalgebra::Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(axis), angle).matrix()
    }

    fn scene() -> Scene {
        let mat = Brdf::Lambert(Lambert {
            albedo: Rgb::new(0.5, 0.5, 0.5),
        });
        let mut catcher = Object::new(
            Shape::Triangles {
                triangles: vec![[
                    Vec3::new(0.0, 0.0, 0.0),
                    Vec3::new(1.0, 0.0, 0.0),
                    Vec3::new(0.0, 0.0, 1.0),
                ]],
            },
            mat,
        );
        catcher.catcher = true;
        Scene {
            camera: Some(
                Camera::look_at(
                    Vec3::new(0.5, 2.0, 3.0),
                    Vec3::new(0.3, 0.0, 0.3),
                    Vec3::new(0.0, 1.0, 0.0),
                    50.0,
                    64,
                    48,
                )
                .unwrap(),
            ),
            objects: vec![
                catcher,
                Object::new(
                    Shape::Sphere(Sphere {
                        center: Vec3::new(0.3, 0.2, 0.3),
                        radius: 0.2,
                    }),
                    mat,
                ),
            ],
            lights: vec![AreaLight {
                radiance: Rgb::new(1.0, 1.0, 1.0),
                triangles: vec![[
                    Vec3::new(0.0, 3.0, 0.0),
                    Vec3::new(1.0, 3.0, 0.0),
                    Vec3::new(0.0, 3.0, 1.0),
                ]],
            }],
            background: Rgb::new(0.0, 0.0, 0.0),
            dome: Some(DomeSpec {
                orig: Vec3::new(0.0, 0.0, -1.0),
                south: Vec3::new(0.0, 1.0, 0.0),
                image: "sky.hdr".into(),
                scale: 1.0,
            }),
        }
    }

    /// A random similarity applied to a scene is recovered from the catcher's vertices and the
    /// sphere's centre to rounding, and mapping the scene back gives the original.
    #[test]
    fn umeyama_recovers_a_random_similarity() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(9);
        for _ in 0..20 {
            let truth = Similarity {
                scale: rng.random_range(0.01..100.0),
                rotation: rot(
                    Vector3::new(
                        rng.random_range(-1.0..1.0),
                        rng.random_range(-1.0..1.0),
                        rng.random_range(-1.0..1.0),
                    ),
                    rng.random_range(-3.1..3.1),
                ),
                translation: Vector3::new(
                    rng.random_range(-50.0..50.0),
                    rng.random_range(-50.0..50.0),
                    rng.random_range(-50.0..50.0),
                ),
            };
            let s = scene();
            let moved = transform_scene(&s, &truth);
            let src = first_catcher_vertices(&s).unwrap();
            let dst = first_catcher_vertices(&moved).unwrap();
            let fit = umeyama(&src, &dst).unwrap();
            let f = &fit.similarity;
            assert!(
                (f.scale / truth.scale - 1.0).abs() < 1e-9,
                "{f:?} {truth:?}"
            );
            assert!((f.rotation - truth.rotation).amax() < 1e-9);
            assert!((f.translation - truth.translation).amax() < 1e-8 * (1.0 + truth.scale));
            assert!(fit.relative_rms < 1e-9);
            // The moved camera projects the moved sphere centre where the original camera
            // projected the original.
            let (c0, c1) = (s.camera.as_ref().unwrap(), moved.camera.as_ref().unwrap());
            let Shape::Sphere(sp) = moved.objects[1].shape else {
                panic!()
            };
            let p0 = c0.project(Vec3::new(0.3, 0.2, 0.3)).unwrap();
            let p1 = c1.project(sp.center).unwrap();
            assert!((p0.0 - p1.0).abs() < 1e-6 && (p0.1 - p1.1).abs() < 1e-6);
            assert!((sp.radius - 0.2 * truth.scale).abs() < 1e-9 * truth.scale);
            c1.validate().unwrap();
            // Dome directions are rotated, not scaled or translated.
            let d = moved.dome.as_ref().unwrap();
            assert!((na(d.south) - truth.rotation * Vector3::y()).norm() < 1e-12);
            // And back.
            let back = transform_scene(&moved, &f.inverse());
            let b = first_catcher_vertices(&back).unwrap();
            for (p, q) in b.iter().zip(&src) {
                assert!((*p - *q).length() < 1e-8);
            }
        }
    }

    #[test]
    fn umeyama_reports_residuals_of_an_inexact_fit() {
        let src = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
        ];
        let mut dst = src;
        dst[3] = Vec3::new(1.0, 1.0, 0.2);
        let fit = umeyama(&src, &dst).unwrap();
        assert!(fit.relative_rms > 0.05 && fit.relative_rms < 0.2, "{fit:?}");
        // Least squares spreads the error: every residual is nonzero.
        assert!(fit.residuals.iter().all(|r| *r > 1e-3), "{fit:?}");
    }

    #[test]
    fn umeyama_errors() {
        let a = [Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0)];
        let line = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 1.0, 1.0),
            Vec3::new(2.0, 2.0, 2.0),
        ];
        let tri = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
        ];
        let msg = |r: Result<SimilarityFit>| r.unwrap_err().to_string();
        assert!(msg(umeyama(&a, &a)).contains("at least 3"));
        assert!(msg(umeyama(&tri, &a)).contains("3 anchor points but 2"));
        assert!(msg(umeyama(&line, &tri)).contains("anchor points are collinear"));
        assert!(msg(umeyama(&tri, &line)).contains("measured points are collinear"));
        let mut nan = tri;
        nan[1].y = f64::NAN;
        assert!(msg(umeyama(&tri, &nan)).contains("measured point 1 is not finite"));
    }

    #[test]
    fn three_points_give_the_books_parallelogram() {
        let (a, b, c) = (
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(3.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 2.0),
        );
        let p = catcher_polygon(&[a, b, c], 0.0, 0.01, None).unwrap();
        let d = Vec3::new(3.0, 0.0, 2.0);
        assert_eq!(p.triangles, vec![[a, b, c], [c, b, d]]);
        assert_eq!(p.frame.unit, 2.0);
        // (B − A) × (C − A) = x × z = −y.
        assert_eq!(p.frame.y, Vec3::new(0.0, -1.0, 0.0));
        // With an `up` hint above the plane the normal flips to +y; the frame stays right-handed.
        let p = catcher_polygon(&[a, b, c], 0.5, 0.01, Some(Vec3::new(0.0, 1.0, 0.0))).unwrap();
        assert_eq!(p.frame.y, Vec3::new(0.0, 1.0, 0.0));
        assert!((p.frame.similarity().rotation.determinant() - 1.0).abs() < 1e-12);
        // Margin 0.5 about the centre (2, 0, 1): A → (0.5, 0, −0.5).
        assert!((p.triangles[0][0] - Vec3::new(0.5, 0.0, -0.5)).length() < 1e-12);
        // A point in the catcher frame lands where expected: (1, 0.25, 0.5) → A + 2·(x, ¼y, ½z)
        // with z = x × y = +z (the frame origin is A itself, not the grown corner).
        let w = p.frame.similarity().point(Vec3::new(1.0, 0.25, 0.5));
        assert!((w - Vec3::new(3.0, 0.5, 1.0)).length() < 1e-12, "{w:?}");
    }

    #[test]
    fn four_or_more_points_give_their_polygon_when_planar() {
        // A square's corners, shuffled, slightly off-plane.
        let pts = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.001, 1.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 0.0, 1.0),
        ];
        let p = catcher_polygon(&pts, 0.0, 0.01, Some(Vec3::new(0.0, 1.0, 0.0))).unwrap();
        assert_eq!(p.corners.len(), 4);
        assert_eq!(p.triangles.len(), 4);
        assert!(p.planarity > 0.0 && p.planarity < 0.001);
        // Area of the fan = the square's.
        let area: f64 = p
            .triangles
            .iter()
            .map(|t| (t[1] - t[0]).cross(t[2] - t[0]).length() / 2.0)
            .sum();
        assert!((area - 1.0).abs() < 1e-3, "{area}");
        assert!((p.frame.y.y - 1.0).abs() < 1e-3);
        // Not planar: a clear error naming the point.
        let mut bent = pts;
        bent[1].y = 0.5;
        let e = catcher_polygon(&bent, 0.0, 0.01, None).unwrap_err();
        assert!(matches!(e, PlacementError::NotPlanar(_)), "{e}");
        assert!(e.to_string().contains("not on one plane"), "{e}");
        // Too few, collinear, NaN.
        assert!(catcher_polygon(&pts[..2], 0.0, 0.01, None).is_err());
        let line = [pts[0], pts[2], Vec3::new(2.0, 0.0, 0.0)];
        assert!(catcher_polygon(&line, 0.0, 0.01, None)
            .unwrap_err()
            .to_string()
            .contains("collinear"));
        let mut nan = pts;
        nan[2].x = f64::NAN;
        assert!(catcher_polygon(&nan, 0.0, 0.01, None)
            .unwrap_err()
            .to_string()
            .contains("ground point 2 is not finite"));
    }
}
