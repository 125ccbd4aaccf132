//! Writing H.264 MP4 files: frames encoded with OpenH264's encoder (Y'CbCr 4:2:0 with the
//! chosen matrix and range, declared in the stream's VUI) and muxed into a minimal MP4 (ISO/IEC
//! 14496-12/-15: `ftyp`, `moov` with one `avc1` track, `mdat`). The tests make their own
//! videos with it; the reader does not depend on it.

use std::borrow::Borrow;
use std::path::Path;

use openh264::encoder::{
    BitRate, Encoder, EncoderConfig, FrameRate, FrameType, IntraFramePeriod, QpRange,
    RateControlMode, VuiConfig,
};
use openh264::formats::YUVBuffer;
use openh264::OpenH264API;
use vfxgraph_imaging::color::linear_to_srgb;
use vfxgraph_imaging::Image;

use crate::sps::{ColorInfo, Matrix};
use crate::VideoError;

/// Y'CbCr code values (0–255, unrounded) of one R'G'B' triple (0–1).
pub(crate) fn rgb_to_ycbcr(rgb: [f32; 3], c: &ColorInfo) -> [f32; 3] {
    let (kr, kb) = c.matrix.kr_kb();
    let y = kr * rgb[0] + (1.0 - kr - kb) * rgb[1] + kb * rgb[2];
    let pb = (rgb[2] - y) / (2.0 * (1.0 - kb));
    let pr = (rgb[0] - y) / (2.0 * (1.0 - kr));
    if c.full_range {
        [255.0 * y, 128.0 + 255.0 * pb, 128.0 + 255.0 * pr]
    } else {
        [16.0 + 219.0 * y, 128.0 + 224.0 * pb, 128.0 + 224.0 * pr]
    }
}

/// I420 planes of a linear-light image (sRGB-encoded first): chroma sited as H.264's type 0
/// (horizontally on even columns with a 1-2-1 filter, vertically between the two rows).
fn to_i420(img: &Image, c: &ColorInfo) -> Vec<u8> {
    let (w, h) = (img.width, img.height);
    let (cw, ch) = (w / 2, h / 2);
    let rgb = img.to_rgb();
    let ycc: Vec<[f32; 3]> = (0..w * h)
        .map(|i| {
            let p = &rgb.data[3 * i..3 * i + 3];
            let e = |v: f32| {
                linear_to_srgb(if v.is_finite() {
                    v.clamp(0.0, 1.0)
                } else {
                    0.0
                })
            };
            rgb_to_ycbcr([e(p[0]), e(p[1]), e(p[2])], c)
        })
        .collect();
    let q = |v: f32| v.round().clamp(0.0, 255.0) as u8;
    let mut out = Vec::with_capacity(w * h * 3 / 2);
    out.extend(ycc.iter().map(|p| q(p[0])));
    for k in [1usize, 2] {
        for j in 0..ch {
            for i in 0..cw {
                let mut acc = 0.0;
                for y in [2 * j, 2 * j + 1] {
                    let at = |x: usize| ycc[y * w + x.min(w - 1)][k];
                    let xl = (2 * i).saturating_sub(1);
                    acc += 0.25 * at(xl) + 0.5 * at(2 * i) + 0.25 * at(2 * i + 1);
                }
                out.push(q(acc * 0.5));
            }
        }
    }
    out
}

fn bx(kind: &[u8; 4], body: &[u8]) -> Vec<u8> {
    let mut v = Vec::with_capacity(body.len() + 8);
    v.extend_from_slice(&((body.len() + 8) as u32).to_be_bytes());
    v.extend_from_slice(kind);
    v.extend_from_slice(body);
    v
}

fn full_box(kind: &[u8; 4], version_flags: u32, body: &[u8]) -> Vec<u8> {
    let mut b = version_flags.to_be_bytes().to_vec();
    b.extend_from_slice(body);
    bx(kind, &b)
}

const MATRIX: [u32; 9] = [0x10000, 0, 0, 0, 0x10000, 0, 0, 0, 0x4000_0000];

fn be32s(v: &[u32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_be_bytes()).collect()
}

/// One encoded frame: its NAL units (no start codes) and whether it is a key frame.
struct Frame {
    nals: Vec<Vec<u8>>,
    sync: bool,
}

/// Splits an Annex-B stream at its start codes.
fn split_annex_b(s: &[u8]) -> Vec<Vec<u8>> {
    let mut starts = Vec::new();
    let mut i = 0;
    while i + 3 <= s.len() {
        if s[i] == 0 && s[i + 1] == 0 && s[i + 2] == 1 {
            starts.push(i + 3);
            i += 3;
        } else {
            i += 1;
        }
    }
    let mut out = Vec::new();
    for (k, &a) in starts.iter().enumerate() {
        let mut b = starts.get(k + 1).map_or(s.len(), |&n| n - 3);
        while b > a && s[b - 1] == 0 {
            b -= 1;
        }
        out.push(s[a..b].to_vec());
    }
    out
}

fn moov(
    frames: &[Frame],
    sps: &[u8],
    pps: &[u8],
    (w, h): (usize, usize),
    timescale: u32,
    delta: u32,
    mdat_offset: u32,
) -> Vec<u8> {
    let n = frames.len() as u32;
    let duration = n * delta;
    let mut mvhd = be32s(&[0, 0, timescale, duration, 0x10000]);
    mvhd.extend_from_slice(&[1, 0, 0, 0]); // volume 1.0, reserved
    mvhd.extend_from_slice(&[0; 8]);
    mvhd.extend(be32s(&MATRIX));
    mvhd.extend_from_slice(&[0; 24]);
    mvhd.extend(be32s(&[2]));
    let mut tkhd = be32s(&[0, 0, 1, 0, duration, 0, 0]);
    tkhd.extend_from_slice(&[0; 8]); // layer, alternate group, volume, reserved
    tkhd.extend(be32s(&MATRIX));
    tkhd.extend(be32s(&[(w as u32) << 16, (h as u32) << 16]));
    let mdhd = {
        let mut b = be32s(&[0, 0, timescale, duration]);
        b.extend_from_slice(&[0x55, 0xc4, 0, 0]); // language "und"
        b
    };
    let hdlr = {
        let mut b = be32s(&[0]);
        b.extend_from_slice(b"vide");
        b.extend_from_slice(&[0; 12]);
        b.extend_from_slice(b"VideoHandler\0");
        b
    };
    let vmhd = full_box(b"vmhd", 1, &[0; 8]);
    let dref = full_box(
        b"dref",
        0,
        &[&be32s(&[1])[..], &full_box(b"url ", 1, &[])].concat(),
    );
    let dinf = bx(b"dinf", &dref);
    let mut avcc = vec![1, sps[1], sps[2], sps[3], 0xff, 0xe1];
    avcc.extend_from_slice(&(sps.len() as u16).to_be_bytes());
    avcc.extend_from_slice(sps);
    avcc.push(1);
    avcc.extend_from_slice(&(pps.len() as u16).to_be_bytes());
    avcc.extend_from_slice(pps);
    let mut avc1 = vec![0; 6];
    avc1.extend_from_slice(&1u16.to_be_bytes());
    avc1.extend_from_slice(&[0; 16]);
    avc1.extend_from_slice(&(w as u16).to_be_bytes());
    avc1.extend_from_slice(&(h as u16).to_be_bytes());
    avc1.extend(be32s(&[0x0048_0000, 0x0048_0000, 0]));
    avc1.extend_from_slice(&1u16.to_be_bytes());
    avc1.extend_from_slice(&[0; 32]);
    avc1.extend_from_slice(&[0x00, 0x18, 0xff, 0xff]);
    avc1.extend(bx(b"avcC", &avcc));
    let stsd = full_box(
        b"stsd",
        0,
        &[&be32s(&[1])[..], &bx(b"avc1", &avc1)].concat(),
    );
    let stts = full_box(b"stts", 0, &be32s(&[1, n, delta]));
    let sync: Vec<u32> = (0..n)
        .filter(|&i| frames[i as usize].sync)
        .map(|i| i + 1)
        .collect();
    let stss = full_box(
        b"stss",
        0,
        &[&be32s(&[sync.len() as u32])[..], &be32s(&sync)].concat(),
    );
    let stsc = full_box(b"stsc", 0, &be32s(&[1, 1, n, 1]));
    let sizes: Vec<u32> = frames
        .iter()
        .map(|f| f.nals.iter().map(|x| 4 + x.len() as u32).sum())
        .collect();
    let stsz = full_box(b"stsz", 0, &[&be32s(&[0, n])[..], &be32s(&sizes)].concat());
    let stco = full_box(b"stco", 0, &be32s(&[1, mdat_offset]));
    let stbl = bx(b"stbl", &[stsd, stts, stss, stsc, stsz, stco].concat());
    let minf = bx(b"minf", &[vmhd, dinf, stbl].concat());
    let mdia = bx(
        b"mdia",
        &[
            full_box(b"mdhd", 0, &mdhd),
            full_box(b"hdlr", 0, &hdlr),
            minf,
        ]
        .concat(),
    );
    let trak = bx(b"trak", &[full_box(b"tkhd", 3, &tkhd), mdia].concat());
    bx(b"moov", &[full_box(b"mvhd", 0, &mvhd), trak].concat())
}

/// Encodes `frames` (linear light, all the same even size) as H.264 with OpenH264 and writes
/// them to an MP4 file at `fps` frames per second (any rate in (0, 1000]: the track's time
/// scale is `fps` × 1000 rounded, one frame 1000 ticks, so 23.976 is exact), with a key frame
/// every `keyframe_interval` frames (0: only the first) and quantisation QP ≤ `max_qp` (0–51;
/// lower is better, 0–10 near-lossless). The colour conversion (`color`) is declared in the
/// stream's VUI; values are clipped to [0, 1] and sRGB-encoded (tone-map HDR input first).
/// The write is atomic.
pub fn write_mp4<I: Borrow<Image>>(
    path: &Path,
    frames: &[I],
    fps: f64,
    keyframe_interval: u32,
    max_qp: u8,
    color: ColorInfo,
) -> Result<(), VideoError> {
    let err = |m: String| VideoError::Encode {
        path: path.to_path_buf(),
        message: m,
    };
    if !(fps.is_finite() && fps > 0.0 && fps <= 1000.0) {
        return Err(err(format!("frame rate {fps} must be in (0, 1000]")));
    }
    let timescale = (fps * 1000.0).round().max(1.0) as u32;
    let first = frames
        .first()
        .map(Borrow::borrow)
        .ok_or_else(|| err("no frames".into()))?;
    let (w, h) = (first.width, first.height);
    if w == 0 || h == 0 || w % 2 == 1 || h % 2 == 1 || w > 4096 || h > 4096 {
        return Err(err(format!("frame size {w}×{h} must be even, 2–4096")));
    }
    if let Some(f) = frames
        .iter()
        .map(Borrow::borrow)
        .find(|f| (f.width, f.height) != (w, h))
    {
        return Err(err(format!(
            "frames differ in size: {w}×{h} and {}×{}",
            f.width, f.height
        )));
    }
    let vui = match color.matrix {
        Matrix::Bt601 => VuiConfig::bt601(),
        Matrix::Bt709 => VuiConfig::bt709(),
        Matrix::Bt2020 => VuiConfig::bt2020(),
    }
    .full_range(color.full_range);
    let config = EncoderConfig::new()
        .vui(vui)
        .bitrate(BitRate::from_bps(50_000_000))
        .max_frame_rate(FrameRate::from_hz(fps as f32))
        .rate_control_mode(RateControlMode::Quality)
        .qp(QpRange::new(0, max_qp.min(51)))
        .skip_frames(false)
        .intra_frame_period(IntraFramePeriod::from_num_frames(keyframe_interval));
    let mut enc = Encoder::with_api_config(OpenH264API::from_source(), config)
        .map_err(|e| err(e.to_string()))?;
    let (mut sps, mut pps) = (None, None);
    let mut out = Vec::with_capacity(frames.len());
    for (k, img) in frames.iter().map(Borrow::borrow).enumerate() {
        let yuv = YUVBuffer::from_vec(to_i420(img, &color), w, h);
        let bs = enc
            .encode(&yuv)
            .map_err(|e| err(format!("frame {k}: {e}")))?;
        let sync = matches!(bs.frame_type(), FrameType::IDR | FrameType::I);
        let mut nals = Vec::new();
        for nal in split_annex_b(&bs.to_vec()) {
            match nal.first().map(|b| b & 0x1f) {
                Some(7) => sps = Some(nal),
                Some(8) => pps = Some(nal),
                Some(_) => nals.push(nal),
                None => {}
            }
        }
        if nals.is_empty() {
            return Err(err(format!("frame {k}: the encoder produced no picture")));
        }
        out.push(Frame { nals, sync });
    }
    let (sps, pps) = match (sps, pps) {
        (Some(s), Some(p)) if s.len() >= 4 => (s, p),
        _ => return Err(err("the encoder produced no parameter sets".into())),
    };
    let ftyp = bx(
        b"ftyp",
        &[&b"isom"[..], &512u32.to_be_bytes(), b"isomiso2avc1mp41"].concat(),
    );
    let probe = moov(&out, &sps, &pps, (w, h), timescale, 1000, 0);
    let offset = (ftyp.len() + probe.len() + 8) as u32;
    let moov = moov(&out, &sps, &pps, (w, h), timescale, 1000, offset);
    let mut mdat = Vec::new();
    for f in &out {
        for n in &f.nals {
            mdat.extend_from_slice(&(n.len() as u32).to_be_bytes());
            mdat.extend_from_slice(n);
        }
    }
    if mdat.len() as u64 + offset as u64 + 8 > u32::MAX as u64 {
        return Err(err(format!(
            "{} MB of video data: over the 4 GB a 32-bit MP4 holds; write shorter clips",
            mdat.len() >> 20
        )));
    }
    let file = [ftyp, moov, bx(b"mdat", &mdat)].concat();
    vfxgraph_imaging::io::write_atomic(path, &file).map_err(|e| err(e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn annex_b_split() {
        let s = [
            0, 0, 0, 1, 0x67, 5, 0, 0, 1, 0x68, 7, 0, 0, 0, 1, 0x65, 1, 2,
        ];
        assert_eq!(
            split_annex_b(&s),
            vec![vec![0x67, 5], vec![0x68, 7], vec![0x65, 1, 2]]
        );
    }
}
