//! Safety rules of the server: which files may be served, how large a request may be, and
//! request errors as clear 4xx answers.
//!
//! - Only files under the graph's folder or the cache folder are served: a requested path is
//!   relative, is joined to the graph's folder, and its canonical form (symlinks resolved)
//!   must lie under one of the two canonical roots; `..`, absolute paths and NUL bytes are
//!   refused before touching the file system.
//! - Request bodies are limited to [`MAX_BODY`] bytes (413 beyond).
//! - Every handler validates its input before changing anything: a refused request leaves the
//!   graph, the overrides and the files as they were.

use std::path::{Component, Path, PathBuf};

use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use axum::Json;
use serde_json::json;

/// Largest request body accepted, in bytes (a marks file of a few hundred points is ~10 kB).
pub const MAX_BODY: usize = 256 * 1024;

/// An error answer: a status and a message (JSON `{"error": …}`), plus details.
#[derive(Debug)]
pub struct ApiError {
    /// HTTP status (4xx for the client's mistakes, 5xx for the server's).
    pub status: StatusCode,
    /// What went wrong, for a person.
    pub message: String,
    /// Extra JSON fields (e.g. the diagnostics of a rejected param).
    pub details: serde_json::Value,
}

impl ApiError {
    /// An error with `status`.
    pub fn new(status: StatusCode, message: impl Into<String>) -> Self {
        ApiError {
            status,
            message: message.into(),
            details: serde_json::Value::Null,
        }
    }
    /// 400.
    pub fn bad(message: impl Into<String>) -> Self {
        Self::new(StatusCode::BAD_REQUEST, message)
    }
    /// 404.
    pub fn not_found(message: impl Into<String>) -> Self {
        Self::new(StatusCode::NOT_FOUND, message)
    }
    /// 403.
    pub fn forbidden(message: impl Into<String>) -> Self {
        Self::new(StatusCode::FORBIDDEN, message)
    }
    /// 409.
    pub fn conflict(message: impl Into<String>) -> Self {
        Self::new(StatusCode::CONFLICT, message)
    }
    /// 500.
    pub fn internal(message: impl Into<String>) -> Self {
        Self::new(StatusCode::INTERNAL_SERVER_ERROR, message)
    }
    /// Adds `details` (merged into the JSON answer).
    pub fn with(mut self, details: serde_json::Value) -> Self {
        self.details = details;
        self
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        let mut body = json!({ "error": self.message });
        if let (Some(b), Some(d)) = (body.as_object_mut(), self.details.as_object()) {
            for (k, v) in d {
                b.insert(k.clone(), v.clone());
            }
        }
        (self.status, Json(body)).into_response()
    }
}

/// Checks a requested relative path's text: no absolute path, no `..`, no NUL, not empty.
pub fn check_relative(text: &str) -> Result<&Path, ApiError> {
    if text.is_empty() {
        return Err(ApiError::bad("empty path"));
    }
    if text.contains('\0') {
        return Err(ApiError::bad("the path holds a NUL byte"));
    }
    let p = Path::new(text);
    for c in p.components() {
        match c {
            Component::Normal(_) | Component::CurDir => {}
            Component::ParentDir => {
                return Err(ApiError::forbidden(format!(
                    "`{text}`: `..` is not allowed (only files under the graph's folder and the \
                     cache are served)"
                )))
            }
            Component::RootDir | Component::Prefix(_) => {
                return Err(ApiError::forbidden(format!(
                    "`{text}`: absolute paths are not allowed (paths are relative to the graph's \
                     folder)"
                )))
            }
        }
    }
    Ok(p)
}

/// Resolves `text` (relative to `base`) to an existing file whose canonical path lies under
/// one of `roots`: 400/403 for a refused path, 404 for a missing file.
pub fn resolve_served(base: &Path, roots: &[PathBuf], text: &str) -> Result<PathBuf, ApiError> {
    let joined = base.join(check_relative(text)?);
    if !joined.exists() {
        return Err(ApiError::not_found(format!("`{text}`: no such file")));
    }
    let canonical = confine(&joined, roots, text)?;
    if !canonical.is_file() {
        return Err(ApiError::not_found(format!("`{text}` is not a file")));
    }
    Ok(canonical)
}

/// `path` (absolute) if it lies under one of `roots` — judged on its canonical form, symlinks
/// followed, so a link out of the folder does not lead out of it; a file that does not exist
/// yet (an output) is judged by its nearest existing folder, and the rest of it may hold no
/// `..`. A 403 naming `shown` (how the client wrote it) otherwise.
pub fn confine(path: &Path, roots: &[PathBuf], shown: &str) -> Result<PathBuf, ApiError> {
    let outside = || {
        ApiError::forbidden(format!(
            "`{shown}` is outside the graph's folder and the cache: the studio reads and writes \
             only there"
        ))
    };
    let mut existing = path;
    let mut rest = Vec::new();
    let canonical = loop {
        match existing.canonicalize() {
            Ok(c) => break c,
            Err(_) => {
                let (Some(parent), Some(name)) = (existing.parent(), existing.file_name()) else {
                    return Err(outside());
                };
                rest.push(name.to_owned());
                existing = parent;
            }
        }
    };
    if rest
        .iter()
        .any(|c| Path::new(c).components().any(|k| k == Component::ParentDir))
    {
        return Err(outside());
    }
    let allowed = roots
        .iter()
        .filter_map(|r| r.canonicalize().ok())
        .any(|r| canonical.starts_with(&r));
    if !allowed {
        return Err(outside());
    }
    Ok(rest.iter().rev().fold(canonical, |p, c| p.join(c)))
}

/// The content type of a served file, by extension.
pub fn content_type(path: &Path) -> &'static str {
    match path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
        .as_deref()
    {
        Some("png") => "image/png",
        Some("jpg" | "jpeg") => "image/jpeg",
        Some("svg") => "image/svg+xml",
        Some("json") => "application/json",
        Some("txt" | "yaml" | "yml" | "scn" | "obj") => "text/plain; charset=utf-8",
        Some("mp4") => "video/mp4",
        _ => "application/octet-stream",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn relative_paths_only() {
        assert!(check_relative("out/a.png").is_ok());
        assert!(check_relative("./a.png").is_ok());
        for bad in ["../a", "a/../../b", "/etc/passwd", "", "a\0b"] {
            let e = check_relative(bad).unwrap_err();
            assert!(e.status.is_client_error(), "{bad}: {e:?}");
        }
    }

    #[test]
    fn symlink_out_of_the_roots_is_refused() {
        let root = tempfile::tempdir().unwrap();
        let outside = tempfile::tempdir().unwrap();
        std::fs::write(outside.path().join("secret.txt"), "x").unwrap();
        std::fs::write(root.path().join("ok.txt"), "y").unwrap();
        std::os::unix::fs::symlink(outside.path(), root.path().join("link")).unwrap();
        let roots = [root.path().to_path_buf()];
        assert!(resolve_served(root.path(), &roots, "ok.txt").is_ok());
        let e = resolve_served(root.path(), &roots, "link/secret.txt").unwrap_err();
        assert_eq!(e.status, StatusCode::FORBIDDEN);
        let e = resolve_served(root.path(), &roots, "missing.txt").unwrap_err();
        assert_eq!(e.status, StatusCode::NOT_FOUND);
    }
}
