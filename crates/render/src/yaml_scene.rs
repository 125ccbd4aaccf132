//! The YAML scene format for new work (the book's `.scn` concepts, §9.13 and §10, in YAML), with
//! Wavefront OBJ meshes ([`crate::obj`]). Errors carry line:column of the offending value.
//!
//! ```yaml
//! camera:                       # optional; look_at (fov: HORIZONTAL degrees, as .scn's view) …
//!   look_at: {from: [0, 1, 4], at: [0, 0.5, 0], up: [0, 1, 0], fov: 50}
//!   size: [640, 360]
//!   # … or a calibrated camera x ~ K(RX + t) (book §2.8): K, R as 3 rows, t
//!   # K: [[800, 0, 319.5], [0, 800, 179.5], [0, 0, 1]]
//!   # R: [[1, 0, 0], [0, 1, 0], [0, 0, 1]]
//!   # t: [0, 0, 5]
//! materials:                    # named materials (objects may also inline one)
//!   red:    {type: lambert, albedo: [0.8, 0.1, 0.1]}
//!   chrome: {type: mirror, reflectance: [0.9, 0.9, 0.9]}
//!   gloss:  {type: plastic, kd: 0.5, ks: 0.4, se: 40, d_col: [1, 1, 1], s_col: [1, 1, 1]}
//!   bp:     {type: blinn_phong, diffuse: [0.4, 0.4, 0.4], specular: [0.3, 0.3, 0.3], exponent: 30}
//! objects:                      # each: one shape key, a material, optional catcher/transform
//!   - sphere: {center: [0, 0.5, 0], radius: 0.5}
//!     material: red
//!   - quad: {corner: [-5, 0, -5], edge1: [10, 0, 0], edge2: [0, 0, 10]}
//!     material: {type: lambert, albedo: [0.5, 0.5, 0.5]}
//!     catcher: true             # a shadow catcher (S3D plshadow)
//!     texture: {type: cells, size: 0.2, contrast: 0.8, seed: 1}   # or {type: checker, size, contrast}
//!   - polygon: [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]   # convex, fanned
//!   - triangles: [[[0, 0, 0], [1, 0, 0], [0, 1, 0]]]
//!   - obj: mesh.obj             # relative to the scene file
//!     transform: {scale: 0.5, rotate: [0, 90, 0], translate: [1, 0, 0]}
//! lights:                       # polygonal area lights, two-sided, radiance in W/(sr·m²)
//!   - radiance: [10, 10, 10]
//!     quad: {corner: [-0.5, 3, -0.5], edge1: [1, 0, 0], edge2: [0, 0, 1]}
//! dome:                         # an HDR light dome (book §10) …
//!   image: studio.hdr           # equirectangular; relative to the scene file
//!   orientation: y_up           # y_up (default) | {orig: [...], south: [...]} (book 10.7)
//!   scale: 1.0
//!   # … or a constant colour: color: [0.5, 0.5, 0.5]
//! ```
//!
//! `camera` may be left out when the scene is only seen through cameras from elsewhere: a
//! solved camera path (the `cameras` input of `render`, `differential_render`, `fit_catcher`)
//! whose K — or the `intrinsics` input — carries the image size. Where a camera is needed and
//! nothing supplies one, the node that needs it says so ([`crate::scene::Scene::camera`]).
//!
//! Meanings: `texture` is a solid texture ([`crate::texture`]) multiplying the diffuse albedo by
//! a factor in [1 − contrast, 1] (`cells`: random per-cell levels on a 3-D grid of side `size`,
//! grey or per channel with `color: true`; `checker`: two levels); `lambert.albedo` ρ; `mirror.reflectance`; `blinn_phong` is the normalized lobe of
//! [`crate::brdf::BlinnPhong`] (diffuse and specular albedos, exponent); `plastic` has exactly
//! the `.scn` meaning ([`crate::scn::plastic`]: ρd = kd·d_col, ρs = ks·s_col, se < 0 a mirror).
//! Light `radiance` is physical (no π factor, unlike `.scn` polylight colours). Transforms
//! apply to mesh shapes (`quad`, `polygon`, `triangles`, `obj`) as scale, then rotations about
//! x, y, z (degrees), then translation. The image file of the dome is named, not loaded: the
//! caller loads it (see [`crate::scene::DomeSpec`]). The world is y-up by convention (the
//! default dome orientation), but any up works with an explicit orientation.

use std::path::{Path, PathBuf};

use crate::brdf::{BlinnPhong, Brdf, Lambert, Mirror};
use crate::camera::Camera;
use crate::math::{Rgb, Vec3};
use crate::obj::parse_obj;
use crate::scene::{AreaLight, DomeSpec, Object, Scene, Shape};
use crate::scn::plastic;
use crate::shape::Sphere;
use crate::texture::Texture;

mod tree;

use tree::{err, parse_tree, Fields, Kind, Node, R};

/// A YAML scene error at a 1-based line and column.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{line}:{col}: {message}")]
pub struct YamlSceneError {
    /// Line (1-based).
    pub line: usize,
    /// Column (1-based, in characters).
    pub col: usize,
    /// What is wrong.
    pub message: String,
}

/// A scene read from YAML and the files it references (OBJ meshes, the dome image), resolved
/// against the scene file's folder.
#[derive(Clone, Debug)]
pub struct YamlScene {
    /// The scene (`dome.image` as written in the file).
    pub scene: Scene,
    /// Every file the scene names, resolved.
    pub files: Vec<PathBuf>,
}

/// The largest image side a scene's camera may ask for.
const MAX_SIDE: f64 = 65536.0;

fn camera(n: &Node) -> R<Camera> {
    let f = n.fields("camera", &["look_at", "size", "K", "R", "t"])?;
    let [w, h] = f.req("size")?.nums::<2>("size")?;
    if !(w >= 1.0 && h >= 1.0 && w.fract() == 0.0 && h.fract() == 0.0) {
        return err(
            f.req("size")?,
            format!("size: two positive whole numbers [width, height], not [{w}, {h}]"),
        );
    }
    if w > MAX_SIDE || h > MAX_SIDE {
        return err(
            f.req("size")?,
            format!("size: [{w}, {h}] is over the largest image side, {MAX_SIDE}"),
        );
    }
    let (w, h) = (w as usize, h as usize);
    match (f.get("look_at"), f.get("K")) {
        (Some(la), None) => {
            for k in ["R", "t"] {
                if let Some(x) = f.get(k) {
                    return err(
                        x,
                        format!("camera: `{k}` goes with `K`, not with `look_at`"),
                    );
                }
            }
            let g = la.fields("look_at", &["from", "at", "up", "fov"])?;
            let up = g
                .get("up")
                .map_or(Ok(Vec3::new(0.0, 1.0, 0.0)), |u| u.vec3("up"))?;
            Camera::look_at(
                g.req("from")?.vec3("from")?,
                g.req("at")?.vec3("at")?,
                up,
                g.num_or("fov", 50.0)?,
                w,
                h,
            )
            .or_else(|e| err(la, e.to_string()))
        }
        (None, Some(k)) => {
            let r = f.req("R")?.mat3("R")?;
            let t = f.req("t")?.nums::<3>("t")?;
            Camera::from_krt(k.mat3("K")?, r, t, w, h).or_else(|e| err(n, e.to_string()))
        }
        (Some(_), Some(k)) => err(k, "camera: give either `look_at` or `K`/`R`/`t`, not both"),
        (None, None) => err(n, "camera: needs `look_at` or `K`, `R`, `t`"),
    }
}

fn material(n: &Node) -> R<Brdf> {
    let Kind::Map(m) = &n.kind else {
        return err(
            n,
            format!("material: expected a mapping, found {}", n.describe()),
        );
    };
    let ty = m
        .iter()
        .find(|(k, _)| matches!(&k.kind, Kind::Scalar(s, _) if s == "type"))
        .map(|(_, v)| v)
        .ok_or(YamlSceneError {
            line: n.line,
            col: n.col,
            message: "material: missing `type` (lambert, mirror, plastic, blinn_phong)".into(),
        })?;
    match ty.str("type")? {
        "lambert" => {
            let f = n.fields("lambert", &["type", "albedo"])?;
            let albedo = f.rgb_or("albedo", Rgb::splat(0.8))?;
            if albedo.max_component() > 1.0 {
                return err(f.req("albedo")?, "albedo must be ≤ 1");
            }
            Ok(Brdf::Lambert(Lambert { albedo }))
        }
        "mirror" => {
            let f = n.fields("mirror", &["type", "reflectance"])?;
            let reflectance = f.rgb_or("reflectance", Rgb::WHITE)?;
            if reflectance.max_component() > 1.0 {
                return err(f.req("reflectance")?, "reflectance must be ≤ 1");
            }
            Ok(Brdf::Mirror(Mirror { reflectance }))
        }
        "plastic" => {
            let f = n.fields("plastic", &["type", "kd", "ks", "se", "d_col", "s_col"])?;
            let (kd, ks) = (f.num_or("kd", 0.9)?, f.num_or("ks", 0.0)?);
            for (k, v) in [("kd", kd), ("ks", ks)] {
                if v < 0.0 {
                    return err(f.req(k)?, format!("{k} must be ≥ 0"));
                }
            }
            Ok(plastic(
                kd,
                ks,
                f.num_or("se", 10.0)?,
                f.rgb_or("d_col", Rgb::WHITE)?,
                f.rgb_or("s_col", Rgb::WHITE)?,
            ))
        }
        "blinn_phong" => {
            let f = n.fields("blinn_phong", &["type", "diffuse", "specular", "exponent"])?;
            let diffuse = f.rgb_or("diffuse", Rgb::splat(0.5))?;
            let specular = f.rgb_or("specular", Rgb::splat(0.3))?;
            let exponent = f.num_or("exponent", 20.0)?;
            if (diffuse + specular).max_component() > 1.0 {
                return err(n, "blinn_phong: diffuse + specular must be ≤ 1 per channel");
            }
            if exponent < 0.0 {
                return err(f.req("exponent")?, "exponent must be ≥ 0");
            }
            Ok(Brdf::BlinnPhong(BlinnPhong {
                diffuse,
                specular,
                exponent,
            }))
        }
        other => err(
            ty,
            format!(
                "unknown material type `{other}`; expected lambert, mirror, plastic or blinn_phong"
            ),
        ),
    }
}

/// A solid texture on the diffuse albedo ([`crate::texture`]).
fn texture(n: &Node) -> R<Texture> {
    let Kind::Map(m) = &n.kind else {
        return err(
            n,
            format!("texture: expected a mapping, found {}", n.describe()),
        );
    };
    let ty = m
        .iter()
        .find(|(k, _)| matches!(&k.kind, Kind::Scalar(s, _) if s == "type"))
        .map(|(_, v)| v)
        .ok_or(YamlSceneError {
            line: n.line,
            col: n.col,
            message: "texture: missing `type` (cells, checker)".into(),
        })?;
    let t = match ty.str("type")? {
        "cells" => {
            let f = n.fields("cells", &["type", "size", "contrast", "seed", "color"])?;
            let seed = f.num_or("seed", 0.0)?;
            if seed < 0.0 || seed.fract() != 0.0 || seed > 9.0e15 {
                return err(f.req("seed")?, "seed: a whole number ≥ 0");
            }
            Texture::Cells {
                size: f.req("size")?.num("size")?,
                contrast: f.num_or("contrast", 0.8)?,
                seed: seed as u64,
                color: f.get("color").map_or(Ok(false), |c| c.bool("color"))?,
            }
        }
        "checker" => {
            let f = n.fields("checker", &["type", "size", "contrast"])?;
            Texture::Checker {
                size: f.req("size")?.num("size")?,
                contrast: f.num_or("contrast", 0.8)?,
            }
        }
        other => {
            return err(
                ty,
                format!("unknown texture type `{other}`; expected cells or checker"),
            )
        }
    };
    t.validate().or_else(|e| err(n, e))?;
    Ok(t)
}

/// Scale, then rotations about x, y, z (degrees), then translation.
struct Transform {
    scale: Vec3,
    rot: [[f64; 3]; 3],
    translate: Vec3,
}

impl Transform {
    fn parse(n: &Node) -> R<Transform> {
        let f = n.fields("transform", &["scale", "rotate", "translate"])?;
        let scale = match f.get("scale") {
            None => Vec3::new(1.0, 1.0, 1.0),
            Some(
                s @ Node {
                    kind: Kind::Scalar(..),
                    ..
                },
            ) => {
                let v = s.num("scale")?;
                Vec3::new(v, v, v)
            }
            Some(s) => s.vec3("scale")?,
        };
        if scale.x * scale.y * scale.z == 0.0 {
            return err(f.req("scale")?, "scale must not be zero");
        }
        let r = f
            .get("rotate")
            .map_or(Ok(Vec3::ZERO), |r| r.vec3("rotate"))?;
        let (sx, cx) = r.x.to_radians().sin_cos();
        let (sy, cy) = r.y.to_radians().sin_cos();
        let (sz, cz) = r.z.to_radians().sin_cos();
        let rx = [[1.0, 0.0, 0.0], [0.0, cx, -sx], [0.0, sx, cx]];
        let ry = [[cy, 0.0, sy], [0.0, 1.0, 0.0], [-sy, 0.0, cy]];
        let rz = [[cz, -sz, 0.0], [sz, cz, 0.0], [0.0, 0.0, 1.0]];
        let rot = mul(&rz, &mul(&ry, &rx));
        Ok(Transform {
            scale,
            rot,
            translate: f
                .get("translate")
                .map_or(Ok(Vec3::ZERO), |t| t.vec3("translate"))?,
        })
    }
    fn apply(&self, p: Vec3) -> Vec3 {
        let s = Vec3::new(p.x * self.scale.x, p.y * self.scale.y, p.z * self.scale.z);
        let m = &self.rot;
        Vec3::new(
            m[0][0] * s.x + m[0][1] * s.y + m[0][2] * s.z,
            m[1][0] * s.x + m[1][1] * s.y + m[1][2] * s.z,
            m[2][0] * s.x + m[2][1] * s.y + m[2][2] * s.z,
        ) + self.translate
    }
}

fn mul(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut o = [[0.0; 3]; 3];
    for (i, row) in o.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    o
}

const SHAPES: [&str; 5] = ["sphere", "quad", "polygon", "triangles", "obj"];

/// The one shape key of an object or light mapping.
fn shape(
    f: &Fields<'_>,
    owner: &Node,
    dir: &Path,
    files: &mut Vec<PathBuf>,
    allow_sphere: bool,
) -> R<Shape> {
    let present: Vec<&str> = SHAPES
        .iter()
        .copied()
        .filter(|k| f.get(k).is_some())
        .collect();
    let key = match present[..] {
        [k] => k,
        [] => {
            return err(
                owner,
                format!("needs a shape: one of {}", SHAPES.join(", ")),
            )
        }
        _ => {
            return err(
                owner,
                format!("one shape per entry, found {}", present.join(" and ")),
            )
        }
    };
    let n = f.req(key)?;
    let tris: Vec<[Vec3; 3]> = match key {
        "sphere" => {
            if !allow_sphere {
                return err(
                    n,
                    "lights are polygons: use quad, polygon, triangles or obj",
                );
            }
            if let Some(t) = f.get("transform") {
                return err(
                    t,
                    "transform applies to meshes; move the sphere's center instead",
                );
            }
            let g = n.fields("sphere", &["center", "radius"])?;
            let radius = g.req("radius")?.num("radius")?;
            if radius <= 0.0 {
                return err(g.req("radius")?, "radius must be > 0");
            }
            return Ok(Shape::Sphere(Sphere {
                center: g.req("center")?.vec3("center")?,
                radius,
            }));
        }
        "quad" => {
            let g = n.fields("quad", &["corner", "edge1", "edge2"])?;
            let c = g.req("corner")?.vec3("corner")?;
            let a = c + g.req("edge1")?.vec3("edge1")?;
            let b = c + g.req("edge2")?.vec3("edge2")?;
            let d = a + (b - c);
            vec![[c, a, d], [c, d, b]]
        }
        "polygon" => {
            let pts = n
                .list("polygon")?
                .iter()
                .map(|p| p.vec3("polygon vertex"))
                .collect::<R<Vec<_>>>()?;
            if pts.len() < 3 {
                return err(n, "a polygon needs at least 3 vertices");
            }
            (1..pts.len() - 1)
                .map(|j| [pts[0], pts[j], pts[j + 1]])
                .collect()
        }
        "triangles" => n
            .list("triangles")?
            .iter()
            .map(|t| {
                let v = t.list("triangle")?;
                if v.len() != 3 {
                    return err(t, format!("a triangle has 3 vertices, found {}", v.len()));
                }
                Ok([
                    v[0].vec3("vertex")?,
                    v[1].vec3("vertex")?,
                    v[2].vec3("vertex")?,
                ])
            })
            .collect::<R<Vec<_>>>()?,
        _ => {
            let name = n.str("obj")?;
            let path = dir.join(name);
            let text = std::fs::read_to_string(&path)
                .or_else(|e| err(n, format!("cannot read {}: {e}", path.display())))?;
            let tris = parse_obj(&text).or_else(|e| err(n, format!("{}:{e}", path.display())))?;
            if tris.is_empty() {
                return err(n, format!("{} has no faces", path.display()));
            }
            files.push(path);
            tris
        }
    };
    let tris = match f.get("transform") {
        Some(t) => {
            let tr = Transform::parse(t)?;
            tris.iter()
                .map(|t| [tr.apply(t[0]), tr.apply(t[1]), tr.apply(t[2])])
                .collect()
        }
        None => tris,
    };
    Ok(Shape::Triangles { triangles: tris })
}

fn dome(n: &Node, dir: &Path, scene: &mut Scene, files: &mut Vec<PathBuf>) -> R<()> {
    let f = n.fields("dome", &["image", "orientation", "scale", "color"])?;
    match (f.get("image"), f.get("color")) {
        (Some(img), None) => {
            let image = img.str("image")?.to_string();
            let (orig, south) = match f.get("orientation") {
                None => (Vec3::new(0.0, 0.0, -1.0), Vec3::new(0.0, 1.0, 0.0)),
                Some(
                    o @ Node {
                        kind: Kind::Scalar(..),
                        ..
                    },
                ) => match o.str("orientation")? {
                    "y_up" => (Vec3::new(0.0, 0.0, -1.0), Vec3::new(0.0, 1.0, 0.0)),
                    "z_up" => (Vec3::new(0.0, -1.0, 0.0), Vec3::new(0.0, 0.0, 1.0)),
                    other => {
                        return err(
                            o,
                            format!(
                                "orientation `{other}`: expected y_up, z_up or {{orig, south}}"
                            ),
                        )
                    }
                },
                Some(o) => {
                    let g = o.fields("orientation", &["orig", "south"])?;
                    (g.req("orig")?.vec3("orig")?, g.req("south")?.vec3("south")?)
                }
            };
            let scale = f.num_or("scale", 1.0)?;
            if scale < 0.0 {
                return err(f.req("scale")?, "scale must be ≥ 0");
            }
            files.push(dir.join(&image));
            scene.dome = Some(DomeSpec {
                orig,
                south,
                image,
                scale,
            });
        }
        (None, Some(c)) => {
            for k in ["orientation", "scale"] {
                if let Some(x) = f.get(k) {
                    return err(x, format!("`{k}` applies to an image dome"));
                }
            }
            scene.background = c.rgb("color")?;
        }
        (Some(_), Some(c)) => return err(c, "dome: give `image` or `color`, not both"),
        (None, None) => return err(n, "dome: needs `image` or `color`"),
    }
    Ok(())
}

/// Parses a YAML scene; OBJ files are read relative to `dir` (the scene file's folder).
pub fn parse_yaml_scene(text: &str, dir: &Path) -> Result<YamlScene, YamlSceneError> {
    let root = parse_tree(text)?;
    let top = root.fields(
        "scene",
        &["camera", "materials", "objects", "lights", "dome"],
    )?;
    let mut files = Vec::new();
    let mut scene = Scene {
        camera: top.get("camera").map(camera).transpose()?,
        objects: Vec::new(),
        lights: Vec::new(),
        background: Rgb::BLACK,
        dome: None,
    };
    let mut named: Vec<(String, Brdf)> = Vec::new();
    if let Some(m) = top.get("materials") {
        let Kind::Map(entries) = &m.kind else {
            return err(m, "materials: expected a mapping of name: {type: …}");
        };
        for (k, v) in entries {
            let name = k.str("material name")?.to_string();
            if named.iter().any(|(n, _)| *n == name) {
                return err(k, format!("duplicate material `{name}`"));
            }
            named.push((name, material(v)?));
        }
    }
    if let Some(objs) = top.get("objects") {
        for o in objs.list("objects")? {
            let mut keys = vec!["material", "catcher", "transform", "texture"];
            keys.extend(SHAPES);
            let f = o.fields("object", &keys)?;
            let material = match f.get("material") {
                None => Brdf::Lambert(Lambert {
                    albedo: Rgb::splat(0.8),
                }),
                Some(
                    m @ Node {
                        kind: Kind::Scalar(..),
                        ..
                    },
                ) => {
                    let name = m.str("material")?;
                    named
                        .iter()
                        .find(|(n, _)| n == name)
                        .map(|(_, b)| *b)
                        .ok_or(YamlSceneError {
                            line: m.line,
                            col: m.col,
                            message: format!("unknown material `{name}`"),
                        })?
                }
                Some(m) => material(m)?,
            };
            let catcher = f.get("catcher").map_or(Ok(false), |c| c.bool("catcher"))?;
            let mut object = Object::new(shape(&f, o, dir, &mut files, true)?, material);
            object.catcher = catcher;
            object.texture = f.get("texture").map(texture).transpose()?;
            scene.objects.push(object);
        }
    }
    if let Some(ls) = top.get("lights") {
        for l in ls.list("lights")? {
            let mut keys = vec!["radiance", "transform"];
            keys.extend(SHAPES);
            let f = l.fields("light", &keys)?;
            let radiance = f.req("radiance")?.rgb("radiance")?;
            let Shape::Triangles { triangles } = shape(&f, l, dir, &mut files, false)? else {
                return err(l, "lights are polygons");
            };
            scene.lights.push(AreaLight {
                radiance,
                triangles,
            });
        }
    }
    if let Some(d) = top.get("dome") {
        dome(d, dir, &mut scene, &mut files)?;
    }
    Ok(YamlScene { scene, files })
}

#[cfg(test)]
mod tests;
