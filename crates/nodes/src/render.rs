//! Rendering nodes (book ch. 9–10): `read_scene` reads the book's `.scn` scene language or a
//! YAML scene (+ OBJ meshes) into a `scene` artifact, loading the dome image it names;
//! `render` path-traces it to a linear HDR image (write it with `write_image` to EXR/PFM, or
//! `tonemap` + PNG), optionally lit by a `dome` from the HDR nodes and seen by frame f's camera
//! of a solved `camera_path`.

use nalgebra::Matrix3;

use vfxgraph_engine::artifact::codec::{put_bytes, put_u64, Reader};
use vfxgraph_engine::artifact::{decode_json, encode_json};
use vfxgraph_engine::{
    ArtifactType, Context, In, Mode, NodeError, NodeSpec, OptIn, Out, Registry, Threads,
};
use vfxgraph_geometry::formats::FramePose;
use vfxgraph_render::dome::{Dome, Light};
use vfxgraph_render::{
    camera_for_frame, read_scene_file, render, with_sync_progress, Camera, ImageSize, PathPose,
    RenderError, RenderOptions, Scene, SolvedK,
};

use crate::artifacts::{CameraPathArt, ImageArt, IntrinsicsArt};
use crate::hdr::DomeArt;

/// A scene (`scene`): camera, objects, lights, dome, shadow catchers (book §9.13, §10), with
/// the dome image it names when that image could be read.
#[derive(Clone, Debug)]
pub struct SceneArt {
    /// The scene model.
    pub scene: Scene,
    /// The loaded, oriented dome of `scene.dome` (`None` without a dome, or when its image was
    /// not found: then `render` needs a `dome` input).
    pub dome: Option<Dome>,
}

impl SceneArt {
    /// A scene with its loaded dome.
    pub fn new(scene: Scene, dome: Option<Dome>) -> Self {
        SceneArt { scene, dome }
    }
}

impl ArtifactType for SceneArt {
    const NAME: &'static str = "scene";
    const DOC: &'static str = "A scene to render: camera (K[R|t] and image size), objects \
        (spheres, triangles; shadow catchers flagged) with materials (Lambert, mirror, \
        normalized Blinn-Phong), polygonal area lights, background colour or HDR dome (with \
        its image), book ch. 9-10.";
    fn encode(&self, out: &mut Vec<u8>) {
        let mut json = Vec::new();
        encode_json(&self.scene, &mut json);
        put_bytes(out, &json);
        match &self.dome {
            None => put_u64(out, 0),
            Some(d) => {
                put_u64(out, 1);
                let mut b = Vec::new();
                DomeArt(d.clone()).encode(&mut b);
                put_bytes(out, &b);
            }
        }
    }
    fn decode(bytes: &[u8]) -> Result<Self, String> {
        let mut r = Reader::new(bytes);
        let scene: Scene = decode_json(r.bytes()?)?;
        if let Some(c) = &scene.camera {
            c.validate().map_err(|e| e.to_string())?;
        }
        let dome = match r.u64()? {
            0 => None,
            1 => Some(DomeArt::decode(r.bytes()?)?.0),
            t => return Err(format!("bad dome tag {t}")),
        };
        r.finish()?;
        Ok(SceneArt::new(scene, dome))
    }
}

/// The inputs of a node that renders a scene, but the `dome` they share ([`DOME`]): each
/// node documents them its own way.
#[derive(Clone, Copy)]
pub(crate) struct SceneInputs {
    /// The scene.
    pub scene: In<SceneArt>,
    /// The solved camera path the frames are seen by.
    pub cameras: OptIn<CameraPathArt>,
    /// K replacing the scene camera's (and the path's).
    pub intrinsics: OptIn<IntrinsicsArt>,
}

/// The `dome` input of a node that renders a scene: replaces the scene's light.
pub(crate) const DOME: OptIn<DomeArt> = OptIn::new(
    "dome",
    "a light dome replacing the scene's dome or background",
);

/// Adds the inputs of a node that renders a scene: `ports.scene`, [`DOME`], `ports.cameras`
/// and `ports.intrinsics`.
pub(crate) fn scene_inputs(spec: NodeSpec, ports: SceneInputs) -> NodeSpec {
    spec.input(ports.scene)
        .input(DOME)
        .input(ports.cameras)
        .input(ports.intrinsics)
}

const RENDER_INPUTS: SceneInputs = SceneInputs {
    scene: In::new("scene", "the scene"),
    cameras: OptIn::new(
        "cameras",
        "a solved camera path: frame f renders with that frame's [R|t]",
    ),
    intrinsics: OptIn::new(
        "intrinsics",
        "K (and image size, if known) replacing the scene camera's",
    ),
};

const SCENE: Out<SceneArt> = Out::new("scene", "the scene");
const IMAGE: Out<ImageArt> = Out::new("image", "radiance, linear RGB");
const VARIANCE: Out<ImageArt> = Out::new("variance", "per-pixel variance of the mean, linear RGB");

/// Registers the nodes of this module.
pub fn register(r: &mut Registry) {
    r.register_fn(
        NodeSpec::new(
            "read_scene",
            "Reads a scene file, by extension: the book's S3D `.scn` language (scene/hdrscene, \
             view, primobj, polyobj, group, sphere, trilist, plastic, polylight, hdrdome, \
             plshadow; book §9.13), or a YAML scene (`.yaml`/`.yml`: camera look_at or K/R/t \
             — optional for a scene seen only through a `cameras` path whose K has a size, \
             spheres, quads, polygons, triangles, OBJ meshes with transforms, lambert/mirror/\
             plastic/blinn_phong materials, area lights, dome image or colour, catchers; see \
             the render crate's `yaml_scene` docs). Errors name file:line:column. Loads the \
             dome image the scene names (relative to the scene file). Polylight colours of \
             `.scn` are multiplied by π and kd·d_col is the diffuse albedo, so direct light \
             matches the book's images. The files the scene names (OBJ meshes, the dome image) are part of the cache \
             key: editing one in place reruns the node.",
        )
        .threads(Threads::One)
        .mode(Mode::Once)
        .memory(vfxgraph_engine::Memory::Fixed(512))
        .input_file_param(
            "path",
            "the .scn or .yaml scene file, relative to the graph file",
        )
        .output(SCENE),
        run_read_scene,
    );
    r.register_fn(
        scene_inputs(
            NodeSpec::new(
                "render",
                "Path-traces a scene (book ch. 9): next-event estimation on the area lights and \
             the dome with multiple importance sampling, Russian roulette, one random stream \
             per pixel (same image for any thread count). Light: the `dome` input if \
             connected, else the scene's dome, else its background colour. With `cameras` \
             (per frame: set `per_frame: true`), frame f is seen by that path's [R|t] of frame \
             f with the scene camera's K (or the `intrinsics` input's, or the path's; a scene \
             without a camera takes its K and image size from those). Output: mean radiance \
             per pixel (linear HDR) and the variance of that mean.",
            )
            .mode(Mode::Either)
            .seeded()
            // Measured (max RSS of graphs/farm_shot.yaml's 2 frames at 640×480 and 1920×1080):
            // 32 MiB + 96 B/pixel.
            .memory(vfxgraph_engine::Memory::Image {
                base_mib: 64,
                bytes_per_pixel: 96,
            })
            .options::<RenderOptions>(),
            RENDER_INPUTS,
        )
        .output(IMAGE)
        .output(VARIANCE),
        run_render,
    );
}

fn run_read_scene(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let file = read_scene_file(&ctx.path("path"))?;
    // The OBJ meshes and dome image it read are part of the cache key (an edit reruns).
    for f in &file.files {
        ctx.declare_input_file(f)?;
    }
    ctx.set(SCENE, SceneArt::new(file.scene, file.dome));
    Ok(())
}

/// The camera of frame `frame` (this instance's: `ctx.frame()`): the scene's, or that frame's
/// pose of input `ports.cameras` with K from `ports.intrinsics`, the path's own K, or the
/// scene camera (book §2.8), then the size override (vfxgraph-render's `camera_for_frame`).
pub(crate) fn camera_for(
    ctx: &Context<'_>,
    ports: SceneInputs,
    scene: &Scene,
    frame: Option<i64>,
) -> Result<Camera, NodeError> {
    let path = ctx.get(ports.cameras)?.map(|p| &p.0);
    let k = crate::intrinsics_or_path_k(ctx, ports.intrinsics, path)?.map(|k| SolvedK {
        k: rows(&k.k()),
        size: k.width.zip(k.height).map(|(w, h)| (w as usize, h as usize)),
        distortion: k.distortion,
    });
    let poses: Option<Vec<PathPose>> = path.map(|p| p.frames.iter().map(path_pose).collect());
    let size: ImageSize = ctx.options()?;
    camera_for_frame(
        scene.camera.as_ref(),
        k.as_ref(),
        poses.as_deref(),
        frame,
        &size,
    )
    .map_err(NodeError::from)
}

/// A matrix as the render crate takes it: an array of its rows.
pub(crate) fn rows(m: &Matrix3<f64>) -> [[f64; 3]; 3] {
    m.transpose().into()
}

/// A camera path's frame as render's pose.
pub(crate) fn path_pose(f: &FramePose) -> PathPose {
    let (r, t) = (&f.pose.r, &f.pose.t);
    PathPose {
        frame: f.frame as i64,
        r: rows(r),
        t: [t.x, t.y, t.z],
        focal: f.focal,
    }
}

/// The light of a render: the `dome` input if connected, else the scene's loaded dome, else its
/// background colour.
pub(crate) fn pick_light<'a>(
    ctx: &'a Context<'_>,
    art: &'a SceneArt,
) -> Result<Light<'a>, NodeError> {
    let input_dome = ctx.get(DOME)?.map(|d| &d.0);
    Light::pick(input_dome, art.dome.as_ref(), &art.scene).map_err(NodeError::msg)
}

fn run_render(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let o: RenderOptions = ctx.options()?;
    let art = ctx.get(RENDER_INPUTS.scene)?;
    let light = pick_light(ctx, art)?;
    let camera = camera_for(ctx, RENDER_INPUTS, &art.scene, ctx.frame())?;
    let (world, settings) = (o.world(&art.scene), o.settings(ctx.seed()));
    let progress = |x| ctx.progress(x);
    let out = with_sync_progress(progress, |progress| {
        let cancel = Some(ctx.cancel_flag());
        render(&world, light.env(), &camera, &settings, progress, cancel)
    })?;
    RenderError::check_finite(out.stats.nonfinite)?;
    ctx.set(IMAGE, ImageArt(out.image));
    ctx.set(VARIANCE, ImageArt(out.variance));
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{params, spec};
    use nalgebra::Vector3;
    use std::path::Path;
    use vfxgraph_engine::{InputValue, ParamValue, Value};
    use vfxgraph_geometry::formats::{CameraPath, FramePose};
    use vfxgraph_geometry::Pose;
    use vfxgraph_imaging::Image;

    const SCN: &str = "scene{ camera = view{ from = {0,-4,1}, at = {0,0,0.5}, fov = 60, imgw = 32, imgh = 24 }
      polylight{ color = {3,3,3}, shape = trilist{ {{-1,-1,3},{1,-1,3},{1,1,3}} } }
      object = primobj{ material = plastic{ kd = .5, ks = .4, se = 30 }, shape = sphere{ center = {0,0,0.6}, radius = .6 } }
      object = polyobj{ material = plastic{ kd = .8 }, shape = trilist{ {{-5,-5,0},{5,-5,0},{5,5,0}}, {{-5,-5,0},{5,5,0},{-5,5,0}} } } }";

    /// A white-furnace YAML scene: an albedo-1 sphere inside a dome whose image is constant.
    const FURNACE: &str = "camera:\n  look_at: {from: [0, 0, 4], at: [0, 0, 0], fov: 40}\n  size: [12, 8]\nobjects:\n  - sphere: {center: [0, 0, 0], radius: 1}\n    material: {type: lambert, albedo: 1}\ndome: {image: sky.pfm, scale: 2}\n";

    fn read(dir: &Path, name: &str) -> Result<SceneArt, NodeError> {
        let rs = spec("read_scene");
        let ps = params(&rs, &[("path", ParamValue::Str(name.into()))]);
        let mut ctx = Context::for_test(&rs, &ps, dir, None, vec![]);
        run_read_scene(&mut ctx)?;
        Ok(ctx.take_output::<SceneArt>("scene").unwrap())
    }

    fn render_node(
        scene: SceneArt,
        frame: Option<i64>,
        extra: Vec<(&'static str, InputValue)>,
        set: &[(&str, ParamValue)],
    ) -> Result<Image, NodeError> {
        let sp = spec("render");
        let mut set = set.to_vec();
        if !set.iter().any(|(k, _)| *k == "spp") {
            set.push(("spp", ParamValue::Int(8)));
        }
        let ps = params(&sp, &set);
        let dir = std::env::temp_dir();
        let mut inputs = vec![("scene", InputValue::One(Value::new(scene)))];
        inputs.extend(extra);
        let mut ctx = Context::for_test(&sp, &ps, &dir, frame, inputs);
        run_render(&mut ctx)?;
        Ok(ctx.take_output::<ImageArt>("image").unwrap().0)
    }

    fn encoded<T: ArtifactType>(v: &T) -> Vec<u8> {
        let mut b = Vec::new();
        v.encode(&mut b);
        b
    }

    #[test]
    fn read_then_render() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("s.scn"), SCN).unwrap();
        let scene = read(dir.path(), "s.scn").unwrap();
        // Canonical round trip.
        let bytes = encoded(&scene);
        assert_eq!(encoded(&SceneArt::decode(&bytes).unwrap()), bytes);
        assert!(SceneArt::decode(b"{}").is_err());
        let img = render_node(
            scene,
            None,
            vec![],
            &[
                ("max_depth", ParamValue::Int(3)),
                ("width", ParamValue::Int(16)),
            ],
        )
        .unwrap();
        assert_eq!((img.width, img.height, img.channels), (16, 24, 3));
        assert!(img.data.iter().all(|v| v.is_finite()));
        assert!(img.data.iter().any(|&v| v > 0.0));
    }

    /// Mean of the image and the largest deviation from `want`.
    fn spread(img: &Image, want: f32) -> (f32, f32) {
        let mean = img.data.iter().sum::<f32>() / img.data.len() as f32;
        let dev = img
            .data
            .iter()
            .map(|v| (v - want).abs())
            .fold(0.0, f32::max);
        (mean, dev)
    }

    #[test]
    fn yaml_scene_with_a_dome_image_is_a_white_furnace() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("f.yaml"), FURNACE).unwrap();
        let sky = Image::from_fn(16, 8, 3, |_, _, _| 0.25);
        vfxgraph_imaging::io::write_image(&dir.path().join("sky.pfm"), &sky).unwrap();
        let scene = read(dir.path(), "f.yaml").unwrap();
        assert!(scene.dome.is_some());
        let bytes = encoded(&scene);
        assert_eq!(encoded(&SceneArt::decode(&bytes).unwrap()), bytes);
        // Dome radiance 0.25 × scale 2: every pixel sees 0.5 (sphere or dome).
        let img = render_node(
            scene.clone(),
            None,
            vec![],
            &[("max_depth", ParamValue::Int(64))],
        )
        .unwrap();
        let (mean, dev) = spread(&img, 0.5);
        assert!((mean - 0.5).abs() < 0.01 && dev < 0.15, "{mean} {dev}");
        // A `dome` input replaces the scene's dome.
        let other = Dome::y_up(&Image::from_fn(8, 4, 3, |_, _, _| 0.125)).unwrap();
        let img = render_node(
            scene,
            None,
            vec![("dome", InputValue::One(Value::new(DomeArt(other))))],
            &[("max_depth", ParamValue::Int(64))],
        )
        .unwrap();
        let (mean, dev) = spread(&img, 0.125);
        assert!((mean - 0.125).abs() < 0.003 && dev < 0.04, "{mean} {dev}");
    }

    #[test]
    fn scn_hdrdome_lights_the_scene() {
        // The book's hdrscene/hdrdome with a constant image: an albedo-1 sphere (kd = 1,
        // d_col white) renders the dome's radiance everywhere.
        let dir = tempfile::tempdir().unwrap();
        let scn = "hdrscene{ hdrdome{ orig = {1, 0, 0}, south = {0, 0, 1}, hdrimg = \"sky.pfm\" }
          camera = view{ from = {0,-4,0}, at = {0,0,0}, fov = 40, imgw = 12, imgh = 8 }
          object = primobj{ material = plastic{ kd = 1 }, shape = sphere{ center = {0,0,0}, radius = 1 } } }";
        std::fs::write(dir.path().join("d.scn"), scn).unwrap();
        let sky = Image::from_fn(16, 8, 3, |_, _, _| 0.5);
        vfxgraph_imaging::io::write_image(&dir.path().join("sky.pfm"), &sky).unwrap();
        let scene = read(dir.path(), "d.scn").unwrap();
        assert!(scene.dome.is_some());
        let img = render_node(scene, None, vec![], &[("max_depth", ParamValue::Int(64))]).unwrap();
        let (mean, dev) = spread(&img, 0.5);
        assert!((mean - 0.5).abs() < 0.01 && dev < 0.15, "{mean} {dev}");
    }

    #[test]
    fn a_dome_image_that_is_missing_needs_a_dome_input() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("f.yaml"), FURNACE).unwrap();
        let scene = read(dir.path(), "f.yaml").unwrap();
        assert!(scene.dome.is_none() && scene.scene.dome.is_some());
        let e = render_node(scene, None, vec![], &[]).unwrap_err();
        assert!(
            e.message.contains("sky.pfm") && e.message.contains("`dome` input"),
            "{e}"
        );
    }

    #[test]
    fn catchers_only_drops_the_synthetic_objects() {
        let dir = tempfile::tempdir().unwrap();
        // A catcher floor under a black sphere, seen from above in a unit sky.
        let text = "camera:\n  look_at: {from: [0, 3, 0.001], at: [0, 0, 0], fov: 30}\n  size: [9, 9]\nobjects:\n  - sphere: {center: [0, 0.6, 0], radius: 0.5}\n    material: {type: lambert, albedo: 0}\n  - quad: {corner: [-5, 0, -5], edge1: [10, 0, 0], edge2: [0, 0, 10]}\n    catcher: true\ndome: {color: 1}\n";
        std::fs::write(dir.path().join("c.yaml"), text).unwrap();
        let scene = read(dir.path(), "c.yaml").unwrap();
        let spp = ("spp", ParamValue::Int(256));
        let all = render_node(scene.clone(), None, vec![], std::slice::from_ref(&spp)).unwrap();
        let empty = render_node(
            scene,
            None,
            vec![],
            &[spp, ("objects", ParamValue::Str("catchers_only".into()))],
        )
        .unwrap();
        // Centre pixel: the black sphere (all) vs the bare floor (albedo 0.8 under a unit sky).
        let (c_all, c_empty) = (all.get(4, 4, 1), empty.get(4, 4, 1));
        assert!((c_empty - 0.8).abs() < 0.05, "{c_empty}");
        assert!(c_all == 0.0, "{c_all}");
    }

    #[test]
    fn cameras_input_renders_frame_f() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("s.scn"), SCN).unwrap();
        let scene = read(dir.path(), "s.scn").unwrap();
        let c = scene.scene.camera.as_ref().unwrap();
        let pose_of = |dx: f64| Pose {
            r: nalgebra::Matrix3::from_fn(|i, j| c.r[i][j]),
            t: Vector3::new(c.t[0] + dx, c.t[1], c.t[2]),
        };
        let path = CameraPath {
            frames: vec![
                FramePose {
                    frame: 3,
                    pose: pose_of(0.0),
                    focal: None,
                },
                FramePose {
                    frame: 4,
                    pose: pose_of(0.5),
                    focal: None,
                },
            ],
            intrinsics: None,
        };
        let cams = || {
            vec![(
                "cameras",
                InputValue::One(Value::new(CameraPathArt(path.clone()))),
            )]
        };
        let base = render_node(scene.clone(), Some(3), vec![], &[]).unwrap();
        // Frame 3's camera is the scene's: the same image; frame 4's moved: another image.
        assert_eq!(
            render_node(scene.clone(), Some(3), cams(), &[]).unwrap(),
            base
        );
        assert_ne!(
            render_node(scene.clone(), Some(4), cams(), &[]).unwrap(),
            base
        );
        let e = render_node(scene.clone(), Some(7), cams(), &[]).unwrap_err();
        assert!(
            e.message.contains("no camera for frame 7") && e.message.contains("3–4"),
            "{e}"
        );
        let e = render_node(scene, None, cams(), &[]).unwrap_err();
        assert!(e.message.contains("per_frame: true"), "{e}");
    }

    /// A scene without a camera renders through a camera path whose K carries the image size,
    /// exactly as one whose camera the path replaces; without a pose, a K or an image size, the
    /// error says which is missing.
    #[test]
    fn a_scene_without_a_camera_is_seen_through_the_path() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("s.scn"), SCN).unwrap();
        let scene = read(dir.path(), "s.scn").unwrap();
        let c = scene.scene.camera.clone().unwrap();
        let k = vfxgraph_geometry::Intrinsics {
            s: c.k[0][1],
            ..vfxgraph_geometry::Intrinsics::new(c.k[0][0], c.k[1][1], c.k[0][2], c.k[1][2])
        };
        let path = |k: Option<vfxgraph_geometry::Intrinsics>| CameraPath {
            frames: vec![FramePose {
                frame: 3,
                pose: Pose {
                    r: nalgebra::Matrix3::from_fn(|i, j| c.r[i][j]),
                    t: Vector3::from(c.t),
                },
                focal: None,
            }],
            intrinsics: k,
        };
        let cams = |k| {
            vec![(
                "cameras",
                InputValue::One(Value::new(CameraPathArt(path(k)))),
            )]
        };
        let base = render_node(scene.clone(), Some(3), vec![], &[]).unwrap();
        let mut bare = scene.clone();
        bare.scene.camera = None;
        let sized = k.clone().with_size(c.width as u32, c.height as u32);
        assert_eq!(
            render_node(bare.clone(), Some(3), cams(Some(sized)), &[]).unwrap(),
            base
        );
        for (inputs, want) in [
            (vec![], "no `cameras` input"),
            (cams(None), "carries K"),
            (cams(Some(k)), "no image size"),
        ] {
            let e = render_node(bare.clone(), Some(3), inputs, &[]).unwrap_err();
            assert!(
                e.message
                    .starts_with("no camera: the scene has no `camera:`")
                    && e.message.contains(want),
                "{e}"
            );
        }
    }

    #[test]
    fn scene_errors_name_file_line_and_column() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(
            dir.path().join("bad.scn"),
            "scene{\n  camera = view{ fov = 0 }\n}",
        )
        .unwrap();
        std::fs::write(
            dir.path().join("bad.yaml"),
            "camera:\n  look_at: {from: [0, 0, 1], at: [0, 0, 0]}\n  size: [8, 8]\nobjects:\n  - obj: m.obj\n",
        )
        .unwrap();
        std::fs::write(dir.path().join("m.obj"), "v 0 0 0\nf 1 2 3\n").unwrap();
        std::fs::write(dir.path().join("x.obj"), "").unwrap();
        for (name, want) in [
            ("bad.scn", "bad.scn:2:12"),
            ("bad.yaml", "bad.yaml:5:10: "),
            ("bad.yaml", "m.obj:2: face corner"),
            ("x.obj", "unknown scene format"),
            ("missing.scn", "cannot read"),
        ] {
            let e = read(dir.path(), name).unwrap_err();
            assert!(e.message.contains(want), "{e}");
        }
    }
}
