//! The error type of the crate.

use std::path::PathBuf;

use crate::io::Format;

/// Everything that can go wrong reading, writing or building an image.
///
/// Errors from [`crate::io::read_image`] and [`crate::io::write_image`] name the file: either
/// through [`ImageError::Io`] or by wrapping the format-level error in [`ImageError::File`]; use
/// [`ImageError::kind`] to look through that wrapper.
#[derive(thiserror::Error, Debug)]
pub enum ImageError {
    /// The operating system refused a read, write, rename or directory operation on `path`.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file or directory the operation was on.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },

    /// The format could not be determined or is not one this crate reads and writes.
    #[error("unsupported image format: {0}")]
    UnsupportedFormat(String),

    /// The bytes are not a valid (or not a supported variant of a) file of `format`.
    #[error("cannot decode {format} data: {reason}")]
    Decode {
        /// The format the bytes were decoded as.
        format: Format,
        /// What is wrong, in words.
        reason: String,
    },

    /// The OpenEXR file holds deep data (several samples per pixel), which this crate does not
    /// read (OpenEXR 2.0 "deepscanline"/"deeptile" parts).
    #[error("OpenEXR deep data is not supported: {0}")]
    DeepData(String),

    /// The image could not be encoded (for example a channel count the format cannot store);
    /// the message names the format.
    #[error("cannot encode image: {0}")]
    Encode(String),

    /// Width, height or channel count are zero, do not match the data, or are too large.
    #[error("invalid image dimensions: {0}")]
    InvalidDimensions(String),

    /// A colour management failure: an OpenColorIO config that does not load, or a colour
    /// space, display or view it does not name (the message names the config and the name).
    #[error("{0}")]
    Colour(String),

    /// An error while reading or writing the file at `path`.
    #[error("{}: {source}", path.display())]
    File {
        /// The file being read or written.
        path: PathBuf,
        /// What went wrong.
        #[source]
        source: Box<ImageError>,
    },
}

impl ImageError {
    /// The underlying error, looking through any [`ImageError::File`] wrappers.
    pub fn kind(&self) -> &ImageError {
        match self {
            ImageError::File { source, .. } => source.kind(),
            other => other,
        }
    }

    /// Wrap `self` so that it names `path` (unless it already names a path).
    pub(crate) fn at_path(self, path: &std::path::Path) -> ImageError {
        match self {
            e @ (ImageError::Io { .. } | ImageError::File { .. }) => e,
            e => ImageError::File {
                path: path.to_path_buf(),
                source: Box::new(e),
            },
        }
    }

    pub(crate) fn decode(format: Format, reason: impl Into<String>) -> ImageError {
        ImageError::Decode {
            format,
            reason: reason.into(),
        }
    }

    pub(crate) fn encode(format: Format, reason: impl Into<String>) -> ImageError {
        ImageError::Encode(format!("{format}: {}", reason.into()))
    }
}
