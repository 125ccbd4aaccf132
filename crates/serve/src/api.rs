//! The HTTP routes. Reads are `GET`, changes `POST` with a JSON body; every error is a JSON
//! `{"error": …}` with a 4xx status for the client's mistakes (see [`crate::safety`]).
//!
//! | route | what |
//! | --- | --- |
//! | `GET /` , `GET /assets/{file}` | the page (embedded) |
//! | `GET /api/state` | graph, node docs, plan, live counts, last run, diagnostics |
//! | `GET /api/events` | server-sent events: `state`, `run_started` (`started_at`), `started`, `progress`, `finished`, `run_done` (`stopped`) |
//! | `POST /api/run`, `POST /api/cancel`, `POST /api/reload` | run (409 while one runs), stop, re-read the file |
//! | `POST /api/params` | `{node, param, value}` (YAML text, as `--set`; `null` resets) |
//! | `POST /api/params/save` | `{node, param}`: the edit written into the graph file (only that value's text) |
//! | `GET /api/image` | `node, port, frame, layer, exposure, srgb, display, view, fmt` → PNG/JPEG preview |
//! | `GET /api/colour` | `node` (optional) → the OpenColorIO config, the working space, the displays and their views |
//! | `GET /api/warm` | same query as `/api/image`: encodes every frame's preview in the background; progress |
//! | `GET /api/pixel` | `node, port, frame, layer, x, y` → linear values |
//! | `GET /api/artifact` | `node, port, frame` → a JSON artifact as stored, or an image's size and layers |
//! | `GET /api/file?path=` | a file under the graph's folder or the cache |
//! | `GET/POST /api/marks`, `POST /api/triangulate` | the point-cloud definer (triangulate: the points, the report, each point through every camera) |
//! | `POST /api/refine` | `{node, port, frame, layer, x, y, radius}` → the corner near (x, y), sub-pixel |

use std::sync::Arc;

use axum::body::Body;
use axum::extract::rejection::{JsonRejection, QueryRejection};
use axum::extract::{DefaultBodyLimit, Path as UrlPath, Query, State};
use axum::http::{header, StatusCode};
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use axum::{Json, Router};
use serde::Deserialize;
use serde_json::{json, Value as Json_};
use tokio_stream::wrappers::BroadcastStream;
use tokio_stream::StreamExt;
use vfxgraph_engine::store::Store;
use vfxgraph_engine::Graph;
use vfxgraph_geometry::formats::marked_points::MarkedPoints;

use crate::preview::{self, find_output, View};
use crate::safety::{self, ApiError, MAX_BODY};
use crate::studio::Studio;

type S = State<Arc<Studio>>;
type ApiResult = Result<Response, ApiError>;

/// The router of a studio; every request passes [`crate::access`]'s checks first.
pub fn router(studio: Arc<Studio>, access: crate::access::Access) -> Router {
    Router::new()
        .route("/", get(index))
        .route("/assets/{file}", get(asset))
        .route("/api/state", get(state))
        .route("/api/events", get(events))
        .route("/api/run", post(run))
        .route("/api/cancel", post(cancel))
        .route("/api/reload", post(reload))
        .route("/api/params", post(params))
        .route("/api/params/save", post(save_param))
        .route("/api/image", get(image))
        .route("/api/colour", get(colour))
        .route("/api/warm", get(warm))
        .route("/api/pixel", get(pixel))
        .route("/api/refine", post(refine))
        .route("/api/artifact", get(artifact))
        .route("/api/file", get(file))
        .route("/api/marks", get(get_marks).post(post_marks))
        .route("/api/triangulate", post(triangulate))
        .fallback(|| async { ApiError::not_found("no such route") })
        .layer(DefaultBodyLimit::max(MAX_BODY))
        .layer(axum::middleware::from_fn_with_state(
            Arc::new(access),
            crate::access::check,
        ))
        .with_state(studio)
}

fn json_rejection(r: JsonRejection) -> ApiError {
    ApiError::new(
        if r.status() == StatusCode::PAYLOAD_TOO_LARGE {
            StatusCode::PAYLOAD_TOO_LARGE
        } else {
            StatusCode::BAD_REQUEST
        },
        format!("bad request body: {}", r.body_text()),
    )
}

fn query_rejection(r: QueryRejection) -> ApiError {
    ApiError::bad(format!("bad query: {}", r.body_text()))
}

async fn index() -> Response {
    (
        [
            (header::CONTENT_TYPE, "text/html; charset=utf-8"),
            (header::CACHE_CONTROL, "no-cache"),
        ],
        crate::assets::INDEX_HTML,
    )
        .into_response()
}

async fn asset(UrlPath(file): UrlPath<String>) -> ApiResult {
    let (ty, bytes) = crate::assets::get(&file)
        .ok_or_else(|| ApiError::not_found(format!("no asset `{file}`")))?;
    Ok(([(header::CONTENT_TYPE, ty)], bytes).into_response())
}

async fn state(State(s): S) -> Json<Json_> {
    Json(s.snapshot())
}

async fn events(State(s): S) -> impl IntoResponse {
    let rx = s.subscribe();
    let stream = BroadcastStream::new(rx).map(|m| {
        Ok::<_, std::convert::Infallible>(match m {
            Ok(text) => Event::default().data(text.as_ref()),
            // A slow page missed events: tell it to fetch the whole state.
            Err(_) => Event::default().data(r#"{"kind":"state","lagged":true}"#),
        })
    });
    Sse::new(stream).keep_alive(KeepAlive::default())
}

async fn blocking<T: Send + 'static>(
    f: impl FnOnce() -> Result<T, ApiError> + Send + 'static,
) -> Result<T, ApiError> {
    tokio::task::spawn_blocking(f)
        .await
        .map_err(|e| ApiError::internal(format!("the request's task failed: {e}")))?
}

async fn run(State(s): S) -> ApiResult {
    if s.graph().is_none() {
        return Err(ApiError::conflict(
            "the graph does not load: fix it and reload",
        ));
    }
    if !s.start_run() {
        return Err(ApiError::conflict("a run is going on"));
    }
    Ok((StatusCode::ACCEPTED, Json(json!({ "started": true }))).into_response())
}

async fn cancel(State(s): S) -> Json<Json_> {
    s.cancel();
    Json(json!({ "cancelling": s.is_running() }))
}

async fn reload(State(s): S) -> ApiResult {
    if s.is_running() {
        return Err(ApiError::conflict("a run is going on"));
    }
    let s2 = s.clone();
    blocking(move || {
        s2.reload();
        Ok(())
    })
    .await?;
    Ok(Json(s.snapshot()).into_response())
}

#[derive(Deserialize)]
struct ParamEdit {
    node: String,
    param: String,
    /// YAML text (as `--set`), or null to drop the override.
    value: Option<String>,
}

async fn params(State(s): S, body: Result<Json<ParamEdit>, JsonRejection>) -> ApiResult {
    let Json(edit) = body.map_err(json_rejection)?;
    if s.is_running() {
        return Err(ApiError::conflict("a run is going on: edit after it"));
    }
    let g = s
        .graph()
        .ok_or_else(|| ApiError::conflict("the graph does not load"))?;
    let node = g
        .index_of(&edit.node)
        .ok_or_else(|| ApiError::bad(format!("no node `{}` in the graph", edit.node)))?;
    if g.nodes[node].spec().param_desc(&edit.param).is_none() {
        return Err(ApiError::bad(format!(
            "node `{}` ({}) has no param `{}`",
            edit.node,
            g.nodes[node].spec().name,
            edit.param
        )));
    }
    if let Some(v) = &edit.value {
        if v.contains('\n') || v.len() > 4096 {
            return Err(ApiError::bad(
                "a param value is one line of at most 4096 bytes",
            ));
        }
    }
    let s2 = s.clone();
    blocking(move || {
        s2.set_param(&edit.node, &edit.param, edit.value.as_deref())
            .map_err(|d| {
                let msg = d
                    .iter()
                    .map(|l| l.message.clone())
                    .collect::<Vec<_>>()
                    .join("; ");
                ApiError::bad(format!("rejected: {msg}")).with(json!({ "diagnostics": d }))
            })
    })
    .await?;
    Ok(Json(s.snapshot()).into_response())
}

#[derive(Deserialize)]
struct ParamRef {
    node: String,
    param: String,
}

/// Writes a param's edit into the graph file (see [`Studio::save_param`]).
async fn save_param(State(s): S, body: Result<Json<ParamRef>, JsonRejection>) -> ApiResult {
    let Json(p) = body.map_err(json_rejection)?;
    if s.is_running() {
        return Err(ApiError::conflict("a run is going on: save after it"));
    }
    let s2 = s.clone();
    let value = blocking(move || {
        s2.save_param(&p.node, &p.param)
            .map_err(|e| ApiError::new(StatusCode::UNPROCESSABLE_ENTITY, e))
    })
    .await?;
    let mut snap = s.snapshot();
    snap["saved"] = json!(value);
    Ok(Json(snap).into_response())
}

#[derive(Deserialize)]
struct OutputQuery {
    node: String,
    port: String,
    frame: Option<i64>,
    layer: Option<String>,
    #[serde(default)]
    exposure: f32,
    #[serde(default = "yes")]
    srgb: bool,
    display: Option<String>,
    view: Option<String>,
    fmt: Option<String>,
    x: Option<i64>,
    y: Option<i64>,
}

fn yes() -> bool {
    true
}

fn loaded(s: &Studio) -> Result<(Arc<Graph>, Store), ApiError> {
    let g = s
        .graph()
        .ok_or_else(|| ApiError::conflict("the graph does not load"))?;
    let store = Store::open(&s.cache_dir)
        .map_err(|e| ApiError::internal(format!("cannot open the cache: {e}")))?;
    Ok((g, store))
}

fn view_of(s: &Studio, q: &OutputQuery) -> Result<View, ApiError> {
    if !(q.exposure.is_finite() && q.exposure.abs() <= 32.0) {
        return Err(ApiError::bad("exposure must be within ±32 stops"));
    }
    let jpeg = match q.fmt.as_deref() {
        None | Some("png") => false,
        Some("jpg" | "jpeg") => true,
        Some(other) => {
            return Err(ApiError::bad(format!(
                "unknown format `{other}` (png, jpg)"
            )))
        }
    };
    let display = match q.display.as_deref().filter(|d| !d.is_empty()) {
        None => None,
        Some(display) => {
            let g = s
                .graph()
                .ok_or_else(|| ApiError::conflict("the graph does not load"))?;
            let node = g
                .index_of(&q.node)
                .ok_or_else(|| ApiError::not_found(format!("no node `{}` in the graph", q.node)))?;
            let (config, space) = preview::output_colour(&g, node)?;
            let view = q.view.as_deref().filter(|v| !v.is_empty());
            Some(s.previews.display_view(&config, space, display, view)?)
        }
    };
    Ok(View {
        exposure: q.exposure,
        srgb: q.srgb,
        jpeg,
        display,
    })
}

#[derive(Deserialize)]
struct ColourQuery {
    node: Option<String>,
}

/// The colour management the previews of `node`'s outputs (default: the graph's first node)
/// can use: the OpenColorIO config, the space the values are in, every display and its views.
async fn colour(State(s): S, q: Result<Query<ColourQuery>, QueryRejection>) -> ApiResult {
    let Query(q) = q.map_err(query_rejection)?;
    let r = blocking(move || {
        let g = s
            .graph()
            .ok_or_else(|| ApiError::conflict("the graph does not load"))?;
        let node = match &q.node {
            Some(id) => g
                .index_of(id)
                .ok_or_else(|| ApiError::not_found(format!("no node `{id}` in the graph")))?,
            None => 0,
        };
        if g.nodes.is_empty() {
            return Err(ApiError::conflict("the graph has no nodes"));
        }
        let (config, space) = preview::output_colour(&g, node)?;
        let displays: Vec<Json_> = config
            .displays()
            .into_iter()
            .map(|d| json!({ "display": d, "views": config.views(&d) }))
            .collect();
        Ok(json!({
            "config": config.source(),
            "working_space": space.name(),
            "displays": displays,
        }))
    })
    .await?;
    Ok(Json(r).into_response())
}

async fn image(State(s): S, q: Result<Query<OutputQuery>, QueryRejection>) -> ApiResult {
    let Query(q) = q.map_err(query_rejection)?;
    let view = view_of(&s, &q)?;
    let jpeg = view.jpeg;
    let bytes = blocking(move || {
        let (g, store) = loaded(&s)?;
        let out = find_output(&g, &store, &q.node, &q.port, q.frame)?;
        s.previews
            .preview(&store, &s.registry, &out, q.layer.as_deref(), &view)
    })
    .await?;
    let ty = if jpeg { "image/jpeg" } else { "image/png" };
    Ok((
        [
            (header::CONTENT_TYPE, ty),
            (header::CACHE_CONTROL, "no-cache"),
        ],
        Body::from(bytes.as_ref().clone()),
    )
        .into_response())
}

/// Encodes the previews of every frame of an output (from `frame` on, wrapping) on one
/// background thread, so the scrubber finds them encoded; answers the progress at once. Asking
/// again with the same query answers the same warming's progress; another query (or a new
/// run) replaces it.
async fn warm(State(s): S, q: Result<Query<OutputQuery>, QueryRejection>) -> ApiResult {
    let Query(q) = q.map_err(query_rejection)?;
    let view = view_of(&s, &q)?;
    let g = s
        .graph()
        .ok_or_else(|| ApiError::conflict("the graph does not load"))?;
    let node = g
        .index_of(&q.node)
        .ok_or_else(|| ApiError::not_found(format!("no node `{}` in the graph", q.node)))?;
    if !g.nodes[node]
        .spec()
        .outputs
        .iter()
        .any(|p| p.name == q.port)
    {
        return Err(ApiError::not_found(format!(
            "node `{}` has no output `{}`",
            q.node, q.port
        )));
    }
    let per_frame = g.instances_of(&g.nodes[node]) > 1 || g.nodes[node].per_frame;
    let mut frames: Vec<Option<i64>> = if per_frame {
        g.frames.frames().iter().copied().map(Some).collect()
    } else {
        vec![None]
    };
    if let Some(i) = q
        .frame
        .and_then(|f| frames.iter().position(|x| *x == Some(f)))
    {
        frames.rotate_left(i);
    }
    let key = format!(
        "{}|{}|{}|{}|{}",
        s.runs(),
        q.node,
        q.port,
        q.layer.as_deref().unwrap_or(""),
        view.key()
    );
    let (w, start) = s.previews.warming(&key, frames.len());
    if start {
        let (s2, w2) = (s.clone(), w.clone());
        std::thread::spawn(move || {
            use std::sync::atomic::Ordering::Relaxed;
            let Ok((g, store)) = loaded(&s2) else { return };
            for f in frames {
                if w2.stale.load(Relaxed) {
                    return;
                }
                let r = find_output(&g, &store, &q.node, &q.port, f).and_then(|out| {
                    s2.previews
                        .preview(&store, &s2.registry, &out, q.layer.as_deref(), &view)
                });
                match r {
                    Ok(_) => w2.done.fetch_add(1, Relaxed),
                    Err(_) => w2.failed.fetch_add(1, Relaxed),
                };
            }
        });
    }
    Ok(Json(w.json()).into_response())
}

#[derive(Deserialize)]
struct RefineBody {
    node: String,
    port: String,
    frame: Option<i64>,
    layer: Option<String>,
    x: f64,
    y: f64,
    #[serde(default = "five")]
    radius: usize,
}

fn five() -> usize {
    5
}

/// The corner near a definer click, at sub-pixel precision (see [`crate::refine`]).
async fn refine(State(s): S, body: Result<Json<RefineBody>, JsonRejection>) -> ApiResult {
    let Json(b) = body.map_err(json_rejection)?;
    if !(1..=crate::refine::MAX_RADIUS).contains(&b.radius) {
        return Err(ApiError::bad(format!(
            "radius must be 1 to {}",
            crate::refine::MAX_RADIUS
        )));
    }
    let r = blocking(move || {
        let (g, store) = loaded(&s)?;
        let out = find_output(&g, &store, &b.node, &b.port, b.frame)?;
        let art = s.previews.artifact(&store, &s.registry, &out)?;
        let img = preview::image_of(art.as_ref(), b.layer.as_deref())?;
        if !(b.x.is_finite()
            && b.y.is_finite()
            && b.x >= -0.5
            && b.y >= -0.5
            && b.x < img.width as f64 - 0.5
            && b.y < img.height as f64 - 0.5)
        {
            return Err(ApiError::bad(format!(
                "({}, {}) is outside the {}×{} image",
                b.x, b.y, img.width, img.height
            )));
        }
        Ok(
            match crate::refine::refine_corner(img, b.x, b.y, b.radius) {
                Some((x, y)) => json!({ "x": x, "y": y, "refined": true }),
                None => json!({ "x": b.x, "y": b.y, "refined": false }),
            },
        )
    })
    .await?;
    Ok(Json(r).into_response())
}

async fn pixel(State(s): S, q: Result<Query<OutputQuery>, QueryRejection>) -> ApiResult {
    let Query(q) = q.map_err(query_rejection)?;
    let (x, y) = match (q.x, q.y) {
        (Some(x), Some(y)) => (x, y),
        _ => return Err(ApiError::bad("give x and y")),
    };
    let v = blocking(move || {
        let (g, store) = loaded(&s)?;
        let out = find_output(&g, &store, &q.node, &q.port, q.frame)?;
        let art = s.previews.artifact(&store, &s.registry, &out)?;
        let img = preview::image_of(art.as_ref(), q.layer.as_deref())?;
        preview::pixel(img, x, y)
    })
    .await?;
    Ok(Json(json!({ "x": x, "y": y, "value": v })).into_response())
}

async fn artifact(State(s): S, q: Result<Query<OutputQuery>, QueryRejection>) -> ApiResult {
    let Query(q) = q.map_err(query_rejection)?;
    let r = blocking(move || {
        let (g, store) = loaded(&s)?;
        let out = find_output(&g, &store, &q.node, &q.port, q.frame)?;
        let art = s.previews.artifact(&store, &s.registry, &out)?;
        if preview::IMAGE_TYPES.contains(&art.type_name()) {
            let layers = preview::layer_names(art.as_ref());
            let img = preview::image_of(art.as_ref(), None)?;
            let info = json!({
                "type": art.type_name(), "width": img.width, "height": img.height,
                "channels": img.channels, "layers": layers, "digest": out.digest.to_hex(),
            });
            return Ok(Json(info).into_response());
        }
        let bytes = preview::json_bytes(art.as_ref())?;
        Ok(([(header::CONTENT_TYPE, "application/json")], bytes).into_response())
    })
    .await?;
    Ok(r)
}

#[derive(Deserialize)]
struct FileQuery {
    path: String,
}

async fn file(State(s): S, q: Result<Query<FileQuery>, QueryRejection>) -> ApiResult {
    let Query(q) = q.map_err(query_rejection)?;
    let g = s
        .graph()
        .ok_or_else(|| ApiError::conflict("the graph does not load"))?;
    let roots = [g.dir.clone(), s.cache_dir.clone()];
    let path = safety::resolve_served(&g.dir, &roots, &q.path)?;
    let bytes = tokio::fs::read(&path)
        .await
        .map_err(|e| ApiError::not_found(format!("cannot read `{}`: {e}", q.path)))?;
    Ok(([(header::CONTENT_TYPE, safety::content_type(&path))], bytes).into_response())
}

#[derive(Deserialize)]
struct MarksQuery {
    node: String,
}

async fn get_marks(State(s): S, q: Result<Query<MarksQuery>, QueryRejection>) -> ApiResult {
    let Query(q) = q.map_err(query_rejection)?;
    let g = s
        .graph()
        .ok_or_else(|| ApiError::conflict("the graph does not load"))?;
    let (path, m) = blocking(move || crate::definer::read(&g, &q.node)).await?;
    Ok(Json(json!({ "path": path.display().to_string(), "marks": m })).into_response())
}

#[derive(Deserialize)]
struct MarksBody {
    node: String,
    marks: MarkedPoints,
}

async fn post_marks(State(s): S, body: Result<Json<MarksBody>, JsonRejection>) -> ApiResult {
    let Json(b) = body.map_err(json_rejection)?;
    if s.is_running() {
        return Err(ApiError::conflict("a run is going on: save after it"));
    }
    let g = s
        .graph()
        .ok_or_else(|| ApiError::conflict("the graph does not load"))?;
    let s2 = s.clone();
    let written = blocking(move || {
        let w = crate::definer::save(&g, &b.node, &b.marks)?;
        s2.refresh_plan();
        Ok(w)
    })
    .await?;
    let mut snap = s.snapshot();
    snap["written"] = json!(written
        .iter()
        .map(|p| p.display().to_string())
        .collect::<Vec<_>>());
    Ok(Json(snap).into_response())
}

async fn triangulate(State(s): S, body: Result<Json<MarksBody>, JsonRejection>) -> ApiResult {
    let Json(b) = body.map_err(json_rejection)?;
    let r = blocking(move || {
        let (g, store) = loaded(&s)?;
        crate::definer::triangulate(&g, &store, &s.registry, &s.previews, &b.node, &b.marks)
    })
    .await?;
    Ok(Json(r).into_response())
}
