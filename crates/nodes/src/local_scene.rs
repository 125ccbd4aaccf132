//! The local scene from the plate (docs/validation/book-shot.md, "The local scene from the plate"; Debevec 1998 §4,
//! book §10.10.1): `catcher_texture` estimates a shadow catcher's diffuse albedo per texel from
//! clean plate frames (the algorithm: [`vfxgraph_render::catcher_texture`]); `proxy_from_points`
//! adds boxes and plane patches of the real set, built from measured points, as catchers
//! ([`vfxgraph_render::proxy`]); `add_objects` puts the designed CG objects into that local scene last, so the local scene's
//! nodes never see them and a change of an object reruns only what renders it.

use vfxgraph_engine::{Context, In, NodeError, NodeSpec, Out, Registry, SeqIn};
use vfxgraph_render::catcher_texture::View;
use vfxgraph_render::local_scene::{add_objects, texture_local_scene_report, LocalTextureOptions};
use vfxgraph_render::plate::plate_frames;
use vfxgraph_render::proxy::{add_proxies, ProxyOptions};
use vfxgraph_render::ImageSize;

use crate::artifacts::{image_sequence, ImageArt, Points3dArt, ReportArt};
use crate::placement::measured;
use crate::render::{camera_for, pick_light, scene_inputs, SceneArt};
use crate::shot::SHOT_INPUTS;

fn run_proxy_from_points(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let o: ProxyOptions = ctx.options()?;
    let art = ctx.get(PLACED_SCENE)?;
    let (scene, report) =
        add_proxies(&art.scene, &measured(ctx, POINTS3D)?, &o).map_err(NodeError::msg)?;
    ctx.set(WITH_PROXIES, SceneArt::new(scene, art.dome.clone()));
    ctx.set(PROXY_REPORT, ReportArt(report));
    Ok(())
}

fn run_add_objects(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let local = ctx.get(LOCAL_SCENE)?;
    let cg = ctx.get(OBJECTS)?;
    let scene = add_objects(&local.scene, &cg.scene).map_err(NodeError::msg)?;
    ctx.set(WITH_OBJECTS, SceneArt::new(scene, local.dome.clone()));
    Ok(())
}

const LOCAL_SCENE: In<SceneArt> = In::new("scene", "the local scene");
const OBJECTS: In<SceneArt> = In::new(
    "objects",
    "the placed insert (its catchers, camera and dome are not used)",
);
const WITH_OBJECTS: Out<SceneArt> = Out::new("scene", "the local scene with the objects");
const PLACED_SCENE: In<SceneArt> = In::new("scene", "the placed scene");
const POINTS3D: In<Points3dArt> = In::new("points3d", "the measured points");
const WITH_PROXIES: Out<SceneArt> =
    Out::new("scene", "the scene with the proxies' faces as catchers");
const PROXY_REPORT: Out<ReportArt> = Out::new("report", "proxies made");
const PLATE: SeqIn<ImageArt> = SeqIn::new("plate", "the plate frames (linear radiance)");
const TEXTURED: Out<SceneArt> = Out::new("scene", "the scene with the catcher's albedo texture");
const ALBEDO: Out<ImageArt> = Out::new(
    "albedo",
    "the estimated albedo, linear RGB; column i along the map's u edge, row j along v \
             (see the report's map corners)",
);
const SEEN: Out<ImageArt> = Out::new("seen", "frames that saw each texel (one channel)");
const TEXTURE_REPORT: Out<ReportArt> = Out::new("report", "the estimate");

/// Registers the nodes of this module.
pub fn register(r: &mut Registry) {
    r.register_fn(
        NodeSpec::new(
            "add_objects",
            "The designed CG objects put into the local scene: `scene`'s camera, dome, lights \
             and catchers (the fitted, textured, proxied local scene) with every non-catcher \
             object and light of `objects` (the placed insert) added. Build the local scene \
             from the set alone and add the objects last: a change of an object's material \
             then reruns only this node and the renders, never the catcher fit or texture.",
        )
        .input(LOCAL_SCENE)
        .input(OBJECTS)
        .output(WITH_OBJECTS),
        run_add_objects,
    );
    r.register_fn(
        NodeSpec::new(
            "proxy_from_points",
            "Proxy geometry of the real set from measured points (point_cloud_calibrate's \
             `points3d`): a box from three base corners and the corner above the first, a plane \
             patch from its 4 corners. Every face is added as a planar shadow catcher (give it \
             its texture with catcher_texture), so it receives the objects' shadows, is seen \
             in their reflections and occludes the dome for their lighting.",
        )
        .options::<ProxyOptions>()
        .input(PLACED_SCENE)
        .input(POINTS3D)
        .output(WITH_PROXIES)
        .output(PROXY_REPORT),
        run_proxy_from_points,
    );
    r.register_fn(
        scene_inputs(
            NodeSpec::new(
                "catcher_texture",
                "The textured shadow catcher (Debevec 1998's local scene; book §10.10.1's \
                 catcher, per texel): per texel of the catcher's plane, albedo = π × plate \
                 radiance / irradiance, the irradiance rendered there from the dome and the \
                 local scene (catchers, no synthetic objects), the plate read where each \
                 pixel's ray meets the catcher first; combined over the frames by the median, \
                 clamped to [0, max_albedo]. Texels never seen keep the catcher's (fitted) \
                 uniform colour; with `others`, a proxy's unseen faces and texels take the \
                 median albedo of its seen texels. The plate frames must be clean: give the \
                 frames without the objects in `frames`. Outputs the scene with the texture \
                 on the catcher (sampled bilinearly by the renders), the albedo image (write it \
                 as EXR), the frames-seen count per texel and a report (texels estimated, \
                 clamped fraction, what became of each proxy face).",
            )
            .seeded()
            // 2: the report gives each proxy face's centre, normal, median albedo, irradiance;
            // 3: a face's irradiance on the side the plate sees it from, and the irradiance
            // grid's points no camera sees (under a box) left out of the interpolation.
            .version(3)
            .options::<LocalTextureOptions>()
            .options::<ImageSize>(),
            SHOT_INPUTS,
        )
        .input(PLATE)
        .output(TEXTURED)
        .output(ALBEDO)
        .output(SEEN)
        .output(TEXTURE_REPORT),
        run_catcher_texture,
    );
}

fn run_catcher_texture(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let o: LocalTextureOptions = ctx.options()?;
    let art = ctx.get(SHOT_INPUTS.scene)?;
    let light = pick_light(ctx, art)?;
    let frames: Vec<i64> = o.frames.iter().map(|&f| f as i64).collect();
    let plates = plate_frames(&image_sequence(ctx, PLATE)?, &frames)
        .map_err(|e| NodeError::msg(format!("param `frames`: {e}")))?;
    let cameras = plates
        .iter()
        .map(|(f, _)| camera_for(ctx, SHOT_INPUTS, &art.scene, Some(*f)))
        .collect::<Result<Vec<_>, _>>()?;
    let views: Vec<View> = plates
        .iter()
        .zip(&cameras)
        .map(|(&(frame, plate), camera)| View::new(frame, camera, plate))
        .collect();
    let out = texture_local_scene_report(
        &art.scene,
        light.env(),
        &views,
        &o,
        ctx.seed(),
        Some(ctx.cancel_flag()),
    )?;
    ctx.set(TEXTURED, SceneArt::new(out.scene, art.dome.clone()));
    ctx.set(ALBEDO, ImageArt(out.albedo));
    ctx.set(SEEN, ImageArt(out.seen));
    ctx.set(TEXTURE_REPORT, ReportArt(out.report));
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{params, spec};
    use nalgebra::Point3;
    use std::path::Path;
    use vfxgraph_engine::{InputValue, ParamValue, Value};
    use vfxgraph_geometry::Points3d;
    use vfxgraph_imaging::Image;

    fn scene(camera_at: &str) -> SceneArt {
        let yaml = format!(
            "camera:\n  look_at: {{from: [0, -4, 2], at: {camera_at}, up: [0, 0, 1], fov: 50}}\n  \
             size: [16, 12]\nobjects:\n  - quad: {{corner: [-2, -2, 0], edge1: [4, 0, 0], \
             edge2: [0, 4, 0]}}\n    material: {{type: lambert, albedo: 0.3}}\n    catcher: true\n\
             dome: {{color: [1, 1, 1]}}\n"
        );
        let s = vfxgraph_render::parse_yaml_scene(&yaml, Path::new(".")).unwrap();
        SceneArt {
            scene: s.scene,
            dome: None,
        }
    }

    fn list(v: &[f64]) -> ParamValue {
        ParamValue::List(v.iter().map(|&x| ParamValue::Float(x)).collect())
    }

    fn run(
        node: &str,
        set: &[(&str, ParamValue)],
        inputs: Vec<(&'static str, InputValue)>,
        f: fn(&mut Context<'_>) -> Result<(), NodeError>,
    ) -> Result<(), NodeError> {
        let sp = spec(node);
        let ps = params(&sp, set);
        let dir = std::env::temp_dir();
        let mut ctx = Context::for_test(&sp, &ps, &dir, None, inputs);
        f(&mut ctx)
    }

    fn plate() -> InputValue<'static> {
        InputValue::Sequence(vec![
            (3, Value::new(ImageArt(Image::new(16, 12, 3)))),
            (4, Value::new(ImageArt(Image::new(16, 12, 3)))),
        ])
    }

    #[test]
    fn a_frame_outside_the_shot_or_a_catcher_never_seen_is_a_clear_error() {
        let s = scene("[0, 0, 0]");
        let e = run(
            "catcher_texture",
            &[("frames", list(&[3.0, 9.0]))],
            vec![
                ("scene", InputValue::One(Value::new(s.clone()))),
                ("plate", plate()),
            ],
            run_catcher_texture,
        )
        .unwrap_err();
        assert!(
            e.to_string().contains("no frame 9 (its frames are 3–4)"),
            "{e}"
        );
        // The camera looks up, away from the ground.
        let up = scene("[0, 0, 40]");
        let e = run(
            "catcher_texture",
            &[],
            vec![
                ("scene", InputValue::One(Value::new(up))),
                ("plate", plate()),
            ],
            run_catcher_texture,
        )
        .unwrap_err();
        assert!(
            e.to_string().contains("is seen by any of the 2 frames"),
            "{e}"
        );
    }

    #[test]
    fn proxies_from_too_few_points_are_a_clear_error() {
        let s = scene("[0, 0, 0]");
        let pts = InputValue::One(Value::new(Points3dArt(Points3d(vec![
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(1.0, 1.0, 0.0),
            Point3::new(0.0, 0.0, 0.5),
        ]))));
        let inputs = || {
            vec![
                ("scene", InputValue::One(Value::new(s.clone()))),
                ("points3d", pts.clone()),
            ]
        };
        let e = run(
            "proxy_from_points",
            &[("boxes", list(&[0.0, 1.0, 2.0]))],
            inputs(),
            run_proxy_from_points,
        )
        .unwrap_err();
        assert!(
            e.to_string()
                .contains("box 0 has 3 point indices, a box needs 4"),
            "{e}"
        );
        let e = run(
            "proxy_from_points",
            &[("planes", list(&[0.0, 1.0, 2.0, 7.0]))],
            inputs(),
            run_proxy_from_points,
        )
        .unwrap_err();
        assert!(e.to_string().contains("7 is not the index"), "{e}");
        run(
            "proxy_from_points",
            &[("boxes", list(&[0.0, 1.0, 2.0, 3.0]))],
            inputs(),
            run_proxy_from_points,
        )
        .unwrap();
    }
}
