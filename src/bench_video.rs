//! `vfxgraph bench video FILE`: how fast a clip reads into the graph, against FFmpeg's own
//! decode of it (`ffmpeg -i FILE -f null -`), measured in one run, and the resident memory the
//! read needs. The read is the `read_video` node's: the shared reader (`Backend::Auto`: the
//! bundled H.264 reader, else FFmpeg's executables) asked for frames 0, 1, 2, … in order, each
//! a linear-light RGB float image, dropped once looked at (as a per-frame consumer does): a
//! clip is streamed, never held in memory.

use std::path::Path;
use std::process::Command;
use std::time::Instant;

/// The peak resident memory of this process so far (VmHWM), bytes.
fn peak_resident() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

pub fn run(file: &Path, frames: Option<usize>, json: bool) -> Result<u8, String> {
    let before = peak_resident();
    let cpu_before = crate::bench::cpu_seconds();
    let t = Instant::now();
    let reader = vfxgraph_video::open_shared(file, vfxgraph_video::Backend::Auto)
        .map_err(|e| e.to_string())?;
    let count = frames.map_or(reader.frame_count(), |n| n.min(reader.frame_count()));
    let mut size = (0, 0);
    let mut sum = 0.0f64;
    for f in 0..count {
        let img = reader.frame(f as i64).map_err(|e| e.to_string())?;
        size = (img.width, img.height);
        // One sample a frame, so the frame is used.
        sum += img.data[img.data.len() / 2] as f64;
        if f % 100 == 99 {
            eprintln!(
                "  {} of {count} frames, {:.1} s",
                f + 1,
                t.elapsed().as_secs_f64()
            );
        }
    }
    let ours = t.elapsed().as_secs_f64();
    let cpu = crate::bench::cpu_seconds()
        .zip(cpu_before)
        .map_or(f64::NAN, |(a, b)| a - b);
    let peak = peak_resident();
    let mut ffmpeg = Command::new("ffmpeg");
    ffmpeg.args(["-v", "error", "-nostdin", "-i"]).arg(file);
    if let Some(n) = frames {
        ffmpeg.args(["-frames:v", &n.to_string()]);
    }
    ffmpeg.args(["-f", "null", "-"]);
    let t = Instant::now();
    let status = ffmpeg
        .status()
        .map_err(|e| format!("cannot run ffmpeg: {e}"))?;
    let theirs = t.elapsed().as_secs_f64();
    if !status.success() {
        return Err(format!("ffmpeg could not decode {}", file.display()));
    }
    let mb = |b: Option<u64>| b.map_or(f64::NAN, |b| b as f64 / (1 << 20) as f64);
    if json {
        println!(
            "{}",
            serde_json::json!({
                "file": file.display().to_string(),
                "frames": count,
                "width": size.0,
                "height": size.1,
                "seconds": ours,
                "own_cpu_seconds": cpu,
                "ffmpeg_null_seconds": theirs,
                "ratio": ours / theirs,
                "peak_resident_mib": mb(peak),
                "peak_resident_before_mib": mb(before),
                "checksum": sum,
            })
        );
    } else {
        println!(
            "{}: {count} frames of {}×{}",
            file.display(),
            size.0,
            size.1
        );
        println!(
            "read into the graph  {ours:8.2} s  ({:.1} fps), peak resident {:.0} MiB",
            count as f64 / ours,
            mb(peak)
        );
        println!(
            "  of which this process's CPU time (the conversion; FFmpeg's decode is a child's) \
             {cpu:.2} s"
        );
        println!(
            "ffmpeg -f null       {theirs:8.2} s  ({:.1} fps)",
            count as f64 / theirs
        );
        println!("ratio                {:8.2}×", ours / theirs);
    }
    Ok(0)
}
