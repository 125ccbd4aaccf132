//! How accurate are our KLT tracks? Tracks a plate with known cameras (the Blender dev plate's
//! `cameras_gt.json`, with its lens) and scores every track against the truth: each track is
//! triangulated from the **true** cameras and its observations' reprojection residuals are
//! measured (in pixels of the distorted image: the observations are undistorted by the true
//! lens, the residual scaled back by the lens's local magnification is below 1 % different).
//! A tracker change is judged by these residuals over hundreds of tracks, not by one solve.
//!
//! ```text
//! cargo run --release -p vfxgraph-klt --example track_accuracy -- \
//!     ../shared/data/blender_plate_dev/distorted [FEATURES] [key=value …]
//! ```
//! Keys: `bad=on` (print each track over 1 px with its residuals), `drift=<px|off>`, `fb=<px|off>`, `noise=<factor>`, `frames=<n>`, `oracle=<dir>` (write `all.json` and `kept.json`, the tracks without those whose RMS against the true cameras exceeds `oracle_px`, default 1 px, to solve both and see what the bad tracks cost). Prints one JSON
//! object: the tracking time, the tracks, the observations, the RMS and median residual over
//! observations of tracks seen ≥ 5 frames, the share of tracks whose RMS is over 1 px, and the
//! mean residual by track age.

use std::time::Instant;

use nalgebra::{Matrix3, Matrix3x4, Point2, Vector3};
use vfxgraph_geometry::camera::Intrinsics;
use vfxgraph_geometry::lens::Distortion;
use vfxgraph_geometry::two_view::triangulation::triangulate;
use vfxgraph_imaging::read_image;
use vfxgraph_klt::{track_sequence, GrayImage, TrackerOptions};

fn main() {
    if let Err(e) = run() {
        eprintln!("track_accuracy: {e}");
        std::process::exit(1);
    }
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let dir = std::path::PathBuf::from(args.first().ok_or("usage: DIR [FEATURES] [k=v …]")?);
    let mut params = TrackerOptions::default();
    let mut nframes = usize::MAX;
    let mut show_bad = false;
    let mut oracle: Option<(std::path::PathBuf, f64)> = None;
    for a in args.iter().skip(1) {
        if let Ok(n) = a.parse::<usize>() {
            params.corners.max_corners = n;
            continue;
        }
        let (k, v) = a.split_once('=').ok_or(format!("bad argument {a}"))?;
        let px = |v: &str| -> Result<Option<f32>, std::num::ParseFloatError> {
            if v == "off" {
                Ok(None)
            } else {
                v.parse().map(Some)
            }
        };
        match k {
            "drift" => params.drift_correction = px(v)?,
            "fb" => params.fb_threshold = px(v)?,
            "noise" => params.noise_factor = v.parse()?,
            "frames" => nframes = v.parse()?,
            "bad" => show_bad = v == "on",
            "oracle" => oracle = Some((v.into(), 1.0)),
            "oracle_px" => {
                if let Some(o) = oracle.as_mut() {
                    o.1 = v.parse()?;
                }
            }
            _ => return Err(format!("unknown key {k}").into()),
        }
    }
    let truth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("cameras_gt.json"))?)?;
    let kj = &truth["K"];
    let kf = |r: usize, c: usize| kj[r][c].as_f64().unwrap_or(f64::NAN);
    let mut intr = Intrinsics::new(kf(0, 0), kf(1, 1), kf(0, 2), kf(1, 2));
    if let Some(d) = truth["distortion"].as_object() {
        let g = |k: &str| d.get(k).and_then(|v| v.as_f64()).unwrap_or(0.0);
        intr = intr.with_distortion(Distortion::BrownConrady {
            k1: g("k1"),
            k2: g("k2"),
            k3: g("k3"),
            p1: g("p1"),
            p2: g("p2"),
        });
    }
    let k = intr.k();
    let mut cams: Vec<Matrix3x4<f64>> = Vec::new();
    for f in truth["frames"].as_array().ok_or("no frames")? {
        let r = Matrix3::from_fn(|i, j| f["R"][i][j].as_f64().unwrap_or(f64::NAN));
        let t = Vector3::from_fn(|i, _| f["t"][i].as_f64().unwrap_or(f64::NAN));
        let mut rt = Matrix3x4::zeros();
        rt.fixed_view_mut::<3, 3>(0, 0).copy_from(&r);
        rt.set_column(3, &t);
        cams.push(k * rt);
    }
    let n = cams.len().min(nframes);
    let mut images = Vec::with_capacity(n);
    for i in 0..n {
        let p = dir.join(format!("plate/frame.{i:04}.jpg"));
        images.push(GrayImage::from_image(&read_image(&p)?));
    }
    let frames: Vec<(i64, &GrayImage)> = images
        .iter()
        .enumerate()
        .map(|(i, g)| (i as i64, g))
        .collect();
    let t0 = Instant::now();
    let tracks = track_sequence(&frames, &params, |_| {})?;
    let seconds = t0.elapsed().as_secs_f64();

    let mut residuals: Vec<f64> = Vec::new();
    let mut track_rms: Vec<f64> = Vec::new();
    let mut by_age = vec![(0.0f64, 0usize); 48];
    let mut scored = 0usize;
    let mut dropped = std::collections::HashSet::new();
    // Signed radial residual (observed − projected, along the direction from the image centre),
    // by radius bin of 100 px: a lens or scale bias shows as a trend.
    let mut radial = [(0.0f64, 0.0f64, 0usize); 6];
    let (cx, cy) = (intr.u0, intr.v0);
    // Signed residual along the point's image motion to the next frame (a tracker that lags
    // behind the motion shows a negative mean; such a bias, shared by every track of a frame,
    // turns into camera rotation).
    let (mut along, mut along2, mut along_n) = (0.0f64, 0.0f64, 0usize);
    // Mean residual vector (observed − projected) by image region, 4 × 3 cells: a bias that a
    // solved lens would absorb shows as a pattern (on the dev plate: at most 0.15 px, in the
    // bottom row).
    let mut grid = [[(0.0f64, 0.0f64, 0usize); 4]; 3];
    for t in &tracks.tracks {
        if t.points.len() < 5 {
            continue;
        }
        let mut ps = Vec::new();
        let mut xs = Vec::new();
        for (j, p) in t.points.iter().enumerate() {
            let u = intr.undistort_pixel(&Point2::new(p[0], p[1]))?;
            ps.push(cams[t.first + j]);
            xs.push(u);
        }
        let Ok(x) = triangulate(&ps, &xs) else {
            continue;
        };
        scored += 1;
        let mut ss = 0.0;
        for (j, (p, u)) in ps.iter().zip(&xs).enumerate() {
            let h = p * x.to_homogeneous();
            let (px, py) = (h.x / h.z, h.y / h.z);
            let e = ((px - u.x).powi(2) + (py - u.y).powi(2)).sqrt();
            let (dx, dy) = (px - cx, py - cy);
            let r = dx.hypot(dy);
            if r > 1.0 && e < 2.0 {
                let b = ((r / 100.0) as usize).min(radial.len() - 1);
                let sgn = ((u.x - px) * dx + (u.y - py) * dy) / r;
                radial[b].0 += sgn;
                radial[b].1 += sgn * sgn;
                radial[b].2 += 1;
            }
            if e < 2.0 {
                let gx = ((px / (2.0 * cx + 1.0)) * 4.0).clamp(0.0, 3.0) as usize;
                let gy = ((py / (2.0 * cy + 1.0)) * 3.0).clamp(0.0, 2.0) as usize;
                grid[gy][gx].0 += u.x - px;
                grid[gy][gx].1 += u.y - py;
                grid[gy][gx].2 += 1;
            }
            residuals.push(e);
            if let Some(next) = ps.get(j + 1) {
                let hn = next * x.to_homogeneous();
                let (mx, my) = (hn.x / hn.z - px, hn.y / hn.z - py);
                let m = mx.hypot(my);
                if m > 0.05 && e < 2.0 {
                    let a = ((u.x - px) * mx + (u.y - py) * my) / m;
                    along += a;
                    along2 += a * a;
                    along_n += 1;
                }
            }
            ss += e * e;
            let a = j.min(by_age.len() - 1);
            by_age[a].0 += e;
            by_age[a].1 += 1;
        }
        track_rms.push((ss / xs.len() as f64).sqrt());
        if let Some((_, px)) = &oracle {
            if (ss / xs.len() as f64).sqrt() > *px {
                dropped.insert(t.id);
            }
        }
        if show_bad && (ss / xs.len() as f64).sqrt() > 1.0 {
            let es: Vec<String> = ps
                .iter()
                .zip(&xs)
                .map(|(p, u)| {
                    let h = p * x.to_homogeneous();
                    format!(
                        "{:.1}",
                        ((h.x / h.z - u.x).powi(2) + (h.y / h.z - u.y).powi(2)).sqrt()
                    )
                })
                .collect();
            eprintln!(
                "track {} first {} at ({:.0},{:.0}) lost {:?}: {}",
                t.id,
                t.first,
                xs[0].x,
                xs[0].y,
                t.lost.as_ref().map(|l| l.reason),
                es.join(" ")
            );
        }
    }
    if let Some((dir, px)) = &oracle {
        std::fs::create_dir_all(dir)?;
        std::fs::write(dir.join("all.json"), tracks.to_native())?;
        let mut kept = tracks.clone();
        kept.tracks.retain(|t| !dropped.contains(&t.id));
        std::fs::write(dir.join("kept.json"), kept.to_native())?;
        eprintln!(
            "oracle: {} of {} tracks over {px} px against the true cameras dropped",
            dropped.len(),
            tracks.tracks.len()
        );
    }
    eprintln!(
        "radial residual by 100 px bin (mean ± s.e.): {}",
        radial
            .iter()
            .map(|&(s, s2, n)| {
                let n = n.max(1) as f64;
                let m = s / n;
                format!("{m:+.3}±{:.3}", ((s2 / n - m * m).max(0.0) / n).sqrt())
            })
            .collect::<Vec<_>>()
            .join(" ")
    );
    for row in &grid {
        eprintln!(
            "grid: {}",
            row.iter()
                .map(|&(x, y, n)| format!(
                    "({:+.3},{:+.3})/{n}",
                    x / n.max(1) as f64,
                    y / n.max(1) as f64
                ))
                .collect::<Vec<_>>()
                .join(" ")
        );
    }
    {
        let n = along_n.max(1) as f64;
        let m = along / n;
        eprintln!(
            "residual along the image motion: {m:+.4} ± {:.4} px over {along_n} observations",
            ((along2 / n - m * m).max(0.0) / n).sqrt()
        );
    }
    let rms = (residuals.iter().map(|e| e * e).sum::<f64>() / residuals.len().max(1) as f64).sqrt();
    residuals.sort_by(f64::total_cmp);
    let median = residuals
        .get(residuals.len() / 2)
        .copied()
        .unwrap_or(f64::NAN);
    let p90 = residuals
        .get(residuals.len() * 9 / 10)
        .copied()
        .unwrap_or(f64::NAN);
    let mut sorted = track_rms.clone();
    sorted.sort_by(f64::total_cmp);
    let q = |f: f64| {
        sorted
            .get((f * sorted.len() as f64) as usize)
            .copied()
            .unwrap_or(f64::NAN)
    };
    eprintln!(
        "track rms quantiles 10/25/50/75/90 %: {:.3} {:.3} {:.3} {:.3} {:.3}",
        q(0.1),
        q(0.25),
        q(0.5),
        q(0.75),
        q(0.9)
    );
    let bad = track_rms.iter().filter(|&&r| r > 1.0).count();
    let ages: Vec<String> = [0usize, 1, 2, 3, 4, 5, 8, 12, 15, 16, 17, 20, 30, 40]
        .iter()
        .filter(|&&a| by_age[a].1 > 0)
        .map(|&a| format!("\"{a}\": {:.4}", by_age[a].0 / by_age[a].1 as f64))
        .collect();
    println!(
        "{{\"features\": {}, \"frames\": {n}, \"seconds\": {seconds:.3}, \"tracks\": {}, \
         \"scored\": {scored}, \"observations\": {}, \"rms_px\": {rms:.4}, \"median_px\": \
         {median:.4}, \"p90_px\": {p90:.4}, \"tracks_over_1px\": {bad}, \"mean_by_age\": {{{}}}}}",
        params.corners.max_corners,
        tracks.tracks.len(),
        residuals.len(),
        ages.join(", ")
    );
    Ok(())
}
