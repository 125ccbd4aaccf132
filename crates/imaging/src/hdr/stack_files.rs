//! Which photographs make a stack, and how they are timed (book 10.2): an exposure list file,
//! or paths with their times, or paths timed by their EXIF ([`StackFiles`]; what the
//! `read_exposure_stack` node runs). Errors name the `list`, `paths` and `times` settings and
//! the files by name.

use std::path::{Path, PathBuf};

use super::stack::{
    exposure_list_files, read_exposure_files, read_exposure_files_exif, ExposureStack, StackOptions,
};
use super::HdrError;

/// The photographs of a stack and where their times come from.
#[derive(Clone, Debug, PartialEq)]
pub enum StackFiles {
    /// Named by an exposure list file, with its times.
    List {
        /// The photographs, resolved.
        paths: Vec<PathBuf>,
        /// Their times, seconds.
        times: Vec<f64>,
    },
    /// Named by `paths` with `times`.
    Timed {
        /// The photographs.
        paths: Vec<PathBuf>,
        /// Their times, seconds.
        times: Vec<f64>,
    },
    /// Named by `paths`, timed by their EXIF.
    Exif {
        /// The photographs.
        paths: Vec<PathBuf>,
    },
}

/// Why a stack cannot be named or read.
#[derive(Debug, thiserror::Error)]
pub enum StackFilesError {
    /// The settings do not name a stack, or the stack's files disagree (the message says how).
    #[error("{0}")]
    Message(String),
    /// The list file or the mask.
    #[error(transparent)]
    Hdr(#[from] HdrError),
    /// An error of the files named by the setting `param`.
    #[error("param `{param}`: {source}")]
    Param {
        /// `list` or `paths`.
        param: &'static str,
        /// What went wrong.
        #[source]
        source: HdrError,
    },
}

impl StackFiles {
    /// The stack named by a `list` file (its photographs resolved relative to it) or by
    /// `paths`, timed by `times` or (empty `times`) by EXIF: exactly one of `list` and `paths`.
    pub fn resolve(
        list: Option<&Path>,
        paths: Vec<PathBuf>,
        times: &[f64],
    ) -> Result<StackFiles, StackFilesError> {
        let msg = |m: &str| Err(StackFilesError::Message(m.into()));
        match (list, paths.len()) {
            (Some(_), 0) if !times.is_empty() => {
                msg("param `times` goes with `paths`; a `list` file holds its own times")
            }
            (Some(list), 0) => {
                let (paths, times) = exposure_list_files(list)?;
                Ok(StackFiles::List { paths, times })
            }
            (None, 0) => {
                msg("give `list` (an exposure list file) or `paths` (with `times`, or EXIF)")
            }
            (Some(_), _) => msg("give either `list` or `paths`, not both"),
            (None, _) if times.is_empty() => Ok(StackFiles::Exif { paths }),
            (None, n) if times.len() != n => Err(StackFilesError::Message(format!(
                "param `paths` names {n} files but `times` has {} values",
                times.len()
            ))),
            (None, _) => Ok(StackFiles::Timed {
                paths,
                times: times.to_vec(),
            }),
        }
    }

    /// The photographs a list file named (`[]` otherwise): inputs a caller may declare.
    pub fn listed(&self) -> &[PathBuf] {
        match self {
            StackFiles::List { paths, .. } => paths,
            _ => &[],
        }
    }

    /// Reads the stack and masks `o.mask_color`.
    pub fn read(&self, o: &StackOptions) -> Result<ExposureStack, StackFilesError> {
        let mut stack = match self {
            StackFiles::List { paths, times } => read_exposure_files(paths, times)
                .map_err(|e| stack_error(e, paths, "list", "list"))?,
            StackFiles::Timed { paths, times } => read_exposure_files(paths, times)
                .map_err(|e| stack_error(e, paths, "paths", "times"))?,
            StackFiles::Exif { paths } => {
                read_exposure_files_exif(paths)
                    .map_err(|e| stack_error(e, paths, "paths", "paths (EXIF times)"))?
                    .0
            }
        };
        o.apply_mask(&mut stack)?;
        Ok(stack)
    }
}

/// The name of a file for messages: its file name.
fn file_name(p: &Path) -> String {
    p.file_name().map_or_else(
        || p.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    )
}

/// Stack validation errors in terms of the settings and the files.
fn stack_error(
    e: HdrError,
    paths: &[PathBuf],
    files_param: &'static str,
    times_param: &str,
) -> StackFilesError {
    match e {
        HdrError::DuplicateExposure {
            first,
            second,
            time,
        } => StackFilesError::Message(format!(
            "param `{times_param}`: {} and {} have the same exposure {time} s (a stack needs \
             distinct exposures)",
            file_name(&paths[first]),
            file_name(&paths[second])
        )),
        HdrError::SizeMismatch {
            index,
            expected,
            found,
        } => StackFilesError::Message(format!(
            "{} is {found}, {} is {expected}: the exposures of a stack must have one size",
            file_name(&paths[index]),
            file_name(&paths[0])
        )),
        other => StackFilesError::Param {
            param: files_param,
            source: other,
        },
    }
}
