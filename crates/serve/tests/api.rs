//! The HTTP API without a browser: the router answered in-process (tower `oneshot`). Refused
//! requests (traversal, oversized bodies, malformed params and marks) get a 4xx and change
//! nothing; a graph that does not load is served with its diagnostics; a run from the API
//! stores outputs whose previews and pixels are served; the book's marks round-trip to its file;
//! a param edit saved into the graph file changes that value's text only.

use std::path::Path;
use std::sync::Arc;
use std::time::{Duration, Instant};

use axum::body::Body;
use axum::http::{Request, StatusCode};
use http_body_util::BodyExt;
use serde_json::{json, Value};
use tower::ServiceExt;
use vfxgraph_serve::{router, Access, Studio};

const GRAPH: &str = "version: 1
frames: 1,2
nodes:
  plate:
    type: read_image_sequence
    params: {path: plate.%04d.pfm}
  grade:
    type: exposure
    inputs: {image: plate.sequence}
    params: {stops: 1}
  marks:
    type: read_marks
    params: {path: marks.txt}
";

fn studio(dir: &Path, graph: &str) -> Arc<Studio> {
    std::fs::write(dir.join("g.yaml"), graph).unwrap();
    for f in [1, 2] {
        let img = vfxgraph_imaging::Image::from_fn(4, 3, 3, |x, y, c| {
            (x + 10 * y + 100 * c) as f32 / 1000.0 + f as f32
        });
        vfxgraph_imaging::write_image(&dir.join(format!("plate.{f:04}.pfm")), &img).unwrap();
    }
    std::fs::write(dir.join("marks.txt"), "Frame 1\nNpoints 1\n1 2\n\n").unwrap();
    let s = Arc::new(Studio::open(
        dir.join("g.yaml"),
        dir.join(".vfxgraph"),
        Arc::new(vfxgraph_nodes::registry()),
        Some(1),
    ));
    s.refresh_plan();
    s
}

async fn call(
    s: &Arc<Studio>,
    method: &str,
    uri: &str,
    body: Option<Vec<u8>>,
) -> (StatusCode, Vec<u8>) {
    let req = Request::builder()
        .method(method)
        .uri(uri)
        .header("host", "127.0.0.1:8080")
        .header("content-type", "application/json")
        .body(body.map_or_else(Body::empty, Body::from))
        .unwrap();
    send(s, req).await
}

/// The studio's answer to `req`, served at 127.0.0.1:8080.
async fn send(s: &Arc<Studio>, req: Request<Body>) -> (StatusCode, Vec<u8>) {
    let access = Access::for_address("127.0.0.1:8080".parse().unwrap(), None);
    let resp = router(s.clone(), access).oneshot(req).await.unwrap();
    let status = resp.status();
    let bytes = resp
        .into_body()
        .collect()
        .await
        .unwrap()
        .to_bytes()
        .to_vec();
    (status, bytes)
}

async fn get_json(s: &Arc<Studio>, uri: &str) -> (StatusCode, Value) {
    let (st, b) = call(s, "GET", uri, None).await;
    (st, serde_json::from_slice(&b).unwrap_or(Value::Null))
}

async fn post_json(s: &Arc<Studio>, uri: &str, v: Value) -> (StatusCode, Value) {
    let (st, b) = call(s, "POST", uri, Some(v.to_string().into_bytes())).await;
    (st, serde_json::from_slice(&b).unwrap_or(Value::Null))
}

#[tokio::test]
async fn files_outside_the_roots_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let s = studio(dir.path(), GRAPH);
    let (st, b) = call(&s, "GET", "/api/file?path=g.yaml", None).await;
    assert_eq!(st, StatusCode::OK);
    assert_eq!(b, GRAPH.as_bytes());
    for bad in [
        "/api/file?path=../g.yaml",
        "/api/file?path=%2e%2e%2f%2e%2e%2fetc%2fpasswd",
        "/api/file?path=/etc/passwd",
        "/api/file?path=sub/../../x",
    ] {
        let (st, v) = get_json(&s, bad).await;
        assert_eq!(st, StatusCode::FORBIDDEN, "{bad}: {v}");
        assert!(v["error"].as_str().unwrap().contains("not allowed"), "{v}");
    }
    let (st, _) = get_json(&s, "/api/file?path=nothing.txt").await;
    assert_eq!(st, StatusCode::NOT_FOUND);
    let (st, _) = get_json(&s, "/api/file").await;
    assert_eq!(st, StatusCode::BAD_REQUEST);
    let (st, _) = get_json(&s, "/assets/..%2Fsrc%2Flib.rs").await;
    assert_eq!(st, StatusCode::NOT_FOUND);
}

#[tokio::test]
async fn oversized_and_malformed_bodies_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let s = studio(dir.path(), GRAPH);
    let before = std::fs::read(dir.path().join("marks.txt")).unwrap();
    let big = format!(
        r#"{{"node": "marks", "marks": {{"frames": [{{"frame": 1, "points": [{}]}}]}}}}"#,
        vec!["[1.0, 2.0]"; 40_000].join(",")
    );
    assert!(big.len() > vfxgraph_serve::safety::MAX_BODY);
    let (st, _) = call(&s, "POST", "/api/marks", Some(big.into_bytes())).await;
    assert_eq!(st, StatusCode::PAYLOAD_TOO_LARGE);
    let (st, v) = call(&s, "POST", "/api/params", Some(b"{not json".to_vec())).await;
    assert_eq!(
        st,
        StatusCode::BAD_REQUEST,
        "{}",
        String::from_utf8_lossy(&v)
    );
    // Marks that are not the book's form: refused, the file as it was.
    for bad in [
        json!({"node": "marks", "marks": {"frames": []}}),
        json!({"node": "marks", "marks": {"frames": [
            {"frame": 1, "points": [[1, 2]]}, {"frame": 2, "points": [[1, 2], [3, 4]]}]}}),
        json!({"node": "marks", "marks": {"frames": [
            {"frame": 1, "points": [[1, 2]]}, {"frame": 1, "points": [[3, 4]]}]}}),
        json!({"node": "grade", "marks": {"frames": [{"frame": 1, "points": [[1, 2]]}]}}),
        json!({"node": "marks", "marks": {"frames": [{"frame": -1, "points": [[1, 2]]}]}}),
    ] {
        let (st, v) = post_json(&s, "/api/marks", bad.clone()).await;
        assert!(st.is_client_error(), "{bad}: {st} {v}");
    }
    assert_eq!(std::fs::read(dir.path().join("marks.txt")).unwrap(), before);
}

#[tokio::test]
async fn bad_params_change_nothing_good_ones_replan() {
    let dir = tempfile::tempdir().unwrap();
    let s = studio(dir.path(), GRAPH);
    for (edit, want) in [
        (
            json!({"node": "nope", "param": "stops", "value": "1"}),
            "no node",
        ),
        (
            json!({"node": "grade", "param": "nope", "value": "1"}),
            "no param",
        ),
        (
            json!({"node": "grade", "param": "stops", "value": "[1, 2"}),
            "rejected",
        ),
        (
            json!({"node": "grade", "param": "stops", "value": "lots"}),
            "rejected",
        ),
        (
            json!({"node": "grade", "param": "stops", "value": "1\nx: 2"}),
            "one line",
        ),
        (json!({"node": "grade"}), "bad request body"),
    ] {
        let (st, v) = post_json(&s, "/api/params", edit.clone()).await;
        assert_eq!(st, StatusCode::BAD_REQUEST, "{edit}: {v}");
        assert!(v["error"].as_str().unwrap().contains(want), "{edit}: {v}");
        assert_eq!(s.snapshot()["sets"], json!([]));
    }
    let (st, v) = post_json(
        &s,
        "/api/params",
        json!({"node": "grade", "param": "stops", "value": "2.5"}),
    )
    .await;
    assert_eq!(st, StatusCode::OK, "{v}");
    assert_eq!(v["sets"], json!(["grade.stops=2.5"]));
    let grade = v["graph"]["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .find(|n| n["id"] == "grade")
        .unwrap()
        .clone();
    let stops = grade["params"]
        .as_array()
        .unwrap()
        .iter()
        .find(|p| p["name"] == "stops")
        .unwrap();
    assert_eq!(stops["value"], "2.5");
    // The graph file itself is never rewritten.
    assert_eq!(
        std::fs::read_to_string(dir.path().join("g.yaml")).unwrap(),
        GRAPH
    );
}

#[tokio::test]
async fn a_broken_graph_is_served_with_its_diagnostics() {
    let dir = tempfile::tempdir().unwrap();
    let s = studio(
        dir.path(),
        "version: 1\nnodes:\n  a:\n    type: no_such_node\n",
    );
    let (st, page) = call(&s, "GET", "/", None).await;
    assert_eq!(st, StatusCode::OK);
    assert!(String::from_utf8_lossy(&page).contains("vfxgraph studio"));
    let (st, v) = get_json(&s, "/api/state").await;
    assert_eq!(st, StatusCode::OK);
    assert!(v["graph"].is_null());
    let d = &v["diagnostics"][0];
    let text = d["text"].as_str().unwrap();
    assert!(text.contains("g.yaml:4:11"), "{text}");
    assert!(text.contains("no_such_node"), "{text}");
    let (st, _) = post_json(&s, "/api/run", json!({})).await;
    assert_eq!(st, StatusCode::CONFLICT);
}

fn wait_idle(s: &Studio) {
    let t0 = Instant::now();
    while s.is_running() {
        assert!(t0.elapsed() < Duration::from_secs(120), "the run hangs");
        std::thread::sleep(Duration::from_millis(10));
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_run_serves_previews_pixels_and_events() {
    let dir = tempfile::tempdir().unwrap();
    let s = studio(dir.path(), GRAPH);
    let (st, v) = get_json(&s, "/api/image?node=grade&port=image&frame=1").await;
    assert_eq!(st, StatusCode::NOT_FOUND, "no output before a run: {v}");
    let mut rx = s.subscribe();
    let (st, _) = post_json(&s, "/api/run", json!({})).await;
    assert_eq!(st, StatusCode::ACCEPTED);
    let s2 = s.clone();
    tokio::task::spawn_blocking(move || wait_idle(&s2))
        .await
        .unwrap();
    let mut kinds = vec![];
    while let Ok(m) = rx.try_recv() {
        let v: Value = serde_json::from_str(&m).unwrap();
        kinds.push((v["kind"].as_str().unwrap().to_string(), v["node"].clone()));
    }
    assert!(
        kinds.iter().any(|(k, n)| k == "started" && n == "grade"),
        "{kinds:?}"
    );
    assert!(
        kinds.iter().any(|(k, n)| k == "finished" && n == "grade"),
        "{kinds:?}"
    );
    assert!(kinds.iter().any(|(k, _)| k == "run_done"), "{kinds:?}");

    let (st, png) = call(
        &s,
        "GET",
        "/api/image?node=grade&port=image&frame=2&srgb=false",
        None,
    )
    .await;
    assert_eq!(st, StatusCode::OK);
    let img = vfxgraph_imaging::decode(&png, vfxgraph_imaging::Format::Png).unwrap();
    assert_eq!((img.width, img.height), (4, 3));
    let (st, v) = get_json(&s, "/api/pixel?node=grade&port=image&frame=2&x=3&y=2").await;
    assert_eq!(st, StatusCode::OK, "{v}");
    let want = [
        (3 + 20) as f64 / 1000.0 + 2.0,
        (3 + 20 + 100) as f64 / 1000.0 + 2.0,
    ];
    assert!(
        (v["value"][0].as_f64().unwrap() - 2.0 * want[0]).abs() < 1e-5,
        "{v}"
    );
    assert!(
        (v["value"][1].as_f64().unwrap() - 2.0 * want[1]).abs() < 1e-5,
        "{v}"
    );
    for (bad, code) in [
        (
            "/api/pixel?node=grade&port=image&frame=2&x=4&y=0",
            StatusCode::BAD_REQUEST,
        ),
        (
            "/api/pixel?node=grade&port=image&frame=9&x=0&y=0",
            StatusCode::NOT_FOUND,
        ),
        (
            "/api/image?node=grade&port=image&frame=1&exposure=nan",
            StatusCode::BAD_REQUEST,
        ),
        (
            "/api/image?node=grade&port=image&frame=1&exposure=1e9",
            StatusCode::BAD_REQUEST,
        ),
        (
            "/api/image?node=grade&port=image&frame=1&fmt=gif",
            StatusCode::BAD_REQUEST,
        ),
        ("/api/image?node=grade&port=image", StatusCode::BAD_REQUEST),
        (
            "/api/image?node=zz&port=image&frame=1",
            StatusCode::NOT_FOUND,
        ),
        (
            "/api/image?node=grade&port=zz&frame=1",
            StatusCode::NOT_FOUND,
        ),
        (
            "/api/image?node=grade&port=image&frame=x",
            StatusCode::BAD_REQUEST,
        ),
    ] {
        let (st, v) = get_json(&s, bad).await;
        assert_eq!(st, code, "{bad}: {v}");
    }
    let (st, v) = get_json(&s, "/api/artifact?node=marks&port=marks").await;
    assert_eq!(st, StatusCode::OK);
    assert_eq!(v["frames"][0]["frame"], 1);

    // Warming: every frame's preview encoded in the background; asking again answers the
    // same warming's progress; the previews then served are the ones encoded.
    let q = "/api/warm?node=grade&port=image&frame=2&fmt=jpg";
    let (st, v) = get_json(&s, q).await;
    assert_eq!(st, StatusCode::OK, "{v}");
    assert_eq!(v["total"], 2);
    let t0 = std::time::Instant::now();
    loop {
        let (_, v) = get_json(&s, q).await;
        if v["done"] == 2 {
            break;
        }
        assert!(t0.elapsed().as_secs() < 60, "warming stuck: {v}");
        tokio::time::sleep(std::time::Duration::from_millis(20)).await;
    }
    for (bad, code) in [
        (
            "/api/warm?node=grade&port=image&exposure=nan",
            StatusCode::BAD_REQUEST,
        ),
        ("/api/warm?node=zz&port=image", StatusCode::NOT_FOUND),
        ("/api/warm?node=grade&port=zz", StatusCode::NOT_FOUND),
        ("/api/warm?node=grade", StatusCode::BAD_REQUEST),
    ] {
        let (st, v) = get_json(&s, bad).await;
        assert_eq!(st, code, "{bad}: {v}");
    }
    // Refinement requests: outside the image, a bad radius, not finite → 400.
    for bad in [
        json!({"node": "grade", "port": "image", "frame": 1, "x": 9.0, "y": 1.0}),
        json!({"node": "grade", "port": "image", "frame": 1, "x": 1.0, "y": -3.0}),
        json!({"node": "grade", "port": "image", "frame": 1, "x": 1.0, "y": 1.0, "radius": 99}),
        json!({"node": "grade", "port": "image", "frame": 1, "x": "a", "y": 1.0}),
        json!({"node": "grade", "port": "image", "x": 1.0, "y": 1.0}),
    ] {
        let (st, v) = post_json(&s, "/api/refine", bad.clone()).await;
        assert_eq!(st, StatusCode::BAD_REQUEST, "{bad}: {v}");
    }
    // A ramp has no corner: the click stays.
    let (st, v) = post_json(
        &s,
        "/api/refine",
        json!({"node": "grade", "port": "image", "frame": 1, "x": 1.0, "y": 1.0, "radius": 1}),
    )
    .await;
    assert_eq!(st, StatusCode::OK, "{v}");
    assert_eq!(v, json!({"x": 1.0, "y": 1.0, "refined": false}));
}

#[tokio::test]
async fn the_vendored_three_js_is_served_with_its_licence() {
    let dir = tempfile::tempdir().unwrap();
    let s = studio(dir.path(), GRAPH);
    for (file, needle) in [
        ("three.module.min.js", "./three.core.min.js"),
        ("three.core.min.js", "WebGL"),
        ("three.LICENSE", "MIT License"),
    ] {
        let (st, b) = call(&s, "GET", &format!("/assets/{file}"), None).await;
        assert_eq!(st, StatusCode::OK, "{file}");
        assert!(String::from_utf8_lossy(&b).contains(needle), "{file}");
    }
}

#[tokio::test]
async fn the_books_marks_are_written_as_the_books_file() {
    let Some(book) = vfxgraph_testdata::path("book-demo/points2d.txt") else {
        return;
    };
    let text = std::fs::read_to_string(&book).unwrap();
    let marks = vfxgraph_geometry::formats::marked_points::parse_marked_points(&text, "b").unwrap();
    let dir = tempfile::tempdir().unwrap();
    let s = studio(dir.path(), GRAPH);
    let (st, v) = post_json(&s, "/api/marks", json!({"node": "marks", "marks": marks})).await;
    assert_eq!(st, StatusCode::OK, "{v}");
    assert_eq!(
        std::fs::read_to_string(dir.path().join("marks.txt")).unwrap(),
        text
    );
    let (st, v) = get_json(&s, "/api/marks?node=marks").await;
    assert_eq!(st, StatusCode::OK);
    assert_eq!(v["marks"], serde_json::to_value(&marks).unwrap());
    // The saved file is read_marks' input: the plan reruns it.
    let plan = &s.snapshot()["plan"];
    let m = plan
        .as_array()
        .unwrap()
        .iter()
        .find(|p| p["id"] == "marks")
        .unwrap();
    assert_eq!(m["status"], "run", "{m}");
}

/// The probes of an attacker's page (a cross-site form or `fetch`, a DNS-rebound name): every
/// change they attempt is refused with a 4xx, and nothing runs; the studio's own requests pass.
#[tokio::test]
async fn requests_from_another_site_or_host_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let s = studio(tmp.path(), GRAPH);
    let probe = |method: &str, uri: &str, headers: &[(&str, &str)], body: &str| {
        let mut b = Request::builder().method(method).uri(uri);
        for (k, v) in headers {
            b = b.header(*k, *v);
        }
        b.body(Body::from(body.to_string())).unwrap()
    };
    let host = ("host", "127.0.0.1:8080");
    let evil = ("origin", "http://evil.example");
    let plain = ("content-type", "text/plain");
    let json = ("content-type", "application/json");
    for uri in ["/api/run", "/api/cancel", "/api/reload"] {
        // A cross-site form or no-cors fetch: text/plain from another origin.
        let (st, body) = send(&s, probe("POST", uri, &[host, evil, plain], "{}")).await;
        assert_eq!(
            st,
            StatusCode::FORBIDDEN,
            "{uri}: {}",
            String::from_utf8_lossy(&body)
        );
        // Its own origin but not JSON (what a form could send).
        let (st, _) = send(&s, probe("POST", uri, &[host, plain], "{}")).await;
        assert_eq!(st, StatusCode::UNSUPPORTED_MEDIA_TYPE, "{uri}");
        // The browser's fetch metadata says cross-site.
        let cross = ("sec-fetch-site", "cross-site");
        let (st, _) = send(&s, probe("POST", uri, &[host, json, cross], "{}")).await;
        assert_eq!(st, StatusCode::FORBIDDEN, "{uri}");
    }
    assert!(!s.is_running(), "no probe started a run");
    // DNS rebinding: the page's own origin under the attacker's name.
    let rebound = ("host", "evil.example:8080");
    let (st, _) = send(&s, probe("GET", "/api/state", &[rebound], "")).await;
    assert_eq!(st, StatusCode::FORBIDDEN);
    let origin = ("origin", "http://evil.example:8080");
    let (st, _) = send(
        &s,
        probe("POST", "/api/run", &[rebound, origin, json], "{}"),
    )
    .await;
    assert_eq!(st, StatusCode::FORBIDDEN);
    let (st, _) = send(
        &s,
        probe(
            "POST",
            "/api/params",
            &[rebound, json],
            r#"{"node":"grade","param":"stops","value":"3"}"#,
        ),
    )
    .await;
    assert_eq!(st, StatusCode::FORBIDDEN);
    assert!(!s.is_running());
    // The studio's own page: same origin, JSON.
    let own = ("origin", "http://127.0.0.1:8080");
    let (st, body) = send(&s, probe("POST", "/api/cancel", &[host, own, json], "{}")).await;
    assert_eq!(st, StatusCode::OK, "{}", String::from_utf8_lossy(&body));
    let (st, _) = send(
        &s,
        probe("GET", "/api/state", &[("host", "localhost:8080")], ""),
    )
    .await;
    assert_eq!(st, StatusCode::OK);
}

/// Off loopback a token is required (printed once in the URL): without it every route answers
/// 401; opened with `?token=`, the page gets it as a cookie for its later requests.
#[tokio::test]
async fn off_loopback_the_token_is_required() {
    let tmp = tempfile::tempdir().unwrap();
    let s = studio(tmp.path(), GRAPH);
    let access = Access::for_address("0.0.0.0:8080".parse().unwrap(), None);
    let token = access.token().unwrap().to_string();
    let get = |uri: &str, cookie: Option<&str>| {
        let mut b = Request::builder()
            .uri(uri)
            .header("host", "studio.lan:8080");
        if let Some(c) = cookie {
            b = b.header("cookie", c);
        }
        b.body(Body::empty()).unwrap()
    };
    let r = router(s.clone(), access.clone());
    let resp = r.clone().oneshot(get("/api/state", None)).await.unwrap();
    assert_eq!(resp.status(), StatusCode::UNAUTHORIZED);
    let resp = r.clone().oneshot(get("/", None)).await.unwrap();
    assert_eq!(resp.status(), StatusCode::UNAUTHORIZED);
    let resp = r
        .clone()
        .oneshot(get(&format!("/?token={token}"), None))
        .await
        .unwrap();
    assert_eq!(resp.status(), StatusCode::OK);
    let cookie = resp.headers()["set-cookie"].to_str().unwrap().to_string();
    assert!(
        cookie.contains("HttpOnly") && cookie.contains("SameSite=Strict"),
        "{cookie}"
    );
    let pair = cookie.split(';').next().unwrap();
    let resp = r
        .clone()
        .oneshot(get("/api/state", Some(pair)))
        .await
        .unwrap();
    assert_eq!(resp.status(), StatusCode::OK);
}

/// A path parameter set from the page names files in the graph's folder (or the cache) only —
/// absolute paths, `..` and symlinks out are refused, and nothing changes — and the marks file
/// is read and written only there, even when the graph file itself points elsewhere (the error
/// does not quote the other file).
#[tokio::test]
async fn paths_set_from_the_page_stay_in_the_graph_folder() {
    let root = tempfile::tempdir().unwrap();
    let dir = root.path().join("shot");
    let outside = root.path().join("outside");
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::create_dir_all(&outside).unwrap();
    std::fs::write(outside.join("secret.txt"), "Frame 1\nNpoints 1\n7 7\n\n").unwrap();
    #[cfg(unix)]
    std::os::unix::fs::symlink(&outside, dir.join("link")).unwrap();
    let s = studio(&dir, GRAPH);
    let set = |node: &str, param: &str, value: &str| json!({"node": node, "param": param, "value": value});
    let abs = outside.join("pwned.txt").display().to_string();
    let mut refused = vec![
        ("marks", abs.clone()),
        ("marks", "../outside/x.txt".to_string()),
        ("marks", "new/../../outside/x.txt".to_string()),
        ("plate", "/etc/passwd".to_string()),
    ];
    if cfg!(unix) {
        refused.push(("marks", "link/secret.txt".to_string()));
        refused.push(("marks", "link/new.txt".to_string()));
    }
    for (node, value) in &refused {
        let (st, body) = post_json(&s, "/api/params", set(node, "path", value)).await;
        assert_eq!(st, StatusCode::BAD_REQUEST, "{node}.path={value}: {body}");
        assert!(
            body["error"]
                .as_str()
                .unwrap()
                .contains("outside the graph's folder"),
            "{body}"
        );
        let (_, m) = get_json(&s, "/api/marks?node=marks").await;
        assert_eq!(
            m["marks"]["frames"][0]["points"][0][0], 1.0,
            "the override was not kept: {m}"
        );
    }
    // Inside the folder, even in a folder not made yet, is fine.
    let (st, body) = post_json(&s, "/api/params", set("marks", "path", "sub/new.txt")).await;
    assert_eq!(st, StatusCode::OK, "{body}");
    assert!(!outside.join("pwned.txt").exists());
    // A graph file whose marks path points out of its folder: the definer refuses it, and the
    // error does not quote the file.
    let g2 = GRAPH.replace(
        "marks.txt",
        &outside.join("secret.txt").display().to_string(),
    );
    let s2 = studio(&dir, &g2);
    let (st, body) = get_json(&s2, "/api/marks?node=marks").await;
    assert_eq!(st, StatusCode::FORBIDDEN, "{body}");
    assert!(!body.to_string().contains("7 7"), "{body}");
    let marks =
        json!({"node": "marks", "marks": {"frames": [{"frame": 1, "points": [[1.0, 2.0]]}]}});
    let (st, _) = post_json(&s2, "/api/marks", marks).await;
    assert_eq!(st, StatusCode::FORBIDDEN);
    assert_eq!(
        std::fs::read_to_string(outside.join("secret.txt")).unwrap(),
        "Frame 1\nNpoints 1\n7 7\n\n"
    );
}

#[tokio::test]
async fn a_saved_param_changes_only_its_text_in_the_graph_file() {
    let dir = tempfile::tempdir().unwrap();
    let graph = GRAPH
        .replace("version: 1\n", "# the grade's graph\nversion: 1 # schema\n")
        .replace("params: {stops: 1}", "params: {stops: 1}   # keep this");
    let s = studio(dir.path(), &graph);
    let file = dir.path().join("g.yaml");
    // Nothing edited: nothing to save.
    let (st, v) = post_json(
        &s,
        "/api/params/save",
        json!({"node": "grade", "param": "stops"}),
    )
    .await;
    assert_eq!(st, StatusCode::UNPROCESSABLE_ENTITY, "{v}");
    assert!(v["error"].as_str().unwrap().contains("not edited"), "{v}");
    // A param the file does not write (its default): refused, the file untouched.
    let (st, _) = post_json(
        &s,
        "/api/params",
        json!({"node": "plate", "param": "working_space", "value": "acescg"}),
    )
    .await;
    assert_eq!(st, StatusCode::OK);
    let (st, v) = post_json(
        &s,
        "/api/params/save",
        json!({"node": "plate", "param": "working_space"}),
    )
    .await;
    assert_eq!(st, StatusCode::UNPROCESSABLE_ENTITY, "{v}");
    assert!(v["error"].as_str().unwrap().contains("by hand"), "{v}");
    assert_eq!(std::fs::read_to_string(&file).unwrap(), graph);
    // Unknown node or param: refused.
    let (st, _) = post_json(
        &s,
        "/api/params/save",
        json!({"node": "nope", "param": "stops"}),
    )
    .await;
    assert_eq!(st, StatusCode::UNPROCESSABLE_ENTITY);
    // An edit saved: exactly that value's text changes, comments and layout kept; the
    // override is dropped (the file says it now) and the plan is the same.
    let (st, _) = post_json(
        &s,
        "/api/params",
        json!({"node": "grade", "param": "stops", "value": "-2.25"}),
    )
    .await;
    assert_eq!(st, StatusCode::OK);
    let (st, v) = post_json(
        &s,
        "/api/params/save",
        json!({"node": "grade", "param": "stops"}),
    )
    .await;
    assert_eq!(st, StatusCode::OK, "{v}");
    assert_eq!(v["saved"], "-2.25");
    assert_eq!(v["sets"], json!(["plate.working_space=acescg"]));
    assert_eq!(
        std::fs::read_to_string(&file).unwrap(),
        graph.replace("{stops: 1}", "{stops: -2.25}")
    );
    let (_, v) = get_json(&s, "/api/state").await;
    let grade = v["graph"]["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .find(|n| n["id"] == "grade")
        .unwrap()
        .clone();
    let stops = grade["params"]
        .as_array()
        .unwrap()
        .iter()
        .find(|p| p["name"] == "stops")
        .unwrap()["value"]
        .clone();
    assert_eq!(stops, "-2.25");
    // No temporary file left beside the graph.
    let left: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().to_string())
        .filter(|n| n.contains("saving"))
        .collect();
    assert!(left.is_empty(), "{left:?}");
}

/// A graph in ACEScg viewed through its OpenColorIO config: `/api/colour` names the config,
/// the working space and the displays; a preview through `sRGB - Display` / `Un-tone-mapped`
/// is each pixel's served linear value taken from ACEScg to Rec. 709 and through the sRGB
/// curve (to a code); an unknown display is refused, naming the config's.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn previews_come_through_the_graphs_display_view() {
    let dir = tempfile::tempdir().unwrap();
    let graph = "version: 1
frames: 1
defaults: {working_space: acescg}
nodes:
  plate:
    type: read_image_sequence
    params: {path: plate.%04d.pfm}
";
    let s = studio(dir.path(), graph);
    let img = vfxgraph_imaging::Image::from_fn(4, 3, 3, |x, y, c| {
        [0.02, 0.18, 0.6][c] * (1.0 + x as f32) / (1.0 + y as f32)
    });
    vfxgraph_imaging::write_image(&dir.path().join("plate.0001.pfm"), &img).unwrap();
    let (st, v) = get_json(&s, "/api/colour").await;
    assert_eq!(st, StatusCode::OK, "{v}");
    assert_eq!(v["working_space"], "ACEScg", "{v}");
    assert!(v["config"].as_str().unwrap().starts_with("ocio://"), "{v}");
    let srgb = v["displays"]
        .as_array()
        .unwrap()
        .iter()
        .find(|d| d["display"] == "sRGB - Display")
        .unwrap_or_else(|| panic!("{v}"));
    assert!(
        srgb["views"]
            .as_array()
            .unwrap()
            .iter()
            .any(|w| w == "Un-tone-mapped"),
        "{v}"
    );
    let (st, _) = post_json(&s, "/api/run", json!({})).await;
    assert_eq!(st, StatusCode::ACCEPTED);
    let s2 = s.clone();
    tokio::task::spawn_blocking(move || wait_idle(&s2))
        .await
        .unwrap();
    let (st, png) = call(
        &s,
        "GET",
        "/api/image?node=plate&port=sequence&frame=1&display=sRGB%20-%20Display&view=Un-tone-mapped",
        None,
    )
    .await;
    assert_eq!(st, StatusCode::OK, "{}", String::from_utf8_lossy(&png));
    let shown = vfxgraph_imaging::decode(&png, vfxgraph_imaging::Format::Png).unwrap();
    let config = vfxgraph_imaging::colour::ColourConfig::builtin();
    let to709 = config
        .transform("ACEScg", vfxgraph_imaging::colour::LINEAR_REC709)
        .unwrap();
    let mut worst = 0i32;
    for (x, y) in [(0, 0), (3, 0), (1, 1), (3, 2)] {
        let (st, v) = get_json(
            &s,
            &format!("/api/pixel?node=plate&port=sequence&frame=1&x={x}&y={y}"),
        )
        .await;
        assert_eq!(st, StatusCode::OK, "{v}");
        let lin: Vec<f32> = (0..3)
            .map(|c| v["value"][c].as_f64().unwrap() as f32)
            .collect();
        let rgb = to709.apply_rgb([lin[0], lin[1], lin[2]]);
        for (c, &v) in rgb.iter().enumerate() {
            let want = vfxgraph_imaging::color::linear_to_srgb8(v) as i32;
            // The PNG decodes to linear values: back to the 8-bit code it holds.
            let got = vfxgraph_imaging::color::linear_to_srgb8(shown.get(x, y, c)) as i32;
            worst = worst.max((got - want).abs());
        }
    }
    assert!(worst <= 1, "codes off by {worst}");
    let (st, v) = get_json(
        &s,
        "/api/image?node=plate&port=sequence&frame=1&display=Cinema",
    )
    .await;
    assert_eq!(st, StatusCode::BAD_REQUEST, "{v}");
    assert!(
        v["error"].as_str().unwrap().contains("sRGB - Display"),
        "{v}"
    );
}
