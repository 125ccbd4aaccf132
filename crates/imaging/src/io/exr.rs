//! OpenEXR through the `exr` crate (the file layout of "OpenEXR File Layout", openexr.com, and
//! Kainz, Bogart & Hess, *The OpenEXR Image File Format*, GPU Gems, 2004).
//!
//! # Reading
//! Scanline and tiled files, single- and multi-part, with any compression the `exr` crate decodes
//! (NONE, RLE, ZIPS, ZIP, PIZ, PXR24, B44, B44A, DWAA/DWAB where supported); HALF, FLOAT and UINT
//! channels (UINT values are converted to `f32` as they are, not normalised). Mip/rip-mapped
//! files give their full-resolution level.
//!
//! **Which channels.** The first part that has channels named exactly `R`, `G` and `B` gives an
//! RGB image (RGBA with its `A`). Otherwise the first part is used: its `Y` (luminance) channel
//! gives a gray image (RGBA with `A`, the gray replicated); failing that, its first channel in
//! alphabetical order (the file's own order) gives a gray image. Subsampled channels (4:2:0
//! chroma `RY`/`BY`) are never selected.
//!
//! **Data window vs display window.** An EXR part stores pixels for its *data window*; the
//! *display window* is the frame the picture is meant to be seen in. The decoded image is the
//! display window: `width × height` = the display window's size, pixel `(0, 0)` its top-left
//! corner; data pixels are placed at their offset from it, data outside the display window is
//! cropped, and display pixels outside the data window are 0 (transparent black). The pixel
//! aspect ratio is ignored (pixels are returned unstretched).
//!
//! **Deep data** (OpenEXR 2 `deepscanline` / `deeptile` parts) is not supported: such files give
//! [`ImageError::DeepData`].
//!
//! # Writing
//! One scanline part, RGB/RGBA (or `Y`/`Y`+`A` for gray), FLOAT or HALF samples, with a lossless
//! compression (ZIP by default, PIZ or none on request); data window = display window.

use std::io::Cursor;

use exr::image::{AnyChannel, AnyChannels, Encoding, FlatSamples, Layer};
use exr::meta::attribute::LineOrder;
use exr::meta::header::LayerAttributes;
use exr::meta::MetaData;
use exr::prelude::{f16, Blocks, Compression, ReadChannels, ReadLayers, SmallVec, WritableImage};

use super::{check_encodable, guard, Format};
use crate::error::ImageError;
use crate::image::{sample_count, Image};

/// Sample precision of written EXR files.
#[derive(
    Clone,
    Copy,
    Debug,
    PartialEq,
    Eq,
    Hash,
    Default,
    serde::Serialize,
    serde::Deserialize,
    vfxgraph_params::Choice,
)]
#[serde(rename_all = "lowercase")]
pub enum ExrPrecision {
    /// 16-bit half float (IEEE 754-2008 binary16): 11-bit precision, range ±65504.
    Half,
    /// 32-bit IEEE float: exact.
    #[default]
    Float,
}

/// Lossless compression of written EXR files.
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, Hash, Default, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "lowercase")]
pub enum ExrCompression {
    /// No compression.
    None,
    /// Deflate over blocks of 16 scanlines (OpenEXR `ZIP_COMPRESSION`).
    #[default]
    Zip,
    /// Wavelet + Huffman (OpenEXR `PIZ_COMPRESSION`), good on noisy photographic data.
    Piz,
}

/// Options of [`encode_exr`].
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, Hash, Default, serde::Serialize, serde::Deserialize,
)]
pub struct ExrOptions {
    /// Sample type of every channel.
    pub precision: ExrPrecision,
    /// Compression of the pixel data.
    pub compression: ExrCompression,
}

/// The largest display window (in RGBA samples: 8192 × 8192) decoded around a smaller data
/// window: 1 GiB as f32, the bound every reader of a user file is fuzzed against.
const ZERO_FILLED_SAMPLES: u128 = 1 << 28;

fn err(reason: impl Into<String>) -> ImageError {
    ImageError::decode(Format::Exr, reason)
}

fn map_exr_error(e: exr::error::Error) -> ImageError {
    match e {
        exr::error::Error::NotSupported(what) if what.contains("deep") => {
            ImageError::DeepData(what.into_owned())
        }
        exr::error::Error::NotSupported(what) if what.contains("subsampling") => err(
            "subsampled channels (e.g. the RY/BY chroma of luminance/chroma files) are not \
             supported by the exr crate",
        ),
        other => err(other.to_string()),
    }
}

/// The most bytes of samples one byte of an OpenEXR file can expand to, per compression, with
/// a factor 2 to spare: uncompressed 1; RLE 128 bytes from 2; zlib (ZIP, and PIZ whose Huffman
/// run-length codes do less) 1032:1; PXR24 zlib over 3-byte floats; B44A flat blocks 32 bytes
/// in 3; DWA DC-only 8×8 blocks (64:1) then zlib. HTJ2K: no bound.
fn max_expansion(c: exr::compression::Compression) -> Option<u128> {
    use exr::compression::Compression::*;
    Some(match c {
        Uncompressed => 2,
        RLE => 128,
        ZIP1 | ZIP16 | PIZ => 2 * 1032,
        PXR24 => 2 * 1032 * 4 / 3,
        B44 | B44A => 2 * 11,
        DWAA(_) | DWAB(_) => 2 * 64 * 1032,
        HTJ2K32 | HTJ2K256 => return None,
    })
}

/// Decode OpenEXR bytes (see the module documentation for channel selection and windows).
pub fn decode(bytes: &[u8]) -> Result<Image, ImageError> {
    decode_layer(bytes, "")
}

/// Decode the layer `name` of a multi-layer file (channels `name.R`, `name.G`, `name.B`
/// [+ `name.A`], or `name.Y` [+ `name.A`]); `""` is the bare-named layer, as [`decode`].
pub fn decode_layer(bytes: &[u8], name: &str) -> Result<Image, ImageError> {
    if !bytes.starts_with(&[0x76, 0x2F, 0x31, 0x01]) {
        return Err(err("missing the OpenEXR magic number 76 2f 31 01"));
    }
    // Version field: bit 11 ("non-image") is set when any part holds deep data.
    if bytes.get(5).is_some_and(|flags| flags & 0x08 != 0) {
        return Err(ImageError::DeepData(
            "the file's version field flags deep data (OpenEXR 2 deepscanline/deeptile parts)"
                .into(),
        ));
    }
    let meta = guard(Format::Exr, || {
        MetaData::read_from_buffered(Cursor::new(bytes), false).map_err(map_exr_error)
    })?;
    if let Some(h) = meta.headers.iter().find(|h| h.deep) {
        let name = h
            .own_attributes
            .layer_name
            .as_ref()
            .map(|n| format!(" {:?}", n.to_string()))
            .unwrap_or_default();
        return Err(ImageError::DeepData(format!(
            "part{name} holds deep data (several samples per pixel)"
        )));
    }
    for h in meta.headers.iter() {
        let size = h.shared_attributes.display_window.size;
        sample_count(size.0, size.1, 4)
            .and_then(|_| sample_count(h.layer_size.0, h.layer_size.1, 4))
            .map_err(|e| err(format!("window too large: {e}")))?;
        if size.0 == 0 || size.1 == 0 {
            return Err(err("empty display window"));
        }
        // The display window is zero-filled around the data window, and nothing in the file
        // codes that: a frame larger than its data window is bounded by ZERO_FILLED_SAMPLES
        // (a 1 KB file declared a display window 16 M pixels wide around 9 × 5 of data).
        let display = size.0 as u128 * size.1 as u128 * 4;
        let data = h.layer_size.0 as u128 * h.layer_size.1 as u128 * 4;
        if display > data && display > ZERO_FILLED_SAMPLES {
            return Err(err(format!(
                "display window {}x{} around a data window {}x{}: the zero-filled frame is \
                 over {ZERO_FILLED_SAMPLES} samples",
                size.0, size.1, h.layer_size.0, h.layer_size.1
            )));
        }
        // The decoder sizes the data window's samples before reading a block: refuse a window
        // the file is too short to hold at its compression's best ratio.
        let sample_bytes: u128 = h
            .channels
            .list
            .iter()
            .map(|c| c.sample_type.bytes_per_sample() as u128)
            .sum::<u128>()
            * h.layer_size.0 as u128
            * h.layer_size.1 as u128;
        if let Some(x) = max_expansion(h.compression) {
            if sample_bytes > x * bytes.len() as u128 + (1 << 16) {
                return Err(err(format!(
                    "data window {}x{} ({} channels, {}) holds {sample_bytes} bytes of samples: \
                     more than a {}-byte file can ({x}:1 at most)",
                    h.layer_size.0,
                    h.layer_size.1,
                    h.channels.list.len(),
                    h.compression,
                    bytes.len()
                )));
            }
        }
    }
    let image = guard(Format::Exr, || {
        exr::prelude::read()
            .no_deep_data()
            .largest_resolution_level()
            .all_channels()
            .all_layers()
            .all_attributes()
            // Sequential decompression: exr's parallel mode runs blocks in `rayon::spawn`ed jobs
            // of a pool it builds per file, where a decoder panic would abort the process rather
            // than reach `guard`; vfxgraph parallelises across nodes and frames instead.
            .non_parallel()
            .from_buffered(Cursor::new(bytes))
            .map_err(map_exr_error)
    })?;
    let display = image.attributes.display_window;
    let layers: &[Layer<AnyChannels<FlatSamples>>] = &image.layer_data;
    let (layer, picked) = pick_channels(layers, name)?;
    let channels = picked.len();
    let (dw, dh) = (display.size.0, display.size.1);
    let mut out = Image::try_new(dw, dh, channels)?;
    let (lw, lh) = (layer.size.0, layer.size.1);
    // Offset of the data window's origin inside the display window.
    let ox = layer.attributes.layer_position.0 as i64 - display.position.0 as i64;
    let oy = layer.attributes.layer_position.1 as i64 - display.position.1 as i64;
    for (c, source) in picked.iter().enumerate() {
        let source = &layer.channel_data.list[*source].sample_data;
        if source.len() != lw * lh {
            return Err(err("channel sample count does not match its data window"));
        }
        let value = |i: usize| -> f32 {
            match source {
                FlatSamples::F16(v) => v[i].to_f32(),
                FlatSamples::F32(v) => v[i],
                FlatSamples::U32(v) => v[i] as f32,
            }
        };
        for y in 0..lh {
            let ty = y as i64 + oy;
            if ty < 0 || ty >= dh as i64 {
                continue;
            }
            for x in 0..lw {
                let tx = x as i64 + ox;
                if tx < 0 || tx >= dw as i64 {
                    continue;
                }
                let i = (ty as usize * dw + tx as usize) * channels + c;
                out.data[i] = value(y * lw + x);
            }
        }
    }
    // Y + A: replicate the gray so decoded images have 1, 3 or 4 channels.
    if channels == 2 {
        out = out.to_rgba();
    }
    Ok(out)
}

/// Choose the part and the channel indices (R, G, B[, A] / Y[, A] / one channel).
fn pick_channels<'a>(
    layers: &'a [Layer<AnyChannels<FlatSamples>>],
    prefix: &str,
) -> Result<(&'a Layer<AnyChannels<FlatSamples>>, Vec<usize>), ImageError> {
    let find = |layer: &Layer<AnyChannels<FlatSamples>>, name: &str| {
        let full = if prefix.is_empty() {
            name.to_string()
        } else {
            format!("{prefix}.{name}")
        };
        layer
            .channel_data
            .list
            .iter()
            .position(|c| c.name.eq(full.as_str()) && c.sampling == exr::math::Vec2(1, 1))
    };
    for layer in layers {
        if let (Some(r), Some(g), Some(b)) = (find(layer, "R"), find(layer, "G"), find(layer, "B"))
        {
            let mut v = vec![r, g, b];
            v.extend(find(layer, "A"));
            return Ok((layer, v));
        }
    }
    if !prefix.is_empty() {
        for layer in layers {
            if let Some(y) = find(layer, "Y") {
                let mut v = vec![y];
                v.extend(find(layer, "A"));
                return Ok((layer, v));
            }
        }
        let mut names: Vec<String> = layers
            .iter()
            .flat_map(|l| l.channel_data.list.iter().map(|c| c.name.to_string()))
            .filter_map(|n| n.rsplit_once('.').map(|(l, _)| l.to_string()))
            .collect();
        names.dedup();
        return Err(err(format!(
            "no layer `{prefix}` (layers: {})",
            if names.is_empty() {
                "none".into()
            } else {
                names.join(", ")
            }
        )));
    }
    let layer = layers.first().ok_or_else(|| err("the file has no parts"))?;
    if let Some(y) = find(layer, "Y") {
        let mut v = vec![y];
        v.extend(find(layer, "A"));
        return Ok((layer, v));
    }
    let first = layer
        .channel_data
        .list
        .iter()
        .position(|c| c.sampling == exr::math::Vec2(1, 1))
        .ok_or_else(|| err("the first part has no full-resolution channel"))?;
    Ok((layer, vec![first]))
}

/// Encode as a single-part scanline OpenEXR file with the given precision and (lossless)
/// compression. Channel names: `R`, `G`, `B` (+ `A`) for colour, `Y` (+ `A`) for gray.
pub fn encode_exr(img: &Image, options: &ExrOptions) -> Result<Vec<u8>, ImageError> {
    encode_exr_layers(&[("", img)], options)
}

/// How `write_layers` writes a multi-layer file: half floats unless asked (a compositor's
/// layers rarely need more).
#[derive(Clone, Copy, Debug, PartialEq, vfxgraph_params::Options)]
pub struct LayersOptions {
    /// sample type
    pub precision: ExrPrecision,
}

impl Default for LayersOptions {
    fn default() -> Self {
        LayersOptions {
            precision: ExrPrecision::Half,
        }
    }
}

impl LayersOptions {
    /// The EXR options: `precision`, the default compression.
    pub fn exr(&self) -> ExrOptions {
        ExrOptions {
            precision: self.precision,
            ..Default::default()
        }
    }

    /// Encodes named layers of one size as `write_layers` writes them: the first also under
    /// the bare channel names (what viewers show), then each under its name.
    pub fn encode(&self, layers: &[(String, Image)]) -> Result<Vec<u8>, ImageError> {
        let (_, first) = layers
            .first()
            .ok_or_else(|| ImageError::encode(Format::Exr, "no layers to write"))?;
        let mut named: Vec<(&str, &Image)> = vec![("", first)];
        named.extend(layers.iter().map(|(n, i)| (n.as_str(), i)));
        encode_exr_layers(&named, &self.exr())
    }
}

/// Encode named layers of one size as a single-part multi-layer OpenEXR file (the layout
/// Nuke, Blender and OpenImageIO read as layers): layer `name`'s channels are `name.R`,
/// `name.G`, … ; a layer named `""` gets the bare `R`, `G`, `B` (+ `A`) names and is what
/// single-layer readers (and [`decode`]) show.
pub fn encode_exr_layers(
    layers: &[(&str, &Image)],
    options: &ExrOptions,
) -> Result<Vec<u8>, ImageError> {
    let first = layers
        .first()
        .ok_or_else(|| ImageError::encode(Format::Exr, "no layers to write"))?
        .1;
    let mut list: SmallVec<[AnyChannel<FlatSamples>; 4]> = SmallVec::new();
    let mut seen = std::collections::HashSet::new();
    for (layer, img) in layers {
        check_encodable(img, Format::Exr)?;
        if (img.width, img.height) != (first.width, first.height) {
            return Err(ImageError::encode(
                Format::Exr,
                format!(
                    "layer `{layer}` is {}×{} but the first layer is {}×{}",
                    img.width, img.height, first.width, first.height
                ),
            ));
        }
        if !seen.insert(*layer) {
            return Err(ImageError::encode(
                Format::Exr,
                format!("layer `{layer}` appears twice"),
            ));
        }
        let names: &[&str] = match img.channels {
            1 => &["Y"],
            2 => &["Y", "A"],
            3 => &["R", "G", "B"],
            _ => &["R", "G", "B", "A"],
        };
        let n = img.pixel_count();
        for (c, name) in names.iter().enumerate() {
            let plane = (0..n).map(|i| img.data[i * img.channels + c]);
            let samples = match options.precision {
                ExrPrecision::Float => FlatSamples::F32(plane.collect()),
                ExrPrecision::Half => FlatSamples::F16(plane.map(f16::from_f32).collect()),
            };
            let full = if layer.is_empty() {
                name.to_string()
            } else {
                format!("{layer}.{name}")
            };
            list.push(AnyChannel::new(full.as_str(), samples));
        }
    }
    let img = first;
    let compression = match options.compression {
        ExrCompression::None => Compression::Uncompressed,
        ExrCompression::Zip => Compression::ZIP16,
        ExrCompression::Piz => Compression::PIZ,
    };
    let layer = Layer::new(
        (img.width, img.height),
        LayerAttributes::default(),
        Encoding {
            compression,
            blocks: Blocks::ScanLines,
            line_order: LineOrder::Increasing,
        },
        AnyChannels::sort(list),
    );
    let image = exr::image::Image::from_layer(layer);
    let mut out = Vec::new();
    image
        .write()
        .to_buffered(Cursor::new(&mut out))
        .map_err(|e| ImageError::encode(Format::Exr, e.to_string()))?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::{Path, PathBuf};

    /// The ILM samples (every listed file present), or `None` when absent (see
    /// `vfxgraph_testdata`).
    fn samples_dir() -> Option<PathBuf> {
        vfxgraph_testdata::path("openexr_images_subset")
    }

    fn all_exr_files(dir: &Path) -> Vec<PathBuf> {
        let mut out = Vec::new();
        let mut stack = vec![dir.to_path_buf()];
        while let Some(d) = stack.pop() {
            for e in std::fs::read_dir(&d).unwrap().flatten() {
                let p = e.path();
                if p.is_dir() {
                    stack.push(p);
                } else if p.extension().is_some_and(|e| e == "exr") {
                    out.push(p);
                }
            }
        }
        out.sort();
        out
    }

    /// Decoded image and the first header of a sample file.
    fn load(path: &Path) -> (Result<Image, ImageError>, exr::meta::header::Header) {
        let bytes = std::fs::read(path).unwrap();
        let meta = MetaData::read_from_buffered(Cursor::new(&bytes), false).unwrap();
        (decode(&bytes), meta.headers[0].clone())
    }

    fn bits(img: &Image) -> Vec<u32> {
        img.data.iter().map(|v| v.to_bits()).collect()
    }

    /// Files of the subset that are expected not to decode, and a word their error must contain.
    const EXPECTED_FAILURES: [(&str, &str); 1] = [("Chromaticities/Rec709_YC.exr", "subsampled")];

    #[test]
    fn every_sample_file_decodes_or_fails_clearly() {
        let Some(dir) = samples_dir() else { return };
        let files = all_exr_files(&dir);
        assert!(
            files.len() >= 39,
            "expected 39 sample files, found {}",
            files.len()
        );
        let mut failures = Vec::new();
        for p in &files {
            let rel = p
                .strip_prefix(&dir)
                .unwrap()
                .to_string_lossy()
                .replace('\\', "/");
            let (result, header) = load(p);
            match result {
                Ok(img) => {
                    let size = header.shared_attributes.display_window.size;
                    assert_eq!((img.width, img.height), (size.0, size.1), "{rel}");
                    assert!(matches!(img.channels, 1 | 3 | 4), "{rel}");
                    assert!(img.finite_range().is_some(), "{rel}: no finite sample");
                }
                Err(e) => {
                    let (_, word) = EXPECTED_FAILURES
                        .iter()
                        .find(|(name, _)| *name == rel)
                        .unwrap_or_else(|| panic!("{rel} failed unexpectedly: {e}"));
                    assert!(matches!(
                        e,
                        ImageError::Decode { .. } | ImageError::DeepData(_)
                    ));
                    assert!(e.to_string().contains(word), "{rel}: {e}");
                    failures.push(rel);
                }
            }
        }
        assert_eq!(failures.len(), EXPECTED_FAILURES.len(), "{failures:?}");
    }

    #[test]
    fn display_window_files_place_data_at_its_offset() {
        let Some(dir) = samples_dir() else { return };
        let dw = dir.join("DisplayWindow");
        let (reference, ref_header) = load(&dw.join("t01.exr"));
        let reference = reference.unwrap();
        assert_eq!((reference.width, reference.height), (400, 300));
        assert_eq!(
            ref_header.own_attributes.layer_position,
            exr::math::Vec2(0, 0)
        );
        for i in 1..=16 {
            let (img, h) = load(&dw.join(format!("t{i:02}.exr")));
            let img = img.unwrap();
            let disp = h.shared_attributes.display_window;
            assert_eq!(
                (img.width, img.height),
                (disp.size.0, disp.size.1),
                "t{i:02}"
            );
            assert_eq!(
                h.layer_size,
                exr::math::Vec2(400, 300),
                "all hold the same pixels"
            );
            let data_pos = h.own_attributes.layer_position;
            let mut inside = 0;
            for y in 0..img.height {
                for x in 0..img.width {
                    // Position in the data window (= in t01's pixels).
                    let dx = x as i64 + disp.position.0 as i64 - data_pos.0 as i64;
                    let dy = y as i64 + disp.position.1 as i64 - data_pos.1 as i64;
                    let expect: &[f32] = if (0..400).contains(&dx) && (0..300).contains(&dy) {
                        inside += 1;
                        reference.pixel(dx as usize, dy as usize)
                    } else {
                        &[0.0; 3]
                    };
                    assert_eq!(img.pixel(x, y), expect, "t{i:02} ({x}, {y})");
                }
            }
            match i {
                1 => assert_eq!(img, reference),
                // No overlap: the whole display window is background.
                9..=12 => {
                    assert_eq!(inside, 0, "t{i:02}");
                    assert!(img.data.iter().all(|&v| v == 0.0));
                }
                // One pixel in common: data's lower right at the display's upper left ...
                13 => {
                    assert_eq!(inside, 1);
                    assert_eq!(img.pixel(0, 0), reference.pixel(399, 299));
                }
                // ... and data's upper left at the display's lower right.
                14 => {
                    assert_eq!(inside, 1);
                    assert_eq!(img.pixel(100, 100), reference.pixel(0, 0));
                }
                _ => assert!(inside > 0, "t{i:02}"),
            }
        }
    }

    #[test]
    fn compressions_and_line_orders_decode_identically() {
        let Some(dir) = samples_dir() else { return };
        let t = dir.join("IlmfmlmflmTest");
        let none = load(&t.join("comp_none.exr")).0.unwrap();
        assert_eq!((none.width, none.height, none.channels), (587, 675, 4));
        for other in ["comp_zip.exr", "comp_piz.exr"] {
            let img = load(&t.join(other)).0.unwrap();
            assert_eq!(bits(&img), bits(&none), "{other}");
        }
        let inc = load(&t.join("lineOrder_increasing.exr")).0.unwrap();
        let dec = load(&t.join("lineOrder_decreasing.exr")).0.unwrap();
        assert_eq!(bits(&inc), bits(&dec));
        // Old-format files with a data window inside the display window: outside is zero.
        for f in ["v1.7.test.1.exr", "v1.7.test.planar.exr"] {
            let (img, h) = load(&t.join(f));
            let img = img.unwrap();
            assert_eq!((img.width, img.height, img.channels), (217, 197, 3), "{f}");
            let pos = h.own_attributes.layer_position;
            assert_eq!((pos.0, pos.1), (20, 20));
            assert!(img.pixel(0, 0).iter().all(|&v| v == 0.0), "{f}");
            assert!(img.pixel(216, 196).iter().all(|&v| v == 0.0), "{f}");
            assert!(img.data.iter().any(|&v| v > 0.0), "{f}");
        }
        // A tiled file with G and Z only: no RGB, no Y, so its first channel (G) as gray.
        let tiled = load(&t.join("v1.7.test.tiled.exr")).0.unwrap();
        assert_eq!((tiled.width, tiled.height, tiled.channels), (217, 197, 1));
    }

    #[test]
    fn test_images_have_their_documented_values() {
        let Some(dir) = samples_dir() else { return };
        let t = dir.join("TestImages");
        // Every 16-bit half value, NaN and ±∞ included.
        let all = load(&t.join("AllHalfValues.exr")).0.unwrap();
        assert_eq!((all.width, all.height, all.channels), (256, 256, 3));
        // Every non-NaN half appears (65536 - 2046 patterns); each of the 65536 pixels holds one
        // half value in R, G and B alike, so the 2046 NaN encodings give 3 x 2046 NaN samples.
        let mut seen = vec![false; 65536];
        for &v in all.data.iter().filter(|v| !v.is_nan()) {
            seen[f16::from_f32(v).to_bits() as usize] = true;
        }
        let non_nan = (0..=u16::MAX).filter(|&b| !f16::from_bits(b).is_nan());
        assert!(
            non_nan.clone().all(|b| seen[b as usize]),
            "a half value is missing"
        );
        assert_eq!(non_nan.count(), 65536 - 2046);
        assert!(all.data.contains(&f32::INFINITY) && all.data.contains(&f32::NEG_INFINITY));
        assert_eq!(all.data.iter().filter(|v| v.is_nan()).count(), 3 * 2046);
        // Written back as HALF, every sample is bit-identical; as FLOAT too.
        for precision in [ExrPrecision::Half, ExrPrecision::Float] {
            let opts = ExrOptions {
                precision,
                compression: ExrCompression::Piz,
            };
            let back = decode(&encode_exr(&all, &opts).unwrap()).unwrap();
            assert_eq!(bits(&back), bits(&all), "{precision:?}");
        }
        // A single FLOAT G channel spanning about ±1e38.
        let wide = load(&t.join("WideFloatRange.exr")).0.unwrap();
        assert_eq!(wide.channels, 1);
        let (lo, hi) = wide.finite_range().unwrap();
        assert!(lo < -1e38 && hi > 1e38, "{lo} .. {hi}");
        // Rings over 1000 on gray; the NaN/Inf variant differs in a few central pixels only.
        let rings = load(&t.join("BrightRings.exr")).0.unwrap();
        let (lo, hi) = rings.finite_range().unwrap();
        assert!(hi > 1000.0 && lo > 0.0, "{lo} .. {hi}");
        let naninf = load(&t.join("BrightRingsNanInf.exr")).0.unwrap();
        let mut differing = 0;
        for y in 0..800 {
            for x in 0..800 {
                let (a, b) = (rings.pixel(x, y), naninf.pixel(x, y));
                if a.iter().zip(b).any(|(p, q)| p.to_bits() != q.to_bits()) {
                    differing += 1;
                    assert!(x.abs_diff(400) < 100 && y.abs_diff(400) < 100, "({x}, {y})");
                    assert!(b.iter().any(|v| !v.is_finite()));
                }
            }
        }
        assert!((1..100).contains(&differing), "{differing} pixels differ");
        // Out-of-gamut colours are negative RGB.
        let wcg = load(&t.join("WideColorGamut.exr")).0.unwrap();
        assert!(wcg.finite_range().unwrap().0 < 0.0);
        // Gray ramps are a single Y channel.
        let ramp = load(&t.join("GrayRampsHorizontal.exr")).0.unwrap();
        assert_eq!(ramp.channels, 1);
    }

    #[test]
    fn multiresolution_and_photographs_give_full_resolution() {
        let Some(dir) = samples_dir() else { return };
        let cases = [
            ("MultiResolution/StageEnvLatLong.exr", 1000, 500, 3),
            ("MultiResolution/KernerEnvLatLong.exr", 1024, 512, 4),
            ("MultiResolution/ColorCodedLevels.exr", 512, 512, 4),
            ("ScanLines/Cannon.exr", 780, 566, 3),
        ];
        for (f, w, h, c) in cases {
            let img = load(&dir.join(f)).0.unwrap();
            assert_eq!((img.width, img.height, img.channels), (w, h, c), "{f}");
            assert!(img.data.iter().all(|v| v.is_finite()), "{f}");
        }
        // The environment maps are HDR: far brighter than 1 somewhere (light sources).
        let kerner = load(&dir.join("MultiResolution/KernerEnvLatLong.exr"))
            .0
            .unwrap();
        assert!(kerner.finite_range().unwrap().1 > 100.0);
        assert!(kerner.alpha().unwrap().data.iter().all(|&a| a == 1.0));
    }

    fn gradient(w: usize, h: usize, ch: usize) -> Image {
        Image::from_fn(w, h, ch, |x, y, c| {
            (x as f32 + 0.25) * 1.7 - (y as f32) * 3.1e3 + c as f32 * 1e-4
        })
    }

    #[test]
    fn float_round_trip_is_exact_for_all_layouts_and_compressions() {
        for ch in 1..=4 {
            let mut img = gradient(13, 7, ch);
            img.data[0] = f32::NAN;
            img.data[1] = f32::INFINITY;
            img.data[2] = 1e-42; // denormal
            for compression in [
                ExrCompression::Zip,
                ExrCompression::Piz,
                ExrCompression::None,
            ] {
                let opts = ExrOptions {
                    precision: ExrPrecision::Float,
                    compression,
                };
                let bytes = encode_exr(&img, &opts).unwrap();
                assert_eq!(Format::sniff(&bytes), Some(Format::Exr));
                let back = decode(&bytes).unwrap();
                let expect = if ch == 2 { img.to_rgba() } else { img.clone() };
                assert_eq!(bits(&back), bits(&expect), "ch {ch} {compression:?}");
                // Orientation: (0, 0) stays the top-left pixel.
                assert_eq!(back.get(3, 0, 0).to_bits(), img.get(3, 0, 0).to_bits());
                assert!(back.get(5, 0, 0) > back.get(5, 6, 0));
            }
        }
    }

    #[test]
    fn half_round_trip_is_within_half_precision() {
        let img = Image::from_fn(20, 10, 3, |x, y, c| {
            (x as f32 - 10.0) * 0.37 * (1.0 + y as f32).powi(3) + c as f32
        });
        let opts = ExrOptions {
            precision: ExrPrecision::Half,
            compression: ExrCompression::Zip,
        };
        let back = decode(&encode_exr(&img, &opts).unwrap()).unwrap();
        for (&a, &b) in img.data.iter().zip(&back.data) {
            // binary16 has an 11-bit significand: relative error at most 2^-11.
            assert!((a - b).abs() <= a.abs() * 4.9e-4 + 6e-8, "{a} vs {b}");
        }
        assert_eq!(back.get(0, 0, 0), f16::from_f32(img.get(0, 0, 0)).to_f32());
    }

    /// Regression (fuzzing): a 544-byte file claiming a large data window made the decoder
    /// allocate and fill 315 MB before finding no blocks (0.7 s, over the time bound under
    /// load); now refused from the header. Highly compressible real data still decodes.
    #[test]
    fn data_window_larger_than_the_file_can_hold_is_refused_first() {
        let small = Image::from_fn(4, 4, 3, |x, y, c| (x + y + c) as f32);
        let mut bytes = encode_exr(&small, &ExrOptions::default()).unwrap();
        // dataWindow is a box2i: xMin yMin xMax yMax (i32, little-endian).
        let at = bytes
            .windows(11)
            .position(|w| w == b"dataWindow\0")
            .unwrap();
        let v = at + 11 + b"box2i\0".len() + 4;
        for (k, value) in [0i32, 0, 16383, 16383].into_iter().enumerate() {
            bytes[v + 4 * k..v + 4 * k + 4].copy_from_slice(&value.to_le_bytes());
        }
        let t = std::time::Instant::now();
        let e = decode(&bytes).unwrap_err().to_string();
        assert!(
            e.contains("data window 16384x16384") && e.contains("more than a"),
            "{e}"
        );
        assert!(t.elapsed().as_millis() < 100, "{:?}", t.elapsed());
        // A constant 1024×1024 RGB float image: ZIP and PIZ compress it > 100:1.
        let flat = Image::from_fn(1024, 1024, 3, |_, _, c| c as f32 * 0.25);
        for compression in [ExrCompression::Zip, ExrCompression::Piz] {
            let o = ExrOptions {
                compression,
                ..ExrOptions::default()
            };
            let b = encode_exr(&flat, &o).unwrap();
            assert!(
                b.len() * 100 < 1024 * 1024 * 12,
                "{compression:?}: {} bytes",
                b.len()
            );
            assert_eq!(decode(&b).unwrap().data, flat.data, "{compression:?}");
        }
    }

    #[test]
    fn synthetic_data_window_is_placed_in_display_window() {
        // A 3x2 data window at (2, 1) inside a 6x4 display window at (0, 0).
        let r = FlatSamples::F32((0..6).map(|i| i as f32 + 1.0).collect());
        let layer = Layer::new(
            (3, 2),
            LayerAttributes {
                layer_position: exr::math::Vec2(2, 1),
                ..LayerAttributes::default()
            },
            Encoding::SMALL_LOSSLESS,
            AnyChannels::sort(SmallVec::from_vec(vec![AnyChannel::new("Y", r)])),
        );
        let mut attributes = exr::meta::header::ImageAttributes::new(
            exr::meta::attribute::IntegerBounds::new((0, 0), (6, 4)),
        );
        attributes.pixel_aspect = 1.0;
        let image = exr::image::Image::new(attributes, layer);
        let mut bytes = Vec::new();
        image.write().to_buffered(Cursor::new(&mut bytes)).unwrap();
        let img = decode(&bytes).unwrap();
        assert_eq!((img.width, img.height, img.channels), (6, 4, 1));
        #[rustfmt::skip]
        let expect = [
            0., 0., 0., 0., 0., 0.,
            0., 0., 1., 2., 3., 0.,
            0., 0., 4., 5., 6., 0.,
            0., 0., 0., 0., 0., 0.,
        ];
        assert_eq!(img.data, expect);
    }

    #[test]
    fn multipart_picks_the_first_part_with_rgb() {
        let plane = |v: f32| FlatSamples::F32(vec![v; 6]);
        let layer = |name: &str, channels: &[(&str, f32)]| {
            let list = channels
                .iter()
                .map(|&(c, v)| AnyChannel::new(c, plane(v)))
                .collect::<Vec<_>>();
            Layer::new(
                (3, 2),
                LayerAttributes::named(name),
                Encoding::SMALL_LOSSLESS,
                AnyChannels::sort(SmallVec::from_vec(list)),
            )
        };
        let write = |layers: Vec<Layer<AnyChannels<FlatSamples>>>| {
            let attributes = exr::meta::header::ImageAttributes::new(
                exr::meta::attribute::IntegerBounds::new((0, 0), (3, 2)),
            );
            let image = exr::image::Image::from_layers(attributes, SmallVec::from_vec(layers));
            let mut bytes = Vec::new();
            image.write().to_buffered(Cursor::new(&mut bytes)).unwrap();
            bytes
        };
        // Part 1 has only depth, part 2 has colour + alpha: part 2 is chosen.
        let bytes = write(vec![
            layer("depth", &[("Z", 9.0)]),
            layer("beauty", &[("R", 1.0), ("G", 2.0), ("B", 3.0), ("A", 0.5)]),
        ]);
        let img = decode(&bytes).unwrap();
        assert_eq!(img.channels, 4);
        assert_eq!(img.pixel(2, 1), &[1.0, 2.0, 3.0, 0.5]);
        // No part has RGB: the first part's Y (+A, as RGBA).
        let bytes = write(vec![
            layer("luma", &[("Y", 0.25), ("A", 1.0)]),
            layer("depth", &[("Z", 9.0)]),
        ]);
        assert_eq!(
            decode(&bytes).unwrap().pixel(0, 0),
            &[0.25, 0.25, 0.25, 1.0]
        );
        // Neither: the first part's first channel.
        let bytes = write(vec![
            layer("depth", &[("Z", 9.0)]),
            layer("n", &[("N", 1.0)]),
        ]);
        let img = decode(&bytes).unwrap();
        assert_eq!((img.channels, img.data[0]), (1, 9.0));
    }

    /// A deep-scanline header as OpenEXR 2 writes it (no pixel data needed to detect it).
    fn deep_scanline_file() -> Vec<u8> {
        fn attr(out: &mut Vec<u8>, name: &str, ty: &str, value: &[u8]) {
            out.extend(name.as_bytes());
            out.push(0);
            out.extend(ty.as_bytes());
            out.push(0);
            out.extend((value.len() as i32).to_le_bytes());
            out.extend(value);
        }
        let i32s = |v: &[i32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
        let mut f = vec![0x76, 0x2F, 0x31, 0x01];
        // Version 2, flags: non-image (deep) bit 11 and multipart bit 12 clear.
        f.extend((2u32 | 0x800).to_le_bytes());
        let mut chlist = b"Z\0".to_vec();
        chlist.extend(i32s(&[2, 0, 1, 1])); // FLOAT, pLinear + reserved, sampling 1 1
        chlist.push(0);
        attr(&mut f, "channels", "chlist", &chlist);
        attr(&mut f, "compression", "compression", &[0]);
        attr(&mut f, "dataWindow", "box2i", &i32s(&[0, 0, 3, 3]));
        attr(&mut f, "displayWindow", "box2i", &i32s(&[0, 0, 3, 3]));
        attr(&mut f, "lineOrder", "lineOrder", &[0]);
        attr(&mut f, "pixelAspectRatio", "float", &1f32.to_le_bytes());
        attr(&mut f, "screenWindowCenter", "v2f", &[0; 8]);
        attr(&mut f, "screenWindowWidth", "float", &1f32.to_le_bytes());
        attr(&mut f, "name", "string", b"deep");
        attr(&mut f, "type", "string", b"deepscanline");
        attr(&mut f, "version", "int", &1i32.to_le_bytes());
        attr(&mut f, "chunkCount", "int", &4i32.to_le_bytes());
        attr(&mut f, "maxSamplesPerPixel", "int", &3i32.to_le_bytes());
        f.push(0);
        f.extend([0u8; 32]); // offset table (4 chunks)
        f
    }

    #[test]
    fn deep_data_is_a_deep_data_error() {
        let f = deep_scanline_file();
        let e = decode(&f).unwrap_err();
        assert!(matches!(e, ImageError::DeepData(_)), "{e}");
        assert!(e.to_string().contains("deep"), "{e}");
        // Even if the version flag is missing, the part's "type" attribute gives it away.
        let mut g = f.clone();
        g[5] &= !0x08;
        let e = decode(&g).unwrap_err();
        assert!(matches!(e, ImageError::DeepData(_)), "{e}");
    }

    #[test]
    fn truncated_and_forged_files_are_errors() {
        let img = gradient(64, 40, 4);
        for compression in [ExrCompression::Zip, ExrCompression::None] {
            let opts = ExrOptions {
                precision: ExrPrecision::Half,
                compression,
            };
            let bytes = encode_exr(&img, &opts).unwrap();
            for len in (0..bytes.len()).step_by(53).chain([bytes.len() - 1]) {
                assert!(
                    decode(&bytes[..len]).is_err(),
                    "{compression:?} cut at {len}"
                );
            }
        }
        // A display window of 2^31 x 2^31 pixels must be refused before allocating.
        let bytes = encode_exr(&gradient(4, 4, 3), &ExrOptions::default()).unwrap();
        let key = b"displayWindow\0box2i\0";
        let at = bytes.windows(key.len()).position(|w| w == key).unwrap() + key.len() + 4;
        let mut forged = bytes.clone();
        forged[at + 8..at + 12].copy_from_slice(&i32::MAX.to_le_bytes());
        forged[at + 12..at + 16].copy_from_slice(&i32::MAX.to_le_bytes());
        assert!(decode(&forged).is_err());
        // A display window of 16 M × 5 pixels zero-filled around 4 × 4 of data (1.3 GB as
        // f32, the fuzzer's find) is refused; 8192 × 8192 around it is decoded.
        for (x1, ok) in [(1i32 << 24, false), (8191, true)] {
            let mut forged = bytes.clone();
            forged[at + 8..at + 12].copy_from_slice(&x1.to_le_bytes());
            forged[at + 12..at + 16].copy_from_slice(&(if ok { 8191i32 } else { 4 }).to_le_bytes());
            match decode(&forged) {
                Ok(img) => assert!(ok && img.width == 8192 && img.height == 8192),
                Err(e) => assert!(!ok && e.to_string().contains("zero-filled"), "{e}"),
            }
        }
        // Not an EXR at all.
        assert!(decode(b"\x76\x2f\x31").is_err());
        assert!(decode(b"PF\n1 1\n-1\n").is_err());
    }

    #[test]
    fn multi_layer_files_round_trip_every_layer() {
        let a = Image::from_fn(5, 4, 3, |x, y, c| (x * 10 + y + c) as f32 * 0.5);
        let b = Image::from_fn(5, 4, 4, |x, y, c| (x + y * 7) as f32 - c as f32);
        let g = Image::from_fn(5, 4, 1, |x, y, _| (x * y) as f32);
        let bytes = encode_exr_layers(
            &[("", &a), ("beauty", &b), ("shadow", &g)],
            &ExrOptions::default(),
        )
        .unwrap();
        assert_eq!(decode(&bytes).unwrap().data, a.data);
        assert_eq!(decode_layer(&bytes, "beauty").unwrap().data, b.data);
        assert_eq!(decode_layer(&bytes, "shadow").unwrap().data, g.data);
        let e = decode_layer(&bytes, "nope").unwrap_err().to_string();
        assert!(e.contains("no layer `nope`") && e.contains("beauty"), "{e}");
        let wrong = Image::new(3, 3, 3);
        let e = encode_exr_layers(&[("a", &a), ("b", &wrong)], &ExrOptions::default());
        assert!(e.unwrap_err().to_string().contains("3×3"));
    }
}
