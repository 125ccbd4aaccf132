//! Our image files against OpenImageIO's (scripts/check/oiio_images.py), DPX and TIFF. Every
//! DPX file it
//! writes — 8, 10, 12 and 16 bits, packed and filled methods A and B, both byte orders, 1, 3
//! and 4 channels, an odd width — decodes to the code values it was given (and to what
//! OpenImageIO reads back, but for one datum its reader drops), and every file we write reads
//! in OpenImageIO as the codes we read, with our depth and transfer.
//!
//! The Python comes from `VFXGRAPH_PYTHON_OIIO` (default
//! `~/.cache/vfxgraph/pyenv-oiio/bin/python`), with OpenImageIO and numpy (`pip install
//! openimageio numpy`). Without them the test prints a notice and passes, unless
//! `VFXGRAPH_REQUIRE_CLIENTS=1` (set by `.ci/run`), where it fails.

use std::collections::BTreeMap;
use std::fs;
use std::path::Path;

use vfxgraph_imaging::image::Image;
use vfxgraph_imaging::io::dpx::{self, DpxOptions, Transfer};
use vfxgraph_testdata::{repo, Python};

/// The Python with the clients these checks use.
fn python() -> Python {
    Python::from_env(
        "VFXGRAPH_PYTHON_OIIO",
        "~/.cache/vfxgraph/pyenv-oiio/bin/python",
        "pip install openimageio numpy, or set VFXGRAPH_PYTHON_OIIO",
    )
}

fn oiio(action: &str, dir: &Path) {
    let out = python()
        .command()
        .arg(repo().join("scripts/check/oiio_images.py"))
        .arg(action)
        .arg(dir)
        .output()
        .expect("run python");
    assert!(
        out.status.success(),
        "oiio_images.py {action}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn floats(path: &Path) -> Vec<f32> {
    fs::read(path)
        .unwrap()
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
        .collect()
}

/// The `bits`-bit code of an OpenImageIO float read: it widens codes to 16 bits (by bit
/// replication for 10 bits, a shift for 12) and divides by 65535, so the code is the top
/// `bits` bits of that 16-bit value.
fn oiio_code(v: f32, bits: u8) -> u32 {
    ((v * 65535.0).round() as u32) >> (16 - bits)
}

/// A quarter of one code of `bits` over [0, 1]: OpenImageIO widens 10- and 12-bit codes to
/// 16 bits by bit replication, ~10⁻⁵ from `code / max`; one code apart is 4 of these.
fn quarter_code(bits: u8) -> f32 {
    0.25 / ((1u32 << bits) - 1) as f32
}

/// The largest difference between two sample lists of one length.
fn max_diff(a: &[f32], b: &[f32]) -> f32 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max)
}

#[test]
fn dpx_files_agree_with_openimageio_both_ways() {
    if !python().has("OpenImageIO, numpy") {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();

    // Theirs, read by us.
    oiio("write", dir);
    let cases: BTreeMap<String, serde_json::Value> =
        serde_json::from_slice(&fs::read(dir.join("cases.json")).unwrap()).unwrap();
    assert!(cases.len() >= 30, "{} cases", cases.len());
    for (name, c) in cases.iter().filter(|(n, _)| n.ends_with(".dpx")) {
        let bytes = fs::read(dir.join(name)).unwrap();
        let (img, info) = dpx::decode_codes(&bytes).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(
            (
                img.width as u64,
                img.height as u64,
                img.channels as u64,
                info.bits as u64
            ),
            (
                c["width"].as_u64().unwrap(),
                c["height"].as_u64().unwrap(),
                c["channels"].as_u64().unwrap(),
                c["bits"].as_u64().unwrap()
            ),
            "{name}"
        );
        assert_eq!(info.transfer, 1, "{name}: printing density");
        let given = floats(&dir.join(format!("{name}.codes.f32")));
        let d = max_diff(&img.data, &given);
        assert!(d < quarter_code(info.bits), "{name}: codes differ by {d}");
        // OpenImageIO's own reading of its file agrees, but for the last datum of a line
        // whose 10-bit datums do not fill the last word (it reads 0 there).
        let theirs = floats(&dir.join(format!("{name}.f32")));
        let odd_tail = info.bits == 10 && (img.width * img.channels) % 3 != 0;
        let max = ((1u32 << info.bits) - 1) as f32;
        for (i, (a, b)) in img.data.iter().zip(&theirs).enumerate() {
            let last = (i + 1) % (img.width * img.channels) == 0;
            if !(odd_tail && last) {
                let (ours, theirs) = ((a * max).round() as u32, oiio_code(*b, info.bits));
                assert_eq!(ours, theirs, "{name}: sample {i}");
            }
        }
    }

    // Ours, read by them.
    let mut ours = Vec::new();
    for (bits, transfer, channels) in [
        (8u8, Transfer::Srgb, 3usize),
        (10, Transfer::PrintingDensity, 3),
        (10, Transfer::PrintingDensity, 1),
        (10, Transfer::Linear, 4),
        (12, Transfer::Bt709, 3),
        (16, Transfer::Linear, 3),
        (16, Transfer::PrintingDensity, 4),
    ] {
        let (w, h) = (9, 4);
        let mut img = Image::new(w, h, channels);
        for (i, v) in img.data.iter_mut().enumerate() {
            *v = ((i * 37) % 101) as f32 / 100.0;
        }
        let bytes = dpx::encode(&img, &DpxOptions { bits, transfer }).unwrap();
        let name = format!("ours_{bits}_{}_{channels}.dpx", transfer.code());
        fs::write(dir.join(&name), &bytes).unwrap();
        ours.push((name, bits, transfer, bytes));
    }
    oiio("read", dir);
    for (name, bits, transfer, bytes) in ours {
        let info: serde_json::Value =
            serde_json::from_slice(&fs::read(dir.join(format!("{name}.json"))).unwrap()).unwrap();
        let (codes, _) = dpx::decode_codes(&bytes).unwrap();
        assert_eq!(info["bits"].as_u64(), Some(bits as u64), "{name}: {info}");
        assert_eq!(
            info["channels"].as_u64(),
            Some(codes.channels as u64),
            "{name}"
        );
        let want = match transfer {
            Transfer::PrintingDensity => "Printing density",
            Transfer::Linear => "Linear",
            Transfer::Bt709 => "ITU-R 709-4",
            Transfer::Srgb => "User defined",
        };
        assert_eq!(info["transfer"].as_str(), Some(want), "{name}: {info}");
        let theirs = floats(&dir.join(format!("{name}.f32")));
        assert_eq!(theirs.len(), codes.data.len(), "{name}");
        let max = ((1u32 << bits) - 1) as f32;
        for (i, (a, b)) in codes.data.iter().zip(&theirs).enumerate() {
            assert_eq!(
                (a * max).round() as u32,
                oiio_code(*b, bits),
                "{name}: sample {i}: OpenImageIO reads another code"
            );
        }
    }
}

/// TIFF: every file OpenImageIO writes (8/16-bit, float; none, LZW, Deflate; 1, 3, 4
/// channels) reads as the samples it was given — integer codes through the sRGB curve, floats
/// as they are — and ours read in OpenImageIO as the codes and floats we wrote, with the
/// compression we chose.
#[test]
fn tiff_files_agree_with_openimageio_both_ways() {
    use vfxgraph_imaging::color::linear_to_srgb;
    use vfxgraph_imaging::io::tiff::{self, TiffCompression, TiffDepth, TiffOptions};
    if !python().has("OpenImageIO, numpy") {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    oiio("write", dir);
    let cases: BTreeMap<String, serde_json::Value> =
        serde_json::from_slice(&fs::read(dir.join("cases.json")).unwrap()).unwrap();
    let tiffs: Vec<_> = cases.iter().filter(|(n, _)| n.ends_with(".tif")).collect();
    assert_eq!(tiffs.len(), 27);
    for (name, c) in tiffs {
        let img = tiff::decode(&fs::read(dir.join(name)).unwrap())
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(
            img.channels as u64,
            c["channels"].as_u64().unwrap(),
            "{name}"
        );
        let given = floats(&dir.join(format!("{name}.codes.f32")));
        let bits = c["bits"].as_u64().unwrap();
        for (i, (a, g)) in img.data.iter().zip(&given).enumerate() {
            let alpha = img.channels == 4 && i % 4 == 3;
            let ours = if bits == 32 || alpha {
                *a
            } else {
                linear_to_srgb(*a)
            };
            let tol = if bits == 32 { 0.0 } else { 1e-5 };
            assert!(
                (ours - g).abs() <= tol,
                "{name}: sample {i}: {ours} for {g}"
            );
        }
    }

    let mut img = Image::new(13, 5, 4);
    for (i, v) in img.data.iter_mut().enumerate() {
        *v = ((i * 29) % 103) as f32 / 80.0;
    }
    for depth in [TiffDepth::U8, TiffDepth::U16, TiffDepth::F32] {
        for compression in [
            TiffCompression::None,
            TiffCompression::Lzw,
            TiffCompression::Deflate,
        ] {
            for channels in [1usize, 3, 4] {
                let mut im = Image::new(13, 5, channels);
                for (p, q) in im
                    .data
                    .chunks_exact_mut(channels)
                    .zip(img.data.chunks_exact(4))
                {
                    p.copy_from_slice(&q[..channels]);
                }
                let name = format!("ours_{depth:?}_{compression:?}_{channels}.tif");
                let bytes = tiff::encode(&im, &TiffOptions { depth, compression }).unwrap();
                fs::write(dir.join(&name), bytes).unwrap();
            }
        }
    }
    oiio("read", dir);
    for depth in [TiffDepth::U8, TiffDepth::U16, TiffDepth::F32] {
        for compression in [
            TiffCompression::None,
            TiffCompression::Lzw,
            TiffCompression::Deflate,
        ] {
            for channels in [1usize, 3, 4] {
                let name = format!("ours_{depth:?}_{compression:?}_{channels}.tif");
                let ours = tiff::decode(&fs::read(dir.join(&name)).unwrap()).unwrap();
                let info: serde_json::Value =
                    serde_json::from_slice(&fs::read(dir.join(format!("{name}.json"))).unwrap())
                        .unwrap();
                let want = match compression {
                    TiffCompression::None => "none",
                    TiffCompression::Lzw => "lzw",
                    TiffCompression::Deflate => "zip",
                };
                assert_eq!(info["compression"].as_str(), Some(want), "{name}: {info}");
                assert_eq!(info["channels"].as_u64(), Some(channels as u64), "{name}");
                let theirs = floats(&dir.join(format!("{name}.f32")));
                assert_eq!(theirs.len(), ours.data.len(), "{name}");
                let max = match depth {
                    TiffDepth::U8 => 255.0,
                    TiffDepth::U16 => 65535.0,
                    TiffDepth::F32 => 0.0,
                };
                for (i, (a, b)) in ours.data.iter().zip(&theirs).enumerate() {
                    let alpha = channels == 4 && i % 4 == 3;
                    if max == 0.0 {
                        assert_eq!(a, b, "{name}: sample {i}");
                    } else {
                        let code = if alpha { *a } else { linear_to_srgb(*a) };
                        assert!(
                            (code - b).abs() < 0.25 / max,
                            "{name}: sample {i}: OpenImageIO reads {b}, ours {code}"
                        );
                    }
                }
            }
        }
    }
}

/// The focal length in JPEGs whose EXIF OpenImageIO wrote: the focal plane's resolution (35 mm
/// on a 23.5 mm sensor 600 px across: 893.6 px) and a phone's 35 mm equivalent (26 mm on a
/// 400 × 300 frame: the same diagonal field of view as 26 mm on 36 × 24 mm).
#[test]
fn exif_focal_lengths_written_by_openimageio() {
    use vfxgraph_imaging::metadata::{camera_focal, FocalSource};
    if !python().has("OpenImageIO, numpy") {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    oiio("write", tmp.path());
    let f = camera_focal(&fs::read(tmp.path().join("camera.jpg")).unwrap(), 600, 400).unwrap();
    assert_eq!(f.source, FocalSource::FocalPlane);
    let want = 35.0 * 600.0 / 23.5;
    assert!((f.pixels - want).abs() < 1e-4 * want, "{f:?}: {want}");
    let f = camera_focal(&fs::read(tmp.path().join("phone.jpg")).unwrap(), 400, 300).unwrap();
    assert_eq!(f.source, FocalSource::Equivalent35mm);
    let fov = 2.0 * (36f64.hypot(24.0) / 2.0 / 26.0).atan();
    let ours = 2.0 * (500.0 / 2.0 / f.pixels).atan();
    assert!((fov - ours).abs() < 1e-9, "{fov} {ours}");
    assert!((f.millimetres.unwrap() - 4.2).abs() < 1e-6);
}
