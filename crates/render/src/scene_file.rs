//! Reading a scene file by its extension — the book's `.scn` language ([`parse_scn`], §9.13)
//! or a YAML scene ([`parse_yaml_scene`]) — with the dome image it names, loaded and oriented
//! ([`read_scene_file`]; what the `read_scene` node runs).

use std::path::{Path, PathBuf};

use nalgebra::Vector3;

use crate::dome::Dome;
use crate::scene::Scene;
use crate::{parse_scn, parse_yaml_scene};

/// A scene read from a file.
#[derive(Clone, Debug)]
pub struct SceneFile {
    /// The scene model.
    pub scene: Scene,
    /// The loaded, oriented dome of `scene.dome` (`None` without a dome, or when its image
    /// file does not exist: a dome can be given later).
    pub dome: Option<Dome>,
    /// The other files the scene read (a YAML scene's OBJ meshes, a `.scn` scene's dome
    /// image), in the order read: part of what the scene is.
    pub files: Vec<PathBuf>,
}

/// Why a scene file cannot be read. Messages start with the file's path.
#[derive(Debug, thiserror::Error)]
pub enum SceneFileError {
    /// The file cannot be read.
    #[error("cannot read {}: {source}", path.display())]
    Read {
        /// The scene file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The file does not parse (the message has line:column).
    #[error("{}:{message}", path.display())]
    Parse {
        /// The scene file.
        path: PathBuf,
        /// The parser's error.
        message: String,
    },
    /// Neither `.scn` nor `.yaml`/`.yml`.
    #[error("{}: unknown scene format `.{ext}` (expected .scn, .yaml or .yml)", path.display())]
    Format {
        /// The scene file.
        path: PathBuf,
        /// Its extension, lower case.
        ext: String,
    },
    /// The dome image cannot be read or is not a dome.
    #[error("dome image {}: {message}", path.display())]
    Dome {
        /// The dome image.
        path: PathBuf,
        /// Why.
        message: String,
    },
}

/// Reads the scene file `path` by its extension (`.scn`, `.yaml` or `.yml`, any case), and
/// loads the dome image it names relative to the file's folder (scaled by the dome's `scale`,
/// oriented by its `orig`/`south`) when that image exists.
pub fn read_scene_file(path: &Path) -> Result<SceneFile, SceneFileError> {
    let text = std::fs::read_to_string(path).map_err(|source| SceneFileError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase();
    let dir = path.parent().unwrap_or(Path::new("."));
    let parse = |message: String| SceneFileError::Parse {
        path: path.to_path_buf(),
        message,
    };
    let (scene, mut files) = match ext.as_str() {
        "scn" => (parse_scn(&text).map_err(|e| parse(e.to_string()))?, vec![]),
        "yaml" | "yml" => {
            let parsed = parse_yaml_scene(&text, dir).map_err(|e| parse(e.to_string()))?;
            let files = parsed.files.into_iter().filter(|f| f.is_file()).collect();
            (parsed.scene, files)
        }
        _ => {
            return Err(SceneFileError::Format {
                path: path.to_path_buf(),
                ext,
            })
        }
    };
    if let Some(spec) = &scene.dome {
        let image = dir.join(&spec.image);
        if image.is_file() && ext == "scn" {
            files.push(image);
        }
    }
    let dome = load_dome(&scene, dir)?;
    Ok(SceneFile { scene, dome, files })
}

/// Loads and orients the dome image a scene names (relative to `dir`); `None` if the file does
/// not exist.
fn load_dome(scene: &Scene, dir: &Path) -> Result<Option<Dome>, SceneFileError> {
    let Some(spec) = &scene.dome else {
        return Ok(None);
    };
    let path = dir.join(&spec.image);
    if !path.exists() {
        return Ok(None);
    }
    let error = |message: String| SceneFileError::Dome {
        path: path.clone(),
        message,
    };
    let mut img = vfxgraph_imaging::io::read_image(&path).map_err(|e| error(e.to_string()))?;
    if spec.scale != 1.0 {
        let k = spec.scale as f32;
        img.data.iter_mut().for_each(|v| *v *= k);
    }
    let v = |p: crate::Vec3| Vector3::new(p.x, p.y, p.z);
    let dome = Dome::new(&img, v(spec.orig), v(spec.south)).map_err(|e| error(e.to_string()))?;
    Ok(Some(dome))
}
