//! Placing nodes (book chapter 8 and §10.10): build the local scene of a shot from measured
//! points. `place_scene` moves a designed scene (the book's `modeling.scn`, or a YAML scene)
//! onto the points measured by `point_cloud_calibrate`, by the similarity between anchor points
//! in the scene and the measured ones; `catcher_from_points` makes the shadow catcher through
//! the measured ground points and sets objects designed in the catcher's own frame on it. The
//! algorithms are in the render crate's `placement` module.

use nalgebra::Vector3;
use serde_json::json;
use vfxgraph_engine::{
    ArtifactType, Context, Mode, NodeError, NodeSpec, ParamSpec, ParamType, ParamValue, PortSpec,
    Registry,
};
use vfxgraph_render::brdf::{Brdf, Lambert};
use vfxgraph_render::dome::Dome;
use vfxgraph_render::placement::{
    catcher_polygon, first_catcher_vertices, transform_scene, umeyama, Similarity,
};
use vfxgraph_render::{Camera, Object, Rgb, Scene, Shape, Vec3};

use crate::artifacts::{CameraPathArt, ImageArt, Points3dArt, ReportArt};
use crate::render::SceneArt;
use crate::FnNode;

const FLIP_DOC: &str = "negate the dome's `south` after placing: the book's `south` is the \
    HDR camera's image-down axis (GAPS ch. 10), which points at the ground in modeling.scn, so an \
    image with the sky on its top row (Poly Haven's) needs it negated to keep the sky up";

fn vec3s(v: &[f64]) -> Vec<Vec3> {
    v.chunks_exact(3)
        .map(|c| Vec3::new(c[0], c[1], c[2]))
        .collect()
}

fn row(v: Vec3) -> [f64; 3] {
    [v.x, v.y, v.z]
}

/// The measured points, checked finite, optionally picked by `indices` (integers).
fn measured(ctx: &Context<'_>, node: &str) -> Result<Vec<Vec3>, NodeError> {
    let pts = &ctx.input::<Points3dArt>("points3d")?.0 .0;
    let all: Vec<Vec3> = pts.iter().map(|p| Vec3::new(p.x, p.y, p.z)).collect();
    if let Some(i) = all.iter().position(|p| !p.is_finite()) {
        return Err(NodeError::msg(format!(
            "{node}: measured point {i} of `points3d` is not finite"
        )));
    }
    let idx = ctx.params().f64s("indices");
    if idx.is_empty() {
        return Ok(all);
    }
    idx.iter()
        .map(|&i| {
            if i.fract() != 0.0 || i < 0.0 || i as usize >= all.len() {
                Err(NodeError::msg(format!(
                    "{node}: param `indices`: {i} is not the index of one of the {} measured \
                     points (0-based integers)",
                    all.len()
                )))
            } else {
                Ok(all[i as usize])
            }
        })
        .collect()
}

/// Rebuilds the scene's dome with its (moved) orientation: from the input scene's loaded image,
/// or from a `dome_image` input (which replaces it). `None` when there is no image.
fn placed_dome(
    ctx: &Context<'_>,
    scene: &Scene,
    loaded: Option<&Dome>,
) -> Result<Option<Dome>, NodeError> {
    let image = match ctx.input_opt::<ImageArt>("dome_image")? {
        Some(img) => &img.0,
        None => match loaded {
            Some(d) => d.image(),
            None => return Ok(None),
        },
    };
    let Some(spec) = &scene.dome else {
        return Err(NodeError::msg(
            "`dome_image` is connected but the scene has no dome to orient it (a `.scn` \
             hdrdome or a YAML `dome:`)",
        ));
    };
    let v = |p: Vec3| Vector3::new(p.x, p.y, p.z);
    let mut img = image.clone();
    if ctx.input_opt::<ImageArt>("dome_image")?.is_some() && spec.scale != 1.0 {
        let k = spec.scale as f32;
        img.data.iter_mut().for_each(|x| *x *= k);
    }
    Ok(Some(Dome::new(&img, v(spec.orig), v(spec.south))?))
}

fn flip_dome(scene: &mut Scene, flip: bool) {
    if let (true, Some(d)) = (flip, scene.dome.as_mut()) {
        d.south = -d.south;
    }
}

fn similarity_json(s: &Similarity) -> serde_json::Value {
    let r = &s.rotation;
    json!({
        "scale": s.scale,
        "rotation": [[r[(0,0)], r[(0,1)], r[(0,2)]], [r[(1,0)], r[(1,1)], r[(1,2)]],
                     [r[(2,0)], r[(2,1)], r[(2,2)]]],
        "rotation_deg": s.angle_deg(),
        "translation": [s.translation.x, s.translation.y, s.translation.z],
    })
}

/// Registers the nodes of this module.
pub fn register(r: &mut Registry) {
    r.register_node(FnNode::new(
        NodeSpec::new(
            "place_scene",
            "Moves a designed scene onto measured points (book ch. 8, §10.10): the similarity \
             (Umeyama 1991: scale, rotation, translation, least squares) mapping the scene's \
             anchor points onto the `points3d` measured by point_cloud_calibrate, applied to \
             every object (triangles, sphere centres and radii), light and the scene camera; \
             the dome's orig/south are rotated so it stays oriented to the real world. Anchors: \
             `catcher` = the first shadow catcher's vertices A, B, C in order (modeling.scn's \
             parallelogram (A, B, C), (C, B, D); the order of the book's points2d.txt marks), \
             or `points` = `anchor_points`. Refuses a fit whose RMS residual exceeds \
             `max_residual` × the measured points' spread. Render the result per frame with the \
             solve's `cameras`.",
        )
        .mode(Mode::Once)
        .param(ParamSpec::optional(
            "anchors",
            ParamType::Enum(&["catcher", "points"]),
            ParamValue::Str("catcher".into()),
            "`catcher`: the first catcher's vertices A, B, C; `points`: the `anchor_points` param",
        ))
        .param(ParamSpec::optional(
            "anchor_points",
            ParamType::FloatList { len: None },
            ParamValue::List(vec![]),
            "anchors in the scene's coordinates, x y z per point (with `anchors: points`)",
        ))
        .param(ParamSpec::optional(
            "indices",
            ParamType::FloatList { len: None },
            ParamValue::List(vec![]),
            "which measured points pair with the anchors, in order (0-based; default all)",
        ))
        .param(ParamSpec::optional(
            "max_residual",
            ParamType::Float { min: 0.0, max: 1e6 },
            ParamValue::Float(0.05),
            "largest accepted RMS anchor residual over the RMS spread of the measured points",
        ))
        .param(ParamSpec::optional(
            "flip_dome",
            ParamType::Bool,
            ParamValue::Bool(false),
            FLIP_DOC,
        ))
        .input(PortSpec::one("scene", SceneArt::NAME, "the designed scene"))
        .input(PortSpec::one(
            "points3d",
            Points3dArt::NAME,
            "the same points measured in the solve's frame",
        ))
        .input(
            PortSpec::one(
                "dome_image",
                ImageArt::NAME,
                "an equirectangular image for the scene's dome (when its own, e.g. the book's \
                 dome.pfm, is not available)",
            )
            .optional(),
        )
        .output(PortSpec::one(
            "scene",
            SceneArt::NAME,
            "the scene in the solve's frame",
        ))
        .output(PortSpec::one(
            "report",
            ReportArt::NAME,
            "the similarity (scale, rotation, angle, translation), anchors, measured points, \
             residuals and the relative RMS",
        )),
        run_place_scene,
    ));
    r.register_node(FnNode::new(
        NodeSpec::new(
            "catcher_from_points",
            "A shadow catcher through measured ground points (book ch. 8, §10.10): 3 points \
             A, B, C → the parallelogram A, B, B + C − A, C of modeling.scn; 4 or more → their \
             polygon, refused when not planar within `planarity`. Objects of an optional \
             designed `scene` are set on it from the catcher's frame: origin A, x along AB, y \
             the ground's normal (towards the cameras when `cameras` is connected), z = x × y, \
             unit = |AB| — so they need no world coordinates and follow the solve's scale. \
             `rest: true` lowers or raises each object onto the ground (y = 0). The catcher is \
             Lambertian with albedo `color` (modeling.scn's plshadow colour by default).",
        )
        .mode(Mode::Once)
        .param(ParamSpec::optional(
            "indices",
            ParamType::FloatList { len: None },
            ParamValue::List(vec![]),
            "which measured points are ground points, in order (0-based; default all)",
        ))
        .param(ParamSpec::optional(
            "margin",
            ParamType::Float {
                min: -0.99,
                max: 100.0,
            },
            ParamValue::Float(0.0),
            "grow the polygon about its centre by this fraction (0: through the points)",
        ))
        .param(ParamSpec::optional(
            "planarity",
            ParamType::Float { min: 0.0, max: 1.0 },
            ParamValue::Float(0.02),
            "largest distance of a ground point from their plane, over the polygon's size",
        ))
        .param(ParamSpec::optional(
            "color",
            ParamType::FloatList { len: Some(3) },
            ParamValue::List(
                [0.576563, 0.539570, 0.466020]
                    .iter()
                    .map(|&v| ParamValue::Float(v))
                    .collect(),
            ),
            "the catcher's diffuse albedo, linear RGB",
        ))
        .param(ParamSpec::optional(
            "rest",
            ParamType::Bool,
            ParamValue::Bool(true),
            "move each designed object along y so its lowest point is on the ground",
        ))
        .param(ParamSpec::optional(
            "flip_dome",
            ParamType::Bool,
            ParamValue::Bool(false),
            "negate the placed dome's `south` (see place_scene)",
        ))
        .input(PortSpec::one(
            "points3d",
            Points3dArt::NAME,
            "measured points (point_cloud_calibrate)",
        ))
        .input(
            PortSpec::one(
                "scene",
                SceneArt::NAME,
                "objects (and dome, lights) designed in the catcher's frame (y up, unit |AB|)",
            )
            .optional(),
        )
        .input(
            PortSpec::one(
                "cameras",
                CameraPathArt::NAME,
                "the solved cameras: the ground's normal faces them; the first one is the \
                 output scene's camera when no scene is connected",
            )
            .optional(),
        )
        .input(
            PortSpec::one(
                "dome_image",
                ImageArt::NAME,
                "an equirectangular image for the designed scene's dome",
            )
            .optional(),
        )
        .output(PortSpec::one(
            "scene",
            SceneArt::NAME,
            "the catcher and the placed objects in the solve's frame",
        ))
        .output(PortSpec::one(
            "report",
            ReportArt::NAME,
            "the catcher's corners, frame (origin, axes, unit), planarity and the placed objects",
        )),
        run_catcher_from_points,
    ));
}

fn run_place_scene(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    const NODE: &str = "place_scene";
    let art = ctx.input::<SceneArt>("scene")?;
    let p = ctx.params();
    let anchors: Vec<Vec3> = if p.str("anchors") == "catcher" {
        let n = p.f64s("anchor_points").len();
        if n > 0 {
            return Err(NodeError::msg(format!(
                "{NODE}: `anchor_points` is set ({n} numbers) but `anchors` is `catcher`: set \
                 `anchors: points` to use them"
            )));
        }
        first_catcher_vertices(&art.scene)
            .ok_or_else(|| {
                NodeError::msg(format!(
                    "{NODE}: `anchors: catcher` but the scene has no triangle shadow catcher \
                     (plshadow / `catcher: true`): give `anchors: points` and `anchor_points`"
                ))
            })?
            .to_vec()
    } else {
        let v = p.f64s("anchor_points");
        if v.len() % 3 != 0 || v.is_empty() {
            return Err(NodeError::msg(format!(
                "{NODE}: `anchor_points` needs x y z per anchor (a multiple of 3 numbers), got {}",
                v.len()
            )));
        }
        vec3s(&v)
    };
    let pts = measured(ctx, NODE)?;
    let fit = umeyama(&anchors, &pts).map_err(|e| NodeError::msg(format!("{NODE}: {e}")))?;
    let max = p.f64("max_residual");
    if fit.relative_rms.is_nan() || fit.relative_rms > max {
        return Err(NodeError::msg(format!(
            "{NODE}: the anchors do not match the measured points: RMS residual {:.4} of their \
             spread (limit `max_residual` {max}); residuals {:?} — check the anchor order \
             against the marks",
            fit.relative_rms, fit.residuals
        )));
    }
    let mut scene = transform_scene(&art.scene, &fit.similarity);
    flip_dome(&mut scene, p.bool("flip_dome"));
    if let Some(c) = &scene.camera {
        c.validate()
            .map_err(|e| NodeError::msg(format!("{NODE}: the moved camera: {e}")))?;
    }
    let dome = placed_dome(ctx, &scene, art.dome.as_ref())?;
    let report = json!({
        "similarity": similarity_json(&fit.similarity),
        "anchors": anchors.iter().map(|a| row(*a)).collect::<Vec<_>>(),
        "measured": pts.iter().map(|a| row(*a)).collect::<Vec<_>>(),
        "placed_anchors": anchors.iter().map(|a| row(fit.similarity.point(*a))).collect::<Vec<_>>(),
        "residuals": fit.residuals,
        "relative_rms": fit.relative_rms,
        "dome": scene.dome.as_ref().map(|d| json!({"orig": row(d.orig), "south": row(d.south)})),
    });
    ctx.output("scene", SceneArt { scene, dome });
    ctx.output("report", ReportArt(report));
    Ok(())
}

/// Lifts each non-catcher object so its lowest point is at y = 0 (catcher frame).
fn rest_on_ground(scene: &mut Scene) {
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

fn run_catcher_from_points(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    const NODE: &str = "catcher_from_points";
    let pts = measured(ctx, NODE)?;
    let p = ctx.params();
    let path = ctx.input_opt::<CameraPathArt>("cameras")?.map(|c| &c.0);
    let centroid = pts.iter().fold(Vec3::ZERO, |a, b| a + *b) / pts.len().max(1) as f64;
    let up = match path {
        Some(path) if !path.frames.is_empty() => {
            let c = path.frames.iter().fold(Vec3::ZERO, |a, f| {
                let c = f.pose.center();
                a + Vec3::new(c.x, c.y, c.z)
            }) / path.frames.len() as f64;
            Some(c - centroid)
        }
        _ => None,
    };
    let poly = catcher_polygon(&pts, p.f64("margin"), p.f64("planarity"), up)
        .map_err(|e| NodeError::msg(format!("{NODE}: {e}")))?;
    let col = p.f64s("color");
    let catcher_material = Brdf::Lambert(Lambert {
        albedo: Rgb::new(col[0], col[1], col[2]),
    });
    let to_world = poly.frame.similarity();
    let art = ctx.input_opt::<SceneArt>("scene")?;
    let (mut scene, loaded) = match art {
        Some(a) => {
            let mut designed = a.scene.clone();
            if p.bool("rest") {
                rest_on_ground(&mut designed);
            }
            (transform_scene(&designed, &to_world), a.dome.as_ref())
        }
        None => {
            // A camera to look at it: the first solved frame's with its K, else one above it.
            let camera = match path.and_then(|c| c.frames.first().map(|f| (c, f))) {
                Some((c, f)) if c.intrinsics.is_some() => {
                    let k = c.intrinsics.as_ref().expect("checked");
                    let r = &f.pose.r;
                    Camera::from_krt(
                        [[k.f1, k.s, k.u0], [0.0, k.f2, k.v0], [0.0, 0.0, 1.0]],
                        [
                            [r[(0, 0)], r[(0, 1)], r[(0, 2)]],
                            [r[(1, 0)], r[(1, 1)], r[(1, 2)]],
                            [r[(2, 0)], r[(2, 1)], r[(2, 2)]],
                        ],
                        [f.pose.t.x, f.pose.t.y, f.pose.t.z],
                        k.width.unwrap_or(1280) as usize,
                        k.height.unwrap_or(720) as usize,
                    )?
                }
                _ => {
                    let f = &poly.frame;
                    Camera::look_at(
                        centroid + (f.y * 3.0 - f.z * 2.0) * f.unit,
                        centroid,
                        f.y,
                        50.0,
                        640,
                        360,
                    )?
                }
            };
            (
                Scene {
                    camera: Some(camera),
                    objects: vec![],
                    lights: vec![],
                    background: Rgb::new(1.0, 1.0, 1.0),
                    dome: None,
                },
                None,
            )
        }
    };
    let mut catcher = Object::new(
        Shape::Triangles {
            triangles: poly.triangles.clone(),
        },
        catcher_material,
    );
    catcher.catcher = true;
    let placed: Vec<serde_json::Value> = scene
        .objects
        .iter()
        .map(|o| match &o.shape {
            Shape::Sphere(s) => json!({"sphere": {"center": row(s.center), "radius": s.radius}}),
            Shape::Triangles { triangles } => json!({"triangles": triangles.len()}),
        })
        .collect();
    scene.objects.insert(0, catcher);
    flip_dome(&mut scene, p.bool("flip_dome"));
    let dome = placed_dome(ctx, &scene, loaded)?;
    let f = &poly.frame;
    let report = json!({
        "corners": poly.corners.iter().map(|c| row(*c)).collect::<Vec<_>>(),
        "frame": {"origin": row(f.origin), "x": row(f.x), "y": row(f.y), "z": row(f.z), "unit": f.unit},
        "planarity": poly.planarity,
        "normal_towards_cameras": up.is_some(),
        "objects": placed,
    });
    ctx.output("scene", SceneArt { scene, dome });
    ctx.output("report", ReportArt(report));
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{params, spec};
    use nalgebra::{Matrix3, Point3, Rotation3, Unit};
    use vfxgraph_engine::{InputValue, Value};
    use vfxgraph_imaging::Image;
    use vfxgraph_render::shape::Sphere;
    use vfxgraph_render::DomeSpec;
    use vfxgraph_vision::formats::{CameraPath, FramePose};
    use vfxgraph_vision::{Points3d, Pose};

    fn lambert() -> Brdf {
        Brdf::Lambert(Lambert {
            albedo: Rgb::new(0.5, 0.5, 0.5),
        })
    }

    /// A designed scene: a catcher A, B, C (+ D) on y = 0, a sphere resting on it, a dome.
    fn designed(with_dome: bool) -> SceneArt {
        let (a, b, c) = (
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(0.0, 0.0, 1.0),
        );
        let mut catcher = Object::new(
            Shape::Triangles {
                triangles: vec![[a, b, c], [c, b, b + c - a]],
            },
            lambert(),
        );
        catcher.catcher = true;
        let sphere = Object::new(
            Shape::Sphere(Sphere {
                center: Vec3::new(1.0, 0.25, 0.5),
                radius: 0.25,
            }),
            lambert(),
        );
        let scene = Scene {
            camera: Camera::look_at(
                Vec3::new(1.0, 2.0, 4.0),
                Vec3::new(1.0, 0.0, 0.5),
                Vec3::new(0.0, 1.0, 0.0),
                50.0,
                32,
                24,
            )
            .ok(),
            objects: vec![catcher, sphere],
            lights: vec![],
            background: Rgb::new(0.0, 0.0, 0.0),
            dome: Some(DomeSpec {
                orig: Vec3::new(0.0, 0.0, -1.0),
                south: Vec3::new(0.0, 1.0, 0.0),
                image: "sky.pfm".into(),
                scale: 1.0,
            }),
        };
        let dome = with_dome.then(|| Dome::y_up(&Image::from_fn(8, 4, 3, |_, _, _| 0.5)).unwrap());
        SceneArt { scene, dome }
    }

    fn truth() -> Similarity {
        let axis = Unit::new_normalize(Vector3::new(0.3, -1.0, 0.4));
        Similarity {
            scale: 0.37,
            rotation: *Rotation3::from_axis_angle(&axis, 2.1).matrix(),
            translation: Vector3::new(-3.0, 1.5, 12.0),
        }
    }

    fn points(p: &[Vec3]) -> InputValue {
        InputValue::One(Value::new(Points3dArt(Points3d(
            p.iter().map(|v| Point3::new(v.x, v.y, v.z)).collect(),
        ))))
    }

    fn run(
        node: &str,
        inputs: Vec<(&'static str, InputValue)>,
        set: &[(&str, ParamValue)],
    ) -> Result<(SceneArt, serde_json::Value), NodeError> {
        let sp = spec(node);
        let ps = params(&sp, set);
        let dir = std::env::temp_dir();
        let mut ctx = Context::for_test(&sp, &ps, &dir, None, inputs);
        match node {
            "place_scene" => run_place_scene(&mut ctx)?,
            _ => run_catcher_from_points(&mut ctx)?,
        }
        Ok((
            ctx.take_output::<SceneArt>("scene").unwrap(),
            ctx.take_output::<ReportArt>("report").unwrap().0,
        ))
    }

    fn sphere(s: &Scene) -> Sphere {
        match s.objects.iter().find(|o| !o.catcher).unwrap().shape {
            Shape::Sphere(s) => s,
            _ => panic!("not a sphere"),
        }
    }

    fn floats(v: &[f64]) -> ParamValue {
        ParamValue::List(v.iter().map(|&x| ParamValue::Float(x)).collect())
    }

    /// The scene's catcher A, B, C moved by a known similarity are the "measured" points: the
    /// similarity is recovered, the sphere lands where the similarity puts it, the dome is
    /// rotated (and rebuilt from the loaded image), and the report says so.
    #[test]
    fn place_scene_recovers_a_known_similarity() {
        let art = designed(true);
        let t = truth();
        let abc = first_catcher_vertices(&art.scene).unwrap();
        let measured: Vec<Vec3> = abc.iter().map(|p| t.point(*p)).collect();
        let inputs = vec![
            ("scene", InputValue::One(Value::new(art.clone()))),
            ("points3d", points(&measured)),
        ];
        let (out, rep) = run("place_scene", inputs, &[]).unwrap();
        let s = sphere(&out.scene);
        assert!((s.center - t.point(Vec3::new(1.0, 0.25, 0.5))).length() < 1e-9);
        assert!((s.radius - 0.25 * 0.37).abs() < 1e-12);
        assert!((rep["similarity"]["scale"].as_f64().unwrap() - 0.37).abs() < 1e-12);
        assert!(rep["relative_rms"].as_f64().unwrap() < 1e-12);
        let south = t.rotation * Vector3::y();
        let dome = out.dome.expect("the loaded dome is re-oriented");
        assert!((dome.south() - south).norm() < 1e-12);
        // flip_dome negates the placed south.
        let inputs = vec![
            ("scene", InputValue::One(Value::new(art.clone()))),
            ("points3d", points(&measured)),
        ];
        let (out, _) = run(
            "place_scene",
            inputs,
            &[("flip_dome", ParamValue::Bool(true))],
        )
        .unwrap();
        assert!((out.dome.unwrap().south() + south).norm() < 1e-12);
        // The same with explicit anchor points (the sphere's centre as a 4th anchor).
        let mut anchors: Vec<f64> = abc.iter().flat_map(|p| row(*p)).collect();
        anchors.extend([1.0, 0.25, 0.5]);
        let mut m4 = measured.clone();
        m4.push(t.point(Vec3::new(1.0, 0.25, 0.5)));
        let inputs = vec![
            ("scene", InputValue::One(Value::new(designed(false)))),
            ("points3d", points(&m4)),
        ];
        let (out, rep) = run(
            "place_scene",
            inputs,
            &[
                ("anchors", ParamValue::Str("points".into())),
                ("anchor_points", floats(&anchors)),
            ],
        )
        .unwrap();
        assert!((sphere(&out.scene).center - m4[3]).length() < 1e-9);
        assert_eq!(rep["residuals"].as_array().unwrap().len(), 4);
        // No image anywhere: the dome stays a spec for a later `dome` input.
        assert!(out.dome.is_none() && out.scene.dome.is_some());
    }

    #[test]
    fn place_scene_errors_name_the_node_and_the_cause() {
        let abc = first_catcher_vertices(&designed(false).scene).unwrap();
        let t = truth();
        let good: Vec<Vec3> = abc.iter().map(|p| t.point(*p)).collect();
        let go = |pts: &[Vec3], set: &[(&str, ParamValue)]| {
            let inputs = vec![
                ("scene", InputValue::One(Value::new(designed(false)))),
                ("points3d", points(pts)),
            ];
            run("place_scene", inputs, set).unwrap_err().message
        };
        let mut nan = good.clone();
        nan[2].z = f64::NAN;
        let e = go(&nan, &[]);
        assert!(e.contains("place_scene") && e.contains("point 2") && e.contains("not finite"));
        let e = go(&good[..2], &[]);
        assert!(e.contains("3 anchor points but 2 measured"), "{e}");
        // Swapped marks: the shapes differ, the fit is refused with its residual.
        let swapped = [good[1], good[0], good[2]];
        let e = go(&swapped, &[]);
        assert!(
            e.contains("do not match") && e.contains("anchor order"),
            "{e}"
        );
        let line = floats(&[0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 2.0, 2.0, 2.0]);
        let points_set = [
            ("anchors", ParamValue::Str("points".into())),
            ("anchor_points", line),
        ];
        let e = go(&good, &points_set);
        assert!(e.contains("anchor points are collinear"), "{e}");
        let e = go(&good, &[("anchor_points", floats(&[1.0, 2.0, 3.0]))]);
        assert!(e.contains("`anchors: points`"), "{e}");
        let e = go(
            &good,
            &[
                ("anchors", ParamValue::Str("points".into())),
                ("anchor_points", floats(&[1.0, 2.0])),
            ],
        );
        assert!(e.contains("multiple of 3"), "{e}");
        let e = go(&good, &[("indices", floats(&[0.0, 1.0, 5.0]))]);
        assert!(e.contains("`indices`") && e.contains("5"), "{e}");
        // A scene without a catcher cannot use `anchors: catcher`.
        let mut bare = designed(false);
        bare.scene.objects.retain(|o| !o.catcher);
        let inputs = vec![
            ("scene", InputValue::One(Value::new(bare))),
            ("points3d", points(&good)),
        ];
        let e = run("place_scene", inputs, &[]).unwrap_err().message;
        assert!(e.contains("no triangle shadow catcher"), "{e}");
    }

    /// Three measured ground points in an arbitrary frame; an object designed in the catcher
    /// frame (unit |AB|) lands on the plane, touching it, at the designed place.
    #[test]
    fn catcher_from_points_sets_designed_objects_on_the_ground() {
        let t = truth();
        let (a, b, c) = (
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(0.0, 0.0, 1.0),
        );
        let ground: Vec<Vec3> = [a, b, c].iter().map(|p| t.point(*p)).collect();
        // A camera above the ground (y > 0 in the design frame), as a path.
        let cam_centre = t.point(Vec3::new(1.0, 3.0, 0.5));
        let pose = Pose::new(
            Matrix3::identity(),
            -Vector3::new(cam_centre.x, cam_centre.y, cam_centre.z),
        );
        let path = CameraPath {
            frames: vec![FramePose { frame: 0, pose }],
            intrinsics: None,
        };
        // Designed: a sphere of radius 0.1 |AB| floating at y = 0.7; `rest` drops it.
        let mut design = designed(true);
        design.scene.objects.retain(|o| !o.catcher);
        design.scene.objects[0].shape = Shape::Sphere(Sphere {
            center: Vec3::new(0.5, 0.7, 0.25),
            radius: 0.1,
        });
        let inputs = || {
            vec![
                ("points3d", points(&ground)),
                ("scene", InputValue::One(Value::new(design.clone()))),
                (
                    "cameras",
                    InputValue::One(Value::new(CameraPathArt(path.clone()))),
                ),
            ]
        };
        let (out, rep) = run("catcher_from_points", inputs(), &[]).unwrap();
        let unit = 2.0 * 0.37;
        assert!((rep["frame"]["unit"].as_f64().unwrap() - unit).abs() < 1e-12);
        let cat = out.scene.catchers().next().unwrap();
        let Shape::Triangles { triangles } = &cat.shape else {
            panic!()
        };
        assert_eq!(triangles.len(), 2);
        assert!((triangles[1][2] - t.point(b + c - a)).length() < 1e-9);
        let s = sphere(&out.scene);
        assert!((s.radius - 0.1 * unit).abs() < 1e-12);
        // Resting on the plane, on the cameras' side, above design point (0.5, 0, 0.25)·|AB|.
        let foot = t.point(Vec3::new(1.0, 0.0, 0.5));
        let up = t.rotation * Vector3::y();
        let d = s.center - foot;
        let d = Vector3::new(d.x, d.y, d.z);
        assert!(
            (d - up * s.radius).norm() < 1e-9,
            "{d} vs {}",
            up * s.radius
        );
        // Without `rest` it floats where designed.
        let (out, _) = run(
            "catcher_from_points",
            inputs(),
            &[("rest", ParamValue::Bool(false))],
        )
        .unwrap();
        let d = sphere(&out.scene).center - foot;
        assert!((Vector3::new(d.x, d.y, d.z) - up * 0.7 * unit).norm() < 1e-9);
        // The dome's south (+y designed) is the ground's normal.
        assert!((out.dome.unwrap().south() - up).norm() < 1e-12);
        // No scene: just the catcher, the normal still facing the cameras; the book's colour.
        let (out, rep) = run(
            "catcher_from_points",
            vec![
                ("points3d", points(&ground)),
                (
                    "cameras",
                    InputValue::One(Value::new(CameraPathArt(path.clone()))),
                ),
            ],
            &[],
        )
        .unwrap();
        assert_eq!(out.scene.objects.len(), 1);
        let y = &rep["frame"]["y"];
        let y = Vector3::new(
            y[0].as_f64().unwrap(),
            y[1].as_f64().unwrap(),
            y[2].as_f64().unwrap(),
        );
        assert!((y - up).norm() < 1e-12, "{y}");
    }

    #[test]
    fn catcher_from_points_polygons_and_errors() {
        // Five points of a pentagon on z = 2: a fan of 5 triangles.
        let pent: Vec<Vec3> = (0..5)
            .map(|k| {
                let a = k as f64 * std::f64::consts::TAU / 5.0;
                Vec3::new(a.cos(), a.sin(), 2.0)
            })
            .collect();
        let (out, rep) = run(
            "catcher_from_points",
            vec![("points3d", points(&pent))],
            &[],
        )
        .unwrap();
        let Shape::Triangles { triangles } = &out.scene.objects[0].shape else {
            panic!()
        };
        assert_eq!(triangles.len(), 5);
        assert_eq!(rep["corners"].as_array().unwrap().len(), 5);
        // `indices` picks 3 of them: the parallelogram.
        let (out, _) = run(
            "catcher_from_points",
            vec![("points3d", points(&pent))],
            &[("indices", floats(&[0.0, 1.0, 3.0]))],
        )
        .unwrap();
        let Shape::Triangles { triangles } = &out.scene.objects[0].shape else {
            panic!()
        };
        assert_eq!(triangles.len(), 2);
        // Not planar.
        let mut bent = pent.clone();
        bent[3].z = 2.5;
        let e = run(
            "catcher_from_points",
            vec![("points3d", points(&bent))],
            &[],
        )
        .unwrap_err()
        .message;
        assert!(
            e.contains("catcher_from_points") && e.contains("not on one plane"),
            "{e}"
        );
        // Collinear, too few, NaN.
        let line = [pent[0], pent[0] * 2.0, pent[0] * 3.0];
        let e = run(
            "catcher_from_points",
            vec![("points3d", points(&line))],
            &[],
        )
        .unwrap_err()
        .message;
        assert!(e.contains("collinear"), "{e}");
        let e = run(
            "catcher_from_points",
            vec![("points3d", points(&pent[..2]))],
            &[],
        )
        .unwrap_err()
        .message;
        assert!(e.contains("at least 3 ground points"), "{e}");
        let mut nan = pent.clone();
        nan[1].x = f64::NAN;
        let e = run("catcher_from_points", vec![("points3d", points(&nan))], &[])
            .unwrap_err()
            .message;
        assert!(e.contains("point 1") && e.contains("not finite"), "{e}");
    }
}
