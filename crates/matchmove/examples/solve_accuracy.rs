//! Scores a solved camera path against the truth (the Blender dev plate's `cameras_gt.json`):
//! the worst rotation error and camera-centre error (as a share of the path length) after the
//! similarity that aligns the two, and the solved lens against the true one.
//!
//! ```text
//! cargo run --release -p vfxgraph-matchmove --example solve_accuracy -- SOLVED.json TRUTH.json \
//!     [POINTS.json "x y z; x y z; …"]
//! ```
//! With a `point_cloud_calibrate` report and the true points (in its order), also the points'
//! errors after the same alignment (true units).
//! Prints one JSON object.

use vfxgraph_geometry::camera_path::aligned_pose_errors;
use vfxgraph_geometry::formats::{read_json, CameraPath};

fn main() {
    if let Err(e) = run() {
        eprintln!("solve_accuracy: {e}");
        std::process::exit(1);
    }
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    let a: Vec<String> = std::env::args().skip(1).collect();
    if a.len() != 2 && a.len() != 4 {
        return Err("usage: SOLVED.json TRUTH.json [POINTS.json \"x y z; …\"]".into());
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
    let (sim, rot, cen) = aligned_pose_errors(&est, &gt)?;
    let mut points = String::new();
    if a.len() == 4 {
        let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&a[2])?)?;
        let measured = report["points"]
            .as_array()
            .ok_or("the report has no `points`")?;
        let errors = a[3]
            .split(';')
            .zip(measured)
            .map(|(want, got)| {
                let w: Vec<f64> = want
                    .split_whitespace()
                    .map(str::parse)
                    .collect::<Result<_, _>>()?;
                let g: Vec<f64> = serde_json::from_value(got.clone())?;
                if w.len() != 3 || g.len() != 3 {
                    return Err("points are x y z".into());
                }
                let d = sim.apply(&nalgebra::Point3::new(g[0], g[1], g[2]))
                    - nalgebra::Point3::new(w[0], w[1], w[2]);
                Ok(format!(
                    "{:.4} ({:.3} {:.3} {:.3})",
                    d.norm(),
                    d.x,
                    d.y,
                    d.z
                ))
            })
            .collect::<Result<Vec<_>, Box<dyn std::error::Error>>>()?;
        points = format!(", \"point_errors\": [{}]", errors.join(", "));
    }
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
        "{{\"frames\": {}, \"rotation_max_deg\": {:.4}, \"centre_max_pct\": {:.3}{lens}{points}}}",
        est.len(),
        max(&rot),
        100.0 * max(&cen) / length
    );
    Ok(())
}
