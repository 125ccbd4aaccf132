//! The camera solve on the robustness corpus ([`vfxgraph_matchmove::corpus`]): every
//! plate solved with the defaults (K given), scored against its true cameras, and the figures
//! printed per set and per motion: success rate, rotation error distribution, centre error.
//!
//! `cargo run --release -p vfxgraph-matchmove --example solve_corpus -- [count] [seed] [init] [json]`
//! (defaults: 126 plates, seed 1, the default start; `init` is `calibrated` or `book`; `json`
//! writes every plate's result to that file). With `VFXGRAPH_CORPUS_EXPORT=DIR` every plate's
//! tracks, K and true cameras are written to `DIR/<name>.json` as well, for
//! `scripts/bench/corpus_vs_colmap.py`. `VFXGRAPH_FOCAL=unknown` solves the focal length too
//! (from the tracks' image size), `VFXGRAPH_TRACK_WEIGHTING=off` turns the global adjustment's
//! track weights off, `VFXGRAPH_PLATE=part` keeps the plates whose name holds `part`, and
//! `VFXGRAPH_ORACLE=1` also adjusts every plate from its true cameras (what the tracks allow).

use std::collections::BTreeMap;
use std::time::Instant;

use rayon::prelude::*;
use serde::Serialize;
use vfxgraph_matchmove::corpus::{corpus, generate, score, PlateSpec};
use vfxgraph_matchmove::{matchmove_with_lens, poses_by_index, MatchmoveOptions};

#[derive(Serialize)]
struct Outcome {
    spec: PlateSpec,
    name: String,
    /// "solved", "failed", "partial".
    status: String,
    error: Option<String>,
    rotation_max_deg: f64,
    rotation_median_deg: f64,
    /// Centre error over the path's extent (moving plates).
    centre_max_rel: f64,
    seconds: f64,
    rotation_only: bool,
    notes: Vec<String>,
    warnings: Vec<String>,
    /// Solved focal length over the true one, less 1.
    focal_error: f64,
    /// The solve's standard deviation of the focal length, relative.
    focal_sd: f64,
    /// The largest per-frame rotation standard deviation of the report, degrees.
    rotation_sd_max_deg: f64,
    /// The solve's RMS reprojection error over its inliers, px.
    rms_px: f64,
    /// With `VFXGRAPH_ORACLE=1`: the worst rotation error of the global adjustment started
    /// from the true cameras (what the tracks allow, whatever the start), degrees.
    oracle_rotation_max_deg: f64,
}

fn quantile(v: &[f64], q: f64) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    let mut v = v.to_vec();
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * q).round() as usize]
}

/// Writes a plate for another solver: K, image size, tracks and the true cameras.
fn export(dir: &str, plate: &vfxgraph_matchmove::corpus::Plate) {
    let tracks: Vec<serde_json::Value> = plate
        .tracks
        .tracks
        .iter()
        .map(|t| serde_json::json!({"id": t.id, "first": t.first, "points": t.points}))
        .collect();
    let truth: Vec<serde_json::Value> = plate
        .truth
        .iter()
        .map(|p| {
            let r: Vec<Vec<f64>> = (0..3)
                .map(|i| (0..3).map(|j| p.r[(i, j)]).collect())
                .collect();
            serde_json::json!({"r": r, "t": [p.t.x, p.t.y, p.t.z]})
        })
        .collect();
    let doc = serde_json::json!({
        "name": plate.spec.name(),
        "spec": plate.spec,
        "k": [plate.k.f1, plate.k.u0, plate.k.v0],
        "size": [vfxgraph_matchmove::corpus::SIZE.0, vfxgraph_matchmove::corpus::SIZE.1],
        "frames": plate.truth.len(),
        "tracks": tracks,
        "truth": truth,
    });
    let path = std::path::Path::new(dir).join(format!("{}.json", plate.spec.name()));
    std::fs::write(path, serde_json::to_string(&doc).unwrap()).unwrap();
}

fn solve(spec: &PlateSpec, options: &MatchmoveOptions) -> Outcome {
    let plate = generate(spec);
    if let Ok(dir) = std::env::var("VFXGRAPH_CORPUS_EXPORT") {
        std::fs::create_dir_all(&dir).unwrap();
        export(&dir, &plate);
    }
    let t0 = Instant::now();
    // VFXGRAPH_FOCAL=unknown: the focal length solved too, from the tracks' image size alone.
    let mut options = options.clone();
    let mut k = plate.k.clone();
    if std::env::var("VFXGRAPH_FOCAL").as_deref() == Ok("unknown") {
        options.lens.focal = vfxgraph_matchmove::FocalMode::Unknown;
        k = options
            .lens
            .initial_intrinsics(None, plate.tracks.image_size)
            .expect("the corpus's tracks carry their image size");
    }
    // VFXGRAPH_TRACK_WEIGHTING=off: the global adjustment without its per-track weights.
    if std::env::var("VFXGRAPH_TRACK_WEIGHTING").as_deref() == Ok("off") {
        if let Some(g) = options.global.as_mut() {
            g.track_weighting = false;
        }
    }
    let options = &options;
    let r = matchmove_with_lens(&plate.tracks, &k, &options.lens, options, &|_, _, _| {});
    let seconds = t0.elapsed().as_secs_f64();
    let mut out = Outcome {
        spec: spec.clone(),
        name: spec.name(),
        status: "failed".into(),
        error: None,
        rotation_max_deg: f64::NAN,
        rotation_median_deg: f64::NAN,
        centre_max_rel: f64::NAN,
        seconds,
        rotation_only: false,
        notes: Vec::new(),
        warnings: Vec::new(),
        focal_error: f64::NAN,
        focal_sd: f64::NAN,
        rotation_sd_max_deg: f64::NAN,
        rms_px: f64::NAN,
        oracle_rotation_max_deg: f64::NAN,
    };
    let solve = match r {
        Ok(s) => s,
        Err(e) => {
            out.error = Some(e.to_string());
            return out;
        }
    };
    out.notes = solve.report.notes.clone();
    out.rms_px = solve.report.overall_rms;
    out.rotation_sd_max_deg = solve.report.largest_rotation_sd_deg();
    if let Some(f) = solve.path.intrinsics.as_ref().map(|k| k.f1) {
        out.focal_error = f / plate.k.f1 - 1.0;
    }
    out.focal_sd = solve
        .report
        .intrinsics
        .iter()
        .find(|i| i.name == "focal_px")
        .and_then(|i| i.sd.map(|sd| sd / i.value))
        .unwrap_or(f64::NAN);
    out.warnings = solve.report.warnings.clone();
    if std::env::var("VFXGRAPH_PLATE").is_ok() {
        for f in &solve.report.fragments {
            eprintln!("{f:?}");
        }
        for s in &solve.report.stages {
            eprintln!("{}: {:.3} s", s.stage, s.seconds);
        }
    }
    out.rotation_only = solve.report.rotation_only;
    if std::env::var("VFXGRAPH_ORACLE").is_ok() && !solve.report.rotation_only {
        if let Some(g) = &options.global {
            let truth: Vec<Option<_>> = plate.truth.iter().cloned().map(Some).collect();
            if let Ok((p, _)) =
                vfxgraph_matchmove::global::global_bundle_adjust(&plate.tracks, &plate.k, &truth, g)
            {
                out.oracle_rotation_max_deg = score(&plate, &p, false).rotation_max_deg;
            }
        }
    }
    let poses = poses_by_index(&plate.tracks, &solve.path);
    let sc = score(&plate, &poses, solve.report.rotation_only);
    out.rotation_max_deg = sc.rotation_max_deg;
    out.rotation_median_deg = sc.rotation_median_deg;
    out.centre_max_rel = sc.centre_max_rel.unwrap_or(f64::NAN);
    if !sc.complete {
        out.status = "partial".into();
        return out;
    }
    out.status = "solved".into();
    out
}

fn table(title: &str, groups: &BTreeMap<String, Vec<&Outcome>>) {
    println!(
        "\n{title:<14} plates solved warned silent>1°  rot p50°  rot p95°  rot max°  centre p95"
    );
    for (k, v) in groups {
        let solved: Vec<&&Outcome> = v.iter().filter(|o| o.status == "solved").collect();
        let warned = solved.iter().filter(|o| !o.warnings.is_empty()).count();
        let wrong = solved
            .iter()
            .filter(|o| o.rotation_max_deg > 1.0 && o.warnings.is_empty())
            .count();
        let rot: Vec<f64> = solved.iter().map(|o| o.rotation_max_deg).collect();
        let cen: Vec<f64> = solved
            .iter()
            .map(|o| o.centre_max_rel)
            .filter(|c| c.is_finite())
            .collect();
        println!(
            "{k:<14} {:>6} {:>6} {:>6} {:>10} {:>9.3} {:>9.3} {:>9.3} {:>10.4}",
            v.len(),
            solved.len(),
            warned,
            wrong,
            quantile(&rot, 0.5),
            quantile(&rot, 0.95),
            quantile(&rot, 1.0),
            quantile(&cen, 0.95),
        );
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let count: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(126);
    let seed: u64 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(1);
    let mut options = MatchmoveOptions::default();
    if let Some(init) = args.get(3) {
        options.pair.init = serde_json::from_value(serde_json::Value::String(init.clone()))
            .expect("init: calibrated or book");
    }
    let mut specs = corpus(count, seed);
    // VFXGRAPH_PLATE=part: only the plates whose name holds it, with their fragments printed.
    let only = std::env::var("VFXGRAPH_PLATE").ok();
    if let Some(part) = &only {
        specs.retain(|s| s.name().contains(part.as_str()));
    }
    let t0 = Instant::now();
    let outcomes: Vec<Outcome> = specs.par_iter().map(|s| solve(s, &options)).collect();
    let wall = t0.elapsed().as_secs_f64();
    let mut by_set: BTreeMap<String, Vec<&Outcome>> = BTreeMap::new();
    let mut by_motion: BTreeMap<String, Vec<&Outcome>> = BTreeMap::new();
    for o in &outcomes {
        by_set
            .entry(format!("{:?}", o.spec.set))
            .or_default()
            .push(o);
        by_motion
            .entry(format!("{:?}", o.spec.motion))
            .or_default()
            .push(o);
    }
    table("set", &by_set);
    table("motion", &by_motion);
    let mut all = BTreeMap::new();
    all.insert("all".to_string(), outcomes.iter().collect::<Vec<_>>());
    table("corpus", &all);
    println!("\nnot solved, over 1° or warned:");
    for o in &outcomes {
        if o.status != "solved" || o.rotation_max_deg > 1.0 || !o.warnings.is_empty() {
            println!(
                "  {:<44} {:>7} {:>8.3}° {} {}",
                o.name,
                o.status,
                o.rotation_max_deg,
                o.error.as_deref().unwrap_or(""),
                o.warnings
                    .first()
                    .map_or(String::new(), |w| w.chars().take(140).collect())
            );
        }
    }
    let cpu: f64 = outcomes.iter().map(|o| o.seconds).sum();
    println!("\n{count} plates (seed {seed}) in {wall:.1} s wall, {cpu:.1} s of solves");
    if let Some(path) = args.get(4) {
        std::fs::write(path, serde_json::to_string_pretty(&outcomes).unwrap()).unwrap();
    }
}
