//! The point-cloud definer (book §8.3, `defpcl`): the marks file of a `read_marks` node —
//! read, validated, written back in the book's `points2d.txt` form (and JSON beside it), and
//! triangulated from the solved cameras with the catalog's own `point_cloud_calibrate`
//! (geometry crate) so the page shows each point's reprojection error while marking.
//!
//! The file is a declared input of `read_marks` (its content digest is in the node's key), so
//! after a save the plan marks exactly `read_marks` and its dependants to run.

use std::path::PathBuf;

use serde_json::{json, Value as Json};
use vfxgraph_engine::node::resolve_path;
use vfxgraph_engine::store::Store;
use vfxgraph_engine::{Graph, Registry};
use vfxgraph_geometry::formats::marked_points::{
    format_marked_points, parse_marked_points, MarkedPoints,
};
use vfxgraph_nodes::artifacts::{CameraPathArt, IntrinsicsArt};

use crate::preview::{find_output, PreviewCache};
use crate::safety::ApiError;

/// Most points a frame may hold, and most frames (a request past these is refused).
pub const MAX_POINTS: usize = 1000;
/// See [`MAX_POINTS`].
pub const MAX_FRAMES: usize = 10_000;

/// The `read_marks` node `id` of `graph` and its marks file, which must lie in the graph's
/// folder ([`crate::safety::confine`]: the studio writes nowhere else).
pub fn marks_file(graph: &Graph, id: &str) -> Result<PathBuf, ApiError> {
    let i = graph
        .index_of(id)
        .ok_or_else(|| ApiError::not_found(format!("no node `{id}` in the graph")))?;
    let n = &graph.nodes[i];
    if n.spec().name != "read_marks" {
        return Err(ApiError::bad(format!(
            "`{id}` is a `{}`, not a `read_marks` node",
            n.spec().name
        )));
    }
    let text = n.params.str("path");
    crate::safety::confine(
        &resolve_path(&graph.dir, text, None),
        std::slice::from_ref(&graph.dir),
        text,
    )
}

/// The marks in the file (none when the file does not exist yet).
pub fn read(graph: &Graph, id: &str) -> Result<(PathBuf, MarkedPoints), ApiError> {
    let path = marks_file(graph, id)?;
    if !path.exists() {
        return Ok((path, MarkedPoints::default()));
    }
    let m = if vfxgraph_geometry::formats::is_json(&path) {
        vfxgraph_geometry::formats::read_json(&path)
    } else {
        vfxgraph_geometry::formats::marked_points::read_marked_points(&path)
    }
    .map_err(|e| ApiError::new(axum::http::StatusCode::UNPROCESSABLE_ENTITY, e.to_string()))?;
    Ok((path, m))
}

/// Checks marks sent by the page: at least one frame, frames distinct and non-negative,
/// the same number (≥ 1) of points on every frame, finite coordinates.
pub fn validate(m: &MarkedPoints) -> Result<(), ApiError> {
    if m.frames.is_empty() {
        return Err(ApiError::bad("no marked frame"));
    }
    if m.frames.len() > MAX_FRAMES {
        return Err(ApiError::bad(format!("more than {MAX_FRAMES} frames")));
    }
    let n = m.frames[0].points.len();
    if n == 0 || n > MAX_POINTS {
        return Err(ApiError::bad(format!(
            "each frame needs between 1 and {MAX_POINTS} points (frame {} has {n})",
            m.frames[0].frame
        )));
    }
    let mut seen = std::collections::BTreeSet::new();
    for f in &m.frames {
        if !seen.insert(f.frame) {
            return Err(ApiError::bad(format!("frame {} is marked twice", f.frame)));
        }
        if f.points.len() != n {
            return Err(ApiError::bad(format!(
                "frame {} has {} points, frame {} has {n}: every frame marks the same points in \
                 the same order",
                f.frame,
                f.points.len(),
                m.frames[0].frame
            )));
        }
        if f.points
            .0
            .iter()
            .any(|p| !(p.x.is_finite() && p.y.is_finite()))
        {
            return Err(ApiError::bad(format!(
                "frame {} has a point that is not finite",
                f.frame
            )));
        }
    }
    Ok(())
}

/// Writes the marks (validated first) to the node's file in its own form, and the other form
/// beside it (`points2d.txt` → `points2d.txt.json`; a `.json` file gets no sidecar). Each file
/// is written to a temporary and renamed. Returns the files written.
pub fn save(graph: &Graph, id: &str, m: &MarkedPoints) -> Result<Vec<PathBuf>, ApiError> {
    validate(m)?;
    let path = marks_file(graph, id)?;
    let io = |e: vfxgraph_geometry::VisionError| ApiError::internal(e.to_string());
    if vfxgraph_geometry::formats::is_json(&path) {
        vfxgraph_geometry::formats::write_json(&path, m).map_err(io)?;
        return Ok(vec![path]);
    }
    let text = format_marked_points(m);
    // What is written must read back as what was sent (the book's form has no other fields).
    let back = parse_marked_points(&text, "marks").map_err(io)?;
    if back != *m {
        return Err(ApiError::internal(
            "the marks do not round-trip through the text form",
        ));
    }
    vfxgraph_geometry::formats::write_text(&path, &text).map_err(io)?;
    let mut sidecar = path.clone().into_os_string();
    sidecar.push(".json");
    let sidecar = PathBuf::from(sidecar);
    vfxgraph_geometry::formats::write_json(&sidecar, m).map_err(io)?;
    Ok(vec![path, sidecar])
}

/// Triangulates the marks from the cameras that the `point_cloud_calibrate` node reading
/// node `id`'s marks uses (its last run's `cameras`, and `intrinsics` when connected):
/// the points and the report (per point RMS, per mark error).
pub fn triangulate(
    graph: &Graph,
    store: &Store,
    registry: &Registry,
    cache: &PreviewCache,
    id: &str,
    m: &MarkedPoints,
) -> Result<Json, ApiError> {
    validate(m)?;
    let src = graph
        .index_of(id)
        .ok_or_else(|| ApiError::not_found(format!("no node `{id}` in the graph")))?;
    let consumer = graph
        .nodes
        .iter()
        .find(|n| {
            n.spec().name == "point_cloud_calibrate" && n.inputs.iter().any(|e| e.from == src)
        })
        .ok_or_else(|| {
            ApiError::new(
                axum::http::StatusCode::UNPROCESSABLE_ENTITY,
                format!(
                    "no `point_cloud_calibrate` node reads `{id}`: no cameras to triangulate with"
                ),
            )
        })?;
    let edge_of = |port: &str| consumer.inputs.iter().find(|e| e.port == port);
    let cams_edge = edge_of("cameras")
        .ok_or_else(|| ApiError::internal("point_cloud_calibrate without cameras"))?;
    let cams_out = find_output(
        graph,
        store,
        &graph.nodes[cams_edge.from].id,
        cams_edge.from_port,
        None,
    )?;
    let cams_art = cache.artifact(store, registry, &cams_out)?;
    let cams = cams_art
        .as_any()
        .downcast_ref::<CameraPathArt>()
        .ok_or_else(|| ApiError::internal("the cameras are not a camera_path"))?;
    let k_art = match edge_of("intrinsics") {
        Some(e) => {
            let o = find_output(graph, store, &graph.nodes[e.from].id, e.from_port, None)?;
            Some(cache.artifact(store, registry, &o)?)
        }
        None => None,
    };
    let k = k_art
        .as_ref()
        .and_then(|a| a.as_any().downcast_ref::<IntrinsicsArt>())
        .map(|k| &k.0);
    let (points, report) = vfxgraph_geometry::modeling::point_cloud_calibrate(m, &cams.0, k)
        .map_err(|e| ApiError::new(axum::http::StatusCode::UNPROCESSABLE_ENTITY, e.to_string()))?;
    let projected = project_all(&points, &cams.0, k);
    Ok(json!({
        "points": points, "report": report, "consumer": consumer.id, "projected": projected,
    }))
}

/// Each point through every camera of `path`: `{frame: [[u, v] or null per point]}` (null
/// behind the camera or without intrinsics), so the page draws the triangulated points back on
/// the marked frames and predicts them on the others.
pub fn project_all(
    points: &vfxgraph_geometry::Points3d,
    path: &vfxgraph_geometry::formats::cameras::CameraPath,
    k: Option<&vfxgraph_geometry::camera::Intrinsics>,
) -> Json {
    let mut out = serde_json::Map::new();
    for (i, f) in path.frames.iter().enumerate() {
        let Some(intrinsics) = path.intrinsics_at(i).or_else(|| k.cloned()) else {
            continue;
        };
        let cam = vfxgraph_geometry::camera::Camera {
            intrinsics,
            pose: f.pose.clone(),
        };
        let uv: Vec<Json> = points
            .0
            .iter()
            .map(|x| match cam.project(x) {
                Ok(p) if cam.depth(x) > 0.0 && p.x.is_finite() && p.y.is_finite() => {
                    json!([p.x, p.y])
                }
                _ => Json::Null,
            })
            .collect();
        out.insert(f.frame.to_string(), Json::Array(uv));
    }
    Json::Object(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use vfxgraph_geometry::formats::MarkedFrame;
    use vfxgraph_geometry::Points2d;

    fn marks(frames: &[(usize, &[(f64, f64)])]) -> MarkedPoints {
        MarkedPoints {
            frames: frames
                .iter()
                .map(|(f, pts)| MarkedFrame {
                    frame: *f,
                    points: Points2d(
                        pts.iter()
                            .map(|&(x, y)| nalgebra::Point2::new(x, y))
                            .collect(),
                    ),
                })
                .collect(),
        }
    }

    #[test]
    fn validation() {
        assert!(validate(&marks(&[(1, &[(1.0, 2.0)]), (2, &[(3.0, 4.0)])])).is_ok());
        assert!(validate(&marks(&[])).is_err());
        assert!(validate(&marks(&[(1, &[])])).is_err());
        assert!(validate(&marks(&[(1, &[(1.0, 2.0)]), (1, &[(3.0, 4.0)])])).is_err());
        assert!(validate(&marks(&[
            (1, &[(1.0, 2.0)]),
            (2, &[(3.0, 4.0), (5.0, 6.0)])
        ]))
        .is_err());
        assert!(validate(&marks(&[(1, &[(f64::NAN, 2.0)])])).is_err());
    }
}
