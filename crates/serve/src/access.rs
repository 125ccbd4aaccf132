//! Who may drive the studio: the checks every request passes before its route.
//!
//! A server on 127.0.0.1 is reachable by every web page the user opens: a page cannot read
//! another origin's answers, but it can *send* requests (a form, a `fetch` with a "simple"
//! content type), and a page on a name its attacker re-points to 127.0.0.1 (DNS rebinding) is
//! same-origin with whatever it reaches. So, as the OWASP CSRF and DNS-rebinding guidance and
//! Jupyter's server do:
//!
//! - **Host**: the request's `Host` must be a name the studio is served under — `localhost`,
//!   `127.0.0.1`, `[::1]` or the bound address, at the served port. A rebound name is refused.
//! - **Changes** (every method but `GET`/`HEAD`): a JSON body (`Content-Type:
//!   application/json`, which a cross-site page cannot send without a CORS preflight the studio
//!   never grants), and when the browser says where the request comes from (`Origin`,
//!   `Sec-Fetch-Site`), the studio's own origin.
//! - **Token**, required when the studio listens off loopback (printed once, in the URL): as
//!   `?token=`, an `Authorization: Bearer` header, or the cookie the page gets when it is opened
//!   with the token. Any `Host` is then accepted (the network's names are not known), the token
//!   standing in for it.

use std::net::SocketAddr;
use std::sync::Arc;

use axum::extract::{Request, State};
use axum::http::{header, HeaderMap, HeaderValue, Method, StatusCode};
use axum::middleware::Next;
use axum::response::Response;

use crate::safety::ApiError;

/// The cookie that carries the token for the page.
pub const TOKEN_COOKIE: &str = "vfxgraph_token";

/// What a request must show (module docs).
#[derive(Clone, Debug)]
pub struct Access {
    /// Accepted `Host` values (`name:port`, and `name` alone at port 80); empty: any.
    hosts: Vec<String>,
    /// The token, when one is required.
    token: Option<String>,
}

impl Access {
    /// The access of a studio listening on `addr`: on a loopback address, its loopback names
    /// and no token; off loopback, a token (`token`, or a new random one) and any name.
    pub fn for_address(addr: SocketAddr, token: Option<String>) -> Access {
        if addr.ip().is_loopback() {
            let port = addr.port();
            let mut names = vec![
                "localhost".to_string(),
                "127.0.0.1".to_string(),
                "[::1]".to_string(),
            ];
            let bound = match addr {
                SocketAddr::V4(a) => a.ip().to_string(),
                SocketAddr::V6(a) => format!("[{}]", a.ip()),
            };
            if !names.contains(&bound) {
                names.push(bound);
            }
            let mut hosts: Vec<String> = names.iter().map(|n| format!("{n}:{port}")).collect();
            if port == 80 {
                hosts.extend(names);
            }
            Access { hosts, token }
        } else {
            Access {
                hosts: Vec::new(),
                token: Some(token.unwrap_or_else(new_token)),
            }
        }
    }

    /// The token a client must show, if any.
    pub fn token(&self) -> Option<&str> {
        self.token.as_deref()
    }

    /// Why `method` with `headers` (and the URL's `query`) may not reach a route, if it may not.
    fn refuse(
        &self,
        method: &Method,
        headers: &HeaderMap,
        query: Option<&str>,
    ) -> Option<ApiError> {
        let host = headers
            .get(header::HOST)
            .and_then(|h| h.to_str().ok())
            .unwrap_or("");
        if host.is_empty() {
            return Some(ApiError::bad("the request has no Host header"));
        }
        if !self.hosts.is_empty() && !self.hosts.iter().any(|h| h.eq_ignore_ascii_case(host)) {
            return Some(ApiError::new(
                StatusCode::FORBIDDEN,
                format!(
                    "this studio answers to {} only, not to the host `{host}`",
                    self.hosts.join(", ")
                ),
            ));
        }
        if let Some(token) = &self.token {
            if !shows_token(token, headers, query) {
                return Some(ApiError::new(
                    StatusCode::UNAUTHORIZED,
                    "this studio needs its token: open the URL it printed (with ?token=…)",
                ));
            }
        }
        if method == Method::GET || method == Method::HEAD {
            return None;
        }
        let own = format!("http://{host}");
        if let Some(origin) = headers.get(header::ORIGIN) {
            if !origin.to_str().is_ok_and(|o| o.eq_ignore_ascii_case(&own)) {
                return Some(ApiError::new(
                    StatusCode::FORBIDDEN,
                    format!(
                        "a change from another site ({}) is refused: only the studio's own page \
                         ({own}) may make one",
                        origin.to_str().unwrap_or("?")
                    ),
                ));
            }
        } else if let Some(site) = headers.get("sec-fetch-site") {
            if !matches!(site.to_str(), Ok("same-origin" | "none")) {
                return Some(ApiError::new(
                    StatusCode::FORBIDDEN,
                    "a change from another site is refused",
                ));
            }
        }
        let json = headers
            .get(header::CONTENT_TYPE)
            .and_then(|c| c.to_str().ok())
            .is_some_and(|c| {
                c.split(';')
                    .next()
                    .is_some_and(|t| t.trim().eq_ignore_ascii_case("application/json"))
            });
        if !json {
            return Some(ApiError::new(
                StatusCode::UNSUPPORTED_MEDIA_TYPE,
                "a change needs a JSON body (Content-Type: application/json)",
            ));
        }
        None
    }
}

/// A new random token: 128 bits from the operating system's generator, in hex.
fn new_token() -> String {
    let bytes: [u8; 16] = rand::random();
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// Whether the request shows `token`: in the query, a bearer header or the cookie.
fn shows_token(token: &str, headers: &HeaderMap, query: Option<&str>) -> bool {
    let from_query = query.into_iter().flat_map(|q| q.split('&')).any(|kv| {
        kv.strip_prefix("token=")
            .is_some_and(|t| same_secret(t, token))
    });
    let from_header = headers
        .get(header::AUTHORIZATION)
        .and_then(|h| h.to_str().ok())
        .and_then(|h| h.strip_prefix("Bearer "))
        .is_some_and(|t| same_secret(t.trim(), token));
    let from_cookie = headers
        .get_all(header::COOKIE)
        .iter()
        .filter_map(|c| c.to_str().ok())
        .flat_map(|c| c.split(';'))
        .filter_map(|kv| kv.trim().split_once('='))
        .any(|(k, v)| k == TOKEN_COOKIE && same_secret(v, token));
    from_query || from_header || from_cookie
}

/// Equality that takes as long whatever the first difference (no timing oracle).
fn same_secret(a: &str, b: &str) -> bool {
    a.len() == b.len() && a.bytes().zip(b.bytes()).fold(0u8, |d, (x, y)| d | (x ^ y)) == 0
}

/// The middleware: refuses what [`Access`] refuses; a page opened with `?token=` gets the
/// token as a cookie (HttpOnly, SameSite=Strict) for its own requests.
pub async fn check(State(access): State<Arc<Access>>, req: Request, next: Next) -> Response {
    let query = req.uri().query().map(str::to_string);
    if let Some(e) = access.refuse(req.method(), req.headers(), query.as_deref()) {
        return axum::response::IntoResponse::into_response(e);
    }
    let mut resp = next.run(req).await;
    if let Some(token) = access.token() {
        if shows_token(token, &HeaderMap::new(), query.as_deref()) {
            if let Ok(v) = HeaderValue::from_str(&format!(
                "{TOKEN_COOKIE}={token}; Path=/; HttpOnly; SameSite=Strict"
            )) {
                resp.headers_mut().append(header::SET_COOKIE, v);
            }
        }
    }
    resp
}

#[cfg(test)]
mod tests {
    use super::*;

    fn headers(pairs: &[(&str, &str)]) -> HeaderMap {
        let mut h = HeaderMap::new();
        for (k, v) in pairs {
            h.append(
                axum::http::HeaderName::from_bytes(k.as_bytes()).unwrap(),
                HeaderValue::from_str(v).unwrap(),
            );
        }
        h
    }

    #[test]
    fn loopback_names_at_the_port_only() {
        let a = Access::for_address("127.0.0.1:8080".parse().unwrap(), None);
        assert!(a.token().is_none());
        for host in [
            "127.0.0.1:8080",
            "localhost:8080",
            "LOCALHOST:8080",
            "[::1]:8080",
        ] {
            assert!(
                a.refuse(&Method::GET, &headers(&[("host", host)]), None)
                    .is_none(),
                "{host}"
            );
        }
        for host in [
            "evil.example:8080",
            "127.0.0.1:9999",
            "localhost",
            "127.0.0.1.evil:8080",
        ] {
            let e = a
                .refuse(&Method::GET, &headers(&[("host", host)]), None)
                .unwrap();
            assert_eq!(e.status, StatusCode::FORBIDDEN, "{host}");
        }
        assert_eq!(
            a.refuse(&Method::GET, &HeaderMap::new(), None)
                .unwrap()
                .status,
            StatusCode::BAD_REQUEST
        );
    }

    #[test]
    fn a_change_needs_json_and_the_own_origin() {
        let a = Access::for_address("127.0.0.1:8080".parse().unwrap(), None);
        let host = ("host", "127.0.0.1:8080");
        let json = ("content-type", "application/json");
        let ok = |h: &[(&str, &str)]| a.refuse(&Method::POST, &headers(h), None);
        assert!(ok(&[host, json]).is_none());
        assert!(ok(&[host, json, ("origin", "http://127.0.0.1:8080")]).is_none());
        assert!(ok(&[host, ("content-type", "application/json; charset=utf-8")]).is_none());
        assert!(ok(&[host, json, ("sec-fetch-site", "same-origin")]).is_none());
        let status = |h: &[(&str, &str)]| ok(h).map(|e| e.status);
        assert_eq!(
            status(&[host, json, ("origin", "http://evil.example")]),
            Some(StatusCode::FORBIDDEN)
        );
        assert_eq!(
            status(&[host, json, ("origin", "null")]),
            Some(StatusCode::FORBIDDEN)
        );
        assert_eq!(
            status(&[host, json, ("sec-fetch-site", "cross-site")]),
            Some(StatusCode::FORBIDDEN)
        );
        assert_eq!(
            status(&[host, ("content-type", "text/plain")]),
            Some(StatusCode::UNSUPPORTED_MEDIA_TYPE)
        );
        assert_eq!(status(&[host]), Some(StatusCode::UNSUPPORTED_MEDIA_TYPE));
    }

    #[test]
    fn off_loopback_a_token_is_required_and_any_host_accepted() {
        let a = Access::for_address("0.0.0.0:8080".parse().unwrap(), None);
        let token = a.token().unwrap().to_string();
        assert_eq!(token.len(), 32);
        let b = Access::for_address("0.0.0.0:8080".parse().unwrap(), None);
        assert_ne!(b.token().unwrap(), token, "a new token each start");
        let host = ("host", "studio.lan:8080");
        let status = |h: &[(&str, &str)], q: Option<&str>| {
            a.refuse(&Method::GET, &headers(h), q).map(|e| e.status)
        };
        assert_eq!(status(&[host], None), Some(StatusCode::UNAUTHORIZED));
        assert_eq!(
            status(&[host], Some("token=0123")),
            Some(StatusCode::UNAUTHORIZED)
        );
        assert_eq!(status(&[host], Some(&format!("x=1&token={token}"))), None);
        let bearer = format!("Bearer {token}");
        assert_eq!(status(&[host, ("authorization", &bearer)], None), None);
        let cookie = format!("a=b; {TOKEN_COOKIE}={token}");
        assert_eq!(status(&[host, ("cookie", &cookie)], None), None);
    }
}
