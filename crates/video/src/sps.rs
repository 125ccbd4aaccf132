//! The colour description of an H.264 stream: the video-signal fields of the sequence
//! parameter set's VUI (ITU-T H.264 sections 7.3.2.1.1 and E.1.1), which say how Y'CbCr maps
//! back to R'G'B' (matrix coefficients, full or limited range).

use crate::VideoError;

/// The Y'CbCr ↔ R'G'B' matrix of a stream (H.264 Table E-5, `matrix_coefficients`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Matrix {
    /// ITU-R BT.601 (codes 5, 6 and 4): Kr = 0.299, Kb = 0.114; SD video.
    Bt601,
    /// ITU-R BT.709 (code 1): Kr = 0.2126, Kb = 0.0722; HD video.
    Bt709,
    /// ITU-R BT.2020 non-constant luminance (code 9): Kr = 0.2627, Kb = 0.0593.
    Bt2020,
}

impl Matrix {
    /// (Kr, Kb) of the matrix.
    pub fn kr_kb(self) -> (f32, f32) {
        match self {
            Matrix::Bt601 => (0.299, 0.114),
            Matrix::Bt709 => (0.2126, 0.0722),
            Matrix::Bt2020 => (0.2627, 0.0593),
        }
    }
}

/// How to convert a stream's samples to R'G'B'.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ColorInfo {
    /// The matrix: from the VUI when the stream says, else BT.709 for HD (height ≥ 720) and
    /// BT.601 below.
    pub matrix: Matrix,
    /// True for full-range samples (0–255); false (the default) for limited range (Y' 16–235,
    /// Cb/Cr 16–240).
    pub full_range: bool,
    /// True when the matrix came from the stream rather than the size-based default.
    pub matrix_from_stream: bool,
}

/// What the sequence parameter set says (the parts the reader needs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SpsInfo {
    /// `profile_idc`.
    pub profile: u8,
    /// 1 for 4:2:0 (the only format OpenH264 decodes).
    pub chroma_format_idc: u32,
    /// Luma bit depth.
    pub bit_depth: u32,
    /// `matrix_coefficients` of the VUI, if present.
    pub matrix_coefficients: Option<u8>,
    /// `video_full_range_flag` of the VUI (false when absent).
    pub full_range: bool,
}

impl SpsInfo {
    /// The colour conversion for a picture `height` pixels tall.
    pub fn color(&self, height: usize) -> ColorInfo {
        let default = if height >= 720 {
            Matrix::Bt709
        } else {
            Matrix::Bt601
        };
        let from = match self.matrix_coefficients {
            Some(1) => Some(Matrix::Bt709),
            Some(4..=6) => Some(Matrix::Bt601),
            Some(9) => Some(Matrix::Bt2020),
            _ => None,
        };
        ColorInfo {
            matrix: from.unwrap_or(default),
            full_range: self.full_range,
            matrix_from_stream: from.is_some(),
        }
    }
}

/// Reads bits of an RBSP (emulation-prevention bytes removed), most significant first.
struct Bits<'a> {
    data: &'a [u8],
    pos: usize,
}

impl Bits<'_> {
    fn bit(&mut self) -> Result<u32, String> {
        let byte = self.data.get(self.pos / 8).ok_or("SPS ends early")?;
        let b = (byte >> (7 - self.pos % 8)) & 1;
        self.pos += 1;
        Ok(b as u32)
    }

    fn bits(&mut self, n: u32) -> Result<u32, String> {
        let mut v = 0;
        for _ in 0..n {
            v = (v << 1) | self.bit()?;
        }
        Ok(v)
    }

    /// Unsigned Exp-Golomb `ue(v)`.
    fn ue(&mut self) -> Result<u32, String> {
        let mut zeros = 0;
        while self.bit()? == 0 {
            zeros += 1;
            if zeros > 31 {
                return Err("bad Exp-Golomb code in SPS".into());
            }
        }
        Ok((1u32 << zeros) - 1 + self.bits(zeros)?)
    }

    /// Signed Exp-Golomb `se(v)`.
    fn se(&mut self) -> Result<i32, String> {
        let k = self.ue()? as i64;
        Ok(if k % 2 == 1 { (k + 1) / 2 } else { -(k / 2) } as i32)
    }
}

/// Removes the emulation-prevention bytes (`00 00 03` → `00 00`) of a NAL unit's payload.
fn rbsp(nal: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(nal.len());
    let mut zeros = 0;
    for &b in nal {
        if zeros >= 2 && b == 3 {
            zeros = 0;
            continue;
        }
        zeros = if b == 0 { zeros + 1 } else { 0 };
        out.push(b);
    }
    out
}

/// Parses a sequence parameter set NAL unit (with its one-byte NAL header).
pub fn parse_sps(nal: &[u8], path: &std::path::Path) -> Result<SpsInfo, VideoError> {
    parse(nal).map_err(|m| VideoError::Container {
        path: path.to_path_buf(),
        message: format!("sequence parameter set: {m}"),
    })
}

fn parse(nal: &[u8]) -> Result<SpsInfo, String> {
    if nal.first().map(|h| h & 0x1f) != Some(7) {
        return Err("not an SPS NAL unit".into());
    }
    let data = rbsp(&nal[1..]);
    let mut r = Bits {
        data: &data,
        pos: 0,
    };
    let profile = r.bits(8)? as u8;
    r.bits(16)?; // constraint flags, level_idc
    r.ue()?; // seq_parameter_set_id
    let (mut chroma_format_idc, mut bit_depth) = (1, 8);
    if [100, 110, 122, 244, 44, 83, 86, 118, 128, 138, 139, 134, 135].contains(&profile) {
        chroma_format_idc = r.ue()?;
        if chroma_format_idc == 3 {
            r.bit()?; // separate_colour_plane_flag
        }
        bit_depth = r.ue()? + 8;
        r.ue()?; // bit_depth_chroma_minus8
        r.bit()?; // qpprime_y_zero_transform_bypass_flag
        if r.bit()? == 1 {
            let lists = if chroma_format_idc == 3 { 12 } else { 8 };
            for i in 0..lists {
                if r.bit()? == 1 {
                    let size = if i < 6 { 16 } else { 64 };
                    let (mut last, mut next) = (8i32, 8i32);
                    for _ in 0..size {
                        if next != 0 {
                            next = (last + r.se()? + 256) % 256;
                        }
                        if next != 0 {
                            last = next;
                        }
                    }
                }
            }
        }
    }
    r.ue()?; // log2_max_frame_num_minus4
    match r.ue()? {
        0 => {
            r.ue()?;
        }
        1 => {
            r.bit()?;
            r.se()?;
            r.se()?;
            let n = r.ue()?;
            if n > 255 {
                return Err("too many reference frame offsets".into());
            }
            for _ in 0..n {
                r.se()?;
            }
        }
        _ => {}
    }
    r.ue()?; // max_num_ref_frames
    r.bit()?; // gaps_in_frame_num_value_allowed_flag
    r.ue()?; // pic_width_in_mbs_minus1
    r.ue()?; // pic_height_in_map_units_minus1
    if r.bit()? == 0 {
        r.bit()?; // mb_adaptive_frame_field_flag
    }
    r.bit()?; // direct_8x8_inference_flag
    if r.bit()? == 1 {
        for _ in 0..4 {
            r.ue()?; // frame cropping offsets
        }
    }
    let mut info = SpsInfo {
        profile,
        chroma_format_idc,
        bit_depth,
        matrix_coefficients: None,
        full_range: false,
    };
    // VUI (Annex E); a stream that ends before it simply has none.
    let Ok(1) = r.bit() else { return Ok(info) };
    if r.bit()? == 1 && r.bits(8)? == 255 {
        r.bits(32)?; // sar_width, sar_height
    }
    if r.bit()? == 1 {
        r.bit()?; // overscan_appropriate_flag
    }
    if r.bit()? == 1 {
        r.bits(3)?; // video_format
        info.full_range = r.bit()? == 1;
        if r.bit()? == 1 {
            r.bits(16)?; // colour_primaries, transfer_characteristics
            info.matrix_coefficients = Some(r.bits(8)? as u8);
        }
    }
    Ok(info)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn emulation_prevention_bytes_are_removed() {
        assert_eq!(
            rbsp(&[0, 0, 3, 1, 0, 0, 3, 0, 5]),
            vec![0, 0, 1, 0, 0, 0, 5]
        );
    }

    #[test]
    fn exp_golomb_codes() {
        // 1 → 0, 010 → 1, 011 → 2, 00100 → 3; se: 010 → +1, 011 → −1.
        let data = [0b1010_0110, 0b0100_0100, 0b1100_0000];
        let mut r = Bits {
            data: &data,
            pos: 0,
        };
        assert_eq!(
            (r.ue().unwrap(), r.ue().unwrap(), r.ue().unwrap()),
            (0, 1, 2)
        );
        assert_eq!(r.ue().unwrap(), 3);
        assert_eq!((r.se().unwrap(), r.se().unwrap()), (1, -1));
    }

    #[test]
    fn default_matrix_follows_the_picture_size() {
        let mut s = SpsInfo {
            profile: 66,
            chroma_format_idc: 1,
            bit_depth: 8,
            matrix_coefficients: None,
            full_range: false,
        };
        assert_eq!(s.color(1080).matrix, Matrix::Bt709);
        assert_eq!(s.color(480).matrix, Matrix::Bt601);
        s.matrix_coefficients = Some(6);
        assert_eq!(s.color(1080).matrix, Matrix::Bt601);
        assert!(s.color(1080).matrix_from_stream);
        assert!(parse(&[0x68, 1, 2]).is_err());
        assert!(parse(&[0x67, 66]).is_err());
    }
}
