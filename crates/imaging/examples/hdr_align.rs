//! Aligns an exposure stack given by a list file with Ward's median threshold bitmaps (book
//! 10.x; Ward 2003) and prints the shifts and the time (best of RUNS, after decoding) as one
//! JSON line. Used by `scripts/bench/hdr_align_vs_opencv.py`.
//!
//! ```text
//! cargo run --release -p vfxgraph-imaging --example hdr_align -- LIST [RUNS] [neighbours|reference]
//! ```

use std::path::PathBuf;
use std::time::Instant;

use vfxgraph_imaging::hdr::{align_exposures, read_exposure_list, AlignChain, AlignOptions};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(list) = args.first().map(PathBuf::from) else {
        return Err("usage: hdr_align LIST [RUNS] [neighbours|reference]".into());
    };
    let runs: usize = args.get(1).map_or(Ok(5), |s| s.parse())?;
    let chain = match args.get(2).map(String::as_str) {
        None | Some("neighbours") => AlignChain::Neighbours,
        Some("reference") => AlignChain::Reference,
        Some(other) => return Err(format!("unknown chain `{other}`").into()),
    };
    let t = Instant::now();
    let (stack, _) = read_exposure_list(&list)?;
    let decode_s = t.elapsed().as_secs_f64();
    let opts = AlignOptions {
        chain,
        ..Default::default()
    };
    let mut best = f64::INFINITY;
    let mut shifts = Vec::new();
    for _ in 0..runs.max(1) {
        let t = Instant::now();
        let (_, s) = align_exposures(&stack, &opts)?;
        best = best.min(t.elapsed().as_secs_f64());
        shifts = s;
    }
    let s: Vec<String> = shifts.iter().map(|(x, y)| format!("[{x}, {y}]")).collect();
    println!(
        "{{\"decode_s\": {decode_s:.4}, \"align_s\": {best:.5}, \"shifts\": [{}], \"threads\": {}}}",
        s.join(", "),
        rayon::current_num_threads()
    );
    Ok(())
}
