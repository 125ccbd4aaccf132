//! Rendering nodes (book ch. 9): `read_scene` reads the book's `.scn` scene language into a
//! `scene` artifact; `render` path-traces it to a linear HDR image (write it with
//! `write_image` to EXR/PFM, or `tonemap` + PNG).

use std::sync::Mutex;

use vfxgraph_engine::artifact::{decode_json, encode_json};
use vfxgraph_engine::{
    ArtifactType, Context, Mode, NodeError, NodeSpec, ParamSpec, ParamType, ParamValue, PathRole,
    PortSpec, Registry,
};
use vfxgraph_render::{
    parse_scn, render, ConstantEnvironment, RenderSettings, Scene, Strategy, World,
};

use crate::artifacts::ImageArt;
use crate::FnNode;

/// A scene (`scene`): camera, objects, lights, dome, shadow catchers (book §9.13, §10).
#[derive(Clone, Debug, PartialEq)]
pub struct SceneArt(pub Scene);

impl ArtifactType for SceneArt {
    const NAME: &'static str = "scene";
    const DOC: &'static str = "A scene to render: camera (K[R|t] and image size), objects \
        (spheres, triangles) with materials (Lambert, mirror, normalized Blinn-Phong), \
        polygonal area lights, background or HDR dome, shadow catchers (book ch. 9-10).";
    fn encode(&self, out: &mut Vec<u8>) {
        encode_json(&self.0, out)
    }
    fn decode(bytes: &[u8]) -> Result<Self, String> {
        let scene: Scene = decode_json(bytes)?;
        scene.camera.validate().map_err(|e| e.to_string())?;
        Ok(SceneArt(scene))
    }
}

/// Registers the artifact and nodes of this module.
pub fn register(r: &mut Registry) {
    r.register_artifact::<SceneArt>();
    r.register_node(FnNode::new(
        NodeSpec::new(
            "read_scene",
            "Reads a scene file: the book's S3D `.scn` language (scene/hdrscene, view, primobj, \
             polyobj, group, sphere, trilist, plastic, polylight, hdrdome, plshadow; book §9.13). \
             Errors name file:line:column. Polylight colours are multiplied by π and kd·d_col is \
             the diffuse albedo, so direct light matches the book's images (see the render \
             crate's `scn` docs).",
        )
        .mode(Mode::Once)
        .param(ParamSpec::required(
            "path",
            ParamType::Path(PathRole::Input),
            "the .scn file, relative to the graph file",
        ))
        .output(PortSpec::one("scene", SceneArt::NAME, "the scene")),
        run_read_scene,
    ));
    r.register_node(FnNode::new(
        NodeSpec::new(
            "render",
            "Path-traces a scene (book ch. 9): next-event estimation on the area lights with \
             multiple importance sampling, Russian roulette, one random stream per pixel (same \
             image for any thread count). Output: mean radiance per pixel (linear HDR) and the \
             variance of that mean.",
        )
        .mode(Mode::Either)
        .seeded()
        .param(ParamSpec::optional(
            "spp",
            ParamType::Int {
                min: 1,
                max: 1 << 20,
            },
            ParamValue::Int(64),
            "samples (paths) per pixel",
        ))
        .param(ParamSpec::optional(
            "max_depth",
            ParamType::Int { min: 0, max: 1024 },
            ParamValue::Int(8),
            "maximum scattering vertices per path (the book's bounces; its Cornell render used 3)",
        ))
        .param(ParamSpec::optional(
            "seed",
            ParamType::Int {
                min: 0,
                max: i64::MAX,
            },
            ParamValue::Int(0),
            "extra seed mixed into the graph seed",
        ))
        .param(ParamSpec::optional(
            "width",
            ParamType::Int { min: 0, max: 65536 },
            ParamValue::Int(0),
            "image width override (0 = the scene camera's; K is rescaled)",
        ))
        .param(ParamSpec::optional(
            "height",
            ParamType::Int { min: 0, max: 65536 },
            ParamValue::Int(0),
            "image height override (0 = the scene camera's)",
        ))
        .input(PortSpec::one("scene", SceneArt::NAME, "the scene"))
        .output(PortSpec::one(
            "image",
            ImageArt::NAME,
            "radiance, linear RGB",
        ))
        .output(PortSpec::one(
            "variance",
            ImageArt::NAME,
            "per-pixel variance of the mean, linear RGB",
        )),
        run_render,
    ));
}

fn run_read_scene(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let path = ctx.path("path");
    let text = std::fs::read_to_string(&path)
        .map_err(|e| NodeError::msg(format!("cannot read {}: {e}", path.display())))?;
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase();
    let scene = match ext.as_str() {
        "scn" => parse_scn(&text).map_err(|e| NodeError::msg(format!("{}:{e}", path.display())))?,
        _ => {
            return Err(NodeError::msg(format!(
                "{}: unknown scene format `.{ext}` (expected .scn)",
                path.display()
            )))
        }
    };
    ctx.output("scene", SceneArt(scene));
    Ok(())
}

fn run_render(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let scene = &ctx.input::<SceneArt>("scene")?.0;
    if scene.dome.is_some() {
        return Err(NodeError::msg(
            "the scene has an hdrdome: dome lighting needs the dome module (not merged yet)",
        ));
    }
    let p = ctx.params();
    let mut camera = scene.camera.clone();
    let (w, h) = (p.i64("width") as usize, p.i64("height") as usize);
    if w > 0 || h > 0 {
        let w = if w > 0 { w } else { camera.width };
        let h = if h > 0 { h } else { camera.height };
        camera = camera.resized(w, h);
    }
    let settings = RenderSettings {
        spp: p.i64("spp") as u32,
        max_depth: p.i64("max_depth") as u32,
        seed: ctx.seed() ^ (p.i64("seed") as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15),
        strategy: Strategy::Mis,
        ..Default::default()
    };
    let world = World::new(scene);
    let env = ConstantEnvironment {
        radiance: scene.background,
    };
    // The engine's progress callback is not `Sync`; serialize calls through a mutex.
    let out = {
        let progress = Mutex::new(|f: f32| ctx.progress(f));
        render(
            &world,
            &env,
            &camera,
            &settings,
            &|f| {
                if let Ok(cb) = progress.lock() {
                    cb(f)
                }
            },
            None,
        )
        .map_err(|e| NodeError::msg(e.to_string()))?
    };
    if out.stats.nonfinite > 0 {
        return Err(NodeError::msg(format!(
            "{} samples had non-finite radiance (a bug: please report the scene)",
            out.stats.nonfinite
        )));
    }
    ctx.output("image", ImageArt(out.image));
    ctx.output("variance", ImageArt(out.variance));
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::spec;
    use vfxgraph_engine::{InputValue, Params, Value};

    const SCN: &str = "scene{ camera = view{ from = {0,-4,1}, at = {0,0,0.5}, fov = 60, imgw = 32, imgh = 24 }
      polylight{ color = {3,3,3}, shape = trilist{ {{-1,-1,3},{1,-1,3},{1,1,3}} } }
      object = primobj{ material = plastic{ kd = .5, ks = .4, se = 30 }, shape = sphere{ center = {0,0,0.6}, radius = .6 } }
      object = polyobj{ material = plastic{ kd = .8 }, shape = trilist{ {{-5,-5,0},{5,-5,0},{5,5,0}}, {{-5,-5,0},{5,5,0},{-5,5,0}} } } }";

    #[test]
    fn read_then_render() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("s.scn"), SCN).unwrap();
        let rs = spec("read_scene");
        let params = Params::new([("path".to_string(), ParamValue::Str("s.scn".into()))].into());
        let mut ctx = Context::for_test(&rs, &params, dir.path(), None, vec![]);
        run_read_scene(&mut ctx).unwrap();
        let scene = ctx.take_output::<SceneArt>("scene").unwrap();
        // Canonical round trip.
        let mut bytes = Vec::new();
        scene.encode(&mut bytes);
        assert_eq!(SceneArt::decode(&bytes).unwrap(), scene);
        assert!(SceneArt::decode(b"{}").is_err());

        let sp = spec("render");
        let params = Params::new(
            [
                ("spp".to_string(), ParamValue::Int(4)),
                ("max_depth".to_string(), ParamValue::Int(3)),
                ("seed".to_string(), ParamValue::Int(0)),
                ("width".to_string(), ParamValue::Int(16)),
                ("height".to_string(), ParamValue::Int(0)),
            ]
            .into(),
        );
        let mut ctx = Context::for_test(
            &sp,
            &params,
            dir.path(),
            None,
            vec![("scene", InputValue::One(Value::new(scene)))],
        );
        run_render(&mut ctx).unwrap();
        let img = ctx.take_output::<ImageArt>("image").unwrap().0;
        assert_eq!((img.width, img.height, img.channels), (16, 24, 3));
        assert!(img.data.iter().all(|v| v.is_finite()));
        assert!(img.data.iter().any(|&v| v > 0.0));
    }

    #[test]
    fn scene_errors_name_file_line_and_column() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(
            dir.path().join("bad.scn"),
            "scene{\n  camera = view{ fov = 0 }\n}",
        )
        .unwrap();
        std::fs::write(dir.path().join("x.obj"), "").unwrap();
        let rs = spec("read_scene");
        for (name, want) in [
            ("bad.scn", "bad.scn:2:12"),
            ("x.obj", "unknown scene format"),
            ("missing.scn", "cannot read"),
        ] {
            let params = Params::new([("path".to_string(), ParamValue::Str(name.into()))].into());
            let mut ctx = Context::for_test(&rs, &params, dir.path(), None, vec![]);
            let e = run_read_scene(&mut ctx).unwrap_err();
            assert!(e.message.contains(want), "{e}");
        }
    }
}
