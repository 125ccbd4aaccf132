//! The graphs users read (`graphs/*.yaml`), run in CI: every graph
//! `check`s, enumerated from the folder so a new graph is covered without editing this file;
//! and the book's scene and shot graphs run end to end on a few frames at low resolution, in a
//! scratch copy (the repository is left untouched), with their outputs checked against what
//! they must be. A test whose data is missing fails, naming the file.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Output;

use serde_json::Value as Json;
use vfxgraph_imaging::color::linear_to_srgb8;
use vfxgraph_imaging::{read_image, Image};
use vfxgraph_matchmove::SolveReport;
use vfxgraph_nodes::modeling::MeasuredReport;

mod common;
use common::{run_json, vfx};
use vfxgraph_testdata::repo;

fn text(out: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    )
}

/// The shared data folder, or a panic naming `file` in it when it is missing.
fn shared(file: &str) -> PathBuf {
    let dir = repo().join("../shared/data");
    let path = dir.join(file);
    assert!(
        path.exists(),
        "missing test data {} (the shared data belongs beside the clone)",
        path.display()
    );
    fs::canonicalize(dir).unwrap()
}

/// The node types a build without a cargo feature lacks, and the words its diagnostic says.
const FEATURE_NODES: &[(&str, &str)] = &[("klt_track_opencv", "built without opencv")];

/// Every `graphs/*.yaml` passes `vfxgraph check`. In a build without the `opencv` feature, a
/// graph using `klt_track_opencv` must fail with exactly that node type's diagnostic (one per
/// such node, saying the build lacks opencv) and nothing else.
#[test]
fn every_graph_checks() {
    let dir = repo().join("graphs");
    let mut graphs: Vec<PathBuf> = fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "yaml" || e == "yml"))
        .collect();
    graphs.sort();
    assert!(!graphs.is_empty(), "no graphs in {}", dir.display());
    let (mut checked, mut lacking) = (Vec::new(), Vec::new());
    for g in &graphs {
        let name = g.file_name().unwrap().to_str().unwrap();
        let out = vfx(&dir, &["check", name]);
        let said = text(&out);
        if out.status.success() {
            assert!(said.contains(": ok ("), "{name}: {said}");
            checked.push(name);
            continue;
        }
        // Only the nodes of a feature this build lacks may fail, each with its reason, and
        // nothing else: as many problems as such nodes, each saying the build lacks it.
        let source = fs::read_to_string(g).unwrap();
        // The diagnostics as one line of words (miette wraps long messages).
        let flat = said
            .replace('│', " ")
            .split_whitespace()
            .collect::<Vec<_>>()
            .join(" ");
        let mut uses = 0;
        let mut explained = 0;
        for (ty, why) in FEATURE_NODES {
            if cfg!(not(feature = "opencv")) {
                uses += source.matches(&format!("type: {ty}")).count();
                explained += flat
                    .split(" × ")
                    .filter(|d| d.contains(&format!("unknown node type `{ty}`")) && d.contains(why))
                    .count();
            }
        }
        let problems = if flat.contains(" 1 problem found") {
            1
        } else {
            flat.split(" problems found")
                .next()
                .and_then(|t| t.rsplit(' ').next())
                .and_then(|n| n.parse().ok())
                .unwrap_or(usize::MAX)
        };
        assert!(
            uses > 0 && problems == uses && explained == uses && out.status.code() == Some(2),
            "{name} does not check ({problems} problems; {uses} nodes this build lacks, \
             {explained} diagnostics saying so):\n{said}"
        );
        lacking.push(name);
    }
    // `describe` gives the same reason.
    for (ty, why) in FEATURE_NODES {
        let out = vfx(&dir, &["describe", ty]);
        let said = text(&out);
        if cfg!(not(feature = "opencv")) {
            assert!(!out.status.success() && said.contains(why), "{said}");
        } else {
            assert!(out.status.success(), "{said}");
        }
    }
    eprintln!(
        "{} graphs: {checked:?} check; {lacking:?} need a feature this build lacks",
        graphs.len()
    );
}

/// Copies `graphs/NAME`, `graphs/scenes/` and the book's embedded marks (`graphs/data/book/`)
/// into a scratch folder with their paths into the shared data made absolute. Returns (scratch
/// dir guard, graphs dir).
fn scratch_copy(name: &str, data: &Path) -> (tempfile::TempDir, PathBuf) {
    let tmp = tempfile::tempdir().unwrap();
    let g = tmp.path().join("graphs");
    fs::create_dir_all(g.join("scenes")).unwrap();
    let abs = data.display().to_string();
    let yaml = fs::read_to_string(repo().join("graphs").join(name)).unwrap();
    assert!(
        yaml.contains("../../shared/data"),
        "{name} reads the shared data"
    );
    fs::write(g.join(name), yaml.replace("../../shared/data", &abs)).unwrap();
    for e in fs::read_dir(repo().join("graphs/scenes")).unwrap() {
        let p = e.unwrap().path();
        let body = fs::read(&p).unwrap();
        let body = match String::from_utf8(body) {
            Ok(t) => t.replace("../../../shared/data", &abs).into_bytes(),
            Err(e) => e.into_bytes(),
        };
        fs::write(g.join("scenes").join(p.file_name().unwrap()), body).unwrap();
    }
    common::copy_dir(&repo().join("graphs/data/book"), &g.join("data/book"));
    (tmp, g)
}

/// Runs `graph` in `dir` on `frames` with the cache `cache` and the `--set` overrides `sets`;
/// (node id, frame, status) of every instance.
fn run_frames(
    dir: &Path,
    graph: &str,
    frames: &str,
    cache: &str,
    sets: &[String],
) -> Vec<(String, Option<i64>, String)> {
    let mut args = vec![graph, "--frames", frames, "--cache", cache];
    for s in sets {
        args.extend(["--set", s.as_str()]);
    }
    run_json(dir, &args)
        .iter()
        .map(|n| {
            let id = n["id"].as_str().unwrap().to_string();
            (
                id,
                n["frame"].as_i64(),
                n["status"].as_str().unwrap().to_string(),
            )
        })
        .collect()
}

/// The names of the files in `dir` that `keep` accepts, sorted.
fn listing(dir: &Path, keep: impl Fn(&str) -> bool) -> Vec<String> {
    let mut names: Vec<String> = fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .filter(|n| keep(n))
        .collect();
    names.sort();
    names
}

fn json_file<T: serde::de::DeserializeOwned>(path: &Path) -> T {
    let t = fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&t).unwrap()
}

fn png(path: &Path, size: (usize, usize)) -> Image {
    let img = read_image(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert_eq!((img.width, img.height), size, "{}", path.display());
    img
}

/// sRGB code of channel `c` at (x, y) of a PNG read as linear light.
fn code(img: &Image, x: usize, y: usize, c: usize) -> u8 {
    linear_to_srgb8(img.get(x, y, c))
}

/// The solve both book graphs share, from its report: every one of the book's 286 frames has a
/// camera, the path is smooth (the bounds of the matchmove's own book test), and the inliers'
/// RMS is within the final tolerance.
fn check_book_solve(report: &SolveReport) {
    let score = report
        .score
        .as_ref()
        .expect("the report has the book's score");
    assert_eq!(score.frames_with_camera, 286, "{score:?}");
    assert!(score.max_rotation_step_deg < 3.0, "{score:?}");
    assert!(score.translation_step_ratio < 10.0, "{score:?}");
    let (rms, tol) = (report.overall_rms, report.inlier_tolerance);
    assert!(
        rms > 0.0 && rms <= tol,
        "overall RMS {rms} px (tolerance {tol})"
    );
}

/// `graphs/book_scene.yaml` and `graphs/book_shot.yaml` on two frames each at 160×90 with few
/// samples, sharing one cache (the shot reuses the scene graph's solve, ground points and
/// placement: same node ids, params and inputs). Checked: each writes exactly the frames asked
/// for at the size asked for; the solve gives every frame a smooth camera; the three marked
/// ground points are measured and the book's catcher is placed on them; in the scene's
/// renders the spheres change a compact part of the frame and leave the rest; in the shot's
/// composite over the grey stand-in plate every pixel that sees no geometry is the plate
/// exactly, the spheres are their render, and their shadow darkens the desk.
#[test]
fn book_scene_and_book_shot_graphs_run_on_a_few_frames() {
    let data = shared("book-demo/f.txt");
    for f in [
        "book-demo/g7cam.txt",
        "book-demo/points2d.txt",
        "book-demo/modeling.scn",
        "polyhaven_hdri_1k/empty_warehouse_01_1k.hdr",
    ] {
        shared(f);
    }
    let cache = tempfile::tempdir().unwrap();
    let cache_dir = cache.path().display().to_string();
    let size = (160, 90);

    // The scene: frames 68 and 186 of the four marked ones.
    let (_tmp, g) = scratch_copy("book_scene.yaml", &data);
    let sets: Vec<String> = ["render", "render_catcher", "desk_render"]
        .iter()
        .flat_map(|n| {
            [
                format!("{n}.width=160"),
                format!("{n}.height=90"),
                format!("{n}.spp=4"),
            ]
        })
        .collect();
    let nodes = run_frames(&g, "book_scene.yaml", "68,186", &cache_dir, &sets);
    assert!(nodes.iter().all(|n| n.2 == "ran"), "{nodes:?}");
    let out = g.join("out/book_scene");
    let written = listing(&out, |n| n.ends_with(".png"));
    assert_eq!(
        written,
        [
            "catcher.0068.png",
            "catcher.0186.png",
            "desk.0068.png",
            "desk.0186.png",
            "full.0068.png",
            "full.0186.png"
        ]
    );
    // The three marked ground points, measured with our cameras, reproject onto the marks
    // (the bound of the book_matchmove graph's test), and the book's catcher — built on the
    // same marks — has the measured triangle's shape (the bound of nodes/tests/book_scene.rs).
    let ground: MeasuredReport = json_file(&out.join("ground_points.json"));
    let rms = &ground.figures.rms;
    assert_eq!(rms.len(), 3, "{ground:?}");
    assert!(rms.iter().all(|r| *r < 10.0), "{ground:?}");
    let place: Json = json_file(&out.join("place_report.json"));
    let rel = place["relative_rms"].as_f64().unwrap();
    assert!(
        rel < 0.01,
        "the catcher's triangle is the measured one's shape: {place}"
    );
    for f in ["0068", "0186"] {
        let full = png(&out.join(format!("full.{f}.png")), size);
        let bare = png(&out.join(format!("catcher.{f}.png")), size);
        let diff = |x, y| {
            (0..3)
                .map(|c| code(&full, x, y, c).abs_diff(code(&bare, x, y, c)))
                .max()
        };
        let (mut same, mut changed) = (0, 0);
        for y in 0..size.1 {
            for x in 0..size.0 {
                let d = diff(x, y).unwrap();
                same += usize::from(d <= 12);
                changed += usize::from(d >= 64);
            }
        }
        let n = size.0 * size.1;
        eprintln!(
            "book_scene frame {f}: {changed} pixels changed by the spheres, {same} of {n} alike"
        );
        assert!(
            changed >= 20,
            "frame {f}: the spheres are in view ({changed} pixels)"
        );
        assert!(
            same >= n / 2,
            "frame {f}: away from the spheres the renders agree ({same} of {n})"
        );
    }

    // The shot: frames 40 and 140, cheap adaptive sampling.
    let (_tmp2, g) = scratch_copy("book_shot.yaml", &data);
    let sets = ["width=160", "height=90", "spp=16", "min_spp=4"].map(|s| format!("shot.{s}"));
    let nodes = run_frames(&g, "book_shot.yaml", "40,140", &cache_dir, &sets);
    for id in ["solve", "relax", "ground", "place"] {
        let n = nodes.iter().find(|n| n.0 == id).unwrap();
        assert_eq!(
            n.2, "cached",
            "{id} comes from the scene graph's run: {n:?}"
        );
    }
    let out = g.join("out/book_shot");
    check_book_solve(&json_file(&out.join("relax_report.json")));
    let written = listing(&out, |n| !n.ends_with(".json"));
    assert_eq!(
        written,
        [
            "composite.0040.png",
            "composite.0140.png",
            "shot.0040.exr",
            "shot.0140.exr"
        ]
    );
    let grey = linear_to_srgb8(0.18);
    for f in ["0040", "0140"] {
        let comp = png(&out.join(format!("composite.{f}.png")), size);
        let exr = fs::read(out.join(format!("shot.{f}.exr"))).unwrap();
        let layer = |name: &str| {
            let img = vfxgraph_imaging::io::exr::decode_layer(&exr, name)
                .unwrap_or_else(|e| panic!("shot.{f}.exr layer {name}: {e}"));
            assert_eq!((img.width, img.height), size, "layer {name}");
            img
        };
        let (beauty, samples) = (layer("beauty"), layer("samples"));
        assert_eq!(beauty.channels, 4, "beauty carries alpha");
        let (mut plate, mut objects, mut objects_differ, mut shadow) = (0, 0, 0, 0);
        for y in 0..size.1 {
            for x in 0..size.0 {
                let px: Vec<u8> = (0..3).map(|c| code(&comp, x, y, c)).collect();
                let alpha = beauty.get(x, y, 3);
                if samples.get(x, y, 0) == 0.0 {
                    plate += 1;
                    assert_eq!(px, [grey; 3], "frame {f} ({x}, {y}) sees no geometry");
                } else if alpha == 1.0 {
                    objects += 1;
                    let b: Vec<u8> = (0..3)
                        .map(|c| linear_to_srgb8(beauty.get(x, y, c)))
                        .collect();
                    for c in 0..3 {
                        assert!(
                            px[c].abs_diff(b[c]) <= 1,
                            "frame {f} ({x}, {y}): {px:?} vs {b:?}"
                        );
                    }
                    objects_differ += usize::from(px.iter().any(|v| v.abs_diff(grey) > 4));
                } else if alpha == 0.0 && px.iter().all(|v| u16::from(*v) + 8 < u16::from(grey)) {
                    shadow += 1;
                }
            }
        }
        eprintln!(
            "book_shot frame {f}: {plate} plate pixels, {objects} sphere pixels \
             ({objects_differ} unlike the plate), {shadow} shadowed desk pixels"
        );
        assert!(plate > 0 && objects > 0 && shadow > 0, "frame {f}");
        assert!(
            10 * objects_differ >= 9 * objects,
            "frame {f}: the spheres are not grey"
        );
    }
}
