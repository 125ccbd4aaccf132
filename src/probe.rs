//! `vfxgraph probe FILE…`: what the readers know of a file before a graph reads it — its
//! picture size and channels; a DPX file's bits, transfer and colorimetric fields and frame
//! rate (SMPTE 268); a video's codec, pixel format, matrix, range, transfer, primaries,
//! rotation, frame count and rate; and the camera's focal length from EXIF (photographs, TIFF)
//! or QuickTime metadata (phone and camera clips), in pixels of the picture: the start
//! `matchmove`'s `focal: unknown` can be given (`intrinsics_from_metadata`).

use std::path::Path;

use serde_json::{json, Map, Value};
use vfxgraph_imaging::io::dpx;
use vfxgraph_imaging::metadata::{camera_focal, pixels_from_35mm};
use vfxgraph_video::{Backend, Reader};

/// Whether `path` names a video container (by its extension).
fn is_video(path: &Path) -> bool {
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase());
    matches!(
        ext.as_deref(),
        Some("mp4" | "mov" | "m4v" | "3gp" | "mkv" | "webm" | "mxf" | "avi")
    )
}

/// What the readers know of one file.
pub fn probe(path: &Path) -> Result<Value, String> {
    let mut out = Map::new();
    out.insert("file".into(), json!(path.display().to_string()));
    if is_video(path) {
        probe_video(path, &mut out)?;
    } else {
        let bytes =
            std::fs::read(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
        let is_dpx = matches!(bytes.get(..4), Some(b"SDPX" | b"XPDS"));
        if is_dpx {
            let h = dpx::read_header(&bytes).map_err(|e| format!("{}: {e}", path.display()))?;
            out.insert("format".into(), json!("dpx"));
            out.insert("size".into(), json!([h.width, h.height]));
            out.insert("channels".into(), json!(h.channels));
            out.insert("bits".into(), json!(h.bits));
            out.insert(
                "transfer".into(),
                json!(dpx::characteristic_name(h.transfer)),
            );
            out.insert(
                "colorimetric".into(),
                json!(dpx::characteristic_name(h.colorimetric)),
            );
            out.insert("frame_rate".into(), json!(h.frame_rate));
        } else {
            let img = vfxgraph_imaging::read_image(path).map_err(|e| e.to_string())?;
            out.insert("size".into(), json!([img.width, img.height]));
            out.insert("channels".into(), json!(img.channels));
            match camera_focal(&bytes, img.width, img.height) {
                Ok(f) => {
                    out.insert("focal_px".into(), json!(f.pixels));
                    out.insert("focal_mm".into(), json!(f.millimetres));
                    out.insert("focal_source".into(), json!(f.source));
                }
                Err(why) => {
                    out.insert("focal_px".into(), Value::Null);
                    out.insert("focal_missing".into(), json!(why));
                }
            }
        }
    }
    Ok(Value::Object(out))
}

fn probe_video(path: &Path, out: &mut Map<String, Value>) -> Result<(), String> {
    let reader = Reader::open(path, Backend::Auto).map_err(|e| e.to_string())?;
    out.insert("frames".into(), json!(reader.frame_count()));
    let size = match &reader {
        Reader::Native(v) => {
            let c = v.color();
            out.insert("reader".into(), json!("bundled H.264"));
            out.insert("codec".into(), json!("h264"));
            out.insert("frame_rate".into(), json!(v.fps()));
            out.insert("matrix".into(), json!(format!("{:?}", c.matrix)));
            out.insert("full_range".into(), json!(c.full_range));
            v.size()
        }
        Reader::Ffmpeg(v) => {
            let p = v.probe();
            out.insert("reader".into(), json!("ffmpeg"));
            out.insert("codec".into(), json!(p.codec));
            out.insert("profile".into(), json!(p.profile));
            out.insert("pixel_format".into(), json!(p.pix_fmt));
            let t = v.times();
            let rate = (t.len() > 1 && t[t.len() - 1] > t[0])
                .then(|| (t.len() - 1) as f64 / (t[t.len() - 1] - t[0]));
            // To the microsecond timestamps' precision.
            let rate = rate.map(|r| (r * 1e6).round() / 1e6);
            out.insert("frame_rate".into(), json!(rate));
            out.insert("matrix".into(), json!(format!("{:?}", p.color.matrix)));
            out.insert("full_range".into(), json!(p.color.full_range));
            out.insert("transfer".into(), json!(p.transfer));
            out.insert("primaries".into(), json!(p.primaries));
            out.insert("rotation".into(), json!(p.rotation));
            v.size()
        }
        #[allow(unreachable_patterns)]
        _ => (0, 0),
    };
    out.insert("size".into(), json!([size.0, size.1]));
    match vfxgraph_video::metadata::camera_metadata(path) {
        Ok(m) => {
            let focal = m
                .focal_35mm
                .map(|f35| pixels_from_35mm(f35, size.0, size.1));
            out.insert("focal_px".into(), json!(focal));
            out.insert("focal_35mm".into(), json!(m.focal_35mm));
            out.insert("make".into(), json!(m.make));
            out.insert("model".into(), json!(m.model));
            out.insert("lens".into(), json!(m.lens_model));
        }
        Err(why) => {
            out.insert("focal_px".into(), Value::Null);
            out.insert("focal_missing".into(), json!(why));
        }
    }
    Ok(())
}

/// Prints what [`probe`] finds of each file (JSON with `json`), a failing file's error in its
/// place; fails (exit 1) when any file could not be read.
pub fn run(files: &[std::path::PathBuf], json: bool) -> Result<u8, String> {
    let mut failed = false;
    let mut all = Vec::new();
    for f in files {
        match probe(f) {
            Ok(v) => all.push(v),
            Err(e) => {
                failed = true;
                all.push(json!({ "file": f.display().to_string(), "error": e }));
            }
        }
    }
    if json {
        println!("{}", serde_json::to_string_pretty(&all).unwrap_or_default());
    } else {
        for v in &all {
            let Value::Object(m) = v else { continue };
            println!("{}", m["file"].as_str().unwrap_or(""));
            for (k, v) in m.iter().filter(|(k, _)| *k != "file") {
                let shown = match v {
                    Value::String(s) => s.clone(),
                    Value::Null => "—".into(),
                    other => other.to_string(),
                };
                println!("  {k:<14} {shown}");
            }
        }
    }
    Ok(if failed { 1 } else { 0 })
}
