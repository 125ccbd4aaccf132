//! The two placing operations (book chapter 8 and §10.10) with their options: [`place_scene`]
//! moves a designed scene onto measured points by the similarity between its anchors and them;
//! [`catcher_from_points`] builds the shadow catcher through measured ground points and sets
//! objects designed in the catcher's own frame on it (resting them on the ground on request).

use nalgebra::Vector3;
use serde_json::json;
use vfxgraph_imaging::Image;

use super::{
    catcher_polygon, first_catcher_vertices, transform_scene, umeyama, CatcherPolygon,
    SimilarityFit,
};
use crate::brdf::{Brdf, Lambert};
use crate::camera::Camera;
use crate::dome::Dome;
use crate::math::{Rgb, Vec3};
use crate::scene::{Object, Scene, Shape};

/// What a designed scene's anchors are.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, vfxgraph_params::Choice)]
pub enum Anchors {
    /// The first shadow catcher's vertices A, B, C, in order.
    #[default]
    Catcher,
    /// The points listed in [`PlaceOptions::anchor_points`].
    Points,
}

/// The `place_scene` operation's options.
#[derive(Clone, Debug, PartialEq, vfxgraph_params::Options)]
#[param(check)]
pub struct PlaceOptions {
    /// `catcher`: the first catcher's vertices A, B, C; `points`: the `anchor_points` param
    pub anchors: Anchors,
    /// anchors in the scene's coordinates, x y z per point (with `anchors: points`)
    pub anchor_points: Vec<f64>,
    /// which measured points pair with the anchors, in order (0-based; default all)
    pub indices: Vec<f64>,
    /// largest accepted RMS anchor residual over the RMS spread of the measured points
    #[param(range = 0.0..=1e6)]
    pub max_residual: f64,
    /// negate the dome's `south` after placing: the book's `south` is the HDR camera's
    /// image-down axis (book §10.8), which points at the ground in modeling.scn, so an image
    /// with the sky on its top row (Poly Haven's) needs it negated to keep the sky up
    pub flip_dome: bool,
}

impl Default for PlaceOptions {
    fn default() -> Self {
        PlaceOptions {
            anchors: Anchors::Catcher,
            anchor_points: vec![],
            indices: vec![],
            max_residual: 0.05,
            flip_dome: false,
        }
    }
}

impl PlaceOptions {
    /// `anchor_points` only with `anchors: points`, and then x y z per anchor.
    pub fn check(&self) -> Result<(), String> {
        let n = self.anchor_points.len();
        match self.anchors {
            Anchors::Catcher if n > 0 => Err(format!(
                "`anchor_points` is set ({n} numbers) but `anchors` is `catcher`: set \
                 `anchors: points` to use them"
            )),
            Anchors::Points if !n.is_multiple_of(3) || n == 0 => Err(format!(
                "`anchor_points` needs x y z per anchor (a multiple of 3 numbers), got {n}"
            )),
            _ => Ok(()),
        }
    }
}

/// The `catcher_from_points` operation's options.
#[derive(Clone, Debug, PartialEq, vfxgraph_params::Options)]
pub struct CatcherOptions {
    /// which measured points are ground points, in order (0-based; default all)
    pub indices: Vec<f64>,
    /// grow the polygon about its centre by this fraction (0: through the points)
    #[param(range = -0.99..=100.0)]
    pub margin: f64,
    /// largest distance of a ground point from their plane, over the polygon's size
    #[param(range = 0.0..=1.0)]
    pub planarity: f64,
    /// the catcher's diffuse albedo, linear RGB
    pub color: [f64; 3],
    /// move each designed object along y so its lowest point is on the ground
    pub rest: bool,
    /// negate the placed dome's `south` (see place_scene)
    pub flip_dome: bool,
}

impl Default for CatcherOptions {
    fn default() -> Self {
        CatcherOptions {
            indices: vec![],
            margin: 0.0,
            planarity: 0.02,
            // modeling.scn's plshadow colour
            color: [0.576563, 0.539570, 0.466020],
            rest: true,
            flip_dome: false,
        }
    }
}

/// The measured points, checked finite, picked by `indices` (integers; empty: all).
pub fn pick_points(points: &[Vec3], indices: &[f64]) -> Result<Vec<Vec3>, String> {
    if let Some(i) = points.iter().position(|p| !p.is_finite()) {
        return Err(format!("measured point {i} of `points3d` is not finite"));
    }
    if indices.is_empty() {
        return Ok(points.to_vec());
    }
    indices
        .iter()
        .map(|&i| {
            if i.fract() != 0.0 || i < 0.0 || i as usize >= points.len() {
                Err(format!(
                    "param `indices`: {i} is not the index of one of the {} measured points \
                     (0-based integers)",
                    points.len()
                ))
            } else {
                Ok(points[i as usize])
            }
        })
        .collect()
}

/// A designed scene's dome image, if any: `replacement` (scaled by the dome's `scale`) or the
/// `loaded` dome's image, oriented by the (moved) scene's dome spec. `None` without an image.
pub fn placed_dome(
    scene: &Scene,
    loaded: Option<&Dome>,
    replacement: Option<&Image>,
) -> Result<Option<Dome>, String> {
    let image = match (replacement, loaded) {
        (Some(img), _) => img,
        (None, Some(d)) => d.image(),
        (None, None) => return Ok(None),
    };
    let Some(spec) = &scene.dome else {
        return Err(
            "`dome_image` is connected but the scene has no dome to orient it (a `.scn` \
             hdrdome or a YAML `dome:`)"
                .into(),
        );
    };
    let v = |p: Vec3| Vector3::new(p.x, p.y, p.z);
    let mut img = image.clone();
    if replacement.is_some() && spec.scale != 1.0 {
        let k = spec.scale as f32;
        img.data.iter_mut().for_each(|x| *x *= k);
    }
    Ok(Some(
        Dome::new(&img, v(spec.orig), v(spec.south)).map_err(|e| e.to_string())?,
    ))
}

fn flip_dome(scene: &mut Scene, flip: bool) {
    if let (true, Some(d)) = (flip, scene.dome.as_mut()) {
        d.south = -d.south;
    }
}

/// A designed scene with its (optional) loaded dome and replacement dome image.
#[derive(Clone, Copy)]
pub struct Design<'a> {
    /// The scene.
    pub scene: &'a Scene,
    /// Its dome, loaded from the scene's image.
    pub dome: Option<&'a Dome>,
}

/// What [`place_scene`] made.
#[derive(Clone, Debug)]
pub struct PlacedScene {
    /// The scene in the measured points' frame.
    pub scene: Scene,
    /// Its dome, oriented (`None` without an image).
    pub dome: Option<Dome>,
    /// The anchors, in the designed scene's coordinates.
    pub anchors: Vec<Vec3>,
    /// The measured points they were fitted to.
    pub measured: Vec<Vec3>,
    /// The fit.
    pub fit: SimilarityFit,
}

impl PlacedScene {
    /// What the `place_scene` node reports: the similarity (scale, rotation, its angle,
    /// translation), the anchors, the measured points, the anchors placed, the residuals, the
    /// relative RMS and the dome's orig/south.
    pub fn report(&self) -> serde_json::Value {
        let s = &self.fit.similarity;
        let r = &s.rotation;
        json!({
            "similarity": {
                "scale": s.scale,
                "rotation": [[r[(0,0)], r[(0,1)], r[(0,2)]], [r[(1,0)], r[(1,1)], r[(1,2)]],
                             [r[(2,0)], r[(2,1)], r[(2,2)]]],
                "rotation_deg": s.angle_deg(),
                "translation": [s.translation.x, s.translation.y, s.translation.z],
            },
            "anchors": rows(&self.anchors),
            "measured": rows(&self.measured),
            "placed_anchors": self.anchors.iter().map(|a| row(s.point(*a))).collect::<Vec<_>>(),
            "residuals": self.fit.residuals,
            "relative_rms": self.fit.relative_rms,
            "dome": self.scene.dome.as_ref().map(|d| json!({"orig": row(d.orig), "south": row(d.south)})),
        })
    }
}

fn row(v: Vec3) -> [f64; 3] {
    [v.x, v.y, v.z]
}

fn rows(v: &[Vec3]) -> Vec<[f64; 3]> {
    v.iter().map(|a| row(*a)).collect()
}

/// Moves a designed scene onto measured points (module docs): the similarity (Umeyama 1991)
/// from its anchors to `points` (picked by `indices`), refused when its relative RMS residual
/// exceeds `max_residual`, applied to the whole scene and its dome.
pub fn place_scene(
    design: Design<'_>,
    dome_image: Option<&Image>,
    points: &[Vec3],
    o: &PlaceOptions,
) -> Result<PlacedScene, String> {
    let anchors: Vec<Vec3> = match o.anchors {
        Anchors::Catcher => first_catcher_vertices(design.scene)
            .ok_or(
                "`anchors: catcher` but the scene has no triangle shadow catcher (plshadow / \
                 `catcher: true`): give `anchors: points` and `anchor_points`",
            )?
            .to_vec(),
        Anchors::Points => o
            .anchor_points
            .chunks_exact(3)
            .map(|c| Vec3::new(c[0], c[1], c[2]))
            .collect(),
    };
    let measured = pick_points(points, &o.indices)?;
    let fit = umeyama(&anchors, &measured).map_err(|e| e.to_string())?;
    let max = o.max_residual;
    if fit.relative_rms.is_nan() || fit.relative_rms > max {
        return Err(format!(
            "the anchors do not match the measured points: RMS residual {:.4} of their spread \
             (limit `max_residual` {max}); residuals {:?} — check the anchor order against the \
             marks",
            fit.relative_rms, fit.residuals
        ));
    }
    let mut scene = transform_scene(design.scene, &fit.similarity);
    flip_dome(&mut scene, o.flip_dome);
    if let Some(c) = &scene.camera {
        c.validate().map_err(|e| format!("the moved camera: {e}"))?;
    }
    let dome = placed_dome(&scene, design.dome, dome_image)?;
    Ok(PlacedScene {
        scene,
        dome,
        anchors,
        measured,
        fit,
    })
}

/// Lifts each non-catcher object so its lowest point is at y = 0 (catcher frame).
pub fn rest_on_ground(scene: &mut Scene) {
    for o in scene.objects.iter_mut().filter(|o| !o.catcher) {
        match &mut o.shape {
            Shape::Sphere(s) => s.center.y = s.radius,
            Shape::Triangles { triangles } => {
                let low = triangles
                    .iter()
                    .flatten()
                    .map(|v| v.y)
                    .fold(f64::INFINITY, f64::min);
                if low.is_finite() {
                    triangles.iter_mut().flatten().for_each(|v| v.y -= low);
                }
            }
        }
    }
}

/// The cameras that look at a catcher: their centres (the ground's normal faces them) and,
/// for a catcher without a designed scene, the view of its output scene.
#[derive(Clone, Debug, Default)]
pub struct Viewers {
    /// The camera centres (empty: no cameras).
    pub centres: Vec<Vec3>,
    /// The first camera, when its intrinsics are known.
    pub first: Option<Camera>,
}

/// What [`catcher_from_points`] made.
#[derive(Clone, Debug)]
pub struct PlacedCatcher {
    /// The catcher (first object) and the placed objects, in the measured points' frame.
    pub scene: Scene,
    /// The designed scene's dome, oriented (`None` without an image).
    pub dome: Option<Dome>,
    /// The catcher polygon and its frame.
    pub polygon: CatcherPolygon,
    /// Whether the ground's normal was turned towards the cameras.
    pub faces_cameras: bool,
}

impl PlacedCatcher {
    /// What the `catcher_from_points` node reports: the corners, the catcher's frame, the
    /// planarity, whether the normal was turned towards the cameras, and each placed object.
    pub fn report(&self) -> serde_json::Value {
        let placed: Vec<serde_json::Value> = self.scene.objects[1..]
            .iter()
            .map(|o| match &o.shape {
                Shape::Sphere(s) => {
                    json!({"sphere": {"center": row(s.center), "radius": s.radius}})
                }
                Shape::Triangles { triangles } => json!({"triangles": triangles.len()}),
            })
            .collect();
        let f = &self.polygon.frame;
        json!({
            "corners": rows(&self.polygon.corners),
            "frame": {"origin": row(f.origin), "x": row(f.x), "y": row(f.y), "z": row(f.z), "unit": f.unit},
            "planarity": self.polygon.planarity,
            "normal_towards_cameras": self.faces_cameras,
            "objects": placed,
        })
    }
}

/// A shadow catcher through measured ground points (module docs), with the objects of an
/// optional `design` (in the catcher's frame: y up, unit |AB|) set on it; without a design, a
/// scene of the catcher alone seen by the first viewer (or a camera above it).
pub fn catcher_from_points(
    points: &[Vec3],
    viewers: &Viewers,
    design: Option<Design<'_>>,
    dome_image: Option<&Image>,
    o: &CatcherOptions,
) -> Result<PlacedCatcher, String> {
    let pts = pick_points(points, &o.indices)?;
    let centroid = pts.iter().fold(Vec3::ZERO, |a, b| a + *b) / pts.len().max(1) as f64;
    let up = (!viewers.centres.is_empty()).then(|| {
        let c = viewers.centres.iter().fold(Vec3::ZERO, |a, b| a + *b);
        c / viewers.centres.len() as f64 - centroid
    });
    let poly = catcher_polygon(&pts, o.margin, o.planarity, up).map_err(|e| e.to_string())?;
    let to_world = poly.frame.similarity();
    let (mut scene, loaded) = match design {
        Some(d) => {
            let mut designed = d.scene.clone();
            if o.rest {
                rest_on_ground(&mut designed);
            }
            (transform_scene(&designed, &to_world), d.dome)
        }
        None => {
            let camera = match &viewers.first {
                Some(c) => c.clone(),
                None => {
                    let f = &poly.frame;
                    Camera::look_at(
                        centroid + (f.y * 3.0 - f.z * 2.0) * f.unit,
                        centroid,
                        f.y,
                        50.0,
                        640,
                        360,
                    )
                    .map_err(|e| e.to_string())?
                }
            };
            let scene = Scene {
                camera: Some(camera),
                objects: vec![],
                lights: vec![],
                background: Rgb::new(1.0, 1.0, 1.0),
                dome: None,
            };
            (scene, None)
        }
    };
    let [r, g, b] = o.color;
    let mut catcher = Object::new(
        Shape::Triangles {
            triangles: poly.triangles.clone(),
        },
        Brdf::Lambert(Lambert {
            albedo: Rgb::new(r, g, b),
        }),
    );
    catcher.catcher = true;
    scene.objects.insert(0, catcher);
    flip_dome(&mut scene, o.flip_dome);
    let dome = placed_dome(&scene, loaded, dome_image)?;
    Ok(PlacedCatcher {
        scene,
        dome,
        polygon: poly,
        faces_cameras: up.is_some(),
    })
}
