//! Any video OpenCV can open, through its `VideoCapture` (FFmpeg backend): every container and
//! codec FFmpeg decodes (H.265, VP9, AV1, ProRes, MPEG-4, MJPEG, B-frame H.264, …), for the
//! footage the book's chapter 6 tracks. Only with the `opencv` cargo feature (system OpenCV:
//! `libopencv-dev`, and `clang libclang-dev` to generate the bindings).
//!
//! [`Capture`] gives the same frames as the native reader ([`crate::Video`]): frame `i` is the
//! `i`-th picture in presentation order, as a linear-light RGB [`Image`] — OpenCV's 8-bit
//! B'G'R' reordered to RGB and decoded with the sRGB curve, as PNG frames and the native
//! reader's are. The Y'CbCr → R'G'B' conversion is OpenCV's (FFmpeg's swscale): it does not
//! read the stream's colour description and converts with BT.601, so a BT.709 stream (HD
//! footage) comes out with slightly shifted saturated colours where the native reader uses
//! the declared matrix; luminance (what tracking uses) agrees either way.
//!
//! Frames are decoded in order: [`Capture::frame`] continues a decoder already positioned
//! before the frame asked for (a small pool of them serves parallel per-frame readers), else
//! opens the file anew and skips forward. No seeking: OpenCV's frame seeks can land near, not
//! on, the frame asked for, and the frame index must be exact.

use std::path::{Path, PathBuf};
use std::sync::Mutex;

use opencv::core::{Mat, MatTraitConst, MatTraitConstManual, CV_8UC1, CV_8UC3};
use opencv::prelude::{VideoCaptureTrait, VideoCaptureTraitConst};
use opencv::videoio::{VideoCapture, CAP_FFMPEG, CAP_PROP_FPS, CAP_PROP_FRAME_COUNT};
use vfxgraph_imaging::color::srgb_to_linear;
use vfxgraph_imaging::Image;

use crate::VideoError;

/// Decoders kept open at once (each positioned somewhere in the file).
const POOL: usize = 4;

/// A video opened with OpenCV's `VideoCapture` (FFmpeg backend).
pub struct Capture {
    path: PathBuf,
    count: usize,
    width: usize,
    height: usize,
    fps: f64,
    /// Open decoders and the index of the next frame each will return.
    pool: Mutex<Vec<(usize, VideoCapture)>>,
}

fn decode_err(path: &Path, frame: usize, e: impl std::fmt::Display) -> VideoError {
    VideoError::Decode {
        path: path.to_path_buf(),
        frame,
        message: e.to_string(),
    }
}

/// OpenCV prints its own warnings on stderr for files it cannot open; the errors returned
/// here say it instead.
fn quiet() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let _ = opencv::core::set_log_level(opencv::core::LogLevel::LOG_LEVEL_ERROR);
    });
}

fn open_capture(path: &Path) -> Result<VideoCapture, VideoError> {
    quiet();
    let cap = VideoCapture::from_file(path.as_os_str(), CAP_FFMPEG).map_err(|e| {
        VideoError::Container {
            path: path.to_path_buf(),
            message: format!("OpenCV: {e}"),
        }
    })?;
    if !cap.is_opened().unwrap_or(false) {
        return Err(VideoError::Container {
            path: path.to_path_buf(),
            message: "OpenCV's VideoCapture (FFmpeg) cannot open it as a video".into(),
        });
    }
    Ok(cap)
}

/// sRGB code value (0–255) → linear light.
fn lut() -> &'static [f32; 256] {
    static LUT: std::sync::OnceLock<[f32; 256]> = std::sync::OnceLock::new();
    LUT.get_or_init(|| std::array::from_fn(|i| srgb_to_linear(i as f32 / 255.0)))
}

/// An 8-bit BGR (or gray) OpenCV picture as a linear-light RGB image.
fn to_image(path: &Path, frame: usize, m: &Mat) -> Result<Image, VideoError> {
    let (w, h) = (m.cols().max(0) as usize, m.rows().max(0) as usize);
    let typ = m.typ();
    if w == 0 || h == 0 {
        return Err(decode_err(path, frame, "OpenCV returned an empty picture"));
    }
    let channels = match typ {
        t if t == CV_8UC3 => 3,
        t if t == CV_8UC1 => 1,
        t => {
            return Err(VideoError::Unsupported {
                path: path.to_path_buf(),
                message: format!("OpenCV picture type {t} (8-bit BGR or gray expected)"),
            })
        }
    };
    let owned;
    let m = if m.is_continuous() {
        m
    } else {
        owned = m.try_clone().map_err(|e| decode_err(path, frame, e))?;
        &owned
    };
    let bytes = m.data_bytes().map_err(|e| decode_err(path, frame, e))?;
    if bytes.len() != w * h * channels {
        return Err(decode_err(path, frame, "OpenCV picture of unexpected size"));
    }
    let lut = lut();
    let mut data = vec![0.0f32; w * h * 3];
    for (o, px) in data.chunks_exact_mut(3).zip(bytes.chunks_exact(channels)) {
        if channels == 3 {
            o[0] = lut[px[2] as usize];
            o[1] = lut[px[1] as usize];
            o[2] = lut[px[0] as usize];
        } else {
            o.fill(lut[px[0] as usize]);
        }
    }
    Ok(Image {
        width: w,
        height: h,
        channels: 3,
        data,
    })
}

impl Capture {
    /// Opens a video file with OpenCV and decodes its first frame (a file OpenCV cannot
    /// decode is an error here, not at the first frame asked for).
    pub fn open(path: &Path) -> Result<Capture, VideoError> {
        // OpenCV says no more than "cannot open" for a missing file: say why first.
        std::fs::File::open(path).map_err(|source| VideoError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let mut cap = open_capture(path)?;
        let prop = |id| cap.get(id).unwrap_or(0.0);
        let (reported, fps) = (prop(CAP_PROP_FRAME_COUNT), prop(CAP_PROP_FPS));
        let mut first = Mat::default();
        if !cap.read(&mut first).map_err(|e| decode_err(path, 0, e))? || first.empty() {
            return Err(VideoError::Container {
                path: path.to_path_buf(),
                message: "OpenCV opened it but decodes no frame".into(),
            });
        }
        let first = to_image(path, 0, &first)?;
        let mut c = Capture {
            path: path.to_path_buf(),
            count: 0,
            width: first.width,
            height: first.height,
            fps: if fps.is_finite() && fps > 0.0 {
                fps
            } else {
                0.0
            },
            pool: Mutex::new(Vec::new()),
        };
        c.count = if reported.is_finite() && reported >= 1.0 {
            reported.round() as usize
        } else {
            // No count in the container: count by decoding (one pass).
            let mut n = 1;
            while cap.grab().map_err(|e| decode_err(path, n, e))? {
                n += 1;
            }
            n
        };
        if c.count > 1 {
            c.give_back(1, cap);
        }
        Ok(c)
    }

    /// Number of frames (as the container reports it; counted by decoding when it does not).
    pub fn frame_count(&self) -> usize {
        self.count
    }

    /// Width and height of the decoded pictures (of the first frame).
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// Frames per second as OpenCV reports it (0 when unknown).
    pub fn fps(&self) -> f64 {
        self.fps
    }

    fn check_frame(&self, frame: i64) -> Result<usize, VideoError> {
        if frame < 0 || frame as usize >= self.count {
            return Err(VideoError::FrameOutOfRange {
                path: self.path.clone(),
                frame,
                count: self.count,
            });
        }
        Ok(frame as usize)
    }

    /// A pooled decoder positioned at or before `frame` (the closest), or a new one.
    fn take(&self, frame: usize) -> Result<(usize, VideoCapture), VideoError> {
        {
            let mut pool = self.pool.lock().unwrap_or_else(|p| p.into_inner());
            let best = (0..pool.len())
                .filter(|&k| pool[k].0 <= frame)
                .max_by_key(|&k| pool[k].0);
            if let Some(k) = best {
                return Ok(pool.swap_remove(k));
            }
        }
        Ok((0, open_capture(&self.path)?))
    }

    /// Returns a decoder to the pool, dropping the least advanced when it is full.
    fn give_back(&self, next: usize, cap: VideoCapture) {
        if next >= self.count {
            return;
        }
        let mut pool = self.pool.lock().unwrap_or_else(|p| p.into_inner());
        pool.push((next, cap));
        if pool.len() > POOL {
            let k = (0..pool.len()).min_by_key(|&k| pool[k].0).unwrap_or(0);
            pool.swap_remove(k);
        }
    }

    /// The frame past the last one OpenCV decodes, as an error: the container promised more.
    fn ended(&self, at: usize) -> VideoError {
        decode_err(
            &self.path,
            at,
            format!(
                "OpenCV decodes only {at} frames, the container reports {}",
                self.count
            ),
        )
    }

    /// Frame `frame` (0-based) as a linear-light RGB image.
    pub fn frame(&self, frame: i64) -> Result<Image, VideoError> {
        let i = self.check_frame(frame)?;
        let (mut next, mut cap) = self.take(i)?;
        while next < i {
            if !cap.grab().map_err(|e| decode_err(&self.path, next, e))? {
                return Err(self.ended(next));
            }
            next += 1;
        }
        let mut m = Mat::default();
        if !cap.read(&mut m).map_err(|e| decode_err(&self.path, i, e))? || m.empty() {
            return Err(self.ended(i));
        }
        let img = to_image(&self.path, i, &m)?;
        self.give_back(i + 1, cap);
        Ok(img)
    }

    /// Every frame in order (one decoding pass).
    pub fn frames(&self) -> Result<Vec<Image>, VideoError> {
        let mut cap = open_capture(&self.path)?;
        let mut out = Vec::with_capacity(self.count);
        let mut m = Mat::default();
        while out.len() < self.count {
            let i = out.len();
            if !cap.read(&mut m).map_err(|e| decode_err(&self.path, i, e))? || m.empty() {
                return Err(self.ended(i));
            }
            out.push(to_image(&self.path, i, &m)?);
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use opencv::core::Size;
    use opencv::prelude::{VideoWriterTrait, VideoWriterTraitConst};
    use opencv::videoio::VideoWriter;
    use vfxgraph_imaging::color::linear_to_srgb;

    use super::*;
    use crate::tests::{mean_diff, pattern};
    use crate::{write_mp4, ColorInfo, Matrix, Video};

    /// Mean absolute difference of the sRGB-encoded luma (BT.601 weights) of two images.
    fn luma_diff(a: &Image, b: &Image) -> f32 {
        let y = |img: &Image, x, yy| {
            let c = |k| linear_to_srgb(img.get(x, yy, k));
            0.299 * c(0) + 0.587 * c(1) + 0.114 * c(2)
        };
        let mut s = 0.0f64;
        for yy in 0..a.height {
            for x in 0..a.width {
                s += (y(a, x, yy) - y(b, x, yy)).abs() as f64;
            }
        }
        (s / (a.width * a.height) as f64) as f32
    }

    fn mp4(dir: &Path, name: &str, frames: &[Image], matrix: Matrix) -> PathBuf {
        let p = dir.join(name);
        let color = ColorInfo {
            matrix,
            full_range: false,
            matrix_from_stream: true,
        };
        write_mp4(&p, frames, 24.0, 5, 4, color).unwrap();
        p
    }

    /// The same H.264 file through OpenCV and through the native reader: the same frame
    /// count, size, rate and, frame by frame, the same pictures up to the two decoders'
    /// Y'CbCr → R'G'B' conversions: FFmpeg's swscale (OpenCV's) comes out about one 8-bit
    /// code darker and upsamples chroma with another filter; for a BT.709 stream it uses the
    /// BT.601 matrix, which moves saturated colours (not luma).
    #[test]
    fn opencv_reads_the_frames_the_native_reader_reads() {
        let dir = tempfile::tempdir().unwrap();
        let (w, h) = (96, 64);
        let src: Vec<Image> = (0..12).map(|k| pattern(w, h, k)).collect();
        for matrix in [Matrix::Bt601, Matrix::Bt709] {
            let p = mp4(dir.path(), &format!("{matrix:?}.mp4"), &src, matrix);
            let native = Video::open(&p).unwrap().frames().unwrap();
            let cap = Capture::open(&p).unwrap();
            assert_eq!(cap.frame_count(), 12);
            assert_eq!(cap.size(), (w, h));
            assert!((cap.fps() - 24.0).abs() < 1e-3, "{}", cap.fps());
            let cv = cap.frames().unwrap();
            assert_eq!(cv.len(), 12);
            // Away from the colour patches, on the patches, and the luma of the whole frame.
            let smooth = |x: usize, _: usize| x > w / 4 + 4;
            let patches = |x: usize, y: usize| {
                x >= 2 && x + 2 < w / 4 && (y % (h / 4)) >= 3 && (y % (h / 4)) + 3 < h / 4
            };
            let mut worst = [0.0f32; 3];
            for (k, (a, b)) in cv.iter().zip(&native).enumerate() {
                assert_eq!((a.width, a.height, a.channels), (w, h, 3));
                let d = [
                    mean_diff(a, b, smooth),
                    mean_diff(a, b, patches),
                    luma_diff(a, b),
                ];
                for (m, x) in worst.iter_mut().zip(d) {
                    *m = m.max(x);
                }
                // Each frame is the native reader's same-numbered frame, not a neighbour (the
                // disc moves 3 px a frame): of all native frames, that one is the closest.
                let closest = (0..native.len())
                    .min_by(|&i, &j| luma_diff(a, &native[i]).total_cmp(&luma_diff(a, &native[j])))
                    .unwrap();
                assert_eq!(closest, k, "{matrix:?}: OpenCV's frame {k}");
                // BT.601: within 2.5 code values of 255 on average everywhere; BT.709: the
                // saturated patches (a quarter of the frame) converted with the wrong matrix
                // are off by more, and so the whole frame's luma.
                let (patch_tol, luma_tol) = match matrix {
                    Matrix::Bt601 => (0.01, 0.01),
                    _ => (0.08, 0.03),
                };
                assert!(
                    d[0] < 0.01 && d[1] < patch_tol && d[2] < luma_tol,
                    "{matrix:?} frame {k}: mean |Δ| smooth {}, patches {}, luma {}",
                    d[0],
                    d[1],
                    d[2]
                );
            }
            eprintln!(
                "{matrix:?}: OpenCV vs native, worst frame's mean |Δ| (sRGB-encoded, 0–1): \
                 smooth part {:.4}, colour patches {:.4}, luma {:.4}",
                worst[0], worst[1], worst[2]
            );
            // Any frame alone, in any order (pooled decoders, re-opening to go back), is the
            // same picture as in the sequential pass.
            for k in [7, 0, 11, 3, 3, 4, 10, 1] {
                assert_eq!(cap.frame(k).unwrap(), cv[k as usize], "frame {k}");
            }
            let e = cap.frame(12).err().unwrap();
            assert!(
                matches!(
                    e,
                    VideoError::FrameOutOfRange {
                        frame: 12,
                        count: 12,
                        ..
                    }
                ),
                "{e}"
            );
            assert!(cap.frame(-1).is_err());
        }
    }

    /// A codec the native reader does not decode (Motion JPEG in AVI, written by OpenCV's
    /// own encoder; MPEG-4 Part 2 in MP4 where FFmpeg's writer is present) reads through
    /// OpenCV to the source frames within JPEG/MPEG-4 error.
    #[test]
    fn other_codecs_read_through_opencv() {
        let dir = tempfile::tempdir().unwrap();
        let (w, h) = (96, 64);
        let src: Vec<Image> = (0..8).map(|k| pattern(w, h, k)).collect();
        let bgr: Vec<Vec<u8>> = src
            .iter()
            .map(|img| {
                let mut v = Vec::with_capacity(w * h * 3);
                for y in 0..h {
                    for x in 0..w {
                        for c in [2, 1, 0] {
                            let s = linear_to_srgb(img.get(x, y, c)) * 255.0;
                            v.push(s.round().clamp(0.0, 255.0) as u8);
                        }
                    }
                }
                v
            })
            .collect();
        let cases = [
            ("clip.avi", ['M', 'J', 'P', 'G'], true),
            ("clip_mp4v.mp4", ['m', 'p', '4', 'v'], false),
        ];
        for (name, cc, required) in cases {
            let p = dir.path().join(name);
            let fourcc = VideoWriter::fourcc(cc[0], cc[1], cc[2], cc[3]).unwrap();
            let size = Size::new(w as i32, h as i32);
            let writer = VideoWriter::new(p.as_os_str(), fourcc, 24.0, size, true);
            let mut writer = match writer {
                Ok(wr) if wr.is_opened().unwrap_or(false) => wr,
                _ if !required => {
                    eprintln!("skipping {name}: this OpenCV cannot write it");
                    continue;
                }
                _ => panic!("OpenCV cannot write {name}"),
            };
            for f in &bgr {
                let m = Mat::new_rows_cols_with_bytes::<opencv::core::Vec3b>(h as i32, w as i32, f)
                    .unwrap();
                writer.write(&m).unwrap();
            }
            writer.release().unwrap();
            drop(writer);
            // The native reader says what it cannot do …
            if let Err(e) = Video::open(&p) {
                eprintln!("native reader on {name}: {e}");
                assert!(e.to_string().contains(name), "{e}");
            }
            // … OpenCV reads it.
            let cap = Capture::open(&p).unwrap();
            assert_eq!((cap.frame_count(), cap.size()), (8, (w, h)), "{name}");
            let frames = cap.frames().unwrap();
            for (k, (a, s)) in frames.iter().zip(&src).enumerate() {
                let e = mean_diff(a, s, |_, _| true);
                eprintln!("{name} frame {k}: mean |Δ| {e:.4}");
                assert!(e < 0.03, "{name} frame {k}: mean |Δ| {e}");
            }
            assert_eq!(cap.frame(5).unwrap(), frames[5]);
        }
    }

    #[test]
    fn bad_files_are_errors_naming_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("missing.mov");
        let e = Capture::open(&missing).err().unwrap();
        assert!(
            matches!(e, VideoError::Io { .. }) && e.to_string().contains("missing.mov"),
            "{e}"
        );
        let junk = dir.path().join("junk.mp4");
        std::fs::write(&junk, b"this is not a video at all, just some text").unwrap();
        let e = Capture::open(&junk).err().unwrap();
        assert!(
            matches!(e, VideoError::Container { .. }) && e.to_string().contains("junk.mp4"),
            "{e}"
        );
        let empty = dir.path().join("empty.mkv");
        std::fs::write(&empty, b"").unwrap();
        let e = Capture::open(&empty).err().unwrap();
        assert!(e.to_string().contains("empty.mkv"), "{e}");
        // Truncated or corrupted: an error naming the file, or the frames that survive;
        // never a panic.
        let src: Vec<Image> = (0..6).map(|k| pattern(32, 32, k)).collect();
        let good = mp4(dir.path(), "good.mp4", &src, Matrix::Bt709);
        let bytes = std::fs::read(&good).unwrap();
        for cut in [10, 40, bytes.len() / 3, bytes.len() / 2, bytes.len() - 7] {
            let p = dir.path().join(format!("cut{cut}.mp4"));
            std::fs::write(&p, &bytes[..cut]).unwrap();
            match Capture::open(&p) {
                Err(e) => assert!(e.to_string().contains(&format!("cut{cut}.mp4")), "{e}"),
                Ok(c) => {
                    if let Err(e) = c.frames() {
                        assert!(e.to_string().contains(&format!("cut{cut}.mp4")), "{e}");
                    }
                }
            }
        }
        let mut bad = bytes.clone();
        let n = bad.len();
        for b in &mut bad[n - 200..n - 100] {
            *b ^= 0x5a;
        }
        let p = dir.path().join("corrupt.mp4");
        std::fs::write(&p, &bad).unwrap();
        if let Ok(c) = Capture::open(&p) {
            let _ = c.frames();
        }
    }
}
