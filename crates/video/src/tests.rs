//! Round trips through OpenH264's encoder and our MP4 writer, and the reader's errors.

use vfxgraph_imaging::color::{linear_to_srgb, srgb_to_linear};
use vfxgraph_imaging::Image;

use super::*;

/// Frame `k` of a moving test pattern (linear light): smooth gradients, a moving disc and
/// saturated colour patches (red, green, blue, yellow) on the left.
pub(crate) fn pattern(w: usize, h: usize, k: usize) -> Image {
    Image::from_fn(w, h, 3, |x, y, c| {
        let (xf, yf) = (x as f32, y as f32);
        let patch = (y * 4) / h;
        let v = if x < w / 4 {
            // Patches: R, G, B, yellow at 0.8 (gamma-encoded).
            let rgb = [
                [0.8, 0.1, 0.1],
                [0.1, 0.8, 0.1],
                [0.1, 0.1, 0.8],
                [0.8, 0.8, 0.1],
            ][patch];
            rgb[c]
        } else {
            let cx = w as f32 * 0.6 + 3.0 * k as f32;
            let d = ((xf - cx).powi(2) + (yf - h as f32 * 0.5).powi(2)).sqrt();
            let disc = if d < h as f32 * 0.25 { 0.3 } else { 0.0 };
            let base = 0.2 + 0.5 * xf / w as f32 + 0.2 * (0.05 * yf + 0.3 * c as f32).sin().abs();
            (base + disc).min(0.95)
        };
        srgb_to_linear(v)
    })
}

/// Mean absolute difference of two images in the gamma-encoded (sRGB) domain, over pixels
/// where `region(x, y)` holds.
pub(crate) fn mean_diff(a: &Image, b: &Image, region: impl Fn(usize, usize) -> bool) -> f32 {
    let (mut s, mut n) = (0.0f64, 0usize);
    for y in 0..a.height {
        for x in 0..a.width {
            if !region(x, y) {
                continue;
            }
            for c in 0..3 {
                let d = linear_to_srgb(a.get(x, y, c)) - linear_to_srgb(b.get(x, y, c));
                s += d.abs() as f64;
                n += 1;
            }
        }
    }
    (s / n as f64) as f32
}

fn write(dir: &Path, name: &str, frames: &[Image], matrix: Matrix) -> PathBuf {
    let p = dir.join(name);
    let color = ColorInfo {
        matrix,
        full_range: false,
        matrix_from_stream: true,
    };
    write_mp4(&p, frames, 24.0, 5, 4, color).unwrap();
    p
}

#[test]
fn decoded_frames_match_the_source_within_codec_error() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (96, 64);
    let src: Vec<Image> = (0..12).map(|k| pattern(w, h, k)).collect();
    for matrix in [Matrix::Bt601, Matrix::Bt709] {
        let p = write(dir.path(), &format!("{matrix:?}.mp4"), &src, matrix);
        let size = std::fs::metadata(&p).unwrap().len();
        let mut v = Video::open(&p).unwrap();
        assert_eq!(v.frame_count(), 12);
        assert_eq!(v.size(), (w, h));
        assert!((v.fps() - 24.0).abs() < 1e-6, "{}", v.fps());
        // The stream declares its matrix (a 64-line picture would default to BT.601).
        assert_eq!(v.color().matrix, matrix);
        assert!(v.color().matrix_from_stream && !v.color().full_range);
        let all = v.frames().unwrap();
        assert_eq!(all.len(), 12);
        for (k, (d, s)) in all.iter().zip(&src).enumerate() {
            assert_eq!((d.width, d.height, d.channels), (w, h, 3));
            let e = mean_diff(d, s, |_, _| true);
            // Chroma subsampling smears the patch edges; away from them the colour holds.
            let patches = mean_diff(d, s, |x, y| {
                x >= 2 && x + 2 < w / 4 && (y % (h / 4)) >= 3 && (y % (h / 4)) + 3 < h / 4
            });
            assert!(
                e < 0.012 && patches < 0.01,
                "{matrix:?} frame {k}: mean error {e}, patches {patches} ({size} bytes)"
            );
        }
        // Any one frame decodes alone (from its key frame) to the same picture.
        for k in [0, 4, 5, 7, 11] {
            assert_eq!(v.frame(k).unwrap(), all[k as usize], "frame {k}");
        }
        // Reading with the other matrix is measurably wrong on the colour patches: the test
        // sees a mix-up of BT.601 and BT.709.
        v.color.matrix = if matrix == Matrix::Bt601 {
            Matrix::Bt709
        } else {
            Matrix::Bt601
        };
        let wrong = v.frame(3).unwrap();
        let e = mean_diff(&wrong, &src[3], |x, y| {
            x >= 2 && x + 2 < w / 4 && (y % (h / 4)) >= 3 && (y % (h / 4)) + 3 < h / 4
        });
        assert!(e > 0.02, "{matrix:?} read as the other matrix: {e}");
    }
}

#[test]
fn errors_name_the_file_and_never_panic() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("missing.mp4");
    let e = Video::open(&missing).err().unwrap();
    assert!(matches!(e, VideoError::Io { .. }) && e.to_string().contains("missing.mp4"));

    let junk = dir.path().join("junk.mp4");
    std::fs::write(&junk, b"this is not a video at all, just some text").unwrap();
    let e = Video::open(&junk).err().unwrap();
    assert!(
        matches!(e, VideoError::Container { .. }) && e.to_string().contains("junk.mp4"),
        "{e}"
    );

    let src: Vec<Image> = (0..6).map(|k| pattern(32, 32, k)).collect();
    let good = write(dir.path(), "good.mp4", &src, Matrix::Bt709);
    let bytes = std::fs::read(&good).unwrap();
    let v = Video::open(&good).unwrap();
    let e = v.frame(6).err().unwrap();
    assert!(
        matches!(
            e,
            VideoError::FrameOutOfRange {
                frame: 6,
                count: 6,
                ..
            }
        ),
        "{e}"
    );
    assert!(v.frame(-1).is_err());

    // Truncated anywhere: an error (or, when only the tail of the data is lost, the frames
    // before it), never a panic.
    for cut in [10, 40, bytes.len() / 3, bytes.len() / 2, bytes.len() - 7] {
        let p = dir.path().join(format!("cut{cut}.mp4"));
        std::fs::write(&p, &bytes[..cut]).unwrap();
        match Video::open(&p) {
            Err(e) => assert!(e.to_string().contains(&format!("cut{cut}.mp4")), "{e}"),
            Ok(v) => {
                let _ = v.frames();
            }
        }
    }
    // Corrupted sample data: errors or (concealed) pictures, never a panic.
    let mut bad = bytes.clone();
    let n = bad.len();
    for b in &mut bad[n - 200..n - 100] {
        *b ^= 0x5a;
    }
    let p = dir.path().join("corrupt.mp4");
    std::fs::write(&p, &bad).unwrap();
    if let Ok(v) = Video::open(&p) {
        let _ = v.frames();
    }
    // Another codec: the sample entry renamed to HEVC's.
    let mut hevc = bytes.clone();
    let at = hevc.windows(4).rposition(|w| w == b"avc1").unwrap();
    hevc[at..at + 4].copy_from_slice(b"hvc1");
    let p = dir.path().join("hevc.mp4");
    std::fs::write(&p, &hevc).unwrap();
    let e = Video::open(&p).err().unwrap();
    assert!(e.to_string().contains("hevc.mp4"), "{e}");
    eprintln!("hevc: {e}");
}

/// Regression (fuzzing): a zero-sized child box inside the `avc1` sample entry sent the
/// demuxer into an endless loop; now a clear error naming the file.
#[test]
fn zero_sized_box_in_the_sample_entry_is_an_error_not_a_hang() {
    let dir = tempfile::tempdir().unwrap();
    let src: Vec<Image> = (0..2).map(|k| pattern(32, 32, k)).collect();
    let good = write(dir.path(), "good.mp4", &src, Matrix::Bt601);
    let mut bytes = std::fs::read(&good).unwrap();
    // The avcC box (avc1's child) becomes `free` with size 0.
    let at = bytes.windows(4).position(|w| w == b"avcC").unwrap();
    bytes[at - 4..at + 4].copy_from_slice(&[0, 0, 0, 0, b'f', b'r', b'e', b'e']);
    let p = dir.path().join("zero_box.mp4");
    std::fs::write(&p, &bytes).unwrap();
    let t = std::time::Instant::now();
    let e = Video::open(&p).err().unwrap();
    assert!(
        matches!(e, VideoError::Container { .. }) && e.to_string().contains("zero_box.mp4"),
        "{e}"
    );
    assert!(e.to_string().contains("malformed"), "{e}");
    assert!(t.elapsed().as_secs() < 5, "took {:?}", t.elapsed());
}
