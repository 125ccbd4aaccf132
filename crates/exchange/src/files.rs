//! The export and import operations as a whole: the format choices, the `export_cameras`
//! options ([`ExportOptions`]: the scene transform, the image size when K lacks it, the plate's
//! and ST-map's names), the shot they export ([`ExportOptions::shot`]), the files a format
//! makes ([`files`]) and writes ([`write`]), what it reports ([`report`]) and what is read back
//! ([`read`]).

use std::path::{Path, PathBuf};

use vfxgraph_imaging::Image;
use vfxgraph_params::Choice;

use super::{blender, colmap, colors, json, nuke, ply, usd, SceneOptions, Shot};
use vfxgraph_geometry::camera::Intrinsics;
use vfxgraph_geometry::error::{Result, VisionError};
use vfxgraph_geometry::formats::{self, CameraPath};
use vfxgraph_geometry::points::PointCloud;
use vfxgraph_klt::Tracks;

/// An export format.
#[derive(Clone, Copy, Debug, PartialEq, Eq, vfxgraph_params::Choice)]
pub enum ExportFormat {
    /// COLMAP's text model (cameras.txt, images.txt, points3D.txt).
    Colmap,
    /// A Python script for Blender.
    Blender,
    /// A `.usda` stage.
    Usd,
    /// A Nuke `.chan` plus a film-back note.
    Nuke,
    /// Our JSON.
    Json,
    /// The point cloud.
    Ply,
}

/// An import format.
#[derive(Clone, Copy, Debug, PartialEq, Eq, vfxgraph_params::Choice)]
pub enum ImportFormat {
    /// COLMAP's text model.
    Colmap,
    /// The book's cameras file (`Frame i`, R, t).
    Book,
}

/// The `export_cameras` operation's options (the format and the path are the caller's).
#[derive(Clone, Debug, Default, PartialEq, vfxgraph_params::Options)]
pub struct ExportOptions {
    /// The scene transform and timing of the DCC formats.
    #[param(flatten)]
    pub scene: SceneOptions,
    /// image width when K does not carry it and no plate is connected (0: from K or plate)
    #[param(range = 0..=1048576)]
    pub width: u32,
    /// image height, as `width`
    #[param(range = 0..=1048576)]
    pub height: u32,
    /// the plate's file names as a frame pattern relative to the export (e.g.
    /// `plate/frame.%04d.png`); COLMAP image names, Blender's background, JSON
    pub image_names: String,
    /// an ST-map of the lens (e.g. from `write_st_map`), relative to the export: referenced by
    /// the usd (`vfxgraph:lens:stMap`) and nuke (note) exports
    pub st_map: String,
}

impl ExportOptions {
    /// K with the image size: `plate`'s (width, height), else the `width`/`height` options when
    /// both are set; an error when K carries another size.
    pub fn sized(&self, k: Intrinsics, plate: Option<(u32, u32)>) -> Result<Intrinsics> {
        let given = match plate {
            Some((w, h)) => Some((w, h, "the plate")),
            None if self.width > 0 && self.height > 0 => {
                Some((self.width, self.height, "the width/height params"))
            }
            None => None,
        };
        let Some((w, h, what)) = given else {
            return Ok(k);
        };
        match (k.width, k.height) {
            (None, None) => Ok(k.with_size(w, h)),
            (Some(kw), Some(kh)) if (kw, kh) != (w, h) => Err(VisionError::InvalidInput(format!(
                "K is for {kw}×{kh} images but {what} says {w}×{h}"
            ))),
            _ => Ok(k),
        }
    }

    /// The shot to export: `path` seen by `k` (sized by the plate's first frame or the
    /// options), with `cloud`, `tracks` and the options' names; validated; its points coloured
    /// from `plate` (frame number, linear-light image) when both are given.
    pub fn shot(
        &self,
        k: Intrinsics,
        path: CameraPath,
        cloud: Option<PointCloud>,
        tracks: Option<Tracks>,
        plate: &[(i64, &Image)],
    ) -> Result<Shot> {
        let plate_size = plate
            .first()
            .map(|(_, i)| (i.width as u32, i.height as u32));
        let mut shot = Shot::new(self.sized(k, plate_size)?, path);
        shot.cloud = cloud;
        shot.tracks = tracks;
        self.name(&mut shot);
        shot.validate()?;
        if !plate.is_empty() && shot.cloud.is_some() {
            shot.colors = Some(colors::sample_point_colors(&shot, plate));
        }
        Ok(shot)
    }

    /// The shot's names from the options: the plate's pattern and the ST-map (empty: none).
    pub fn name(&self, shot: &mut Shot) {
        if !self.image_names.is_empty() {
            shot.image_pattern = Some(self.image_names.clone());
        }
        if !self.st_map.is_empty() {
            shot.st_map = Some(self.st_map.clone());
        }
    }
}

/// The files that export `shot` in `format` at `path`, with their contents: the file `path`
/// names first (colmap: cameras.txt; nuke: the .chan), then the ones written beside it (colmap:
/// images.txt and points3D.txt; nuke: `<name>_filmback.txt`). Write the others first and
/// `path` last, so that its presence means the export is whole.
pub fn files(
    format: ExportFormat,
    path: &Path,
    shot: &Shot,
    o: &SceneOptions,
) -> Result<Vec<(PathBuf, String)>> {
    let one = |text: String| Ok(vec![(path.to_path_buf(), text)]);
    match format {
        ExportFormat::Colmap => {
            let model = colmap::format(shot)?;
            if path.file_name().and_then(|n| n.to_str()) != Some("cameras.txt") {
                return Err(VisionError::InvalidInput(format!(
                    "format colmap: `path` names the model's cameras.txt (images.txt and \
                     points3D.txt are written beside it), got {}",
                    path.display()
                )));
            }
            let [cameras, images, points] = colmap::model_files(path);
            Ok(vec![
                (cameras, model.cameras),
                (images, model.images),
                (points, model.points3d),
            ])
        }
        ExportFormat::Blender => one(blender::script(shot, o)?),
        ExportFormat::Usd => one(usd::stage(shot, o)?),
        ExportFormat::Nuke => {
            let chan = nuke::chan(shot, o)?;
            let note = nuke::filmback_note(shot, o)?;
            let stem = path
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| "camera".into());
            let note_path = path.with_file_name(format!("{stem}_filmback.txt"));
            Ok(vec![(path.to_path_buf(), chan), (note_path, note)])
        }
        ExportFormat::Json => one(json::format(shot, o.fps)?),
        ExportFormat::Ply => one(ply::format(shot)?),
    }
}

/// Writes `shot` in `format` at `path`: each of its [`files`] handed to `put` (the others first,
/// the file `path` names last, so its presence means the export is whole); returns the files
/// written.
pub fn write_with<E: From<VisionError>>(
    format: ExportFormat,
    path: &Path,
    shot: &Shot,
    o: &SceneOptions,
    mut put: impl FnMut(&Path, &str) -> std::result::Result<(), E>,
) -> std::result::Result<Vec<PathBuf>, E> {
    let out = files(format, path, shot, o)?;
    for (p, text) in out.iter().skip(1).chain(out.first()) {
        put(p, text)?;
    }
    Ok(out.into_iter().map(|(p, _)| p).collect())
}

/// [`write_with`] writing each file atomically ([`formats::write_text`]).
pub fn write(
    format: ExportFormat,
    path: &Path,
    shot: &Shot,
    o: &SceneOptions,
) -> Result<Vec<PathBuf>> {
    write_with(format, path, shot, o, formats::write_text)
}

/// The report of an export: format, files written, frames, points, image size, whether the
/// points were coloured, the lens.
pub fn report(format: ExportFormat, shot: &Shot, files: &[PathBuf]) -> serde_json::Value {
    serde_json::json!({
        "format": format.choice(),
        "files": files.iter().map(|f| f.display().to_string()).collect::<Vec<_>>(),
        "frames": shot.path.frames.len(),
        "points": shot.cloud.as_ref().map_or(0, |c| c.points.len()),
        "width": shot.intrinsics.width,
        "height": shot.intrinsics.height,
        "coloured": shot.colors.is_some(),
        "lens": shot.intrinsics.distortion.name(),
    })
}

/// Reads a solve made elsewhere: COLMAP's text model at `path` (its cameras.txt; K from the
/// model) or the book's cameras file (K = `intrinsics`, required).
pub fn read(
    format: ImportFormat,
    path: &Path,
    intrinsics: Option<&Intrinsics>,
) -> Result<(CameraPath, Intrinsics, PointCloud)> {
    match format {
        ImportFormat::Colmap => {
            let m = colmap::read(path)?;
            Ok((m.path, m.intrinsics, m.cloud))
        }
        ImportFormat::Book => {
            let k = intrinsics.cloned().ok_or_else(|| {
                VisionError::InvalidInput(
                    "format book: connect `intrinsics` (the book's cameras file has no K)".into(),
                )
            })?;
            let mut cams = formats::read_cameras(path)?;
            cams.intrinsics = Some(k.clone());
            Ok((cams, k, PointCloud::default()))
        }
    }
}
