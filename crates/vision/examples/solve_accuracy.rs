//! Scores a solved camera path against the truth (the Blender dev plate's `cameras_gt.json`):
//! the worst rotation error and camera-centre error (as a share of the path length) after the
//! similarity that aligns the two, and the solved lens against the true one.
//!
//! ```text
//! cargo run --release -p vfxgraph-vision --example solve_accuracy -- SOLVED.json TRUTH.json
//! ```
//! Prints one JSON object.

use vfxgraph_vision::camera_path::aligned_pose_errors;
use vfxgraph_vision::formats::{read_json, CameraPath};

fn main() {
    if let Err(e) = run() {
        eprintln!("solve_accuracy: {e}");
        std::process::exit(1);
    }
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    let a: Vec<String> = std::env::args().skip(1).collect();
    if a.len() != 2 {
        return Err("usage: SOLVED.json TRUTH.json".into());
    }
    let solved: CameraPath = read_json(a[0].as_ref())?;
    let truth: CameraPath = read_json(a[1].as_ref())?;
    let mut est = Vec::new();
    let mut gt = Vec::new();
    for f in &solved.frames {
        if let Some(t) = truth.frames.iter().find(|t| t.frame == f.frame) {
            est.push(f.pose.clone());
            gt.push(t.pose.clone());
        }
    }
    let (_, rot, cen) = aligned_pose_errors(&est, &gt)?;
    let centres: Vec<_> = truth.frames.iter().map(|f| f.pose.center()).collect();
    let length: f64 = centres.windows(2).map(|w| (w[1] - w[0]).norm()).sum();
    eprintln!(
        "rotation (°) by frame: {}",
        rot.iter()
            .map(|r| format!("{r:.3}"))
            .collect::<Vec<_>>()
            .join(" ")
    );
    let max = |v: &[f64]| v.iter().cloned().fold(0.0, f64::max);
    let lens = solved
        .intrinsics
        .as_ref()
        .map(|k| {
            format!(
                ", \"focal\": {:.2}, \"cx\": {:.2}, \"cy\": {:.2}, \"distortion\": {}",
                k.f1,
                k.u0,
                k.v0,
                serde_json::to_string(&k.distortion).unwrap_or_default()
            )
        })
        .unwrap_or_default();
    println!(
        "{{\"frames\": {}, \"rotation_max_deg\": {:.4}, \"centre_max_pct\": {:.3}{lens}}}",
        est.len(),
        max(&rot),
        100.0 * max(&cen) / length
    );
    Ok(())
}
