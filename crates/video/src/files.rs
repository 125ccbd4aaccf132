//! Videos as the `read_video` and `write_video` nodes use them: a reader chosen by
//! [`Backend`] and kept open across the frames of a run ([`open_shared`]), and frames of one
//! even size tone-mapped and written as an MP4 ([`write_video`]).

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::SystemTime;

use vfxgraph_imaging::{tonemap, Image, Operator};

use crate::{write_mp4, ColorInfo, Matrix, Video, VideoError};

/// Which reader opens a video file.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, vfxgraph_params::Choice)]
pub enum Backend {
    /// The bundled reader for the H.264 MP4 it reads, FFmpeg for everything else.
    #[default]
    Auto,
    /// H.264 MP4 without B-frames through OpenH264 (bundled, no system library): [`Video`].
    Native,
    /// Any codec and container through the system's FFmpeg executables:
    /// [`crate::ffmpeg::FfmpegVideo`].
    Ffmpeg,
    /// Any codec OpenCV's VideoCapture reads (a build with the `opencv` feature).
    #[param(name = "opencv")]
    OpenCv,
}

/// The options of reading a video (the `read_video` node's params besides its path).
#[derive(Clone, Debug, Default, PartialEq, vfxgraph_params::Options)]
pub struct ReadVideoOptions {
    /// auto (native where it can, else ffmpeg) | native (H.264 MP4 without B-frames, bundled) |
    /// ffmpeg (every codec, through the system's `ffmpeg`) | opencv (any codec OpenCV's
    /// VideoCapture reads; needs a build with the `opencv` cargo feature; OpenCV converts
    /// Y'CbCr with BT.601 whatever the stream declares)
    pub backend: Backend,
}

/// An opened video file, through one of the readers.
pub enum Reader {
    /// [`Video`].
    Native(Video),
    /// [`crate::ffmpeg::FfmpegVideo`].
    Ffmpeg(Box<crate::ffmpeg::FfmpegVideo>),
    /// OpenCV's VideoCapture.
    #[cfg(feature = "opencv")]
    OpenCv(crate::capture::Capture),
}

impl Reader {
    /// Opens `path` with `backend`; without the `opencv` feature, `OpenCv` is an error that
    /// says how to get it.
    pub fn open(path: &Path, backend: Backend) -> Result<Reader, VideoError> {
        match backend {
            Backend::Auto => match Video::open(path) {
                Ok(v) => Ok(Reader::Native(v)),
                Err(
                    VideoError::Unsupported { message, .. } | VideoError::Container { message, .. },
                ) => {
                    if crate::ffmpeg::available() {
                        crate::ffmpeg::FfmpegVideo::open(path).map(|v| Reader::Ffmpeg(Box::new(v)))
                    } else {
                        Err(crate::ffmpeg::missing(
                            path,
                            &format!("the bundled reader cannot ({message})"),
                        ))
                    }
                }
                Err(e) => Err(e),
            },
            Backend::Native => Video::open(path).map(Reader::Native),
            Backend::Ffmpeg => {
                crate::ffmpeg::FfmpegVideo::open(path).map(|v| Reader::Ffmpeg(Box::new(v)))
            }
            #[cfg(feature = "opencv")]
            Backend::OpenCv => crate::capture::Capture::open(path).map(Reader::OpenCv),
            #[cfg(not(feature = "opencv"))]
            Backend::OpenCv => Err(VideoError::Unavailable {
                path: path.to_path_buf(),
            }),
        }
    }

    /// The number of frames (pictures shown).
    pub fn frame_count(&self) -> usize {
        match self {
            Reader::Native(v) => v.frame_count(),
            Reader::Ffmpeg(v) => v.frame_count(),
            #[cfg(feature = "opencv")]
            Reader::OpenCv(c) => c.frame_count(),
        }
    }

    /// Frame `frame` (0 = the first picture), linear-light RGB.
    pub fn frame(&self, frame: i64) -> Result<Image, VideoError> {
        match self {
            Reader::Native(v) => v.frame(frame),
            Reader::Ffmpeg(v) => v.frame(frame),
            #[cfg(feature = "opencv")]
            Reader::OpenCv(c) => c.frame(frame),
        }
    }
}

/// The last opened video (the file is parsed once for all the frames of a run) — or why it
/// could not be opened (a clip in a codec no backend reads fails once, not once a frame);
/// keyed by path, size, modification time and backend.
type Opened = Option<(
    PathBuf,
    u64,
    Option<SystemTime>,
    Backend,
    Result<Arc<Reader>, Arc<VideoError>>,
)>;
static OPEN: Mutex<Opened> = Mutex::new(None);

/// `path` opened with `backend`, or the reader opened last (or the error it gave) when it is
/// the same file (path, size and modification time) and backend.
pub fn open_shared(path: &Path, backend: Backend) -> Result<Arc<Reader>, VideoError> {
    let meta = std::fs::metadata(path).map_err(|source| VideoError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let (len, mtime) = (meta.len(), meta.modified().ok());
    let mut guard = OPEN.lock().unwrap_or_else(|p| p.into_inner());
    if let Some((p, l, m, b, v)) = guard.as_ref() {
        if p == path && *l == len && *m == mtime && *b == backend {
            return v.clone().map_err(|e| e.replay());
        }
    }
    let v = Reader::open(path, backend).map(Arc::new).map_err(Arc::new);
    *guard = Some((path.to_path_buf(), len, mtime, backend, v.clone()));
    v.map_err(|e| e.replay())
}

/// The options of writing a video (the `write_video` node's params besides its path).
#[derive(Clone, Debug, PartialEq, vfxgraph_params::Options)]
pub struct WriteVideoOptions {
    /// frames per second (23.976, 24, 25, 30, …)
    #[param(range = 0.1..=1000.0)]
    pub fps: f64,
    /// the largest H.264 quantiser (QP): lower is better and larger; 0–10 is near lossless,
    /// 18–23 what streaming services use
    #[param(range = 0..=51)]
    pub quality: u8,
    /// a key frame every this many frames (0: the first only); smaller seeks faster
    #[param(range = 0..=100_000)]
    pub keyframe_interval: u32,
    /// srgb (clip to [0, 1], as PNG frames are) | reinhard (L/(1+L), for HDR input)
    pub tonemap: Operator,
    /// stops applied before the tone map
    #[param(range = -30.0..=30.0)]
    pub exposure: f64,
}

impl Default for WriteVideoOptions {
    fn default() -> Self {
        WriteVideoOptions {
            fps: 24.0,
            quality: 20,
            keyframe_interval: 24,
            tonemap: Operator::Srgb,
            exposure: 0.0,
        }
    }
}

/// Writes `frames` (numbered, in order; linear light) as an H.264 MP4 at `path`: tone-mapped
/// and sRGB-encoded, Y'CbCr 4:2:0 limited range with BT.709 declared, atomically. The frames
/// must be one even size.
pub fn write_video(
    path: &Path,
    frames: &[(i64, &Image)],
    o: &WriteVideoOptions,
) -> Result<(), VideoError> {
    let invalid = |message: String| VideoError::Invalid { message };
    let Some((first, img0)) = frames.first() else {
        return Err(invalid(format!(
            "write_video: no frames to write to {}",
            path.display()
        )));
    };
    let (w, h) = (img0.width, img0.height);
    if let Some((f, img)) = frames.iter().find(|(_, i)| (i.width, i.height) != (w, h)) {
        return Err(invalid(format!(
            "write_video: frame {f} is {}×{}, frame {first} is {w}×{h}: a video has one size",
            img.width, img.height
        )));
    }
    if w % 2 == 1 || h % 2 == 1 {
        return Err(invalid(format!(
            "write_video: frames are {w}×{h}; H.264 4:2:0 needs an even width and height \
             (render or crop to an even size)"
        )));
    }
    let stops = o.exposure as f32;
    let mapped: Vec<Image> = frames
        .iter()
        .map(|(_, img)| tonemap(img, o.tonemap, stops))
        .collect();
    if let Some(parent) = path.parent() {
        std::fs::create_dir_all(parent)
            .map_err(|e| invalid(format!("cannot create {}: {e}", parent.display())))?;
    }
    let color = ColorInfo {
        matrix: Matrix::Bt709,
        full_range: false,
        matrix_from_stream: true,
    };
    write_mp4(path, &mapped, o.fps, o.keyframe_interval, o.quality, color)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A file no backend reads fails with the same error for every frame, from the one open
    /// attempt; once the file changes it is opened again.
    #[test]
    fn a_failed_open_is_remembered_until_the_file_changes() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("clip.mp4");
        std::fs::write(&p, b"not a video at all").unwrap();
        let first = open_shared(&p, Backend::Native).err().unwrap().to_string();
        assert!(first.contains("clip.mp4"), "{first}");
        for _ in 0..3 {
            let again = open_shared(&p, Backend::Native).err().unwrap().to_string();
            assert_eq!(again, first);
        }
        let guard = OPEN.lock().unwrap();
        assert!(matches!(guard.as_ref(), Some((q, _, _, _, Err(_))) if q == &p));
        drop(guard);
        std::fs::write(&p, b"still not a video, but longer").unwrap();
        let changed = open_shared(&p, Backend::Native).err().unwrap().to_string();
        assert!(changed.contains("clip.mp4"));
        let guard = OPEN.lock().unwrap();
        assert!(matches!(guard.as_ref(), Some((_, l, _, _, Err(_))) if *l == 29));
    }
}
