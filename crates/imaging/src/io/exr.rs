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
    Clone, Copy, Debug, PartialEq, Eq, Hash, Default, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "lowercase")]
pub enum ExrPrecision {
    /// 32-bit IEEE float: exact.
    #[default]
    Float,
    /// 16-bit half float (IEEE 754-2008 binary16): 11-bit precision, range ±65504.
    Half,
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

fn err(reason: impl Into<String>) -> ImageError {
    ImageError::decode(Format::Exr, reason)
}

fn map_exr_error(e: exr::error::Error) -> ImageError {
    match e {
        exr::error::Error::NotSupported(what) if what.contains("deep") => {
            ImageError::DeepData(what.into_owned())
        }
        other => err(other.to_string()),
    }
}

/// Decode OpenEXR bytes (see the module documentation for channel selection and windows).
pub fn decode(bytes: &[u8]) -> Result<Image, ImageError> {
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
    }
    let image = guard(Format::Exr, || {
        exr::prelude::read()
            .no_deep_data()
            .largest_resolution_level()
            .all_channels()
            .all_layers()
            .all_attributes()
            .from_buffered(Cursor::new(bytes))
            .map_err(map_exr_error)
    })?;
    let display = image.attributes.display_window;
    let layers: &[Layer<AnyChannels<FlatSamples>>] = &image.layer_data;
    let (layer, picked) = pick_channels(layers)?;
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
fn pick_channels(
    layers: &[Layer<AnyChannels<FlatSamples>>],
) -> Result<(&Layer<AnyChannels<FlatSamples>>, Vec<usize>), ImageError> {
    let find = |layer: &Layer<AnyChannels<FlatSamples>>, name: &str| {
        layer
            .channel_data
            .list
            .iter()
            .position(|c| c.name.eq(name) && c.sampling == exr::math::Vec2(1, 1))
    };
    for layer in layers {
        if let (Some(r), Some(g), Some(b)) = (find(layer, "R"), find(layer, "G"), find(layer, "B"))
        {
            let mut v = vec![r, g, b];
            v.extend(find(layer, "A"));
            return Ok((layer, v));
        }
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
    check_encodable(img, Format::Exr)?;
    let names: &[&str] = match img.channels {
        1 => &["Y"],
        2 => &["Y", "A"],
        3 => &["R", "G", "B"],
        _ => &["R", "G", "B", "A"],
    };
    let n = img.pixel_count();
    let list: SmallVec<[AnyChannel<FlatSamples>; 4]> = names
        .iter()
        .enumerate()
        .map(|(c, name)| {
            let plane = (0..n).map(|i| img.data[i * img.channels + c]);
            let samples = match options.precision {
                ExrPrecision::Float => FlatSamples::F32(plane.collect()),
                ExrPrecision::Half => FlatSamples::F16(plane.map(f16::from_f32).collect()),
            };
            AnyChannel::new(*name, samples)
        })
        .collect();
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
