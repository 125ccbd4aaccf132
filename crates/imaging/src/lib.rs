//! # vfxgraph-imaging
//!
//! Image buffers, file I/O, colour transfer functions and tone mapping for vfxgraph, the
//! dataflow engine implementing *Introduction to Visual Effects: A Computational Approach*
//! (Madeira & Velho). Usable on its own: it knows nothing about graphs or nodes.
//!
//! - [`Image`]: a linear-light `f32` buffer, row-major, interleaved channels, origin at the
//!   top-left pixel (x right, y down), as everywhere in vfxgraph.
//! - [`io`]: PNG and JPEG (sRGB 8/16-bit, through the `image` crate), OpenEXR (through the `exr`
//!   crate), PFM and Radiance RGBE `.hdr` (hand-written). sRGB is decoded to linear on read and
//!   encoded on write; float formats are stored as they are.
//! - [`color`]: the IEC 61966-2-1 sRGB transfer functions and Rec. 709 luminance.
//! - [`colour`]: colour management through OpenColorIO configs (the built-in ACES studio
//!   config, or a studio's): file colour spaces to and from the scene-linear working space,
//!   display/view transforms for previews.
//! - [`draw`]: plots and overlays drawn into images (the response curve figure; lines, crosses,
//!   squares and colours by id for track overlays).
//! - [`blur`]: a Gaussian and a motion streak, as a lens and a moving camera blur.
//! - [`tonemap`]: photographic exposure and display tone mapping (clip, or Reinhard et al. 2002).
//!
//! No function of this crate panics on the content of a file: malformed, truncated or huge inputs
//! give an [`ImageError`].
//!
//! ```
//! use vfxgraph_imaging::{decode, encode, tonemap, Format, Image, Operator};
//!
//! // A 2x1 HDR image: a dim and a very bright pixel, in linear light.
//! let hdr = Image::from_vec(2, 1, 3, vec![0.1, 0.1, 0.1, 40.0, 20.0, 10.0])?;
//! let exr = encode(&hdr, Format::Exr)?; // 32-bit float, ZIP: exact
//! assert_eq!(decode(&exr, Format::Exr)?, hdr);
//!
//! // For display: Reinhard (L / (1 + L) on luminance) one stop brighter, then 8-bit sRGB PNG.
//! let ldr = tonemap(&hdr, Operator::Reinhard, 1.0);
//! assert!(ldr.data.iter().all(|v| (0.0..=1.0).contains(v)));
//! let png = encode(&ldr, Format::Png)?;
//! assert_eq!(Format::sniff(&png), Some(Format::Png));
//! # Ok::<(), vfxgraph_imaging::ImageError>(())
//! ```

#![warn(missing_docs)]

pub mod blur;
pub mod color;
pub mod colour;
pub mod draw;
mod error;
pub mod hdr;
pub mod image;
pub mod io;
pub mod metadata;
pub mod tonemap;

pub use crate::blur::{blur, BlurOptions};
pub use crate::error::ImageError;
pub use crate::image::{constant, ConstantOptions, Image};
pub use crate::io::{
    decode, decode_as, encode, encode_as, read_image, read_image_as, write_image, write_image_as,
    Format, Values,
};
pub use crate::tonemap::{exposure, tonemap, ExposureOptions, Operator, TonemapOptions};
