//! The front end, embedded in the binary (no network, no npm at build time). Our own files are
//! in `assets/`; vendored libraries, with their licences, in `assets/vendor/` (see its
//! README for the npm package and version of each).

/// The page.
pub const INDEX_HTML: &str = include_str!("../assets/index.html");

const FILES: &[(&str, &str, &[u8])] = &[
    (
        "app.js",
        "text/javascript; charset=utf-8",
        include_bytes!("../assets/app.js"),
    ),
    (
        "style.css",
        "text/css; charset=utf-8",
        include_bytes!("../assets/style.css"),
    ),
];

/// The content type and bytes of asset `name`.
pub fn get(name: &str) -> Option<(&'static str, &'static [u8])> {
    FILES
        .iter()
        .find(|(n, _, _)| *n == name)
        .map(|(_, ty, b)| (*ty, *b))
}
