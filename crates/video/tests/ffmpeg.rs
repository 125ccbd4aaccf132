//! The FFmpeg reader on clips FFmpeg encodes from frames of ours: H.264 High with B-frames,
//! HEVC Main 10, ProRes 422 HQ, DNxHR HQ, VP9, MJPEG, a variable-frame-rate clip and a
//! portrait phone clip (rotation metadata). Each frame read (in order, backwards and at random)
//! is the source frame it should be — nearer to it than to its neighbours, and within the
//! codec's error — and the stream's facts (codec, bits, matrix, range) are reported.
//! FFmpeg is installed by CI; elsewhere its absence is a notice, under `CI=true` a failure.

use std::path::{Path, PathBuf};
use std::process::Command;

use vfxgraph_imaging::{write_image, Image};
use vfxgraph_video::ffmpeg::{available, FfmpegVideo};
use vfxgraph_video::{open_shared, Backend, Reader};

/// A textured frame that moves 3 px a frame sideways, with a bright bar whose height
/// encodes `k`: every frame unlike its neighbours (linear light).
fn frame(w: usize, h: usize, k: usize) -> Image {
    Image::from_fn(w, h, 3, |x, y, c| {
        let (xf, yf) = (x as f32 - 3.0 * k as f32, y as f32);
        let mut v = 0.4
            + 0.2 * (0.19 * xf + 0.6 * (0.11 * yf).sin()).sin()
            + 0.15 * (0.23 * yf + 0.5 * (0.09 * xf).cos()).cos();
        if x < 8 && y < 4 + 6 * k {
            v = 0.95;
        }
        let tint = [1.0, 0.9, 0.75][c];
        vfxgraph_imaging::color::srgb_to_linear((v * tint).clamp(0.0, 1.0))
    })
}

fn have_ffmpeg() -> bool {
    vfxgraph_testdata::tool(available(), "FFmpeg (ffmpeg, ffprobe)")
}

/// Writes `n` source frames as PNGs and encodes them with `args`; the clip's path.
fn encode(dir: &Path, name: &str, size: (usize, usize), n: usize, args: &[&str]) -> PathBuf {
    let src = dir.join(format!("{name}-src"));
    std::fs::create_dir_all(&src).unwrap();
    for k in 0..n {
        write_image(&src.join(format!("f{k:03}.png")), &frame(size.0, size.1, k)).unwrap();
    }
    let out = dir.join(name);
    let status = Command::new("ffmpeg")
        .args(["-v", "error", "-y", "-framerate", "24", "-i"])
        .arg(src.join("f%03d.png"))
        .args(args)
        .arg(&out)
        .status()
        .unwrap();
    assert!(status.success(), "ffmpeg could not encode {name}");
    out
}

fn mean_abs(a: &Image, b: &Image) -> f32 {
    assert_eq!((a.width, a.height), (b.width, b.height));
    a.data
        .iter()
        .zip(&b.data)
        .map(|(x, y)| (x - y).abs())
        .sum::<f32>()
        / a.data.len() as f32
}

/// Every frame of `video` read in `order` is source frame k: within `tolerance` (mean
/// absolute difference, linear) and nearer to it than to frames k ± 1.
fn frames_are_the_sources(
    name: &str,
    video: &FfmpegVideo,
    size: (usize, usize),
    order: &[usize],
    tolerance: f32,
) {
    for &k in order {
        let got = video.frame(k as i64).unwrap();
        let own = mean_abs(&got, &frame(size.0, size.1, k));
        assert!(own < tolerance, "{name}: frame {k}: {own}");
        for j in [k.wrapping_sub(1), k + 1] {
            if j < video.frame_count() {
                let other = mean_abs(&got, &frame(size.0, size.1, j));
                assert!(
                    own * 3.0 < other,
                    "{name}: frame {k} is nearer frame {j}: {own} vs {other}"
                );
            }
        }
    }
}

/// A clip to encode and what reading it must show: file name, encoder arguments, codec, pixel
/// format, full range, tolerance (mean absolute difference, linear).
type Case = (
    &'static str,
    &'static [&'static str],
    &'static str,
    &'static str,
    bool,
    f32,
);

#[test]
fn every_common_codec_reads_frame_by_frame() {
    if !have_ffmpeg() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let size = (256, 144); // DNxHR's smallest is 256×120
    let n = 12;
    let order: Vec<usize> = (0..n)
        .chain((0..n).rev())
        .chain([5, 2, 9, 9, 0, 11])
        .collect();
    // (file, encoder arguments, codec, pixel format, full range, tolerance)
    let cases: [Case; 7] = [
        (
            "h264-bframes.mp4",
            &[
                "-c:v",
                "libx264",
                "-profile:v",
                "high",
                "-bf",
                "3",
                "-g",
                "6",
                "-crf",
                "12",
                "-pix_fmt",
                "yuv420p",
                "-colorspace",
                "bt709",
                "-color_range",
                "tv",
            ],
            "h264",
            "yuv420p",
            false,
            0.012,
        ),
        (
            "hevc-main10.mp4",
            &[
                "-c:v",
                "libx265",
                "-x265-params",
                "log-level=error:bframes=4:keyint=8",
                "-crf",
                "12",
                "-pix_fmt",
                "yuv420p10le",
                "-tag:v",
                "hvc1",
            ],
            "hevc",
            "yuv420p10le",
            false,
            0.012,
        ),
        (
            "prores-hq.mov",
            &[
                "-c:v",
                "prores_ks",
                "-profile:v",
                "3",
                "-pix_fmt",
                "yuv422p10le",
            ],
            "prores",
            "yuv422p10le",
            false,
            0.006,
        ),
        (
            "dnxhr-hq.mxf",
            &[
                "-c:v",
                "dnxhd",
                "-profile:v",
                "dnxhr_hq",
                "-pix_fmt",
                "yuv422p",
            ],
            "dnxhd",
            "yuv422p",
            false,
            0.01,
        ),
        (
            "vp9.webm",
            &[
                "-c:v",
                "libvpx-vp9",
                "-crf",
                "15",
                "-b:v",
                "0",
                "-g",
                "5",
                "-deadline",
                "realtime",
                "-pix_fmt",
                "yuv420p",
            ],
            "vp9",
            "yuv420p",
            false,
            0.015,
        ),
        (
            "mjpeg.avi",
            &["-c:v", "mjpeg", "-q:v", "2", "-pix_fmt", "yuvj420p"],
            "mjpeg",
            "yuvj420p",
            true,
            0.015,
        ),
        // R'G'B' as coded (PNG frames in a QuickTime movie): 16-bit RGB through the pipe.
        // Within the 8-bit sRGB quantisation of the PNG frames (measured 0.0012).
        ("png.mov", &["-c:v", "png"], "png", "rgb24", true, 0.0025),
    ];
    for (name, args, codec, pix_fmt, full, tolerance) in cases {
        let clip = encode(dir.path(), name, size, n, args);
        let video = FfmpegVideo::open(&clip).unwrap();
        let p = video.probe();
        assert_eq!(
            (p.codec.as_str(), p.pix_fmt.as_str()),
            (codec, pix_fmt),
            "{name}"
        );
        assert_eq!(p.color.full_range, full, "{name}");
        assert_eq!(video.frame_count(), n, "{name}");
        assert_eq!(video.size(), size, "{name}");
        frames_are_the_sources(name, &video, size, &order, tolerance);
        assert!(video.frame(n as i64).is_err() && video.frame(-1).is_err());
    }
    // The default reader opens B-frames through FFmpeg, with no word of the bundled one's limit.
    let clip = dir.path().join("h264-bframes.mp4");
    let reader = open_shared(&clip, Backend::Auto).unwrap();
    assert!(matches!(*reader, Reader::Ffmpeg(_)));
    let native = Reader::open(&clip, Backend::Native)
        .err()
        .unwrap()
        .to_string();
    assert!(native.contains("B-frames"), "{native}");
}

/// A variable-frame-rate clip (frames shown 0.04, 0.08, 0.04 … s apart) numbers its pictures
/// in presentation order with their times; a portrait phone clip (coded landscape, rotated 90°
/// by its display matrix) reads portrait.
#[test]
fn variable_frame_rate_and_rotation() {
    if !have_ffmpeg() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let size = (96, 64);
    let n = 8;
    let src = dir.path().join("vfr-src");
    std::fs::create_dir_all(&src).unwrap();
    let mut list = String::new();
    for k in 0..n {
        let f = src.join(format!("f{k:03}.png"));
        write_image(&f, &frame(size.0, size.1, k)).unwrap();
        let d = if k % 2 == 1 { 0.08 } else { 0.04 };
        list.push_str(&format!("file '{}'\nduration {d}\n", f.display()));
    }
    std::fs::write(dir.path().join("list.txt"), list).unwrap();
    let clip = dir.path().join("vfr.mp4");
    let ok = Command::new("ffmpeg")
        .args(["-v", "error", "-y", "-f", "concat", "-safe", "0", "-i"])
        .arg(dir.path().join("list.txt"))
        .args([
            "-fps_mode",
            "vfr",
            "-c:v",
            "libx264",
            "-bf",
            "2",
            "-crf",
            "12",
        ])
        .args(["-pix_fmt", "yuv420p", "-video_track_timescale", "2400"])
        .arg(&clip)
        .status()
        .unwrap();
    assert!(ok.success());
    let video = FfmpegVideo::open(&clip).unwrap();
    assert_eq!(video.frame_count(), n);
    let gaps: Vec<f64> = video.times().windows(2).map(|w| w[1] - w[0]).collect();
    for (k, g) in gaps.iter().enumerate() {
        let want = if k % 2 == 1 { 0.08 } else { 0.04 };
        assert!((g - want).abs() < 1e-3, "gap {k}: {g}");
    }
    frames_are_the_sources("vfr.mp4", &video, size, &[7, 3, 4, 5, 0, 1, 6], 0.012);

    // Portrait: a landscape coding with a display matrix (the `rotate` tag phones write).
    let landscape = encode(
        dir.path(),
        "coded.mp4",
        size,
        4,
        &["-c:v", "libx264", "-crf", "12", "-pix_fmt", "yuv420p"],
    );
    let portrait = dir.path().join("portrait.mp4");
    let ok = Command::new("ffmpeg")
        .args(["-v", "error", "-y", "-i"])
        .arg(&landscape)
        .args(["-c", "copy", "-metadata:s:v:0", "rotate=90"])
        .arg(&portrait)
        .status()
        .unwrap();
    assert!(ok.success());
    let video = FfmpegVideo::open(&portrait).unwrap();
    let rotation = video.probe().rotation;
    assert_eq!(rotation % 180, 90);
    assert_eq!(video.size(), (size.1, size.0));
    let got = video.frame(2).unwrap();
    // The display matrix turns the picture `rotation` degrees counter-clockwise (FFmpeg's
    // av_display_rotation_get): at 90°, pixel (x, y) shown is the source's (w − 1 − y, x).
    let src = frame(size.0, size.1, 2);
    let ccw = Image::from_fn(size.1, size.0, 3, |x, y, c| src.get(size.0 - 1 - y, x, c));
    let cw = Image::from_fn(size.1, size.0, 3, |x, y, c| src.get(y, size.1 - 1 - x, c));
    let (right, wrong) = if rotation == 90 {
        (&ccw, &cw)
    } else {
        (&cw, &ccw)
    };
    let (right, wrong) = (mean_abs(&got, right), mean_abs(&got, wrong));
    assert!(
        right < 0.012 && wrong > 3.0 * right,
        "turned as said {right}, the other way {wrong}"
    );
}

/// A file FFmpeg cannot read is one clear error naming it.
#[test]
fn a_file_that_is_not_a_video_is_a_clear_error() {
    if !have_ffmpeg() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("notes.mov");
    std::fs::write(&bad, b"this is not a video at all").unwrap();
    let e = FfmpegVideo::open(&bad).err().unwrap().to_string();
    assert!(e.contains("notes.mov") && e.contains("ffprobe"), "{e}");
    let e = Reader::open(&bad, Backend::Auto).err().unwrap().to_string();
    assert!(e.contains("notes.mov"), "{e}");
}

/// The camera metadata a phone writes (the 35 mm equivalent focal length, make, model, lens),
/// written by FFmpeg as QuickTime metadata items, read back with the picture's size as shown:
/// a landscape clip and the same clip turned to portrait by its display matrix. FFprobe reads
/// the same values from the same files.
#[test]
fn quicktime_camera_metadata_and_the_size_as_shown() {
    if !have_ffmpeg() {
        return;
    }
    use vfxgraph_video::metadata::{camera_metadata, KEY_FOCAL_35MM};
    let dir = tempfile::tempdir().unwrap();
    let size = (96, 64);
    let coded = encode(
        dir.path(),
        "coded.mp4",
        size,
        3,
        &["-c:v", "libx264", "-crf", "20", "-pix_fmt", "yuv420p"],
    );
    let tag = |k: &str, v: &str| format!("com.apple.quicktime.{k}={v}");
    for (name, rotate, shown) in [
        ("phone.mov", "0", (96, 64)),
        ("portrait.mov", "90", (64, 96)),
    ] {
        let clip = dir.path().join(name);
        let ok = Command::new("ffmpeg")
            .args(["-v", "error", "-y", "-i"])
            .arg(&coded)
            .args(["-c", "copy", "-movflags", "use_metadata_tags"])
            .args(["-metadata", &format!("{KEY_FOCAL_35MM}=26")])
            .args(["-metadata", &tag("make", "Apple")])
            .args(["-metadata", &tag("model", "iPhone 12")])
            .args([
                "-metadata",
                &tag("camera.lens_model", "iPhone 12 back camera 4.2mm f/1.6"),
            ])
            .args(["-metadata:s:v:0", &format!("rotate={rotate}")])
            .arg(&clip)
            .status()
            .unwrap();
        assert!(ok.success());
        let m = camera_metadata(&clip).unwrap();
        assert_eq!(m.focal_35mm, Some(26.0), "{name}");
        assert_eq!(m.make.as_deref(), Some("Apple"));
        assert_eq!(m.model.as_deref(), Some("iPhone 12"));
        assert_eq!(
            m.lens_model.as_deref(),
            Some("iPhone 12 back camera 4.2mm f/1.6")
        );
        assert_eq!(m.display_size, Some(shown), "{name}");
        // The picture FFmpeg shows has that size.
        let (w, h) = FfmpegVideo::open(&clip).unwrap().size();
        assert_eq!((w as u32, h as u32), shown, "{name}");
        let probe = Command::new("ffprobe")
            .args(["-v", "error", "-show_entries", "format_tags", "-of", "json"])
            .arg(&clip)
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&probe.stdout);
        assert!(
            text.contains(&format!("\"{KEY_FOCAL_35MM}\": \"26\"")),
            "{text}"
        );
    }
    // A clip without them: none, and no error.
    let m = camera_metadata(&coded).unwrap();
    assert_eq!((m.focal_35mm, m.model), (None, None));
    assert_eq!(m.display_size, Some((size.0 as u32, size.1 as u32)));
    // Not a QuickTime file: an error naming it.
    let png = dir.path().join("coded.mp4-src/f000.png");
    let e = camera_metadata(&png).unwrap_err();
    assert!(e.contains("f000.png"), "{e}");
}
