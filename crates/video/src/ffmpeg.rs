//! Any video through the system's FFmpeg: the `ffprobe` and `ffmpeg` executables, run as child
//! processes, FFmpeg decoding and this crate converting. FFmpeg reads what users bring — H.264
//! of every profile with B-frames, HEVC (Main, Main 10), ProRes, DNxHR, VP9, AV1, MJPEG — in
//! MP4, MOV, MKV, MXF. Reaching it as an executable keeps the default build free of system
//! libraries (docs/design/algorithms.md, *Video*).
//!
//! - **Frames in presentation order**: `ffprobe` lists the stream's packets (no decoding);
//!   their presentation times, sorted, number the frames, so frame `i` is the `i`-th picture
//!   shown, also for variable-frame-rate phone clips ([`FfmpegVideo::times`]).
//! - **Seeking**: frame `i` is decoded by an `ffmpeg` that seeks to the key frame before it
//!   and keeps the pictures from frame `i`'s time on (the stream's own timestamps, `-copyts`,
//!   selected by a quarter frame's margin: what FFmpeg's own accurate seek keeps differs by
//!   container); a reader asked for `i + 1` next reads on from the same process, so a run's
//!   frames stream through one decoder, never held in memory together.
//! - **Samples as coded**: FFmpeg hands over the stream's own planar Y'CbCr (8 to 16 bits,
//!   4:2:0, 4:2:2 or 4:4:4, no scaling or conversion), which [`crate::yuv::Planar`] turns to
//!   linear RGB with the matrix and range the stream declares (BT.601 / 709 / 2020; the size
//!   default when it does not). Other layouts (RGB codecs, grey, palettes) come as 16-bit
//!   R'G'B'. The stream's transfer and primaries are reported ([`Probe`]); the samples are
//!   decoded with the sRGB curve, as the H.264 reader's are.
//! - **Rotation**: a phone clip's display matrix is applied (FFmpeg's autorotate), so a
//!   portrait clip reads portrait.
//! - The executables are `$VFXGRAPH_FFMPEG` (and `ffprobe` beside it) or `ffmpeg` / `ffprobe`
//!   on the `PATH`; without them the error says what to install.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdout, Command, Stdio};
use std::sync::Mutex;

use vfxgraph_imaging::Image;

use crate::sps::{ColorInfo, Matrix};
use crate::yuv::Planar;
use crate::VideoError;

/// What `ffprobe` says of a file's first video stream.
#[derive(Clone, Debug, PartialEq)]
pub struct Probe {
    /// FFmpeg's codec name (`h264`, `hevc`, `prores`, …).
    pub codec: String,
    /// The codec profile (`High`, `Main 10`, …), empty when not given.
    pub profile: String,
    /// The stream's pixel format (`yuv420p10le`, …).
    pub pix_fmt: String,
    /// Coded width and height, before rotation.
    pub coded_size: (usize, usize),
    /// The display rotation: degrees (0, 90, 180, 270) the picture is turned counter-clockwise
    /// for display (the display matrix, as FFmpeg reads it); the frames come turned.
    pub rotation: i32,
    /// The matrix and range the samples are converted with.
    pub color: ColorInfo,
    /// The stream's transfer characteristic as FFmpeg names it (`bt709`, `arib-std-b67` for
    /// HLG, `smpte2084` for PQ), empty when not declared.
    pub transfer: String,
    /// The stream's colour primaries (`bt709`, `bt2020`, …), empty when not declared.
    pub primaries: String,
}

/// How the frames come through the pipe.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Layout {
    /// Planar Y'CbCr: bits a sample, chroma halved across, chroma halved down.
    Yuv {
        bits: u32,
        half_width: bool,
        half_height: bool,
    },
    /// 16-bit R'G'B' interleaved (`rgb48le`).
    Rgb48,
}

impl Layout {
    /// The layout of a stream's `pix_fmt` and the `-pix_fmt` to ask FFmpeg for; full range
    /// for the JPEG (`yuvj…`) formats.
    fn of(pix_fmt: &str) -> (Layout, String, bool) {
        let full = pix_fmt.starts_with("yuvj");
        let rest = pix_fmt
            .strip_prefix("yuvj")
            .or_else(|| pix_fmt.strip_prefix("yuva"))
            .or_else(|| pix_fmt.strip_prefix("yuv"));
        if let Some(rest) = rest {
            let sub = &rest[..rest.len().min(3)];
            let tail = rest.get(4..).unwrap_or("");
            let bits = match tail {
                "" => Some(8),
                "10le" | "10be" => Some(10),
                "12le" | "12be" => Some(12),
                "16le" | "16be" => Some(16),
                _ => None,
            };
            let halves = match sub {
                "420" => Some((true, true)),
                "422" => Some((true, false)),
                "444" => Some((false, false)),
                _ => None,
            };
            if let (Some(bits), Some((hw, hh)), true) = (bits, halves, rest.get(3..4) == Some("p"))
            {
                let fmt = match bits {
                    8 => format!("yuv{sub}p"),
                    b => format!("yuv{sub}p{b}le"),
                };
                let layout = Layout::Yuv {
                    bits,
                    half_width: hw,
                    half_height: hh,
                };
                return (layout, fmt, full);
            }
        }
        (Layout::Rgb48, "rgb48le".into(), true)
    }

    /// Bytes of one `width` × `height` frame, or `None` past the image limit.
    fn frame_bytes(self, width: usize, height: usize) -> Option<usize> {
        Image::try_new(width, height, 3).ok()?;
        match self {
            Layout::Yuv {
                bits,
                half_width,
                half_height,
            } => {
                let (cw, ch) = Planar::chroma_size(width, height, half_width, half_height);
                let per = if bits > 8 { 2 } else { 1 };
                Some(per * (width * height + 2 * cw * ch))
            }
            Layout::Rgb48 => Some(6 * width * height),
        }
    }
}

/// A video opened through FFmpeg (module docs).
pub struct FfmpegVideo {
    path: PathBuf,
    ffmpeg: PathBuf,
    probe: Probe,
    layout: Layout,
    out_fmt: String,
    /// Width and height of the frames delivered (after rotation).
    size: (usize, usize),
    /// Presentation times of the frames, seconds from the file's start, ascending.
    times: Vec<f64>,
    /// The file's start time (the stream's timestamps are `times` + `start`).
    start: f64,
    /// The decoder reading on, and the frame it delivers next.
    cursor: Mutex<Option<(usize, Decoder)>>,
    /// Raw frame buffers done with, kept for the next reads (a 4K frame is 25 MB: a fresh
    /// buffer a frame is that much memory mapped, faulted in and unmapped again).
    spare: Mutex<Vec<Vec<u8>>>,
}

/// A running `ffmpeg` writing raw frames to its standard output.
struct Decoder {
    child: Child,
    out: ChildStdout,
}

impl Drop for Decoder {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// The `ffmpeg` and `ffprobe` executables (module docs).
fn executables() -> (PathBuf, PathBuf) {
    match std::env::var_os("VFXGRAPH_FFMPEG") {
        Some(f) if !f.is_empty() => {
            let ffmpeg = PathBuf::from(f);
            let probe = ffmpeg.with_file_name(match ffmpeg.extension() {
                Some(e) => format!("ffprobe.{}", e.to_string_lossy()),
                None => "ffprobe".into(),
            });
            (ffmpeg, probe)
        }
        _ => ("ffmpeg".into(), "ffprobe".into()),
    }
}

/// Whether FFmpeg's executables run here.
pub fn available() -> bool {
    let (ffmpeg, probe) = executables();
    [ffmpeg, probe].iter().all(|exe| {
        Command::new(exe)
            .arg("-version")
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
            .is_ok_and(|s| s.success())
    })
}

/// The error of a file FFmpeg is needed for and is not here.
pub fn missing(path: &Path, what: &str) -> VideoError {
    VideoError::Unsupported {
        path: path.to_path_buf(),
        message: format!(
            "{what}: this needs FFmpeg, which was not found (install it: `apt-get install \
             ffmpeg`, `brew install ffmpeg`, or https://ffmpeg.org/download.html; or set \
             VFXGRAPH_FFMPEG to the ffmpeg executable, ffprobe beside it)"
        ),
    }
}

/// Runs `ffprobe` with `args` on `path`; its standard output.
fn ffprobe(probe: &Path, path: &Path, args: &[&str]) -> Result<String, VideoError> {
    let out = Command::new(probe)
        .args(["-v", "error"])
        .args(args)
        .arg(path)
        .stdin(Stdio::null())
        .output()
        .map_err(|_| missing(path, "reading this file"))?;
    if !out.status.success() {
        let msg = String::from_utf8_lossy(&out.stderr);
        return Err(VideoError::Container {
            path: path.to_path_buf(),
            message: format!("ffprobe cannot read it: {}", msg.trim()),
        });
    }
    Ok(String::from_utf8_lossy(&out.stdout).into_owned())
}

impl FfmpegVideo {
    /// Opens `path`: its first video stream probed and its frames' times listed.
    pub fn open(path: &Path) -> Result<FfmpegVideo, VideoError> {
        std::fs::metadata(path).map_err(|source| VideoError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let (ffmpeg, probe_exe) = executables();
        let json = ffprobe(
            &probe_exe,
            path,
            &[
                "-select_streams",
                "v:0",
                "-show_entries",
                "stream=codec_name,profile,width,height,pix_fmt,color_range,color_space,\
                 color_transfer,color_primaries:stream_side_data=rotation:format=start_time",
                "-of",
                "json",
            ],
        )?;
        let container = |message: String| VideoError::Container {
            path: path.to_path_buf(),
            message,
        };
        let v: serde_json::Value =
            serde_json::from_str(&json).map_err(|e| container(format!("ffprobe's answer: {e}")))?;
        let stream = v["streams"]
            .get(0)
            .ok_or_else(|| container("no video stream".into()))?;
        let text = |k: &str| stream[k].as_str().unwrap_or("").to_string();
        let dim = |k: &str| stream[k].as_u64().unwrap_or(0) as usize;
        let (w, h) = (dim("width"), dim("height"));
        let pix_fmt = text("pix_fmt");
        if w == 0 || h == 0 || pix_fmt.is_empty() {
            return Err(VideoError::Unsupported {
                path: path.to_path_buf(),
                message: format!(
                    "codec {}: FFmpeg gives no picture size or pixel format (a codec this \
                     FFmpeg cannot decode?)",
                    text("codec_name")
                ),
            });
        }
        let rotation = stream["side_data_list"]
            .as_array()
            .into_iter()
            .flatten()
            .find_map(|d| d["rotation"].as_f64())
            .map(|r| (r.round() as i32).rem_euclid(360))
            .unwrap_or(0);
        let (layout, out_fmt, jpeg_range) = Layout::of(&pix_fmt);
        let matrix = match text("color_space").as_str() {
            "bt709" => Some(Matrix::Bt709),
            "bt470bg" | "smpte170m" | "bt601" => Some(Matrix::Bt601),
            "bt2020nc" | "bt2020c" => Some(Matrix::Bt2020),
            _ => None,
        };
        let color = ColorInfo {
            matrix: matrix.unwrap_or(if h >= 720 {
                Matrix::Bt709
            } else {
                Matrix::Bt601
            }),
            full_range: text("color_range") == "pc" || (jpeg_range && text("color_range") != "tv"),
            matrix_from_stream: matrix.is_some(),
        };
        let probe = Probe {
            codec: text("codec_name"),
            profile: text("profile"),
            pix_fmt,
            coded_size: (w, h),
            rotation,
            color,
            transfer: text("color_transfer"),
            primaries: text("color_primaries"),
        };
        let size = if rotation % 180 == 90 { (h, w) } else { (w, h) };
        if layout.frame_bytes(size.0, size.1).is_none() {
            return Err(VideoError::Unsupported {
                path: path.to_path_buf(),
                message: format!("a {w}×{h} picture is larger than an image can be"),
            });
        }
        let start = v["format"]["start_time"]
            .as_str()
            .and_then(|s| s.parse::<f64>().ok())
            .unwrap_or(0.0);
        let packets = ffprobe(
            &probe_exe,
            path,
            &[
                "-select_streams",
                "v:0",
                "-show_entries",
                "packet=pts_time",
                "-of",
                "csv=p=0",
            ],
        )?;
        let mut times: Vec<f64> = packets
            .lines()
            .filter_map(|l| l.trim().trim_end_matches(',').parse::<f64>().ok())
            .filter(|t| t.is_finite())
            .map(|t| t - start)
            .collect();
        times.sort_by(f64::total_cmp);
        times.dedup();
        if times.is_empty() {
            return Err(container("the video stream has no timed pictures".into()));
        }
        Ok(FfmpegVideo {
            path: path.to_path_buf(),
            ffmpeg,
            probe,
            layout,
            out_fmt,
            size,
            times,
            start,
            cursor: Mutex::new(None),
            spare: Mutex::new(Vec::new()),
        })
    }

    /// What `ffprobe` said of the stream.
    pub fn probe(&self) -> &Probe {
        &self.probe
    }

    /// Number of frames.
    pub fn frame_count(&self) -> usize {
        self.times.len()
    }

    /// Width and height of the frames, rotation applied.
    pub fn size(&self) -> (usize, usize) {
        self.size
    }

    /// Presentation time of every frame, seconds from the start, ascending.
    pub fn times(&self) -> &[f64] {
        &self.times
    }

    /// A decoder delivering frames from `i` on.
    fn start(&self, i: usize) -> Result<Decoder, VideoError> {
        let mut cmd = Command::new(&self.ffmpeg);
        cmd.args(["-v", "error", "-nostdin"]);
        if i > 0 {
            // Seek to the key frame at or before half-way from the frame before, keep the
            // pictures from a quarter of that gap before frame i on, by their own timestamps.
            let gap = self.times[i] - self.times[i - 1];
            let seek = self.times[i] - 0.5 * gap;
            let keep = self.start + self.times[i] - 0.25 * gap;
            cmd.args(["-noaccurate_seek", "-ss", &format!("{seek:.6}"), "-copyts"])
                .arg("-i")
                .arg(&self.path)
                .args(["-vf", &format!("select=gte(t\\,{keep:.9})")]);
        } else {
            cmd.arg("-i").arg(&self.path);
        }
        cmd.args([
            "-map",
            "0:v:0",
            "-an",
            "-sn",
            "-dn",
            "-fps_mode",
            "passthrough",
        ])
        .args(["-f", "rawvideo", "-pix_fmt", &self.out_fmt, "-"])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::null());
        let mut child = cmd.spawn().map_err(|_| missing(&self.path, "decoding"))?;
        let out = child.stdout.take().expect("piped");
        Ok(Decoder { child, out })
    }

    /// Frame `frame` (0 = the first picture shown), linear-light RGB.
    pub fn frame(&self, frame: i64) -> Result<Image, VideoError> {
        let count = self.times.len();
        let i = usize::try_from(frame)
            .ok()
            .filter(|&i| i < count)
            .ok_or_else(|| VideoError::FrameOutOfRange {
                path: self.path.clone(),
                frame,
                count,
            })?;
        let (w, h) = self.size;
        let bytes = self.layout.frame_bytes(w, h).expect("checked at open");
        let mut cursor = self.cursor.lock().unwrap_or_else(|p| p.into_inner());
        let mut dec = match cursor.take() {
            Some((next, d)) if next == i => d,
            _ => self.start(i)?,
        };
        let spare = self.spare.lock().unwrap_or_else(|p| p.into_inner()).pop();
        let mut buf = spare.unwrap_or_default();
        buf.resize(bytes, 0);
        if let Err(e) = dec.out.read_exact(&mut buf) {
            return Err(VideoError::Decode {
                path: self.path.clone(),
                frame: i,
                message: format!("ffmpeg delivered no picture ({e})"),
            });
        }
        *cursor = Some((i + 1, dec));
        drop(cursor);
        // Converted with the decoder free: another thread reads the next frame meanwhile.
        let img = self.convert(&buf);
        let mut spare = self.spare.lock().unwrap_or_else(|p| p.into_inner());
        if spare.len() < 2 {
            spare.push(buf);
        }
        Ok(img)
    }

    /// One raw frame as delivered, to linear RGB.
    fn convert(&self, buf: &[u8]) -> Image {
        let (w, h) = self.size;
        match self.layout {
            Layout::Yuv {
                bits,
                half_width,
                half_height,
            } => {
                let (cw, ch) = Planar::chroma_size(w, h, half_width, half_height);
                let (y, rest) = buf.split_at(Planar::plane_bytes(w * h, bits));
                let (u, v) = rest.split_at(Planar::plane_bytes(cw * ch, bits));
                Planar {
                    width: w,
                    height: h,
                    bits,
                    half_width,
                    half_height,
                    y,
                    u,
                    v,
                }
                .to_image(&self.probe.color)
            }
            Layout::Rgb48 => {
                let data = buf
                    .chunks_exact(2)
                    .map(|b| {
                        let v = u16::from_le_bytes([b[0], b[1]]) as f32 / 65535.0;
                        vfxgraph_imaging::color::srgb_to_linear(v)
                    })
                    .collect();
                Image {
                    width: w,
                    height: h,
                    channels: 3,
                    data,
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pixel_formats_map_to_layouts() {
        let yuv = |bits, half_width, half_height| Layout::Yuv {
            bits,
            half_width,
            half_height,
        };
        for (fmt, layout, out, full) in [
            ("yuv420p", yuv(8, true, true), "yuv420p", false),
            ("yuvj420p", yuv(8, true, true), "yuv420p", true),
            ("yuv420p10le", yuv(10, true, true), "yuv420p10le", false),
            ("yuv422p10le", yuv(10, true, false), "yuv422p10le", false),
            ("yuva444p12le", yuv(12, false, false), "yuv444p12le", false),
            ("yuv444p16be", yuv(16, false, false), "yuv444p16le", false),
            ("gbrp10le", Layout::Rgb48, "rgb48le", true),
            ("rgb24", Layout::Rgb48, "rgb48le", true),
            ("yuv410p", Layout::Rgb48, "rgb48le", true),
            ("nv12", Layout::Rgb48, "rgb48le", true),
        ] {
            let (l, o, f) = Layout::of(fmt);
            assert_eq!((l, o.as_str()), (layout, out), "{fmt}");
            if matches!(l, Layout::Yuv { .. }) {
                assert_eq!(f, full, "{fmt}");
            }
        }
        assert_eq!(yuv(10, true, true).frame_bytes(4, 2), Some(2 * (8 + 2 * 2)));
        assert_eq!(yuv(8, false, false).frame_bytes(3, 3), Some(27));
        assert_eq!(Layout::Rgb48.frame_bytes(1 << 20, 1 << 20), None);
    }
}
