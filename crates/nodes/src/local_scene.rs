//! The local scene from the plate (issue 17; Debevec 1998 §4, book §10.10.1): `catcher_texture`
//! estimates a shadow catcher's diffuse albedo per texel from clean plate frames (the algorithm:
//! [`vfxgraph_render::catcher_texture`]); `proxy_from_points` adds boxes and plane patches of
//! the real set, built from measured points, as catchers ([`vfxgraph_render::proxy`]);
//! `add_objects` puts the designed CG objects into that local scene last, so the local scene's
//! nodes never see them and a change of an object reruns only what renders it.

use vfxgraph_engine::{ArtifactType, Context, NodeError, NodeSpec, PortSpec, Registry};
use vfxgraph_imaging::Image;
use vfxgraph_params::Options;
use vfxgraph_render::catcher_texture::{TextureOptions, View};
use vfxgraph_render::local_scene::{texture_local_scene, FaceTexture};

use vfxgraph_render::proxy::{box_faces, box_on_plane, catchers, plane_patch};
use vfxgraph_render::{Rgb, Shape, Vec3};

use crate::artifacts::{ImageArt, Points3dArt, ReportArt};
use crate::hdr::DomeArt;
use crate::render::{camera_for_frame, pick_light, SceneArt};
use crate::shot::{light_and_camera_inputs, size_params};
use crate::FnNode;

/// The params of `catcher_texture`.
#[derive(Debug, PartialEq, Options)]
#[param(check)]
pub(crate) struct CatcherTextureParams {
    /// the plate frames to estimate from, which must be clean (without the CG objects or their shadows); empty = every frame of the plate
    frames: Vec<f64>,
    /// which shadow catcher (0 = the scene's first), a planar one
    catcher: usize,
    /// texels along the catcher's longer side
    #[param(range = 1..=8192)]
    resolution: usize,
    /// spacing of the irradiance grid, in texels (irradiance is smooth away from contact shadows)
    #[param(range = 1..=256)]
    irradiance_cell: usize,
    /// paths per irradiance grid point
    #[param(range = 1..=1048576)]
    irradiance_samples: u32,
    /// maximum scattering vertices of the irradiance paths
    #[param(range = 1..=64)]
    max_depth: u32,
    /// a texel is estimated when seen in at least this many frames (else it keeps the uniform colour)
    #[param(range = 1..=100000)]
    min_frames: usize,
    /// the physical albedo range's upper end (estimates are clamped to [0, max_albedo])
    #[param(range = 0.01..=1.0)]
    max_albedo: f64,
    /// estimates, each rendering the irradiance with the previous texture (catchers that see one another)
    #[param(range = 1..=10)]
    iterations: usize,
    /// also texture every other planar catcher the frames see (proxy faces), after `catcher`; a proxy's faces and texels no frame sees take the median albedo of its seen texels
    others: bool,
    /// texels along the longer side of each other catcher
    #[param(range = 1..=8192)]
    others_resolution: usize,
}

impl CatcherTextureParams {
    fn check(&self) -> Result<(), String> {
        if let Some(f) = self.frames.iter().find(|f| f.fract() != 0.0) {
            return Err(format!("param `frames`: {f} is not a frame number"));
        }
        Ok(())
    }
}

impl Default for CatcherTextureParams {
    fn default() -> Self {
        let d = TextureOptions::default();
        CatcherTextureParams {
            frames: Vec::new(),
            catcher: d.catcher,
            resolution: d.resolution,
            irradiance_cell: 8,
            irradiance_samples: 1024,
            max_depth: d.max_depth,
            min_frames: d.min_frames,
            max_albedo: d.max_albedo,
            iterations: d.iterations,
            others: true,
            others_resolution: 64,
        }
    }
}

/// The params of `proxy_from_points`.
#[derive(Debug, PartialEq, Options)]
pub(crate) struct ProxyParams {
    /// boxes, 4 indices into `points3d` each: three base corners a, b, c (b adjacent to a and c) and the corner above a
    boxes: Vec<f64>,
    /// boxes standing on the first catcher's plane (the ground), 3 indices into `points3d` each: top corners a, b, c (b adjacent to a and c) — for a box whose base corners are hidden
    tops: Vec<f64>,
    /// plane patches, 4 indices into `points3d` each: the corners in order around the patch
    planes: Vec<f64>,
    /// the proxies' starting diffuse colour (catcher_texture then estimates it from the plate)
    albedo: Vec<f64>,
}

impl Default for ProxyParams {
    fn default() -> Self {
        ProxyParams {
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
) -> Result<Vec<Vec<Vec3>>, NodeError> {
    indices
        .chunks(size)
        .enumerate()
        .map(|(g, c)| {
            let one = if what == "planes" {
                "plane patch"
            } else {
                "box"
            };
            if c.len() < size {
                return Err(NodeError::msg(format!(
                    "param `{what}`: {} {g} has {} point indices, a {} needs {size}",
                    one,
                    c.len(),
                    one
                )));
            }
            c.iter()
                .map(|&i| {
                    if i.fract() != 0.0 || i < 0.0 || i as usize >= pts.len() {
                        Err(NodeError::msg(format!(
                            "param `{what}`: {i} is not the index of one of the {} measured \
                             points (0-based)",
                            pts.len()
                        )))
                    } else {
                        Ok(pts[i as usize])
                    }
                })
                .collect()
        })
        .collect()
}

/// A point on the scene's first catcher (the ground) and its normal, from its first triangle.
fn ground_plane(scene: &vfxgraph_render::Scene) -> Result<(Vec3, Vec3), NodeError> {
    let tri = scene
        .catchers()
        .find_map(|o| match &o.shape {
            Shape::Triangles { triangles } => triangles.first().copied(),
            _ => None,
        })
        .ok_or_else(|| {
            NodeError::msg(
                "param `tops`: a box by its top stands on the first catcher's plane, but the \
                 scene has no triangle catcher",
            )
        })?;
    Ok((tri[0], (tri[1] - tri[0]).cross(tri[2] - tri[0])))
}

fn run_proxy_from_points(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let p: ProxyParams = ctx.options()?;
    let art = ctx.input::<SceneArt>("scene")?;
    let pts: Vec<Vec3> = ctx
        .input::<Points3dArt>("points3d")?
        .0
         .0
        .iter()
        .map(|p| Vec3::new(p.x, p.y, p.z))
        .collect();
    if p.boxes.is_empty() && p.tops.is_empty() && p.planes.is_empty() {
        return Err(NodeError::msg(
            "no proxies: give `boxes`, `planes` (4 point indices each) and/or `tops` (3)",
        ));
    }
    if p.albedo.len() != 3 || p.albedo.iter().any(|a| !(0.0..=1.0).contains(a)) {
        return Err(NodeError::msg("param `albedo`: 3 values in [0, 1]"));
    }
    let albedo = Rgb::new(p.albedo[0], p.albedo[1], p.albedo[2]);
    let mut scene = art.scene.clone();
    let mut faces = 0;
    for (g, q) in groups(&pts, &p.boxes, "boxes", 4)?.iter().enumerate() {
        let f = box_faces(q).map_err(|e| NodeError::msg(format!("box {g}: {e}")))?;
        faces += f.len();
        scene.objects.extend(catchers(f, albedo));
    }
    let tops = groups(&pts, &p.tops, "tops", 3)?;
    if !tops.is_empty() {
        let (origin, normal) = ground_plane(&art.scene)?;
        for (g, q) in tops.iter().enumerate() {
            let f = box_on_plane(q, origin, normal)
                .map_err(|e| NodeError::msg(format!("tops box {g}: {e}")))?;
            faces += f.len();
            scene.objects.extend(catchers(f, albedo));
        }
    }
    for (g, q) in groups(&pts, &p.planes, "planes", 4)?.iter().enumerate() {
        let f = plane_patch(q).map_err(|e| NodeError::msg(format!("plane {g}: {e}")))?;
        faces += 1;
        scene.objects.extend(catchers(vec![f], albedo));
    }
    let report = serde_json::json!({
        "boxes": p.boxes.len() / 4 + p.tops.len() / 3,
        "planes": p.planes.len() / 4,
        "catcher_faces": faces,
    });
    let dome = art.dome.clone();
    ctx.output("scene", SceneArt { scene, dome });
    ctx.output("report", ReportArt(report));
    Ok(())
}

fn run_add_objects(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let local = ctx.input::<SceneArt>("scene")?;
    let cg = ctx.input::<SceneArt>("objects")?;
    let insert: Vec<_> = cg
        .scene
        .objects
        .iter()
        .filter(|o| !o.catcher)
        .cloned()
        .collect();
    if insert.is_empty() {
        return Err(NodeError::msg(format!(
            "the `objects` scene has no synthetic objects (its {} objects are all shadow \
             catchers)",
            cg.scene.objects.len()
        )));
    }
    let mut scene = local.scene.clone();
    scene.objects.extend(insert);
    scene.lights.extend(cg.scene.lights.iter().cloned());
    let dome = local.dome.clone();
    ctx.output("scene", SceneArt { scene, dome });
    Ok(())
}

/// Registers the nodes of this module.
pub fn register(r: &mut Registry) {
    r.register_node(FnNode::new(
        NodeSpec::new(
            "add_objects",
            "The designed CG objects put into the local scene: `scene`'s camera, dome, lights \
             and catchers (the fitted, textured, proxied local scene) with every non-catcher \
             object and light of `objects` (the placed insert) added. Build the local scene \
             from the set alone and add the objects last: a change of an object's material \
             then reruns only this node and the renders, never the catcher fit or texture.",
        )
        .input(PortSpec::one("scene", SceneArt::NAME, "the local scene"))
        .input(PortSpec::one(
            "objects",
            SceneArt::NAME,
            "the placed insert (its catchers, camera and dome are not used)",
        ))
        .output(PortSpec::one(
            "scene",
            SceneArt::NAME,
            "the local scene with the objects",
        )),
        run_add_objects,
    ));
    r.register_node(FnNode::new(
        NodeSpec::new(
            "proxy_from_points",
            "Proxy geometry of the real set from measured points (point_cloud_calibrate's \
             `points3d`): a box from three base corners and the corner above the first, a plane \
             patch from its 4 corners. Every face is added as a planar shadow catcher (give it \
             its texture with catcher_texture), so it receives the objects' shadows, is seen \
             in their reflections and occludes the dome for their lighting.",
        )
        .options::<ProxyParams>()
        .input(PortSpec::one("scene", SceneArt::NAME, "the placed scene"))
        .input(PortSpec::one(
            "points3d",
            Points3dArt::NAME,
            "the measured points",
        ))
        .output(PortSpec::one(
            "scene",
            SceneArt::NAME,
            "the scene with the proxies' faces as catchers",
        ))
        .output(PortSpec::one("report", ReportArt::NAME, "proxies made")),
        run_proxy_from_points,
    ));
    r.register_node(FnNode::new(
        light_and_camera_inputs(size_params(
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
            .options::<CatcherTextureParams>(),
        ))
        .input(PortSpec::sequence(
            "plate",
            ImageArt::NAME,
            "the plate frames (linear radiance)",
        ))
        .output(PortSpec::one(
            "scene",
            SceneArt::NAME,
            "the scene with the catcher's albedo texture",
        ))
        .output(PortSpec::one(
            "albedo",
            ImageArt::NAME,
            "the estimated albedo, linear RGB; column i along the map's u edge, row j along v \
             (see the report's map corners)",
        ))
        .output(PortSpec::one(
            "seen",
            ImageArt::NAME,
            "frames that saw each texel (one channel)",
        ))
        .output(PortSpec::one("report", ReportArt::NAME, "the estimate")),
        run_catcher_texture,
    ));
}

fn run_catcher_texture(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let p: CatcherTextureParams = ctx.options()?;
    let art = ctx.input::<SceneArt>("scene")?;
    let input_dome = ctx.input_opt::<DomeArt>("dome")?.map(|d| &d.0);
    let light = pick_light(input_dome, art)?;
    let plates = ctx.sequence::<ImageArt>("plate")?;
    let range = match (plates.first(), plates.last()) {
        (Some(a), Some(b)) => format!("{}–{}", a.0, b.0),
        _ => "none".into(),
    };
    let wanted: Vec<i64> = if p.frames.is_empty() {
        plates.iter().map(|(f, _)| *f).collect()
    } else {
        p.frames.iter().map(|&f| f as i64).collect()
    };
    let mut chosen = Vec::new();
    for f in &wanted {
        let plate = plates
            .iter()
            .find(|(g, _)| g == f)
            .map(|(_, i)| &i.0)
            .ok_or_else(|| {
                NodeError::msg(format!(
                    "param `frames`: the plate has no frame {f} (its frames are {range})"
                ))
            })?;
        let camera = camera_for_frame(ctx, &art.scene, Some(*f))?;
        chosen.push((*f, camera, plate));
    }
    let views: Vec<View> = chosen
        .iter()
        .map(|(frame, camera, plate)| View {
            frame: *frame,
            camera,
            plate,
        })
        .collect();
    let options = TextureOptions {
        catcher: p.catcher,
        resolution: p.resolution,
        irradiance_cell: p.irradiance_cell,
        irradiance_samples: p.irradiance_samples,
        max_depth: p.max_depth,
        seed: ctx.seed(),
        min_frames: p.min_frames,
        max_albedo: p.max_albedo,
        iterations: p.iterations,
    };
    let (scene, rep, others) = texture_local_scene(
        &art.scene,
        light.env(),
        &views,
        &options,
        p.others.then_some(p.others_resolution),
        Some(ctx.cancel_flag()),
    )
    .map_err(|e| NodeError::msg(e.to_string()))?;
    let others: Vec<serde_json::Value> = others
        .iter()
        .map(|c| match &c.texture {
            FaceTexture::Estimated {
                texels_estimated,
                clamped_fraction,
                median_albedo,
                mean_irradiance,
            } => serde_json::json!({"catcher": c.catcher, "proxy": c.proxy,
                "centre": c.centre, "normal": c.normal,
                "texels_estimated": texels_estimated, "clamped_fraction": clamped_fraction,
                "median_albedo": median_albedo, "mean_irradiance": mean_irradiance}),
            FaceTexture::Unestimated { why, filled } => serde_json::json!({"catcher": c.catcher,
                "proxy": c.proxy, "centre": c.centre, "normal": c.normal, "skipped": why,
                "filled_with_proxy_median": filled}),
        })
        .collect();
    let m = &rep.map;
    let seen = Image::from_fn(m.width, m.height, 1, |x, y, _| {
        rep.seen[y * m.width + x] as f32
    });
    let texels = m.width * m.height;
    let report = serde_json::json!({
        "frames": wanted,
        "width": m.width,
        "height": m.height,
        "corner": [m.origin.x, m.origin.y, m.origin.z],
        "u_edge": [m.u.x, m.u.y, m.u.z],
        "v_edge": [m.v.x, m.v.y, m.v.z],
        "uniform_colour": rep.uniform,
        "texels_estimated": rep.estimated,
        "fraction_estimated": rep.estimated as f64 / texels as f64,
        "clamped_fraction": rep.clamped_fraction,
        "pixels_per_frame": rep.pixels_per_frame,
        "mean_irradiance": rep.mean_irradiance,
        "others": others,
    });
    let dome = art.dome.clone();
    ctx.output("scene", SceneArt { scene, dome });
    ctx.output("albedo", ImageArt(rep.albedo));
    ctx.output("seen", ImageArt(seen));
    ctx.output("report", ReportArt(report));
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{params, spec};
    use nalgebra::Point3;
    use std::path::Path;
    use vfxgraph_engine::{InputValue, ParamValue, Value};
    use vfxgraph_vision::Points3d;

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

    fn plate() -> InputValue {
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
