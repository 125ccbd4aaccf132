//! End-to-end tests of the `vfxgraph` binary: the example graph, partial reruns, crash safety,
//! determinism across thread counts, exit codes.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::Value as Json;
use vfxgraph_engine::artifact::content_digest;
use vfxgraph_engine::store::Store;
use vfxgraph_engine::Digest;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_vfxgraph"))
}

mod common;
use common::{run_json, vfx};
use vfxgraph_testdata::repo;

fn statuses<'a>(nodes: &'a [Json], status: &str) -> Vec<(&'a str, Option<i64>)> {
    nodes
        .iter()
        .filter(|n| n["status"] == status)
        .map(|n| (n["id"].as_str().unwrap(), n["frame"].as_i64()))
        .collect()
}

fn copy_dir(from: &Path, to: &Path) {
    fs::create_dir_all(to).unwrap();
    for e in fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        let name = e.file_name();
        if name == ".vfxgraph" || name == "out" {
            continue;
        }
        let p = e.path();
        if p.is_dir() {
            copy_dir(&p, &to.join(&name));
        } else {
            fs::copy(&p, to.join(&name)).unwrap();
        }
    }
}

#[test]
fn example_graph_runs_then_is_cached_then_reruns_one_branch() {
    let tmp = tempfile::tempdir().unwrap();
    let g = tmp.path().join("graphs");
    copy_dir(&repo().join("graphs"), &g);
    let first = run_json(&g, &["tonemap_hdri.yaml"]);
    assert!(first.iter().all(|n| n["status"] == "ran"), "{first:?}");
    for f in [
        "studio_small_03_reinhard.png",
        "studio_small_03_srgb.png",
        "studio_small_03_exposed.exr",
    ] {
        let img = vfxgraph_imaging::read_image(&g.join("out").join(f)).unwrap();
        assert_eq!((img.width, img.height), (1024, 512), "{f}");
    }
    // The Reinhard output lies in [0, 1] and is not black.
    let png = vfxgraph_imaging::read_image(&g.join("out/studio_small_03_reinhard.png")).unwrap();
    let mean = png.data.iter().sum::<f32>() / png.data.len() as f32;
    assert!(mean > 0.05 && mean < 0.95, "mean {mean}");
    let second = run_json(&g, &["tonemap_hdri.yaml"]);
    assert!(second.iter().all(|n| n["status"] == "cached"), "{second:?}");
    let third = run_json(&g, &["tonemap_hdri.yaml", "--set", "reinhard.exposure=1.5"]);
    let ran = statuses(&third, "ran");
    assert_eq!(ran, vec![("reinhard", None), ("png_reinhard", None)]);
    let reason = third.iter().find(|n| n["id"] == "reinhard").unwrap()["reason"]
        .as_str()
        .unwrap()
        .to_string();
    assert!(reason.contains("exposure"), "{reason}");
    // plan --json has the documented schema.
    let out = vfx(
        &g,
        &[
            "plan",
            "--json",
            "tonemap_hdri.yaml",
            "--set",
            "expose.stops=0",
        ],
    );
    let plan: Json = serde_json::from_slice(&out.stdout).unwrap();
    for n in plan["nodes"].as_array().unwrap() {
        for k in ["id", "type", "frame", "status", "reason", "seconds"] {
            assert!(n.get(k).is_some(), "plan entry lacks {k}: {n}");
        }
        let expect = match n["id"].as_str().unwrap() {
            "dome" => "cached",
            "expose" => "run",
            _ => "blocked",
        };
        assert_eq!(n["status"], expect, "{n}");
    }
}

fn write_frames(dir: &Path, frames: std::ops::RangeInclusive<i64>) {
    fs::create_dir_all(dir.join("plate")).unwrap();
    for f in frames {
        let img = vfxgraph_imaging::Image::from_fn(16, 8, 3, |x, y, c| {
            ((x + y + c) as f32 * 0.03 + f as f32 * 0.01).min(1.0)
        });
        vfxgraph_imaging::write_image(&dir.join(format!("plate/{f:04}.png")), &img).unwrap();
    }
}

const SEQ: &str = "version: 1
frames: 1-5
nodes:
  plate: {type: read_image_sequence, params: {path: plate/%04d.png}}
  bright: {type: exposure, inputs: {image: plate.sequence}, params: {stops: 1}}
  out: {type: write_image_sequence, inputs: {sequence: bright.image}, params: {path: out/####.exr}}
";

#[test]
fn changing_one_plate_frame_reruns_one_frame() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    write_frames(d, 1..=5);
    fs::write(d.join("seq.yaml"), SEQ).unwrap();
    let r = run_json(d, &["seq.yaml"]);
    assert_eq!(statuses(&r, "ran").len(), 15);
    assert!(d.join("out/0005.exr").is_file());
    // Rewrite frame 3 with other content.
    let img = vfxgraph_imaging::Image::from_fn(16, 8, 3, |_, _, _| 0.5);
    vfxgraph_imaging::write_image(&d.join("plate/0003.png"), &img).unwrap();
    let r = run_json(d, &["seq.yaml"]);
    assert_eq!(
        statuses(&r, "ran"),
        vec![("plate", Some(3)), ("bright", Some(3)), ("out", Some(3))]
    );
    assert_eq!(statuses(&r, "cached").len(), 12);
    let out3 = vfxgraph_imaging::read_image(&d.join("out/0003.exr")).unwrap();
    let expect = 2.0
        * vfxgraph_imaging::color::srgb8_to_linear(vfxgraph_imaging::color::linear_to_srgb8(0.5));
    assert!(
        out3.data.iter().all(|&v| (v - expect).abs() < 1e-5),
        "{:?}",
        &out3.data[..3]
    );
}

/// Every object in the cache matches its digest; every action's objects exist.
fn assert_cache_sound(cache: &Path) {
    let store = Store::open(cache).unwrap();
    let entries = store.list();
    assert!(!entries.is_empty());
    for e in &entries {
        for o in &e.entry.outputs {
            let d = Digest::from_hex(&o.digest).unwrap();
            let (ty, bytes) = store
                .get_object(&d)
                .expect("object of a recorded action exists and verifies");
            assert_eq!(content_digest(&ty, &bytes), d);
        }
    }
}

fn long_graph(frames: usize) -> String {
    format!(
        "version: 1
frames: 0..{frames}
nodes:
  src: {{type: constant, per_frame: true, params: {{width: 1200, height: 900, ramp: 2.0}}}}
  lit: {{type: exposure, inputs: {{image: src.image}}, params: {{stops: 0.5}}}}
  tm: {{type: tonemap, inputs: {{image: lit.image}}, params: {{operator: reinhard}}}}
  out: {{type: write_image_sequence, inputs: {{sequence: tm.image}}, params: {{path: out/f.####.exr}}}}
"
    )
}

#[test]
#[cfg(unix)]
fn sigkill_mid_run_then_rerun_reuses_work_and_matches_a_clean_run() {
    let frames = 40;
    let tmp = tempfile::tempdir().unwrap();
    let (a, b) = (tmp.path().join("killed"), tmp.path().join("clean"));
    for d in [&a, &b] {
        fs::create_dir_all(d).unwrap();
        fs::write(d.join("g.yaml"), long_graph(frames)).unwrap();
    }
    let mut child = bin()
        .current_dir(&a)
        .args(["run", "-q", "--jobs", "1", "g.yaml"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    // Wait until a few outputs exist, then SIGKILL.
    let t0 = Instant::now();
    loop {
        let done = fs::read_dir(a.join("out")).map(|r| r.count()).unwrap_or(0);
        if done >= 3 {
            break;
        }
        if let Some(st) = child.try_wait().unwrap() {
            panic!("run finished ({st}) before it could be killed; make the graph longer");
        }
        assert!(t0.elapsed() < Duration::from_secs(120), "no progress");
        std::thread::sleep(Duration::from_millis(20));
    }
    child.kill().unwrap(); // SIGKILL
    child.wait().unwrap();
    let finished_before = fs::read_dir(a.join("out"))
        .unwrap()
        .filter(|e| {
            e.as_ref()
                .unwrap()
                .file_name()
                .to_string_lossy()
                .ends_with(".exr")
        })
        .count();
    assert!(finished_before < frames, "killed too late");
    assert_cache_sound(&a.join(".vfxgraph"));

    let r = run_json(&a, &["g.yaml"]);
    let cached = statuses(&r, "cached");
    assert!(!cached.is_empty(), "finished work was reused");
    assert!(
        statuses(&r, "cached")
            .iter()
            .filter(|(id, _)| *id == "out")
            .count()
            + 1
            >= finished_before,
        "written frames were reused"
    );
    assert!(statuses(&r, "failed").is_empty());
    assert_cache_sound(&a.join(".vfxgraph"));

    run_json(&b, &["g.yaml"]);
    for f in 0..frames {
        let name = format!("out/f.{f:04}.exr");
        assert_eq!(
            fs::read(a.join(&name)).unwrap(),
            fs::read(b.join(&name)).unwrap(),
            "{name}"
        );
    }
    // Nothing but complete outputs under output names. A kill during a write can leave that
    // write's hidden temporary (`.vfxgraph-tmp-*`) beside the outputs, never a partial output.
    let mut outputs = 0;
    for e in fs::read_dir(a.join("out")).unwrap() {
        let n = e.unwrap().file_name().to_string_lossy().into_owned();
        if n.starts_with(".vfxgraph-tmp-") {
            continue;
        }
        assert!(
            n.starts_with("f.") && n.ends_with(".exr"),
            "unexpected file {n}"
        );
        outputs += 1;
    }
    assert_eq!(outputs, frames);
}

#[test]
fn outputs_identical_with_one_and_eight_jobs() {
    let tmp = tempfile::tempdir().unwrap();
    let mut outs = Vec::new();
    for jobs in ["1", "8"] {
        let d = tmp.path().join(jobs);
        fs::create_dir_all(&d).unwrap();
        write_frames(&d, 1..=5);
        fs::write(d.join("seq.yaml"), SEQ).unwrap();
        run_json(&d, &["seq.yaml", "--jobs", jobs]);
        let files: Vec<Vec<u8>> = (1..=5)
            .map(|f| fs::read(d.join(format!("out/{f:04}.exr"))).unwrap())
            .collect();
        let mut keys: Vec<(String, Vec<String>)> = Store::open(&d.join(".vfxgraph"))
            .unwrap()
            .list()
            .into_iter()
            .map(|e| {
                (
                    e.key,
                    e.entry.outputs.into_iter().map(|o| o.digest).collect(),
                )
            })
            .collect();
        keys.sort();
        outs.push((files, keys));
    }
    assert_eq!(outs[0], outs[1]);
}

#[test]
fn exit_codes_and_messages() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    fs::write(
        d.join("bad.yaml"),
        "version: 1\nnodes:\n  x: {type: tonemapp}\n",
    )
    .unwrap();
    let out = vfx(d, &["check", "bad.yaml"]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("bad.yaml:3:13") && err.contains("did you mean `tonemap`"),
        "{err}"
    );

    fs::write(
        d.join("fail.yaml"),
        "version: 1\nnodes:\n  img: {type: read_image, params: {path: missing.png}}\n  t: {type: tonemap, inputs: {image: img.image}}\n  ok: {type: constant}\n",
    )
    .unwrap();
    let out = vfx(d, &["run", "--json", "fail.yaml"]);
    assert_eq!(out.status.code(), Some(1));
    let v: Json = serde_json::from_slice(&out.stdout).unwrap();
    let by_id = |id: &str| {
        v["nodes"]
            .as_array()
            .unwrap()
            .iter()
            .find(|n| n["id"] == id)
            .unwrap()
            .clone()
    };
    assert_eq!(by_id("img")["status"], "failed");
    assert!(by_id("img")["reason"]
        .as_str()
        .unwrap()
        .contains("missing.png"));
    assert_eq!(by_id("t")["status"], "skipped");
    assert_eq!(by_id("ok")["status"], "ran");

    let out = vfx(d, &["run", "nope.yaml"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("nope.yaml"));
}

#[test]
fn describe_nodes_dot_and_cache_commands() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let out = vfx(d, &["nodes"]);
    let text = String::from_utf8_lossy(&out.stdout);
    for n in [
        "read_image",
        "write_image",
        "read_image_sequence",
        "write_image_sequence",
        "exposure",
        "tonemap",
    ] {
        assert!(text.contains(n), "{n} missing from `vfxgraph nodes`");
    }
    let out = vfx(d, &["describe", "tonemap"]);
    assert!(String::from_utf8_lossy(&out.stdout).contains("srgb | reinhard"));
    write_frames(d, 1..=5);
    fs::write(d.join("seq.yaml"), SEQ).unwrap();
    let dot = String::from_utf8_lossy(&vfx(d, &["dot", "seq.yaml"]).stdout).into_owned();
    assert!(
        dot.starts_with("digraph") && dot.contains("orange"),
        "{dot}"
    );
    run_json(d, &["seq.yaml"]);
    let dot = String::from_utf8_lossy(&vfx(d, &["dot", "seq.yaml"]).stdout).into_owned();
    assert!(
        dot.contains("palegreen") && !dot.contains("orange"),
        "{dot}"
    );
    let ls = String::from_utf8_lossy(&vfx(d, &["cache", "ls", "seq.yaml"]).stdout).into_owned();
    assert!(ls.contains("15 entries"), "{ls}");
    let gc = vfx(d, &["cache", "gc", "seq.yaml", "--max-size", "0"]);
    assert!(gc.status.success());
    let ls = String::from_utf8_lossy(&vfx(d, &["cache", "ls", "seq.yaml"]).stdout).into_owned();
    assert!(ls.contains("0 entries"), "{ls}");
    let r = run_json(d, &["seq.yaml"]);
    assert_eq!(statuses(&r, "ran").len(), 15, "evicted entries run again");
    assert!(vfx(d, &["cache", "clear", "seq.yaml"]).status.success());
}

/// The book's HDR-camera calibration graph, with a synthetic 3D set made by back-projecting the
/// six marked points from a known camera at known depths: the graph must give that camera back.
#[test]
fn calibrate_hdr_camera_graph_recovers_a_known_camera() {
    let Some((tmp, g)) = example_with_shared_data("calibrate_hdr_camera.yaml") else {
        return;
    };
    let data = vfxgraph_testdata::require("book-demo/calib_projs.txt");
    let projs = vfxgraph_geometry::formats::read_points2d(&data).unwrap().0;
    let k = vfxgraph_geometry::Intrinsics::new(3100.0, 3100.0, 2000.0, 1500.0);
    let r = vfxgraph_geometry::rotation::axis_angle_to_r(&nalgebra::Vector3::new(0.1, -0.4, 0.05));
    let truth =
        vfxgraph_geometry::Camera::new(k.clone(), r, nalgebra::Vector3::new(0.2, -0.1, 3.0));
    let inv = truth.pose.inverse();
    let depths = [4.0, 6.5, 5.0, 8.0, 3.5, 7.0];
    let mut text = String::new();
    for (x, d) in projs.iter().zip(depths) {
        let p = inv.transform(&nalgebra::Point3::from(k.unproject(x) * d));
        text.push_str(&format!("{} {} {}\n", p.x, p.y, p.z));
    }
    let pts = tmp.path().join("points3d.txt");
    fs::write(&pts, text).unwrap();
    let set = format!("world.path={}", pts.display());
    let r1 = run_json(&g, &["calibrate_hdr_camera.yaml", "--set", &set]);
    assert_eq!(statuses(&r1, "ran").len(), 5);
    let cam: Json =
        serde_json::from_slice(&fs::read(g.join("out/hdr_camera.json")).unwrap()).unwrap();
    assert!(
        (cam["K"][0][0].as_f64().unwrap() - 3100.0).abs() < 1e-3,
        "{cam}"
    );
    assert!(
        (cam["K"][1][2].as_f64().unwrap() - 1500.0).abs() < 1e-3,
        "{cam}"
    );
    for i in 0..3 {
        for j in 0..3 {
            assert!((cam["R"][i][j].as_f64().unwrap() - r[(i, j)]).abs() < 1e-6);
        }
    }
    let rep: vfxgraph_geometry::calibration::CalibrationReport =
        serde_json::from_slice(&fs::read(g.join("out/hdr_camera_report.json")).unwrap()).unwrap();
    assert!(rep.rms < 1e-6, "{rep:?}");
    assert_eq!(rep.errors.len(), 6);
}

/// Copies an example graph into a scratch folder with its `../../shared/data` paths pointing at
/// the tests' data folder; `None` (a notice, or a failure under CI=true) when data it names is
/// absent.
fn example_with_shared_data(name: &str) -> Option<(tempfile::TempDir, PathBuf)> {
    let tmp = tempfile::tempdir().unwrap();
    let g = tmp.path().join("graphs");
    vfxgraph_testdata::graph_with_data(&repo().join("graphs").join(name), &g)?;
    // The book's marks are embedded beside the graphs.
    common::copy_dir(&repo().join("graphs/data/book"), &g.join("data/book"));
    Some((tmp, g))
}

#[test]
fn track_graph_runs_on_rubberwhale() {
    let Some((_tmp, g)) = example_with_shared_data("track.yaml") else {
        return;
    };
    let r = run_json(&g, &["track.yaml"]);
    assert!(statuses(&r, "failed").is_empty());
    let tracks = fs::read_to_string(g.join("out/track/f.txt")).unwrap();
    assert!(tracks.lines().count() > 100, "book-format tracks written");
    let drawn = vfxgraph_imaging::read_image(&g.join("out/track/draw.11.png")).unwrap();
    assert!(drawn.width > 0);
}

#[test]
fn read_video_feeds_klt_track_in_a_graph() {
    // A clip made here: a smooth texture panning (2, −1) px per frame, H.264 in MP4.
    let tmp = tempfile::tempdir().unwrap();
    let g = tmp.path();
    let frames: Vec<vfxgraph_imaging::Image> = (0..6)
        .map(|k| {
            vfxgraph_imaging::Image::from_fn(128, 96, 3, |x, y, _| {
                let (x, y) = (x as f32 - 2.0 * k as f32, y as f32 + k as f32);
                let v = 0.45
                    + 0.2 * (0.21 * x + 0.5 * (0.13 * y).sin()).sin()
                    + 0.15 * (0.17 * y + 0.4 * (0.11 * x).cos()).cos();
                vfxgraph_imaging::color::srgb_to_linear(v)
            })
        })
        .collect();
    let color = vfxgraph_video::ColorInfo {
        matrix: vfxgraph_video::Matrix::Bt601,
        full_range: false,
        matrix_from_stream: true,
    };
    vfxgraph_video::write_mp4(&g.join("clip.mp4"), &frames, 30.0, 3, 8, color).unwrap();
    let yaml = "version: 1\nframes: 0..=5\nnodes:\n  plate:\n    type: read_video\n    \
                params: {path: clip.mp4}\n  track:\n    type: klt_track\n    \
                inputs: {frames: plate.sequence}\n    params: {features: 30, min_distance: 8}\n  \
                book:\n    type: write_tracks\n    inputs: {tracks: track.tracks}\n    \
                params: {path: out/f.txt, format: book}\n";
    fs::write(g.join("video.yaml"), yaml).unwrap();
    let r = run_json(g, &["video.yaml"]);
    assert!(statuses(&r, "failed").is_empty());
    assert_eq!(
        statuses(&r, "ran")
            .iter()
            .filter(|s| s.0 == "plate")
            .count(),
        6
    );
    let f = fs::read_to_string(g.join("out/f.txt")).unwrap();
    assert!(f.lines().count() > 10, "{f}");
    // A missing video fails the node with the file's name; exit code 1.
    let out = vfx(g, &["run", "video.yaml", "--set", "plate.path=gone.mp4"]);
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("gone.mp4"), "{err}");
}

#[test]
fn hdr_memorial_graph_runs() {
    let Some((_tmp, g)) = example_with_shared_data("hdr_memorial.yaml") else {
        return;
    };
    let r = run_json(&g, &["hdr_memorial.yaml", "--set", "curve.samples=1000"]);
    assert!(statuses(&r, "failed").is_empty());
    let hdr = vfxgraph_imaging::read_image(&g.join("out/memorial.exr")).unwrap();
    let (lo, hi) = hdr.finite_range().unwrap();
    assert!(
        lo >= 0.0 && hi / lo.max(1e-6) > 1000.0,
        "a high dynamic range: {lo}..{hi}"
    );
    let csv = fs::read_to_string(g.join("out/memorial_response.csv")).unwrap();
    assert_eq!(csv.lines().count(), 256);
}

#[test]
fn cornell_graph_renders_small() {
    let Some((_tmp, g)) = example_with_shared_data("cornell.yaml") else {
        return;
    };
    let r = run_json(
        &g,
        &[
            "cornell.yaml",
            "--set",
            "render.spp=4",
            "--set",
            "render.width=80",
            "--set",
            "render.height=60",
        ],
    );
    assert!(statuses(&r, "failed").is_empty());
    let img = vfxgraph_imaging::read_image(&g.join("out/cornell.exr")).unwrap();
    assert_eq!((img.width, img.height), (80, 60));
    assert!(img.data.iter().all(|v| v.is_finite() && *v >= 0.0));
    let mean = img.data.iter().sum::<f32>() / img.data.len() as f32;
    assert!(mean > 0.01, "the box is lit: mean {mean}");
}

#[test]
fn bench_ba_reads_ladybug_with_the_reference_initial_cost() {
    let Some(file) = vfxgraph_testdata::path("bal_ladybug_49/problem-49-7776-pre.txt") else {
        return;
    };
    let out = bin()
        .args(["bench", "ba", "--json", "--max-iterations", "1"])
        .arg(&file)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: Json = serde_json::from_slice(&out.stdout).unwrap();
    let c = v["initial_cost"].as_f64().unwrap();
    assert!(((c - 850912.4606808) / 850912.4606808).abs() < 1e-6, "{c}");
    assert!(v["final_cost"].as_f64().unwrap() < c);
    assert_eq!(v["observations"], 31843);
    for k in ["iterations", "seconds"] {
        assert!(v.get(k).is_some());
    }
}

/// The book's matchmove graph: every frame gets a camera in both formats, the plot is written,
/// and changing a relaxation param reruns only the relaxation and what reads it.
#[test]
fn book_matchmove_graph_runs_and_reruns_only_the_relaxation() {
    let Some((_tmp, g)) = example_with_shared_data("book_matchmove.yaml") else {
        return;
    };
    let fast = ["--set", "relax.rounds=2", "--set", "relax.cycles=2"];
    let mut args = vec!["book_matchmove.yaml"];
    args.extend(fast);
    let r = run_json(&g, &args);
    assert!(statuses(&r, "failed").is_empty());
    let out = g.join("out/book_matchmove");
    let book = fs::read_to_string(out.join("cameras.txt")).unwrap();
    assert_eq!(book.lines().filter(|l| l.starts_with("Frame")).count(), 286);
    let json: Json =
        serde_json::from_str(&fs::read_to_string(out.join("cameras.json")).unwrap()).unwrap();
    assert_eq!(json["frames"].as_array().unwrap().len(), 286);
    assert!(json["intrinsics"]["K"][0][0].as_f64().unwrap() > 1228.0);
    let svg = fs::read_to_string(out.join("solve_error.svg")).unwrap();
    assert!(svg.starts_with("<svg"));
    let report: vfxgraph_matchmove::SolveReport =
        serde_json::from_str(&fs::read_to_string(out.join("solve_report.json")).unwrap()).unwrap();
    assert_eq!(report.score.unwrap().frames_with_camera, 286);
    // Chapter 8: the three marked ground points, measured with the relaxed cameras.
    let ground: vfxgraph_nodes::modeling::MeasuredReport =
        serde_json::from_str(&fs::read_to_string(out.join("ground_points.json")).unwrap()).unwrap();
    assert_eq!(ground.points.len(), 3);
    assert!(ground.figures.rms.iter().all(|r| *r < 10.0));

    let args = [
        "book_matchmove.yaml",
        "--set",
        "relax.rounds=1",
        "--set",
        "relax.cycles=2",
    ];
    let r = run_json(&g, &args);
    let mut ran: Vec<&str> = statuses(&r, "ran").into_iter().map(|(id, _)| id).collect();
    ran.sort();
    assert_eq!(
        ran,
        [
            "ground",
            "ground_report",
            "relax",
            "relax_plot",
            "relax_report",
            "relaxed_book"
        ],
        "only the relaxation and its readers rerun"
    );
}

/// Threads independent of the graph's size: a chain of 3,000 nodes runs with at most
/// cores + 8 threads (sampled from `/proc` while it runs, with and without `-q`); a progress
/// bar per node once started a redraw thread each.
#[test]
#[cfg(target_os = "linux")]
fn a_long_chain_runs_on_a_bounded_number_of_threads() {
    use std::fmt::Write as _;
    let n = 3000;
    let mut g =
        String::from("version: 1\nnodes:\n  n0: {type: constant, params: {width: 2, height: 2}}\n");
    for i in 1..n {
        writeln!(
            g,
            "  n{i}: {{type: exposure, inputs: {{image: n{}.image}}, params: {{stops: 0.001}}}}",
            i - 1
        )
        .unwrap();
    }
    let cores = std::thread::available_parallelism().map_or(1, |c| c.get());
    for quiet in [true, false] {
        let tmp = tempfile::tempdir().unwrap();
        fs::write(tmp.path().join("g.yaml"), &g).unwrap();
        let mut args = vec!["run", "g.yaml"];
        if quiet {
            args.push("-q");
        }
        let mut child = bin()
            .current_dir(tmp.path())
            .args(&args)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        let status = format!("/proc/{}/status", child.id());
        let mut most = 0usize;
        let t0 = Instant::now();
        while child.try_wait().unwrap().is_none() {
            if let Ok(s) = fs::read_to_string(&status) {
                if let Some(t) = s
                    .lines()
                    .find_map(|l| l.strip_prefix("Threads:"))
                    .and_then(|t| t.trim().parse::<usize>().ok())
                {
                    most = most.max(t);
                }
            }
            assert!(
                t0.elapsed() < Duration::from_secs(300),
                "the chain did not finish"
            );
            std::thread::sleep(Duration::from_millis(2));
        }
        assert!(child.wait().unwrap().success());
        eprintln!("{n}-node chain (quiet {quiet}): at most {most} threads on {cores} cores");
        assert!(most >= 1, "threads were sampled");
        assert!(
            most <= cores + 8,
            "{most} threads for {n} nodes on {cores} cores"
        );
    }
}

/// A listing piped into a reader that stops early (`vfxgraph cache ls | head`) ends quietly,
/// as `ls | head` does: no panic, no exit 101 (it used to panic on the closed pipe).
#[test]
#[cfg(unix)]
fn a_listing_into_a_closed_pipe_ends_quietly() {
    use std::os::unix::process::ExitStatusExt;
    let tmp = tempfile::tempdir().unwrap();
    fs::write(tmp.path().join("g.yaml"), long_graph(30)).unwrap();
    let out = bin()
        .current_dir(tmp.path())
        .args(["run", "-q", "g.yaml"])
        .output()
        .unwrap();
    assert!(out.status.success());
    for args in [
        &["cache", "ls"][..],
        &["nodes"][..],
        &["plan", "g.yaml"][..],
    ] {
        let mut child = bin()
            .current_dir(tmp.path())
            .args(args)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        // The reader goes away before the listing is written.
        drop(child.stdout.take());
        let out = child.wait_with_output().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
        assert!(
            out.status.success() || out.status.signal() == Some(libc::SIGPIPE),
            "{args:?}: {:?} {stderr}",
            out.status
        );
    }
}

/// The same graph in two folders sharing one cache: each writes its own files. The second
/// run's write action has the same key as the first's (same node, params and input), but its
/// file is elsewhere, so it is not a cache hit (it used to be: the second folder got no file).
#[test]
fn twin_graphs_sharing_a_cache_each_write_their_files() {
    let tmp = tempfile::tempdir().unwrap();
    let cache = tmp.path().join("cache");
    let graph = "version: 1\nframes: 0..3\nnodes:\n  c: {type: constant, per_frame: true, \
                 params: {width: 4, height: 2}}\n  w: {type: write_image_sequence, inputs: \
                 {sequence: c.image}, params: {path: out/f.####.png}}\n";
    for name in ["a", "b"] {
        let d = tmp.path().join(name);
        fs::create_dir_all(&d).unwrap();
        fs::write(d.join("g.yaml"), graph).unwrap();
        let out = bin()
            .current_dir(&d)
            .args(["run", "-q", "--cache", cache.to_str().unwrap(), "g.yaml"])
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        for f in 0..3 {
            assert!(
                d.join(format!("out/f.{f:04}.png")).is_file(),
                "{name}: frame {f}"
            );
        }
    }
    // The entry now records the second folder's files: the first reruns its writes (the
    // price of sharing the key) and its files stay right.
    let out = bin()
        .current_dir(tmp.path().join("a"))
        .args(["run", "-q", "--cache", cache.to_str().unwrap(), "g.yaml"])
        .output()
        .unwrap();
    assert!(out.status.success());
    assert!(tmp.path().join("a/out/f.0000.png").is_file());
}

/// A graph of 100 000 nodes is checked and planned (no recursion deep enough to overflow the
/// stack: the cycle search is iterative).
#[test]
fn a_graph_of_100000_nodes_is_checked_and_planned() {
    use std::fmt::Write as _;
    let n = 100_000;
    let mut g =
        String::from("version: 1\nnodes:\n  n0: {type: constant, params: {width: 2, height: 2}}\n");
    for i in 1..n {
        writeln!(
            g,
            "  n{i}: {{type: exposure, inputs: {{image: n{}.image}}, params: {{stops: 0.001}}}}",
            i - 1
        )
        .unwrap();
    }
    let tmp = tempfile::tempdir().unwrap();
    fs::write(tmp.path().join("g.yaml"), &g).unwrap();
    let out = bin()
        .current_dir(tmp.path())
        .args(["check", "g.yaml"])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        stdout.contains("100000 nodes, 100000 instances"),
        "{stdout}"
    );
    let out = bin()
        .current_dir(tmp.path())
        .args(["plan", "g.yaml"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(
        String::from_utf8_lossy(&out.stdout)
            .lines()
            .filter(|l| l.starts_with('n'))
            .count(),
        n
    );
}

/// A mistyped frame range (a million frames for a hundred) and a render of 65536 × 65536 are
/// refused by `check` with the figure and the flag that allows them; the flag does.
#[test]
fn a_huge_graph_is_refused_at_check_with_the_figure_and_the_flag() {
    let tmp = tempfile::tempdir().unwrap();
    let g = common::farm_shot_copy(tmp.path());
    let check = |args: &[&str]| {
        let out = bin()
            .current_dir(g.parent().unwrap())
            .arg("check")
            .arg(&g)
            .args(args)
            .output()
            .unwrap();
        (
            out.status.code(),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    };
    let (code, err) = check(&["--frames", "0..1000000"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("3000003 node instances")
            && err.contains("1000000 frames")
            && err.contains("--max-instances 3000003"),
        "{err}"
    );
    let (code, err) = check(&["--frames", "0..1000000", "--max-instances", "3000003"]);
    assert_eq!(code, Some(0), "{err}");
    let big = ["--set", "plate.width=65536", "--set", "plate.height=65536"];
    let (code, err) = check(&big);
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("node `plate` (render) declares 385 GiB")
            && err.contains("--max-instance-memory 385"),
        "{err}"
    );
    let (code, err) = check(&[&big[..], &["--max-instance-memory", "385"]].concat());
    assert_eq!(code, Some(0), "{err}");
}

/// `--ocio FILE` gives every node with an `ocio_config` parameter the studio's config (its
/// content in the cache keys), `$OCIO` stands in for it, a farm task (`exec`) ignores its host's
/// `$OCIO`, and a config that cannot be read fails the node naming the file.
#[test]
fn ocio_flag_and_environment() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("g.yaml"),
        "version: 1\nnodes:\n  c:\n    type: constant\n    params: {width: 8, height: 4, color: \
         [0.18, 0.18, 0.18]}\n  w:\n    type: write_image\n    inputs: {image: c.image}\n    \
         params: {path: out.tif, colour_space: ACEScct}\n",
    )
    .unwrap();
    let vfx_env = |args: &[&str], ocio: Option<&str>| {
        let mut c = std::process::Command::new(env!("CARGO_BIN_EXE_vfxgraph"));
        c.current_dir(dir.path()).args(args).env_remove("OCIO");
        if let Some(o) = ocio {
            c.env("OCIO", o);
        }
        c.output().unwrap()
    };
    // The built-in config: it runs.
    let out = vfx_env(&["run", "g.yaml"], None);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // A missing config given by the flag: the node fails naming the file and the parameter.
    let out = vfx_env(&["run", "g.yaml", "--ocio", "studio.ocio"], None);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("studio.ocio") && err.contains("ocio_config"),
        "{err}"
    );
    // $OCIO is the same as the flag …
    let out = vfx_env(&["plan", "g.yaml", "--json"], Some("env.ocio"));
    let plan = String::from_utf8_lossy(&out.stdout);
    assert!(plan.contains("env.ocio"), "{plan}");
    // … but not for a farm task, which runs with its submit's config only.
    let out = vfx_env(&["exec", "g.yaml", "--node", "w"], Some("env.ocio"));
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // A config file that is not a config: the node fails naming it.
    std::fs::write(dir.path().join("bad.ocio"), "ocio_profile_version: 2\n").unwrap();
    let out = vfx_env(&["run", "g.yaml", "--ocio", "bad.ocio"], None);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("bad.ocio"), "{err}");
}

/// `probe` reports what the readers know: a DPX file's size, bits, transfer and the frame rate
/// of its film header; a PNG's size and that it records no focal length; a missing file is an
/// error in its place and exit status 1.
#[test]
fn probe_reports_what_the_readers_know() {
    let dir = tempfile::tempdir().unwrap();
    let img = vfxgraph_imaging::Image::from_fn(6, 4, 3, |x, y, c| (x + y + c) as f32 / 16.0);
    let mut dpx =
        vfxgraph_imaging::io::dpx::encode(&img, &vfxgraph_imaging::io::dpx::DpxOptions::default())
            .unwrap();
    // The film industry header's frame rate (big-endian f32 at byte 1724).
    dpx[1724..1728].copy_from_slice(&23.976f32.to_be_bytes());
    std::fs::write(dir.path().join("plate.dpx"), &dpx).unwrap();
    vfxgraph_imaging::write_image(&dir.path().join("still.png"), &img).unwrap();
    let out = bin()
        .args(["probe", "--json", "plate.dpx", "still.png"])
        .current_dir(dir.path())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: Json = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v[0]["format"], "dpx", "{v}");
    assert_eq!(v[0]["size"], serde_json::json!([6, 4]), "{v}");
    assert_eq!(v[0]["bits"], 10, "{v}");
    assert!(
        (v[0]["frame_rate"].as_f64().unwrap() - 23.976).abs() < 1e-4,
        "{v}"
    );
    assert!(
        v[0]["transfer"].as_str().unwrap().contains("density"),
        "{v}"
    );
    assert_eq!(v[1]["size"], serde_json::json!([6, 4]), "{v}");
    assert!(
        v[1]["focal_px"].is_null() && v[1]["focal_missing"].is_string(),
        "{v}"
    );
    let out = bin()
        .args(["probe", "still.png", "gone.mov"])
        .current_dir(dir.path())
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("still.png") && text.contains("gone.mov"),
        "{text}"
    );
    assert!(text.contains("error"), "{text}");
}
