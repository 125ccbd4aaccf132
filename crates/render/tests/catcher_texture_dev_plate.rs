//! The textured catcher against the exact albedo Cycles used: the ground of the
//! Blender dev plate (`blender_plate_dev`, a photo mosaic under the `empty_warehouse_01` dome)
//! estimated by [`catcher_texture`] from its 48 JPEG plate frames (sRGB decoded to linear) with
//! the exact cameras, against `ground_albedo.exr` area-averaged to the
//! estimate's texels (2 × 2 texels of the 1024² truth: 1.95 cm). The set's four boxes are in
//! the local scene as catchers of a uniform grey (they occlude the dome and bounce light onto
//! the ground; proxy geometry builds them from measured points in the shot graph).
//!
//! Measured (this commit): median relative error per texel 4.6 % over 30 030 texels seen in ≥ 3
//! frames (90th percentile 16.6 %; signed median −2.5 %, −2.3 %, +0.2 % in R, G, B), 0.01 % of
//! texel channels clamped. Texels seen in 8+ frames: 4.4 %; in 3–7 frames: 8–13 % (the view's
//! edge, grazing). The rest is the plates' 32-spp grain and JPEG, Cycles' pixel filter and the
//! irradiance's own Monte Carlo noise (1024 → 2048 paths per grid point: 4.8 → 4.7 % on 24
//! frames). Bound: the 5 % aimed at.

use std::path::Path;

use nalgebra::Vector3;
use vfxgraph_imaging::{read_image, Image};
use vfxgraph_render::brdf::{Brdf, Lambert};
use vfxgraph_render::catcher_texture::{catcher_texture, TextureOptions, View};
use vfxgraph_render::dome::Dome;
use vfxgraph_render::{Camera, Object, Rgb, Scene, Shape, Vec3};

fn json(p: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
}

fn v3(v: &serde_json::Value) -> Vec3 {
    Vec3::new(
        v[0].as_f64().unwrap(),
        v[1].as_f64().unwrap(),
        v[2].as_f64().unwrap(),
    )
}

fn m3(v: &serde_json::Value) -> [[f64; 3]; 3] {
    let r = |i: usize| {
        let a = v3(&v[i]);
        [a.x, a.y, a.z]
    };
    [r(0), r(1), r(2)]
}

fn lambert(c: Rgb) -> Brdf {
    Brdf::Lambert(Lambert { albedo: c })
}

/// A box from its 8 corners (bottom 0–3, top 4–7) as 12 triangles.
fn box_triangles(c: &[Vec3]) -> Vec<[Vec3; 3]> {
    let quad = |a: usize, b: usize, cc: usize, d: usize| [[c[a], c[b], c[cc]], [c[a], c[cc], c[d]]];
    let mut t = Vec::new();
    for q in [
        quad(4, 5, 6, 7),
        quad(0, 1, 5, 4),
        quad(1, 2, 6, 5),
        quad(2, 3, 7, 6),
        quad(3, 0, 4, 7),
    ] {
        t.extend(q);
    }
    t
}

#[test]
fn the_ground_texture_matches_cycles_albedo_within_5_percent() {
    let Some([scene_json, albedo_exr, cams_json, dome_hdr]) = vfxgraph_testdata::paths([
        "blender_plate_dev/scene.json",
        "blender_plate_dev/ground_albedo.exr",
        "blender_plate_dev/pinhole/cameras_gt.json",
        "polyhaven_hdri_1k/empty_warehouse_01_1k.hdr",
    ]) else {
        return;
    };
    let frames: Vec<i64> = (0..48).collect();
    let mut plates = Vec::new();
    for f in &frames {
        let rel = format!("blender_plate_dev/pinhole/plate/frame.{f:04}.jpg");
        let Some(p) = vfxgraph_testdata::path(&rel) else {
            return;
        };
        plates.push(read_image(&p).unwrap());
    }
    let sj = json(&scene_json);
    let cj = json(&cams_json);
    let k = m3(&cj["K"]);
    let (w, h) = (
        cj["width"].as_u64().unwrap() as usize,
        cj["height"].as_u64().unwrap() as usize,
    );
    let cameras: Vec<Camera> = frames
        .iter()
        .map(|&f| {
            let c = &cj["frames"][f as usize];
            assert_eq!(c["frame"].as_i64(), Some(f));
            let t = v3(&c["t"]);
            Camera::from_krt(k, m3(&c["R"]), [t.x, t.y, t.z], w, h).unwrap()
        })
        .collect();
    let d = &sj["dome"];
    let (o, s) = (v3(&d["orig"]), v3(&d["south"]));
    let dome = Dome::new(
        &read_image(&dome_hdr).unwrap(),
        Vector3::new(o.x, o.y, o.z),
        Vector3::new(s.x, s.y, s.z),
    )
    .unwrap();
    // The ground: ±2.5 m (texel edges on the truth's 1024² grid), started at the mean albedo.
    let p = |x: f64, y: f64| Vec3::new(x, y, 0.0);
    let mut ground = Object::new(
        Shape::Triangles {
            triangles: vec![
                [p(-2.5, -2.5), p(2.5, -2.5), p(2.5, 2.5)],
                [p(-2.5, -2.5), p(2.5, 2.5), p(-2.5, 2.5)],
            ],
        },
        lambert(Rgb::new(0.077, 0.060, 0.036)),
    );
    ground.catcher = true;
    let mut objects = vec![ground];
    for b in sj["boxes"].as_array().unwrap() {
        let c: Vec<Vec3> = b["corners"].as_array().unwrap().iter().map(v3).collect();
        let mut o = Object::new(
            Shape::Triangles {
                triangles: box_triangles(&c),
            },
            lambert(Rgb::splat(0.15)),
        );
        o.catcher = true;
        objects.push(o);
    }
    let scene = Scene {
        camera: None,
        objects,
        lights: vec![],
        background: Rgb::BLACK,
        dome: None,
    };
    let views: Vec<View> = frames
        .iter()
        .zip(&cameras)
        .zip(&plates)
        .map(|((&frame, camera), plate)| View {
            frame,
            camera,
            plate,
        })
        .collect();
    let opts = TextureOptions {
        resolution: 256,
        irradiance_cell: 8,
        irradiance_samples: 2048,
        seed: 1,
        ..Default::default()
    };
    let (_, rep) = catcher_texture(&scene, &dome, &views, &opts, None).unwrap();
    assert_eq!((rep.map.width, rep.map.height), (256, 256));
    let truth: Image = read_image(&albedo_exr).unwrap();
    // Texel (i, j) of the map (origin (−2.5, −2.5), u = +x, v = +y) covers truth columns
    // 256 + 2i.., rows 766 − 2j.. (row 0 = y = +5).
    let boxes: Vec<(Vec3, Vec3)> = sj["boxes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|b| {
            let c: Vec<Vec3> = b["corners"].as_array().unwrap().iter().map(v3).collect();
            let lo = c.iter().fold(c[0], |a, &b| a.min(b));
            let hi = c.iter().fold(c[0], |a, &b| a.max(b));
            (lo, hi)
        })
        .collect();
    let mut errs = Vec::new();
    let mut signed = [Vec::new(), Vec::new(), Vec::new()];
    let mut by_seen = vec![Vec::new(); 9];
    for j in 0..256 {
        for i in 0..256 {
            if rep.seen[j * 256 + i] < 3 {
                continue;
            }
            let (x, y) = (
                -2.5 + (i as f64 + 0.5) * 5.0 / 256.0,
                -2.5 + (j as f64 + 0.5) * 5.0 / 256.0,
            );
            // Off the boxes' footprints (a texel there is the box's base, never seen).
            if boxes.iter().any(|(lo, hi)| {
                x > lo.x - 0.02 && x < hi.x + 0.02 && y > lo.y - 0.02 && y < hi.y + 0.02
            }) {
                continue;
            }
            for (c, sc) in signed.iter_mut().enumerate() {
                let mut t = 0.0;
                for dy in 0..2 {
                    for dx in 0..2 {
                        t += truth.get(256 + 2 * i + dx, 766 - 2 * j + dy, c) as f64 / 4.0;
                    }
                }
                let a = rep.albedo.get(i, j, c) as f64;
                errs.push((a - t).abs() / t);
                sc.push((a - t) / t);
                by_seen[(rep.seen[j * 256 + i] as usize).min(8)].push((a - t).abs() / t);
            }
        }
    }
    for v in signed.iter_mut().chain(by_seen.iter_mut()) {
        v.sort_by(|a, b| a.total_cmp(b));
    }
    eprintln!(
        "signed median per channel {:?}; median |err| by frames seen {:?}",
        signed.iter().map(|v| v[v.len() / 2]).collect::<Vec<_>>(),
        by_seen
            .iter()
            .map(|v| (v.len(), v.get(v.len() / 2).copied()))
            .collect::<Vec<_>>()
    );
    errs.sort_by(|a, b| a.total_cmp(b));
    let n = errs.len();
    let med = errs[n / 2];
    let p90 = errs[n * 9 / 10];
    assert!(n > 3 * 20_000, "texels seen in ≥ 3 frames: {}", n / 3);
    assert!(
        med <= 0.05,
        "median relative error {med:.4} (90th percentile {p90:.4}) over {} texels seen in ≥ 3 \
         frames; clamped {:.4}",
        n / 3,
        rep.clamped_fraction
    );
    eprintln!(
        "median relative error {med:.4}, p90 {p90:.4}, texels {}, clamped {:.5}, E {:?}",
        n / 3,
        rep.clamped_fraction,
        rep.mean_irradiance
    );
}
