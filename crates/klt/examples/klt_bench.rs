//! Times and runs our KLT (book chapter 6) on one frame pair for `scripts/bench/klt_vs_opencv.py`.
//!
//! ```text
//! cargo run --release -p vfxgraph-klt --example klt_bench -- \
//!     A.png B.png CORNERS.txt FEATURES WINDOW LEVELS ITERATIONS REPEAT [EPSILON]
//! ```
//! CORNERS.txt holds `x y` per line: the points tracked from A to B (so both trackers are
//! scored on the same corners). Prints one JSON object: the best-of-REPEAT times (ms) of
//! corner detection on A (FEATURES corners, quality 0.01, minimum distance 10) and of
//! tracking (pyramid of B + LK of every corner, A's pyramid prebuilt, as in a sequence),
//! and the tracked points (`null` when lost).

use std::time::Instant;

use vfxgraph_imaging::read_image;
use vfxgraph_klt::{
    good_features_to_track, track_points, CornerOptions, GrayImage, LkOptions, Pyramid,
};

fn main() {
    if let Err(e) = run() {
        eprintln!("klt_bench: {e}");
        std::process::exit(1);
    }
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    let a: Vec<String> = std::env::args().skip(1).collect();
    if a.len() != 8 && a.len() != 9 {
        return Err(
            "usage: A.png B.png CORNERS.txt FEATURES WINDOW LEVELS ITERATIONS REPEAT [EPSILON]"
                .into(),
        );
    }
    let ga = GrayImage::from_image(&read_image(a[0].as_ref())?);
    let gb = GrayImage::from_image(&read_image(a[1].as_ref())?);
    let pts: Vec<[f32; 2]> = std::fs::read_to_string(&a[2])?
        .lines()
        .filter_map(|l| {
            let mut it = l.split_whitespace().map(|v| v.parse::<f32>());
            match (it.next(), it.next()) {
                (Some(Ok(x)), Some(Ok(y))) => Some([x, y]),
                _ => None,
            }
        })
        .collect();
    let features: usize = a[3].parse()?;
    let lk = LkOptions {
        window: a[4].parse()?,
        levels: a[5].parse()?,
        max_iterations: a[6].parse()?,
        epsilon: match a.get(8) {
            Some(e) => e.parse()?,
            None => LkOptions::default().epsilon,
        },
        ..LkOptions::default()
    };
    let repeat: usize = a[7].parse()?;
    let cp = CornerOptions {
        max_corners: features,
        quality: 0.01,
        min_distance: 10.0,
        block_size: 3,
    };
    let mut t_corners = f64::INFINITY;
    let mut n_corners = 0;
    for _ in 0..repeat {
        let t = Instant::now();
        let c = good_features_to_track(&ga, &cp, None, &[])?;
        t_corners = t_corners.min(t.elapsed().as_secs_f64());
        n_corners = c.len();
    }
    let pa = Pyramid::new(&ga, lk.levels, lk.pad())?;
    // As in the tracker: the new frame's pyramid reuses the memory of an older one.
    let mut pb = Pyramid::new(&ga, lk.levels, lk.pad())?;
    let mut t_track = f64::INFINITY;
    let mut res = Vec::new();
    for _ in 0..repeat {
        let t = Instant::now();
        pb.rebuild(&gb, lk.levels, lk.pad())?;
        res = track_points(&pa, &pb, &pts, None, &lk)?;
        t_track = t_track.min(t.elapsed().as_secs_f64());
    }
    let mut t_pyr = f64::INFINITY;
    for _ in 0..repeat {
        let t = Instant::now();
        pb.rebuild(&gb, lk.levels, lk.pad())?;
        std::hint::black_box(&pb);
        t_pyr = t_pyr.min(t.elapsed().as_secs_f64());
    }
    let points: Vec<String> = res
        .iter()
        .map(|r| match r.lost {
            None => format!("[{},{}]", r.pos[0], r.pos[1]),
            Some(_) => "null".into(),
        })
        .collect();
    println!(
        "{{\"corners_ms\":{},\"n_corners\":{},\"track_ms\":{},\"pyramid_ms\":{},\"threads\":{},\"points\":[{}]}}",
        t_corners * 1e3,
        n_corners,
        t_track * 1e3,
        t_pyr * 1e3,
        rayon::current_num_threads(),
        points.join(",")
    );
    Ok(())
}
