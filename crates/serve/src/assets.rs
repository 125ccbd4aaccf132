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
    // three.js (npm `three` 0.171.0, MIT, assets/vendor/three.LICENSE): the solve view's 3-D.
    // The module imports `./three.core.min.js`, which resolves to the entry below.
    (
        "three.module.min.js",
        "text/javascript; charset=utf-8",
        include_bytes!("../assets/vendor/three.module.min.js"),
    ),
    (
        "three.core.min.js",
        "text/javascript; charset=utf-8",
        include_bytes!("../assets/vendor/three.core.min.js"),
    ),
    (
        "three.LICENSE",
        "text/plain; charset=utf-8",
        include_bytes!("../assets/vendor/three.LICENSE"),
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
