//! Placing nodes (book chapter 8 and §10.10): build the local scene of a shot from measured
//! points. `place_scene` moves a designed scene (the book's `modeling.scn`, or a YAML scene)
//! onto the points measured by `point_cloud_calibrate`, by the similarity between anchor points
//! in the scene and the measured ones; `catcher_from_points` makes the shadow catcher through
//! the measured ground points and sets objects designed in the catcher's own frame on it. The
//! algorithms and their options are in the render crate's `placement` module.

use vfxgraph_engine::{Context, In, Mode, NodeError, NodeSpec, OptIn, Out, Registry};
use vfxgraph_geometry::formats::CameraPath;
use vfxgraph_render::placement::place::{
    catcher_from_points, place_scene, CatcherOptions, Design, PlaceOptions, Viewers,
};
use vfxgraph_render::{Camera, Vec3};

use crate::artifacts::{CameraPathArt, ImageArt, Points3dArt, ReportArt};
use crate::render::{rows, SceneArt};

/// Input `port` (a node's `points3d`) as render points.
pub(crate) fn measured(ctx: &Context<'_>, port: In<Points3dArt>) -> Result<Vec<Vec3>, NodeError> {
    let pts = &ctx.get(port)?.0 .0;
    Ok(pts.iter().map(|p| Vec3::new(p.x, p.y, p.z)).collect())
}

/// The cameras of a solved path as viewers of a catcher: their centres, and the first one as a
/// render camera (its K, R, t) when `with_view` and the path has intrinsics.
fn viewers(path: &CameraPath, with_view: bool) -> Result<Viewers, NodeError> {
    let centres = path.frames.iter().map(|f| f.pose.center());
    let centres = centres.map(|c| Vec3::new(c.x, c.y, c.z)).collect();
    let first = match (path.frames.first(), &path.intrinsics) {
        (Some(f), Some(k)) if with_view => Some(Camera::from_krt(
            rows(&k.k()),
            rows(&f.pose.r),
            [f.pose.t.x, f.pose.t.y, f.pose.t.z],
            k.width.unwrap_or(1280) as usize,
            k.height.unwrap_or(720) as usize,
        )?),
        _ => None,
    };
    Ok(Viewers { centres, first })
}

const DESIGNED: In<SceneArt> = In::new("scene", "the designed scene");
const MEASURED: In<Points3dArt> =
    In::new("points3d", "the same points measured in the solve's frame");
const DOME_IMAGE: OptIn<ImageArt> = OptIn::new(
    "dome_image",
    "an equirectangular image for the scene's dome (when its own, e.g. the book's \
     dome.pfm, is not available)",
);
const PLACED: Out<SceneArt> = Out::new("scene", "the scene in the solve's frame");
const PLACE_REPORT: Out<ReportArt> = Out::new(
    "report",
    "the similarity (scale, rotation, angle, translation), anchors, measured points, \
     residuals and the relative RMS",
);
const CATCHER_POINTS: In<Points3dArt> =
    In::new("points3d", "measured points (point_cloud_calibrate)");
const DESIGNED_IN_CATCHER: OptIn<SceneArt> = OptIn::new(
    "scene",
    "objects (and dome, lights) designed in the catcher's frame (y up, unit |AB|)",
);
const CAMERAS: OptIn<CameraPathArt> = OptIn::new(
    "cameras",
    "the solved cameras: the ground's normal faces them; the first one is the \
             output scene's camera when no scene is connected",
);
const DESIGN_DOME_IMAGE: OptIn<ImageArt> = OptIn::new(
    "dome_image",
    "an equirectangular image for the designed scene's dome",
);
const WITH_CATCHER: Out<SceneArt> = Out::new(
    "scene",
    "the catcher and the placed objects in the solve's frame",
);
const CATCHER_REPORT: Out<ReportArt> = Out::new(
    "report",
    "the catcher's corners, frame (origin, axes, unit), planarity and the placed objects",
);

/// Registers the nodes of this module.
pub fn register(r: &mut Registry) {
    r.register_fn(
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
        .options::<PlaceOptions>()
        .input(DESIGNED)
        .input(MEASURED)
        .input(DOME_IMAGE)
        .output(PLACED)
        .output(PLACE_REPORT),
        run_place_scene,
    );
    r.register_fn(
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
        .options::<CatcherOptions>()
        .input(CATCHER_POINTS)
        .input(DESIGNED_IN_CATCHER)
        .input(CAMERAS)
        .input(DESIGN_DOME_IMAGE)
        .output(WITH_CATCHER)
        .output(CATCHER_REPORT),
        run_catcher_from_points,
    );
}

fn run_place_scene(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let o: PlaceOptions = ctx.options()?;
    let art = ctx.get(DESIGNED)?;
    let design = Design {
        scene: &art.scene,
        dome: art.dome.as_ref(),
    };
    let image = ctx.get(DOME_IMAGE)?.map(|i| &i.0);
    let p = place_scene(design, image, &measured(ctx, MEASURED)?, &o)
        .map_err(|e| NodeError::msg(format!("place_scene: {e}")))?;
    ctx.set(PLACE_REPORT, ReportArt(p.report()));
    ctx.set(PLACED, SceneArt::new(p.scene, p.dome));
    Ok(())
}

fn run_catcher_from_points(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let o: CatcherOptions = ctx.options()?;
    let pts = measured(ctx, CATCHER_POINTS)?;
    let art = ctx.get(DESIGNED_IN_CATCHER)?;
    let design = art.map(|a| Design {
        scene: &a.scene,
        dome: a.dome.as_ref(),
    });
    let viewers = match ctx.get(CAMERAS)? {
        Some(path) => viewers(&path.0, design.is_none())?,
        None => Viewers::default(),
    };
    let image = ctx.get(DESIGN_DOME_IMAGE)?.map(|i| &i.0);
    let c = catcher_from_points(&pts, &viewers, design, image, &o)
        .map_err(|e| NodeError::msg(format!("catcher_from_points: {e}")))?;
    ctx.set(CATCHER_REPORT, ReportArt(c.report()));
    ctx.set(WITH_CATCHER, SceneArt::new(c.scene, c.dome));
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{params, spec};
    use nalgebra::{Matrix3, Point3, Rotation3, Unit, Vector3};
    use vfxgraph_engine::{InputValue, ParamValue, Value};
    use vfxgraph_geometry::formats::{CameraPath, FramePose};
    use vfxgraph_geometry::{Points3d, Pose};
    use vfxgraph_imaging::Image;
    use vfxgraph_render::brdf::{Brdf, Lambert};
    use vfxgraph_render::dome::Dome;
    use vfxgraph_render::placement::first_catcher_vertices;
    use vfxgraph_render::placement::Similarity;
    use vfxgraph_render::shape::Sphere;
    use vfxgraph_render::DomeSpec;
    use vfxgraph_render::Shape;
    use vfxgraph_render::{Object, Rgb, Scene};

    fn row(v: Vec3) -> [f64; 3] {
        [v.x, v.y, v.z]
    }

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

    fn points(p: &[Vec3]) -> InputValue<'static> {
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
            frames: vec![FramePose {
                frame: 0,
                pose,
                focal: None,
            }],
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
