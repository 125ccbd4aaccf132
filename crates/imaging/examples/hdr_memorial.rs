//! Calibrates and merges an exposure stack given by a list file (book 10.2–10.4, Debevec & Malik
//! 1997) and reports timings and the exposure-consistency error. Used by
//! `scripts/bench/hdr_vs_opencv.py`.
//!
//! ```text
//! cargo run --release -p vfxgraph-imaging --example hdr_memorial -- LIST OUT_DIR [SAMPLES] [LAMBDA] [RUNS]
//! ```
//!
//! Writes `OUT_DIR/response.csv` (256 rows `R,G,B` of f⁻¹(z) = exp g(z)) and
//! `OUT_DIR/radiance.pfm`, and prints one JSON line on stdout.

use std::path::PathBuf;
use std::time::Instant;

use vfxgraph_imaging::hdr::{
    calibrate_debevec, consistency_error, merge_debevec, read_exposure_list, CalibrateOptions,
};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 2 {
        return Err("usage: hdr_memorial LIST OUT_DIR [SAMPLES] [LAMBDA] [RUNS]".into());
    }
    let list = PathBuf::from(&args[0]);
    let out = PathBuf::from(&args[1]);
    let samples: usize = args.get(2).map_or(Ok(1000), |s| s.parse())?;
    let lambda: f64 = args.get(3).map_or(Ok(10.0), |s| s.parse())?;
    let runs: usize = args.get(4).map_or(Ok(5), |s| s.parse())?;
    std::fs::create_dir_all(&out)?;

    let t = Instant::now();
    let (mut stack, _) = read_exposure_list(&list)?;
    let decode_s = t.elapsed().as_secs_f64();
    let masked = stack.mask_code(&[0, 0, 255])?;

    let opts = CalibrateOptions {
        samples,
        lambda,
        ..Default::default()
    };
    let (mut cal_s, mut merge_s) = (f64::INFINITY, f64::INFINITY);
    let mut curve = None;
    let mut img = None;
    for _ in 0..runs.max(1) {
        let t = Instant::now();
        let c = calibrate_debevec(&stack, &opts)?;
        cal_s = cal_s.min(t.elapsed().as_secs_f64());
        let t = Instant::now();
        let m = merge_debevec(&stack, &c)?;
        merge_s = merge_s.min(t.elapsed().as_secs_f64());
        curve = Some(c);
        img = Some(m);
    }
    let (curve, img) = (curve.expect("one run"), img.expect("one run"));
    let err = consistency_error(&stack, &curve, 32, 223)?.unwrap_or(f64::NAN);

    let mut csv = String::new();
    for z in 0..=255u8 {
        let row: Vec<String> = (0..curve.channels())
            .map(|c| format!("{:.9e}", curve.exposure(c, z)))
            .collect();
        csv.push_str(&row.join(","));
        csv.push('\n');
    }
    vfxgraph_imaging::io::write_atomic(&out.join("response.csv"), csv.as_bytes())?;
    vfxgraph_imaging::write_image(&out.join("radiance.pfm"), &img)?;
    let monotonic = (0..curve.channels()).all(|c| curve.is_monotonic(c, 0, 255));
    // The paper's unconstrained solution, for comparison (not timed).
    let free = calibrate_debevec(
        &stack,
        &CalibrateOptions {
            monotonic: false,
            ..opts
        },
    )?;
    let free_err = consistency_error(&stack, &free, 32, 223)?.unwrap_or(f64::NAN);
    let free_monotonic = (0..free.channels()).all(|c| free.is_monotonic(c, 0, 255));
    println!(
        "{{\"decode_s\": {decode_s:.4}, \"calibrate_s\": {cal_s:.4}, \"merge_s\": {merge_s:.4}, \
         \"consistency\": {err:.5}, \"masked_pixels\": {masked}, \"samples\": {samples}, \
         \"lambda\": {lambda}, \"monotonic\": {monotonic}, \
         \"unconstrained_consistency\": {free_err:.5}, \
         \"unconstrained_monotonic\": {free_monotonic}, \"threads\": {}}}",
        rayon::current_num_threads()
    );
    Ok(())
}
