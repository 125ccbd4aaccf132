//! The local scene's textures (Debevec 1998 §4: the local scene's reflectance solved from the
//! photograph): the main shadow catcher (the ground) by [`catcher_texture`], then every other
//! planar catcher the frames see (the faces of proxy boxes and patches, [`crate::proxy`]) the
//! same way, at a coarser resolution.
//!
//! A proxy is rarely seen whole: the face of a box that turns away from every camera is exactly
//! the one an inserted mirror object between the camera and the box reflects. Such a face, and
//! the texels of a partly seen face that no frame sees, take the **median albedo of the
//! estimated texels of the same proxy** (its faces are the catchers connected to it by shared
//! corners), not the proxy's starting colour: a real object's sides are usually of one material,
//! and the median of what the plate shows of it is the best estimate the plate gives. A proxy no
//! frame sees at all keeps its colour. The main catcher is left as its estimate makes it (its
//! unseen texels keep its fitted uniform colour, [`crate::catcher_fit`]).

use std::sync::atomic::AtomicBool;

use crate::brdf::Brdf;
use crate::catcher_texture::{
    catcher_texture, median, TextureError, TextureOptions, TextureReport, View,
};
use crate::environment::Environment;
use crate::math::{Rgb, Vec3};
use crate::scene::{Scene, Shape};
use crate::texture::Texture;
use vfxgraph_imaging::Image;

/// What became of one of the other catchers.
#[derive(Clone, Debug, PartialEq)]
pub enum FaceTexture {
    /// Estimated from the plate.
    Estimated {
        /// Texels seen by enough frames.
        texels_estimated: usize,
        /// Fraction of estimated channel values clamped to the physical range.
        clamped_fraction: f64,
        /// Median albedo of the estimated texels (after the proxy fill: what the render uses).
        median_albedo: [f64; 3],
        /// Mean irradiance over the face's grid (per channel).
        mean_irradiance: [f64; 3],
    },
    /// Not estimated (`why`: not seen, not planar, not diffuse); its colour is `filled` — the
    /// median albedo of its proxy's seen texels — or unchanged when `None`.
    Unestimated {
        /// Why not.
        why: String,
        /// The colour it was given.
        filled: Option<[f64; 3]>,
    },
}

/// One of the other catchers: its index among the scene's catchers, the proxy it belongs to
/// (the index of its connected group of catchers, in order of first face), where it is and
/// the outcome.
#[derive(Clone, Debug, PartialEq)]
pub struct OtherCatcher {
    /// Index among the scene's catchers.
    pub catcher: usize,
    /// Connected group (proxy) number.
    pub proxy: usize,
    /// The centre of its triangles' corners (scene coordinates).
    pub centre: [f64; 3],
    /// Its unit normal (of its first triangle, as wound).
    pub normal: [f64; 3],
    /// What was done.
    pub texture: FaceTexture,
}

/// The designed CG objects put into the local scene: `local`'s camera, dome, lights and
/// catchers with every non-catcher object and every light of `objects` added. An error when
/// `objects` has no synthetic object.
pub fn add_objects(local: &Scene, objects: &Scene) -> Result<Scene, String> {
    let insert: Vec<_> = objects
        .objects
        .iter()
        .filter(|o| !o.catcher)
        .cloned()
        .collect();
    if insert.is_empty() {
        return Err(format!(
            "the `objects` scene has no synthetic objects (its {} objects are all shadow \
             catchers)",
            objects.objects.len()
        ));
    }
    let mut scene = local.clone();
    scene.objects.extend(insert);
    scene.lights.extend(objects.lights.iter().cloned());
    Ok(scene)
}

/// The `catcher_texture` node's params: the frames to estimate from, [`TextureOptions`]
/// (its seed is the node's) and the other catchers' textures.
#[derive(Debug, PartialEq, vfxgraph_params::Options)]
#[param(check)]
pub struct LocalTextureOptions {
    /// the plate frames to estimate from, which must be clean (without the CG objects or their shadows); empty = every frame of the plate
    pub frames: Vec<f64>,
    /// The main catcher's estimate.
    #[param(flatten)]
    pub texture: TextureOptions,
    /// also texture every other planar catcher the frames see (proxy faces), after `catcher`; a proxy's faces and texels no frame sees take the median albedo of its seen texels
    pub others: bool,
    /// texels along the longer side of each other catcher
    #[param(range = 1..=8192)]
    pub others_resolution: usize,
}

impl LocalTextureOptions {
    fn check(&self) -> Result<(), String> {
        if let Some(f) = self.frames.iter().find(|f| f.fract() != 0.0) {
            return Err(format!("param `frames`: {f} is not a frame number"));
        }
        Ok(())
    }
}

impl Default for LocalTextureOptions {
    fn default() -> Self {
        LocalTextureOptions {
            frames: Vec::new(),
            texture: TextureOptions {
                irradiance_cell: 8,
                irradiance_samples: 1024,
                ..TextureOptions::default()
            },
            others: true,
            others_resolution: 64,
        }
    }
}

/// What [`texture_local_scene_report`] makes: the textured scene, the main catcher's albedo
/// and frames-seen count per texel (one channel), and a report.
pub struct LocalTexture {
    /// The scene with the textures.
    pub scene: Scene,
    /// The main catcher's estimated albedo, linear RGB.
    pub albedo: Image,
    /// Frames that saw each texel of the main catcher.
    pub seen: Image,
    /// The estimate: the map's corners, texels estimated, clamped fraction, each other face.
    pub report: serde_json::Value,
}

/// [`texture_local_scene`] with the options of the `catcher_texture` node (`seed`: the irradiance
/// paths'), its outputs as images and the report.
pub fn texture_local_scene_report(
    scene: &Scene,
    env: &dyn Environment,
    views: &[View<'_>],
    o: &LocalTextureOptions,
    seed: u64,
    cancel: Option<&AtomicBool>,
) -> Result<LocalTexture, TextureError> {
    let options = TextureOptions { seed, ..o.texture };
    let others_resolution = o.others.then_some(o.others_resolution);
    let (scene, rep, others) =
        texture_local_scene(scene, env, views, &options, others_resolution, cancel)?;
    let others: Vec<serde_json::Value> = others.iter().map(other_report).collect();
    let m = &rep.map;
    let seen = Image::from_fn(m.width, m.height, 1, |x, y, _| {
        rep.seen[y * m.width + x] as f32
    });
    let texels = m.width * m.height;
    let frames: Vec<i64> = views.iter().map(|v| v.frame).collect();
    let report = serde_json::json!({
        "frames": frames,
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
    Ok(LocalTexture {
        scene,
        albedo: rep.albedo,
        seen,
        report,
    })
}

/// One other catcher's line of the report.
fn other_report(c: &OtherCatcher) -> serde_json::Value {
    match &c.texture {
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
    }
}

/// The textures of the main catcher (`o.catcher`) and, when `others_resolution` is given, of
/// every other catcher, with the report of the main one and the outcome of each other.
/// (Estimating the whole local scene a second time with the first pass's textures, as the
/// catchers light one another, changed a box side's albedo by 0.3 % in
/// `faces_seen_only_from_a_later_frame_face_that_frame`: one pass.)
pub fn texture_local_scene(
    scene: &Scene,
    env: &dyn Environment,
    views: &[View<'_>],
    o: &TextureOptions,
    others_resolution: Option<usize>,
    cancel: Option<&AtomicBool>,
) -> Result<(Scene, TextureReport, Vec<OtherCatcher>), TextureError> {
    let (mut scene, report) = catcher_texture(scene, env, views, o, cancel)?;
    let Some(resolution) = others_resolution else {
        return Ok((scene, report, Vec::new()));
    };
    let catchers: Vec<usize> = (0..scene.objects.len())
        .filter(|&i| scene.objects[i].catcher)
        .collect();
    let others: Vec<usize> = (0..catchers.len()).filter(|&k| k != o.catcher).collect();
    let proxy = proxies(&scene, &catchers, &others);
    // Per other catcher: its estimate (absolute albedo of the estimated texels) or why not.
    let mut outcome: Vec<Result<TextureReport, String>> = Vec::new();
    for &k in &others {
        let ok = TextureOptions {
            catcher: k,
            resolution,
            irradiance_cell: o.irradiance_cell.min(resolution),
            ..*o
        };
        match catcher_texture(&scene, env, views, &ok, cancel) {
            Ok((s, r)) => {
                scene = s;
                outcome.push(Ok(r));
            }
            Err(
                e @ (TextureError::NotSeen { .. }
                | TextureError::NotPlanar(_)
                | TextureError::NotDiffuse(_)),
            ) => outcome.push(Err(e.to_string())),
            Err(e) => return Err(e),
        }
    }
    // The median albedo of each proxy's estimated texels.
    let groups = proxy.iter().copied().max().map_or(0, |g| g + 1);
    let mut samples: Vec<[Vec<f64>; 3]> = vec![Default::default(); groups];
    for (i, r) in outcome.iter().enumerate() {
        let Ok(r) = r else { continue };
        for (all, one) in samples[proxy[i]]
            .iter_mut()
            .zip(estimated_albedos(r, o.min_frames))
        {
            all.extend(one);
        }
    }
    let median_of = |g: usize| -> Option<[f64; 3]> {
        let s = &samples[g];
        if s[0].is_empty() {
            return None;
        }
        Some([0, 1, 2].map(|c| median(&mut s[c].clone())))
    };
    let mut out = Vec::new();
    for (i, (&k, r)) in others.iter().zip(outcome).enumerate() {
        let fill = median_of(proxy[i]);
        let object = &mut scene.objects[catchers[k]];
        let texture = match r {
            Ok(r) => {
                if let Some(m) = fill {
                    refill_unseen(object, &r, m, o.min_frames.max(1));
                }
                let v = estimated_albedos(&r, o.min_frames);
                FaceTexture::Estimated {
                    texels_estimated: r.estimated,
                    clamped_fraction: r.clamped_fraction,
                    median_albedo: v.map(|mut v| if v.is_empty() { 0.0 } else { median(&mut v) }),
                    mean_irradiance: r.mean_irradiance,
                }
            }
            Err(why) => {
                let filled = fill.filter(|&m| set_diffuse(&mut object.material, rgb(m)));
                FaceTexture::Unestimated { why, filled }
            }
        };
        let (centre, normal) = centre_and_normal(&object.shape);
        out.push(OtherCatcher {
            catcher: k,
            proxy: proxy[i],
            centre,
            normal,
            texture,
        });
    }
    Ok((scene, report, out))
}

/// Per channel, the albedo of the texels of `r` seen in at least `min_frames` frames (those
/// estimated).
fn estimated_albedos(r: &TextureReport, min_frames: usize) -> [Vec<f64>; 3] {
    let mut v: [Vec<f64>; 3] = Default::default();
    for (t, &s) in r.seen.iter().enumerate() {
        if (s as usize) >= min_frames.max(1) {
            let (x, y) = (t % r.map.width, t / r.map.width);
            for (c, v) in v.iter_mut().enumerate() {
                v.push(r.albedo.get(x, y, c) as f64);
            }
        }
    }
    v
}

/// The centre of a shape's triangle corners and its first triangle's unit normal (zeros for
/// a shape without triangles).
fn centre_and_normal(shape: &Shape) -> ([f64; 3], [f64; 3]) {
    let Shape::Triangles { triangles } = shape else {
        return ([0.0; 3], [0.0; 3]);
    };
    let Some(first) = triangles.first() else {
        return ([0.0; 3], [0.0; 3]);
    };
    let sum = triangles
        .iter()
        .flat_map(|t| t.iter())
        .fold(Vec3::new(0.0, 0.0, 0.0), |a, &p| a + p);
    let c = sum * (1.0 / (3 * triangles.len()) as f64);
    let n = (first[1] - first[0]).cross(first[2] - first[0]);
    let n = n * (1.0 / n.length().max(1e-300));
    ([c.x, c.y, c.z], [n.x, n.y, n.z])
}

fn rgb(c: [f64; 3]) -> Rgb {
    Rgb::new(c[0], c[1], c[2])
}

/// Sets a diffuse material's colour; false for a mirror.
fn set_diffuse(b: &mut Brdf, c: Rgb) -> bool {
    match b {
        Brdf::Lambert(l) => l.albedo = c,
        Brdf::BlinnPhong(p) => p.diffuse = c,
        Brdf::Mirror(_) => return false,
    }
    true
}

/// A textured face's unseen texels take the proxy's median `m`: the colour becomes `m` and the
/// estimated texels' factors are rescaled to keep their albedo.
fn refill_unseen(object: &mut crate::scene::Object, r: &TextureReport, m: [f64; 3], min: usize) {
    if m.iter().any(|&c| c <= 0.0) || !set_diffuse(&mut object.material, rgb(m)) {
        return;
    }
    let Some(Texture::Planar(map)) = object.texture.as_mut() else {
        return;
    };
    for (t, &s) in r.seen.iter().enumerate() {
        let (x, y) = (t % map.width, t / map.width);
        for (c, mc) in m.iter().enumerate() {
            map.texels[3 * t + c] = if (s as usize) >= min {
                (r.albedo.get(x, y, c) as f64 / mc) as f32
            } else {
                1.0
            };
        }
    }
}

/// For each of `others` (indices into `catchers`), its proxy: the connected group of the others
/// that share a corner with it (within 1 µm), numbered in order of first appearance.
fn proxies(scene: &Scene, catchers: &[usize], others: &[usize]) -> Vec<usize> {
    let corners: Vec<Vec<Vec3>> = others
        .iter()
        .map(|&k| match &scene.objects[catchers[k]].shape {
            Shape::Triangles { triangles } => triangles.iter().flatten().copied().collect(),
            Shape::Sphere(_) => Vec::new(),
        })
        .collect();
    let touch = |a: &[Vec3], b: &[Vec3]| {
        a.iter()
            .any(|p| b.iter().any(|q| (*p - *q).length() <= 1e-6))
    };
    // Union–find over the others.
    let mut parent: Vec<usize> = (0..others.len()).collect();
    fn root(p: &mut [usize], mut i: usize) -> usize {
        while p[i] != i {
            p[i] = p[p[i]];
            i = p[i];
        }
        i
    }
    for i in 0..others.len() {
        for j in 0..i {
            if touch(&corners[i], &corners[j]) {
                let (a, b) = (root(&mut parent, i), root(&mut parent, j));
                parent[a.max(b)] = a.min(b);
            }
        }
    }
    let mut number = vec![usize::MAX; others.len()];
    let mut next = 0;
    (0..others.len())
        .map(|i| {
            let r = root(&mut parent, i);
            if number[r] == usize::MAX {
                number[r] = next;
                next += 1;
            }
            number[r]
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brdf::Lambert;
    use crate::camera::Camera;
    use crate::environment::ConstantEnvironment;
    use crate::proxy::{box_faces, catchers};
    use crate::render::{render, RenderSettings};
    use crate::scene::Object;
    use crate::world::World;

    /// A 6 m square ground catcher of `albedo` on z = 0.
    fn ground(albedo: Rgb) -> Object {
        Object {
            catcher: true,
            ..Object::new(
                Shape::Triangles {
                    triangles: vec![
                        [
                            Vec3::new(-3.0, -3.0, 0.0),
                            Vec3::new(3.0, -3.0, 0.0),
                            Vec3::new(3.0, 3.0, 0.0),
                        ],
                        [
                            Vec3::new(-3.0, -3.0, 0.0),
                            Vec3::new(3.0, 3.0, 0.0),
                            Vec3::new(-3.0, 3.0, 0.0),
                        ],
                    ],
                },
                Brdf::Lambert(Lambert { albedo }),
            )
        }
    }

    fn scene(objects: Vec<Object>) -> Scene {
        Scene {
            camera: None,
            objects,
            lights: vec![],
            background: Rgb::BLACK,
            dome: None,
        }
    }

    /// A box of one albedo on a grey ground, under a uniform sky, seen from one side: the faces
    /// the camera sees are estimated near the truth; the faces it never sees take their median,
    /// not the starting grey.
    #[test]
    fn unseen_faces_of_a_proxy_take_its_seen_faces_median() {
        let truth = Rgb::new(0.6, 0.3, 0.15);
        let corners = [
            Vec3::new(-0.3, -0.3, 0.0),
            Vec3::new(0.3, -0.3, 0.0),
            Vec3::new(0.3, 0.3, 0.0),
            Vec3::new(-0.3, -0.3, 0.5),
        ];
        let faces = box_faces(&corners).unwrap();
        let ground = ground(Rgb::new(0.4, 0.4, 0.4));
        let mut real = scene(vec![ground.clone()]);
        real.objects.extend(catchers(faces.clone(), truth));
        // The camera looks at the box from -y and above: it sees the top and the -y face (and
        // grazes ±x); the +y face is hidden.
        let camera = Camera::look_at(
            Vec3::new(0.4, -2.5, 1.6),
            Vec3::new(0.0, 0.0, 0.25),
            Vec3::new(0.0, 0.0, 1.0),
            45.0,
            96,
            72,
        )
        .unwrap();
        let env = ConstantEnvironment {
            radiance: Rgb::new(1.0, 1.0, 1.0),
        };
        let settings = RenderSettings {
            spp: 256,
            max_depth: 3,
            seed: 3,
            ..RenderSettings::default()
        };
        let plate = render(&World::new(&real), &env, &camera, &settings, &|_| {}, None)
            .unwrap()
            .image;
        let mut model = scene(vec![ground]);
        model
            .objects
            .extend(catchers(faces, Rgb::new(0.18, 0.18, 0.18)));
        let views = [View {
            frame: 0,
            camera: &camera,
            plate: &plate,
        }];
        let o = TextureOptions {
            resolution: 32,
            irradiance_samples: 256,
            ..TextureOptions::default()
        };
        let (textured, _, others) =
            texture_local_scene(&model, &env, &views, &o, Some(8), None).unwrap();
        assert_eq!(others.len(), 5, "a box proxy has 5 faces (no base)");
        assert!(others.iter().all(|c| c.proxy == 0), "{others:?}");
        let filled: Vec<_> = others
            .iter()
            .filter_map(|c| match &c.texture {
                FaceTexture::Unestimated { filled, .. } => Some(filled.unwrap()),
                _ => None,
            })
            .collect();
        assert!(!filled.is_empty(), "{others:?}");
        for f in filled {
            for (c, t) in f.iter().zip([truth.r, truth.g, truth.b]) {
                assert!((c / t - 1.0).abs() < 0.10, "filled {f:?} for {truth:?}");
            }
        }
        // Every face's colour (the unseen texels' value) is the median, not 0.18.
        for c in &others {
            let Brdf::Lambert(l) = &textured.objects[c.catcher].material else {
                panic!()
            };
            assert!((l.albedo.r / truth.r - 1.0).abs() < 0.10, "{l:?}");
        }
    }

    /// A box face seen only by a later frame, from the side opposite the first frame's camera:
    /// its irradiance is gathered on the side the plate sees (outside the box), so its albedo
    /// is estimated near the truth (gathered inside, towards the first camera, it was the
    /// starting grey, 70 % off, or clamped).
    #[test]
    fn faces_seen_only_from_a_later_frame_face_that_frame() {
        let truth = Rgb::new(0.6, 0.3, 0.15);
        let corners = [
            Vec3::new(-0.3, -0.3, 0.0),
            Vec3::new(0.3, -0.3, 0.0),
            Vec3::new(0.3, 0.3, 0.0),
            Vec3::new(-0.3, -0.3, 0.5),
        ];
        let faces = box_faces(&corners).unwrap();
        let grey = Rgb::new(0.4, 0.4, 0.4);
        let mut real = scene(vec![ground(grey)]);
        real.objects.extend(catchers(faces.clone(), truth));
        let env = ConstantEnvironment {
            radiance: Rgb::new(1.0, 1.0, 1.0),
        };
        let settings = RenderSettings {
            spp: 256,
            max_depth: 3,
            seed: 5,
            ..RenderSettings::default()
        };
        // Frame 0 from +y, frame 1 from -y: the -y face is seen by frame 1 alone.
        let cameras: Vec<Camera> = [Vec3::new(0.3, 2.5, 1.4), Vec3::new(-0.3, -2.5, 1.4)]
            .iter()
            .map(|&eye| {
                Camera::look_at(
                    eye,
                    Vec3::new(0.0, 0.0, 0.25),
                    Vec3::new(0.0, 0.0, 1.0),
                    45.0,
                    96,
                    72,
                )
                .unwrap()
            })
            .collect();
        let world = World::new(&real);
        let plates: Vec<_> = cameras
            .iter()
            .map(|c| {
                render(&world, &env, c, &settings, &|_| {}, None)
                    .unwrap()
                    .image
            })
            .collect();
        let views: Vec<View<'_>> = (0..2)
            .map(|i| View {
                frame: i as i64,
                camera: &cameras[i],
                plate: &plates[i],
            })
            .collect();
        let mut model = scene(vec![ground(grey)]);
        model
            .objects
            .extend(catchers(faces, Rgb::new(0.18, 0.18, 0.18)));
        let o = TextureOptions {
            resolution: 16,
            irradiance_samples: 256,
            min_frames: 1,
            ..TextureOptions::default()
        };
        let (_, main, others) =
            texture_local_scene(&model, &env, &views, &o, Some(16), None).unwrap();
        let mut checked = 0;
        let medians = others.iter().filter_map(|c| match &c.texture {
            FaceTexture::Estimated { median_albedo, .. } => Some(*median_albedo),
            _ => None,
        });
        for m in medians {
            checked += 1;
            for (c, t) in m.iter().zip([truth.r, truth.g, truth.b]) {
                assert!((c / t - 1.0).abs() < 0.02, "median {m:?} for {truth:?}");
            }
        }
        assert_eq!(checked, 3, "the top and the ±y faces: {others:?}");
        // The ground's texels next to the box (within 0.3 m of its footprint): the irradiance
        // grid's points under the box are left out, so their albedo is not inflated (with
        // them interpolated it was 0.80 for the truth's 0.40).
        let mut near = Vec::new();
        for (t, &seen) in main.seen.iter().enumerate() {
            let (x, y) = (t % main.map.width, t / main.map.width);
            let p = main.map.point(
                (x as f64 + 0.5) / main.map.width as f64,
                (y as f64 + 0.5) / main.map.height as f64,
            );
            if seen > 0 && p.x.abs().max(p.y.abs()) < 0.6 {
                near.push(main.albedo.get(x, y, 0) as f64);
            }
        }
        assert!(near.len() >= 8, "{} texels", near.len());
        let m = median(&mut near);
        assert!(
            (m / 0.4 - 1.0).abs() < 0.15,
            "ground next to the box: {m} for 0.4"
        );
    }

    #[test]
    fn faces_sharing_corners_are_one_proxy() {
        let a = box_faces(&[
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(0.0, 0.0, 1.0),
        ])
        .unwrap();
        let b = box_faces(&[
            Vec3::new(5.0, 0.0, 0.0),
            Vec3::new(6.0, 0.0, 0.0),
            Vec3::new(6.0, 1.0, 0.0),
            Vec3::new(5.0, 0.0, 1.0),
        ])
        .unwrap();
        let mut s = scene(vec![]);
        let grey = Rgb::new(0.5, 0.5, 0.5);
        s.objects.extend(catchers(a.clone(), grey));
        s.objects.extend(catchers(b.clone(), grey));
        let n = a.len() + b.len();
        let all: Vec<usize> = (0..n).collect();
        let p = proxies(&s, &all, &all);
        assert_eq!(p[..a.len()], vec![0; a.len()][..]);
        assert_eq!(p[a.len()..], vec![1; b.len()][..]);
    }
}
