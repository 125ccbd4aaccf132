//! # vfxgraph-video
//!
//! Video files for vfxgraph (book chapter 6 tracks what phones and cameras film): H.264 in
//! MP4 — what they write — demuxed with `re_mp4` and decoded with OpenH264 (the `openh264`
//! crate builds its bundled C++ source, so no system library is needed). Frames come out as
//! linear-light RGB [`Image`]s, converted from Y'CbCr with the matrix and range the stream's
//! VUI declares ([`sps`], [`yuv`]; BT.709 for HD and BT.601 below when it does not say).
//!
//! Frame `i` is the `i`-th picture in presentation order. [`Video::frame`] decodes from the
//! nearest preceding sync sample (key frame), so reading any one frame costs at most one
//! group of pictures. Streams whose samples are reordered (B-frames) are reported as
//! unsupported rather than returned out of order.
//!
//! With the `opencv` cargo feature, `capture::Capture` reads any container and codec
//! OpenCV's `VideoCapture` opens into the same frames.
//!
//! [`write_mp4`] encodes frames with OpenH264's encoder and muxes a minimal MP4 (used by the
//! tests to make their own videos); [`files`] holds what the nodes do: a reader kept open
//! across a run's frames and [`write_video`], frames checked, tone-mapped and encoded.

#![warn(missing_docs)]

use std::path::{Path, PathBuf};

use openh264::decoder::Decoder;
use openh264::formats::YUVSource;
use vfxgraph_imaging::Image;

mod bounded;
#[cfg(feature = "opencv")]
pub mod capture;
pub mod ffmpeg;
pub mod files;
pub mod metadata;
mod mux;
pub mod sps;
pub mod yuv;

pub use files::{open_shared, write_video, Backend, ReadVideoOptions, Reader, WriteVideoOptions};
pub use mux::write_mp4;
pub use sps::{ColorInfo, Matrix};

/// Errors reading a video; each names the file.
#[derive(Debug, thiserror::Error)]
pub enum VideoError {
    /// The file cannot be read.
    #[error("cannot read {}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// Not an MP4, or a damaged one.
    #[error("{}: not a readable MP4 file: {message}", path.display())]
    Container {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A codec or stream feature this reader does not handle.
    #[error("{}: unsupported: {message}", path.display())]
    Unsupported {
        /// The file.
        path: PathBuf,
        /// What.
        message: String,
    },
    /// The H.264 decoder failed on a frame.
    #[error("{}: frame {frame}: cannot decode: {message}", path.display())]
    Decode {
        /// The file.
        path: PathBuf,
        /// The frame being decoded.
        frame: usize,
        /// The decoder's message.
        message: String,
    },
    /// A frame past the end of the video.
    #[error("{}: frame {frame} asked for, the video has {count} frames (0–{})", path.display(), count.saturating_sub(1))]
    FrameOutOfRange {
        /// The file.
        path: PathBuf,
        /// The frame asked for.
        frame: i64,
        /// Number of frames.
        count: usize,
    },
    /// A backend this build does not have.
    #[error(
        "read_video: param `backend: opencv` needs a vfxgraph built with the `opencv` cargo \
         feature, and this one was built without it: install OpenCV (`apt-get install \
         libopencv-dev clang libclang-dev`) and rebuild with `cargo build --release --features \
         opencv`, or use `backend: native` (H.264 MP4 only) for {}",
        path.display()
    )]
    Unavailable {
        /// The file.
        path: PathBuf,
    },
    /// Frames that cannot be written as one video (none, sizes differ, odd sizes).
    #[error("{message}")]
    Invalid {
        /// What is wrong.
        message: String,
    },
    /// Encoding (writing) failed.
    #[error("{}: cannot encode: {message}", path.display())]
    Encode {
        /// The file.
        path: PathBuf,
        /// Why.
        message: String,
    },
}

impl VideoError {
    /// The same error again (for a cached failure: `std::io::Error` is not `Clone`, so an I/O
    /// error keeps its kind and message).
    pub fn replay(&self) -> VideoError {
        use VideoError::*;
        match self {
            Io { path, source } => Io {
                path: path.clone(),
                source: std::io::Error::new(source.kind(), source.to_string()),
            },
            Container { path, message } => Container {
                path: path.clone(),
                message: message.clone(),
            },
            Unsupported { path, message } => Unsupported {
                path: path.clone(),
                message: message.clone(),
            },
            Decode {
                path,
                frame,
                message,
            } => Decode {
                path: path.clone(),
                frame: *frame,
                message: message.clone(),
            },
            FrameOutOfRange { path, frame, count } => FrameOutOfRange {
                path: path.clone(),
                frame: *frame,
                count: *count,
            },
            Unavailable { path } => Unavailable { path: path.clone() },
            Invalid { message } => Invalid {
                message: message.clone(),
            },
            Encode { path, message } => Encode {
                path: path.clone(),
                message: message.clone(),
            },
        }
    }
}

/// One video sample (an access unit) in the file.
#[derive(Clone, Copy, Debug)]
struct SampleRef {
    offset: usize,
    size: usize,
    is_sync: bool,
}

/// An opened H.264/MP4 video: its first video track, ready to decode any frame.
pub struct Video {
    path: PathBuf,
    data: Vec<u8>,
    samples: Vec<SampleRef>,
    /// SPS and PPS NAL units (without start codes) from the `avcC` box.
    parameter_sets: Vec<Vec<u8>>,
    /// Bytes of the NAL length prefix in samples (1, 2 or 4).
    length_size: usize,
    width: usize,
    height: usize,
    color: ColorInfo,
    fps: f64,
}

fn container(path: &Path, message: impl Into<String>) -> VideoError {
    VideoError::Container {
        path: path.to_path_buf(),
        message: message.into(),
    }
}

fn unsupported(path: &Path, message: impl Into<String>) -> VideoError {
    VideoError::Unsupported {
        path: path.to_path_buf(),
        message: message.into(),
    }
}

impl Video {
    /// Opens an MP4 file and checks that its first video track is 8-bit 4:2:0 H.264.
    pub fn open(path: &Path) -> Result<Video, VideoError> {
        let data = std::fs::read(path).map_err(|source| VideoError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Video::from_bytes(path, data)
    }

    /// [`Video::open`] on bytes already read; `path` names them in errors.
    pub fn from_bytes(path: &Path, data: Vec<u8>) -> Result<Video, VideoError> {
        if data.len() < 8
            || !matches!(
                &data[4..8],
                b"ftyp" | b"moov" | b"mdat" | b"free" | b"wide" | b"skip"
            )
        {
            return Err(container(path, "no MP4 box structure at the start"));
        }
        // The demuxer is third-party code reading untrusted input: a panic in it becomes an
        // error naming the file.
        // Its reads go through a budget: a malformed box tree can send it into an endless
        // loop (see `bounded`).
        let mut reader = bounded::Bounded::new(&data);
        let parsed = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            re_mp4::Mp4::read(&mut reader, data.len() as u64)
        }));
        let mp4 = match parsed {
            Ok(Ok(m)) => m,
            Ok(Err(_)) if reader.exhausted() => {
                return Err(container(
                    path,
                    "the MP4 box structure is malformed (the demuxer made no progress)",
                ))
            }
            Ok(Err(e)) => return Err(container(path, e.to_string())),
            Err(_) => return Err(container(path, "the MP4 parser failed on this file")),
        };
        let track = mp4
            .tracks()
            .values()
            .find(|t| t.kind == Some(re_mp4::TrackKind::Video))
            .ok_or_else(|| container(path, "no video track"))?;
        let trak = mp4
            .moov
            .traks
            .iter()
            .find(|t| t.tkhd.track_id == track.track_id)
            .ok_or_else(|| container(path, "video track without its trak box"))?;
        let avc = match &trak.mdia.minf.stbl.stsd.contents {
            re_mp4::StsdBoxContent::Avc1(a) => a,
            other => {
                let codec = other.codec_string().unwrap_or_else(|| "unknown".into());
                return Err(unsupported(
                    path,
                    format!(
                        "codec `{codec}`: only H.264 (avc1) is decoded natively (other \
                         codecs: the OpenCV reader, in a build with the `opencv` feature)"
                    ),
                ));
            }
        };
        let cfg = &avc.avcc.contents;
        let length_size = cfg.length_size_minus_one as usize % 4 + 1;
        if length_size == 3 {
            return Err(container(path, "avcC length size 3 is not allowed"));
        }
        let sps_nal = cfg
            .sequence_parameter_sets
            .first()
            .ok_or_else(|| container(path, "avcC has no sequence parameter set"))?;
        let sps = sps::parse_sps(&sps_nal.bytes, path)?;
        if sps.chroma_format_idc != 1 || sps.bit_depth != 8 {
            return Err(unsupported(
                path,
                format!(
                    "H.264 with chroma format {} at {} bits (OpenH264 decodes 8-bit 4:2:0)",
                    sps.chroma_format_idc, sps.bit_depth
                ),
            ));
        }
        let mut parameter_sets: Vec<Vec<u8>> = cfg
            .sequence_parameter_sets
            .iter()
            .map(|n| n.bytes.clone())
            .collect();
        parameter_sets.extend(cfg.picture_parameter_sets.iter().map(|n| n.bytes.clone()));
        let mut samples = Vec::with_capacity(track.samples.len());
        for s in &track.samples {
            let (offset, size) = (s.offset as usize, s.size as usize);
            if offset.checked_add(size).is_none_or(|e| e > data.len()) {
                return Err(container(
                    path,
                    format!("sample {} lies past the end of the file (truncated?)", s.id),
                ));
            }
            samples.push(SampleRef {
                offset,
                size,
                is_sync: s.is_sync,
            });
        }
        if samples.is_empty() {
            return Err(container(path, "the video track has no samples"));
        }
        if track
            .samples
            .windows(2)
            .any(|w| w[1].composition_timestamp <= w[0].composition_timestamp)
        {
            return Err(unsupported(
                path,
                "reordered frames (B-frames); re-encode without B-frames or use the OpenCV \
                 reader (a build with the `opencv` feature)",
            ));
        }
        let duration = track.duration as f64 / track.timescale.max(1) as f64;
        let fps = if duration > 0.0 {
            samples.len() as f64 / duration
        } else {
            0.0
        };
        let (width, height) = (track.width as usize, track.height as usize);
        Ok(Video {
            path: path.to_path_buf(),
            data,
            samples,
            parameter_sets,
            length_size,
            width,
            height,
            color: sps.color(height),
            fps,
        })
    }

    /// Number of frames.
    pub fn frame_count(&self) -> usize {
        self.samples.len()
    }

    /// Width and height from the track header.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// Frames per second (frame count over the track's duration; 0 when unknown).
    pub fn fps(&self) -> f64 {
        self.fps
    }

    /// The colour conversion in use.
    pub fn color(&self) -> ColorInfo {
        self.color
    }

    /// Annex-B bytes (start codes) of sample `i`.
    fn annex_b(&self, i: usize) -> Result<Vec<u8>, VideoError> {
        let s = self.samples[i];
        let mut b = &self.data[s.offset..s.offset + s.size];
        let mut out = Vec::with_capacity(s.size + 16);
        while !b.is_empty() {
            if b.len() < self.length_size {
                return Err(container(
                    &self.path,
                    format!("sample {i}: truncated NAL length"),
                ));
            }
            let n = b[..self.length_size]
                .iter()
                .fold(0usize, |a, &x| (a << 8) | x as usize);
            b = &b[self.length_size..];
            if n > b.len() {
                return Err(container(
                    &self.path,
                    format!("sample {i}: NAL unit of {n} bytes overruns the sample"),
                ));
            }
            out.extend_from_slice(&[0, 0, 0, 1]);
            out.extend_from_slice(&b[..n]);
            b = &b[n..];
        }
        Ok(out)
    }

    /// Decodes frames `first..=last` (a run starting at a sync sample) and hands each
    /// picture to `f` with its frame number.
    fn decode_run(
        &self,
        first: usize,
        last: usize,
        mut f: impl FnMut(usize, Image),
    ) -> Result<(), VideoError> {
        let dec_err = |frame: usize, e: &dyn std::fmt::Display| VideoError::Decode {
            path: self.path.clone(),
            frame,
            message: e.to_string(),
        };
        let mut dec = Decoder::new().map_err(|e| dec_err(first, &e))?;
        let mut header = Vec::new();
        for ps in &self.parameter_sets {
            header.extend_from_slice(&[0, 0, 0, 1]);
            header.extend_from_slice(ps);
        }
        // Parameter sets alone give no picture.
        dec.decode(&header).map_err(|e| dec_err(first, &e))?;
        let mut next = first;
        for i in first..=last {
            let au = self.annex_b(i)?;
            let pic = dec.decode(&au).map_err(|e| dec_err(i, &e))?;
            if let Some(p) = pic {
                f(next, self.convert(&p));
                next += 1;
            }
        }
        if next <= last {
            let rest = dec.flush_remaining().map_err(|e| dec_err(next, &e))?;
            for p in rest {
                if next > last {
                    break;
                }
                f(next, self.convert(&p));
                next += 1;
            }
        }
        if next <= last {
            return Err(dec_err(next, &"the decoder returned no picture"));
        }
        Ok(())
    }

    fn convert(&self, p: &openh264::decoder::DecodedYUV<'_>) -> Image {
        let (w, h) = p.dimensions();
        let (sy, su, _) = p.strides();
        yuv::to_image(
            &yuv::Planes {
                width: w,
                height: h,
                y: p.y(),
                u: p.u(),
                v: p.v(),
                y_stride: sy,
                uv_stride: su,
            },
            &self.color,
        )
    }

    fn check_frame(&self, frame: i64) -> Result<usize, VideoError> {
        if frame < 0 || frame as usize >= self.samples.len() {
            return Err(VideoError::FrameOutOfRange {
                path: self.path.clone(),
                frame,
                count: self.samples.len(),
            });
        }
        Ok(frame as usize)
    }

    /// Frame `frame` (0-based) as a linear-light RGB image, decoded from the nearest
    /// preceding sync sample.
    pub fn frame(&self, frame: i64) -> Result<Image, VideoError> {
        let i = self.check_frame(frame)?;
        let start = (0..=i)
            .rev()
            .find(|&k| self.samples[k].is_sync)
            .unwrap_or(0);
        let mut out = None;
        self.decode_run(start, i, |k, img| {
            if k == i {
                out = Some(img);
            }
        })?;
        out.ok_or_else(|| VideoError::Decode {
            path: self.path.clone(),
            frame: i,
            message: "no picture".into(),
        })
    }

    /// Every frame in order (one decoding pass).
    pub fn frames(&self) -> Result<Vec<Image>, VideoError> {
        let mut out = Vec::with_capacity(self.samples.len());
        self.decode_run(0, self.samples.len() - 1, |_, img| out.push(img))?;
        Ok(out)
    }
}

#[cfg(feature = "opencv")]
pub use capture::Capture;

#[cfg(test)]
mod tests;
