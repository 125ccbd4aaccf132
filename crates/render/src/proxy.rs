//! Proxy geometry of the real set from measured points (Debevec 1998 §4's local scene
//! "approximated by simple geometry"; book ch. 8's point-cloud calibration measures the points):
//! a plane patch from its 4 corners, a box from 3 corners of its base and the corner above the
//! first, or from 3 corners of its top standing on a known plane (the ground catcher's: for a box
//! whose base corners are hidden behind it or out of frame). Each face is a separate planar shadow catcher, so [`crate::catcher_texture`] can
//! texture it from the plate; as catchers they receive the objects' shadows, are seen in the
//! objects' reflections and occlude the dome for the objects' lighting.

use crate::brdf::{Brdf, Lambert};
use crate::math::{Rgb, Vec3};
use crate::scene::{Object, Scene, Shape};

/// Why a proxy could not be built.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ProxyError {
    /// Too few points.
    #[error("a {kind} needs {need} measured points, found {found}")]
    TooFewPoints {
        /// Plane or box.
        kind: &'static str,
        /// Points needed.
        need: usize,
        /// Points given.
        found: usize,
    },
    /// The points are degenerate.
    #[error("the {kind}'s points are degenerate: {why}")]
    Degenerate {
        /// Plane or box.
        kind: &'static str,
        /// What is wrong.
        why: String,
    },
}

fn quad(a: Vec3, b: Vec3, c: Vec3, d: Vec3) -> Vec<[Vec3; 3]> {
    vec![[a, b, c], [a, c, d]]
}

fn finite(kind: &'static str, p: &[Vec3]) -> Result<(), ProxyError> {
    if p.iter().all(|p| p.is_finite()) {
        Ok(())
    } else {
        Err(ProxyError::Degenerate {
            kind,
            why: "a point is not finite".into(),
        })
    }
}

/// A plane patch through 4 corners in order around it (made planar: the 4th corner is
/// projected onto the plane of the first three, and must lie within 5 % of the patch's size
/// from it).
pub fn plane_patch(p: &[Vec3]) -> Result<Vec<[Vec3; 3]>, ProxyError> {
    let kind = "plane patch";
    if p.len() < 4 {
        return Err(ProxyError::TooFewPoints {
            kind,
            need: 4,
            found: p.len(),
        });
    }
    finite(kind, &p[..4])?;
    let n = (p[1] - p[0]).cross(p[2] - p[0]);
    let size = (p[2] - p[0]).length();
    if !(n.length() > 1e-9 * size * size && size > 0.0) {
        return Err(ProxyError::Degenerate {
            kind,
            why: "the first three corners are collinear".into(),
        });
    }
    let n = n.normalized();
    let off = (p[3] - p[0]).dot(n);
    if off.abs() > 0.05 * size {
        return Err(ProxyError::Degenerate {
            kind,
            why: format!(
                "the 4th corner is {:.3} off the plane of the first three ({:.1} % of the patch)",
                off.abs(),
                100.0 * off.abs() / size
            ),
        });
    }
    Ok(quad(p[0], p[1], p[2], p[3] - n * off))
}

/// A box's faces (top and 4 sides; the base stands on the ground) from 4 points: base corners
/// `a`, `b`, `c` (b adjacent to both: the base is the parallelogram a, b, c, a + c − b) and
/// `top`, the corner above `a` (only its height above the base's plane is used).
pub fn box_faces(p: &[Vec3]) -> Result<Vec<Vec<[Vec3; 3]>>, ProxyError> {
    let kind = "box";
    if p.len() < 4 {
        return Err(ProxyError::TooFewPoints {
            kind,
            need: 4,
            found: p.len(),
        });
    }
    finite(kind, &p[..4])?;
    let (a, b, c) = (p[0], p[1], p[2]);
    let d = a + c - b;
    let n = (b - a).cross(c - b);
    let size = (b - a).length().max((c - b).length());
    if !(n.length() > 1e-6 * size * size && size > 0.0) {
        return Err(ProxyError::Degenerate {
            kind,
            why: "the three base corners are collinear".into(),
        });
    }
    let n = n.normalized();
    let h = (p[3] - a).dot(n);
    if h.abs() < 1e-3 * size {
        return Err(ProxyError::Degenerate {
            kind,
            why: "the top corner is on the base's plane (zero height)".into(),
        });
    }
    let up = n * h;
    let (a2, b2, c2, d2) = (a + up, b + up, c + up, d + up);
    Ok(vec![
        quad(a2, b2, c2, d2),
        quad(a, b, b2, a2),
        quad(b, c, c2, b2),
        quad(c, d, d2, c2),
        quad(d, a, a2, d2),
    ])
}

/// A box standing on a plane (through `origin`, normal `normal`: the ground catcher's) from 3
/// corners of its top: `a`, `b`, `c` with b adjacent to both (the top is the parallelogram a, b,
/// c, a + c − b); its base is the top projected onto the plane. The faces of [`box_faces`].
pub fn box_on_plane(
    top: &[Vec3],
    origin: Vec3,
    normal: Vec3,
) -> Result<Vec<Vec<[Vec3; 3]>>, ProxyError> {
    let kind = "box";
    if top.len() < 3 {
        return Err(ProxyError::TooFewPoints {
            kind,
            need: 3,
            found: top.len(),
        });
    }
    finite(kind, &top[..3])?;
    if !(normal.length() > 0.0 && normal.is_finite()) {
        return Err(ProxyError::Degenerate {
            kind,
            why: "the ground plane has no normal".into(),
        });
    }
    let n = normal.normalized();
    let down = |p: Vec3| p - n * (p - origin).dot(n);
    box_faces(&[down(top[0]), down(top[1]), down(top[2]), top[0]])
}

/// Each face as a Lambertian shadow catcher of colour `albedo`.
pub fn catchers(faces: Vec<Vec<[Vec3; 3]>>, albedo: Rgb) -> Vec<Object> {
    faces
        .into_iter()
        .map(|triangles| {
            let mut o = Object::new(
                Shape::Triangles { triangles },
                Brdf::Lambert(Lambert { albedo }),
            );
            o.catcher = true;
            o
        })
        .collect()
}

/// The proxies of a set (the `proxy_from_points` node's params): groups of indices into the
/// measured points.
#[derive(Debug, PartialEq, vfxgraph_params::Options)]
pub struct ProxyOptions {
    /// boxes, 4 indices into `points3d` each: three base corners a, b, c (b adjacent to a and c) and the corner above a
    pub boxes: Vec<f64>,
    /// boxes standing on the first catcher's plane (the ground), 3 indices into `points3d` each: top corners a, b, c (b adjacent to a and c) — for a box whose base corners are hidden
    pub tops: Vec<f64>,
    /// plane patches, 4 indices into `points3d` each: the corners in order around the patch
    pub planes: Vec<f64>,
    /// the proxies' starting diffuse colour (catcher_texture then estimates it from the plate)
    pub albedo: Vec<f64>,
}

impl Default for ProxyOptions {
    fn default() -> Self {
        ProxyOptions {
            boxes: Vec::new(),
            tops: Vec::new(),
            planes: Vec::new(),
            albedo: vec![0.18, 0.18, 0.18],
        }
    }
}

/// The measured points named by `indices` (groups of `size`).
fn groups(
    pts: &[Vec3],
    indices: &[f64],
    what: &str,
    size: usize,
) -> Result<Vec<Vec<Vec3>>, String> {
    let one = if what == "planes" {
        "plane patch"
    } else {
        "box"
    };
    indices
        .chunks(size)
        .enumerate()
        .map(|(g, c)| {
            if c.len() < size {
                return Err(format!(
                    "param `{what}`: {one} {g} has {} point indices, a {one} needs {size}",
                    c.len(),
                ));
            }
            c.iter()
                .map(|&i| {
                    if i.fract() != 0.0 || i < 0.0 || i as usize >= pts.len() {
                        Err(format!(
                            "param `{what}`: {i} is not the index of one of the {} measured \
                             points (0-based)",
                            pts.len()
                        ))
                    } else {
                        Ok(pts[i as usize])
                    }
                })
                .collect()
        })
        .collect()
}

/// A point on the scene's first catcher (the ground) and its normal, from its first triangle.
fn ground_plane(scene: &Scene) -> Result<(Vec3, Vec3), String> {
    let tri = scene
        .catchers()
        .find_map(|o| match &o.shape {
            Shape::Triangles { triangles } => triangles.first().copied(),
            _ => None,
        })
        .ok_or_else(|| {
            "param `tops`: a box by its top stands on the first catcher's plane, but the scene \
             has no triangle catcher"
                .to_string()
        })?;
    Ok((tri[0], (tri[1] - tri[0]).cross(tri[2] - tri[0])))
}

/// `scene` with the proxies of `o` (built from the measured points `pts`) added, every face a
/// planar shadow catcher; and a report (proxies made, catcher faces). An error names the
/// param or the proxy that cannot be built.
pub fn add_proxies(
    scene: &Scene,
    pts: &[Vec3],
    o: &ProxyOptions,
) -> Result<(Scene, serde_json::Value), String> {
    if o.boxes.is_empty() && o.tops.is_empty() && o.planes.is_empty() {
        return Err(
            "no proxies: give `boxes`, `planes` (4 point indices each) and/or `tops` (3)".into(),
        );
    }
    if o.albedo.len() != 3 || o.albedo.iter().any(|a| !(0.0..=1.0).contains(a)) {
        return Err("param `albedo`: 3 values in [0, 1]".into());
    }
    let albedo = Rgb::new(o.albedo[0], o.albedo[1], o.albedo[2]);
    let mut out = scene.clone();
    let mut faces = 0;
    for (g, q) in groups(pts, &o.boxes, "boxes", 4)?.iter().enumerate() {
        let f = box_faces(q).map_err(|e| format!("box {g}: {e}"))?;
        faces += f.len();
        out.objects.extend(catchers(f, albedo));
    }
    let tops = groups(pts, &o.tops, "tops", 3)?;
    if !tops.is_empty() {
        let (origin, normal) = ground_plane(scene)?;
        for (g, q) in tops.iter().enumerate() {
            let f = box_on_plane(q, origin, normal).map_err(|e| format!("tops box {g}: {e}"))?;
            faces += f.len();
            out.objects.extend(catchers(f, albedo));
        }
    }
    for (g, q) in groups(pts, &o.planes, "planes", 4)?.iter().enumerate() {
        let f = plane_patch(q).map_err(|e| format!("plane {g}: {e}"))?;
        faces += 1;
        out.objects.extend(catchers(vec![f], albedo));
    }
    let report = serde_json::json!({
        "boxes": o.boxes.len() / 4 + o.tops.len() / 3,
        "planes": o.planes.len() / 4,
        "catcher_faces": faces,
    });
    Ok((out, report))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_box_from_four_points_has_the_measured_size() {
        let v = Vec3::new;
        let faces = box_faces(&[
            v(0.0, 0.0, 0.0),
            v(2.0, 0.0, 0.0),
            v(2.0, 1.0, 0.0),
            v(0.0, 0.0, 0.5),
        ])
        .unwrap();
        assert_eq!(faces.len(), 5);
        // Total area: top 2 + sides 2·(2·0.5) + 2·(1·0.5) = 5.
        let area: f64 = faces
            .iter()
            .flatten()
            .map(|t| 0.5 * (t[1] - t[0]).cross(t[2] - t[0]).length())
            .sum();
        assert!((area - 5.0).abs() < 1e-12, "{area}");
        assert!(faces[0].iter().flatten().all(|p| (p.z - 0.5).abs() < 1e-12));
    }

    #[test]
    fn a_box_from_its_top_stands_on_the_plane() {
        let v = Vec3::new;
        let top = [v(0.0, 0.0, 0.5), v(2.0, 0.0, 0.5), v(2.0, 1.0, 0.5)];
        let a = box_on_plane(&top, v(0.0, 0.0, 0.0), v(0.0, 0.0, -3.0)).unwrap();
        let b = box_faces(&[
            v(0.0, 0.0, 0.0),
            v(2.0, 0.0, 0.0),
            v(2.0, 1.0, 0.0),
            v(0.0, 0.0, 0.5),
        ])
        .unwrap();
        assert_eq!(a, b);
        // A tilted top (measurement noise): the base is its projection onto the plane, the top
        // flat at the first corner's height.
        let top = [v(0.0, 0.0, 0.5), v(2.0, 0.0, 0.6), v(2.0, 1.0, 0.6)];
        let faces = box_on_plane(&top, v(0.0, 0.0, 0.0), v(0.0, 0.0, 1.0)).unwrap();
        for side in &faces[1..] {
            let z: Vec<f64> = side.iter().flatten().map(|p| p.z).collect();
            assert!(
                z.iter().all(|z| z.abs() < 1e-12 || (z - 0.5).abs() < 1e-12),
                "{z:?}"
            );
            assert!(z.iter().any(|z| z.abs() < 1e-12), "{z:?}");
        }
        let e = box_on_plane(&top[..2], v(0.0, 0.0, 0.0), v(0.0, 0.0, 1.0)).unwrap_err();
        assert_eq!(e.to_string(), "a box needs 3 measured points, found 2");
        let e = box_on_plane(&top, v(0.0, 0.0, 0.5), v(0.0, 0.0, 1.0)).unwrap_err();
        assert!(e.to_string().contains("zero height"), "{e}");
    }

    #[test]
    fn too_few_or_degenerate_points_are_errors() {
        let v = Vec3::new;
        let e = box_faces(&[v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(1.0, 1.0, 0.0)]).unwrap_err();
        assert_eq!(e.to_string(), "a box needs 4 measured points, found 3");
        let e = plane_patch(&[v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0)]).unwrap_err();
        assert!(e.to_string().contains("needs 4"), "{e}");
        let e = plane_patch(&[
            v(0.0, 0.0, 0.0),
            v(1.0, 0.0, 0.0),
            v(2.0, 0.0, 0.0),
            v(0.0, 1.0, 0.0),
        ])
        .unwrap_err();
        assert!(e.to_string().contains("collinear"), "{e}");
        let e = plane_patch(&[
            v(0.0, 0.0, 0.0),
            v(1.0, 0.0, 0.0),
            v(1.0, 1.0, 0.0),
            v(0.0, 1.0, 0.5),
        ])
        .unwrap_err();
        assert!(e.to_string().contains("off the plane"), "{e}");
        let e = box_faces(&[
            v(0.0, 0.0, 0.0),
            v(1.0, 0.0, 0.0),
            v(1.0, 1.0, 0.0),
            v(3.0, 0.0, 0.0),
        ])
        .unwrap_err();
        assert!(e.to_string().contains("zero height"), "{e}");
    }
}
