//! The fuzz targets: every reader of a user file, called through the public function its node
//! uses (text or bytes in, `Result` out), with its seed corpus.
//!
//! Seeds are real files read at run time — the repository's graphs and scenes, the shared
//! third-party data (`../shared/data`: the book's demo files, OpenEXR test images, Middlebury
//! and Oxford photos…), the small seeds in `crates/fuzz/seeds/` — plus files made here by the
//! project's own writers (every image format and compression, an H.264 MP4, the book's text
//! formats and their JSON forms), so each target has valid seeds even without the shared data.

use std::cell::RefCell;
use std::path::{Path, PathBuf};

use nalgebra::{Matrix3, Point2, Point3, Vector3};
use vfxgraph_engine::{Overrides, Registry};
use vfxgraph_geometry::camera::{Intrinsics, Pose};
use vfxgraph_geometry::formats::{self, CameraPath, FramePose, MarkedFrame, MarkedPoints};
use vfxgraph_geometry::{Points2d, Points3d};
use vfxgraph_imaging::io::{encode_exr, ExrCompression, ExrOptions, ExrPrecision};
use vfxgraph_imaging::{Format, Image};
use vfxgraph_klt::tracks::{LostReason, Track, TrackEnd, Tracks};

use crate::mutate::Kind;

/// One seed file.
pub struct Seed {
    /// Where it came from (a path, or `generated:…`).
    pub name: String,
    /// Its bytes.
    pub bytes: Vec<u8>,
}

/// Where seeds are read from.
#[derive(Clone, Debug)]
pub struct SeedDirs {
    /// The repository root.
    pub repo: PathBuf,
    /// The shared third-party data (`../shared/data` beside the repository).
    pub shared: PathBuf,
}

impl Default for SeedDirs {
    fn default() -> Self {
        let repo = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
        let shared = repo.join("../shared/data");
        SeedDirs { repo, shared }
    }
}

/// A reader under test.
pub struct Target {
    /// Its name (`--target`).
    pub name: &'static str,
    /// What it reads.
    pub what: &'static str,
    /// The mutation family.
    pub kind: Kind,
    /// Tokens the text mutations insert.
    pub dict: &'static [&'static str],
    /// Its seed corpus.
    pub seeds: fn(&SeedDirs) -> Vec<Seed>,
    /// Runs the reader on one input; true when it accepted the input.
    pub run: fn(&[u8]) -> bool,
}

const YAML_DICT: &[&str] = &[
    "&a ",
    "*a",
    "&b ",
    "*b",
    "<<: *a\n",
    "[",
    "]",
    "{",
    "}",
    ", ",
    ": ",
    "- ",
    "\n  ",
    "\n",
    "\t",
    "'",
    "\"",
    "#",
    "~",
    "null",
    "true",
    "!!str ",
    "!!binary ",
    "---\n",
    "...\n",
    "|\n",
    ">\n",
    "? ",
    "%YAML 1.2\n",
    "\u{feff}",
    "é",
    "\r\n",
    "\\u0000",
];

const GRAPH_DICT: &[&str] = &[
    "version: 1\n",
    "frames: ",
    "0..=239",
    "1-10,15,20-40:2",
    "-5--3",
    ":0",
    "..",
    "..=",
    "seed: ",
    "nodes:\n",
    "  n:\n    type: ",
    "exposure",
    "read_image",
    "write_image_sequence",
    "constant",
    "per_frame: true",
    "per_frame: false",
    "inputs: {image: ",
    ".image}",
    "params: {",
    "%04d",
    "####",
    "stops: ",
    "path: ",
    "\n    params:\n      stops: 1\n",
];

const SCENE_DICT: &[&str] = &[
    "camera:\n",
    "look_at: {from: [0, 1, 5], at: [0, 0, 0], up: [0, 1, 0], fov: 45}",
    "size: ",
    "K: [[1, 0, 0], [0, 1, 0], [0, 0, 1]]",
    "materials:\n",
    "objects:\n",
    "lights:\n",
    "dome: ",
    "- sphere: {center: [0, 0, 0], radius: 1}\n",
    "polygon: ",
    "triangles: ",
    "obj: cube.obj",
    "transform: ",
    "rotate: ",
    "scale: ",
    "texture: {type: cells, size: 0, contrast: 2}",
    "type: plastic",
    "catcher: true",
    "radiance: ",
    "[0, 0, 0]",
    "[1e308, 1, 1]",
];

const SCN_DICT: &[&str] = &[
    "{",
    "}",
    "=",
    ",",
    "scene{",
    "camera = view {",
    "object = primobj{",
    "polyobj",
    "trilist",
    "sphere",
    "plastic",
    "material = ",
    "shape = ",
    "polylight{",
    "color = ",
    "{0,0,0}",
    "{{0,0,0},{1,0,0},{0,1,0}}",
    "plshadow",
    "dome",
    "imgw = ",
    "fov = ",
    "\"",
    "#",
    "-",
];

const OBJ_DICT: &[&str] = &[
    "v ", "f ", "vn ", "vt ", "/", "//", "-1", "0", "#", "o ", "g ", "s off",
];

const TEXT_DICT: &[&str] = &[
    "Frame ",
    "Npoints ",
    "Features per frame = ",
    "#",
    "\n",
    " ",
    "\t",
    "{",
    "}",
    "[",
    "]",
    "\"",
    ",",
    ":",
    "null",
    "\"frames\"",
    "\"K\"",
    "\"R\"",
    "\"t\"",
    "\"slots\"",
    "\"tracks\"",
    "\"points\"",
    "\"lost\"",
    "-1",
    "1e999",
];

const COLMAP_DICT: &[&str] = &[
    "PINHOLE ",
    "SIMPLE_PINHOLE ",
    "OPENCV ",
    "SIMPLE_RADIAL ",
    "# ",
    "\n",
    "\u{0}",
    " ",
    "-1",
    "image_0001.png",
    "0 0 ",
];

/// The target of one image format: `imaging::decode`, seeds from [`image_seeds`].
macro_rules! image_target {
    ($name:literal, $what:literal, $format:ident) => {
        Target {
            name: $name,
            what: $what,
            kind: Kind::Binary,
            dict: &[],
            seeds: |d| image_seeds(d, Format::$format),
            run: |b| vfxgraph_imaging::decode(b, Format::$format).is_ok(),
        }
    };
}

/// The target of a book text format with a JSON form: both readers on each input.
macro_rules! text_and_json_target {
    ($name:literal, $what:literal, $seeds:ident, $parse:path, $json:ty) => {
        Target {
            name: $name,
            what: $what,
            kind: Kind::Text,
            dict: TEXT_DICT,
            seeds: $seeds,
            run: |b| {
                let t = text(b);
                let book = $parse(&t, "f").is_ok();
                book | serde_json::from_str::<$json>(&t).is_ok()
            },
        }
    };
}

/// Every target, in report order.
pub fn all() -> Vec<Target> {
    vec![
        Target {
            name: "graph",
            what: "graph YAML (engine::graph::parse with the node catalog)",
            kind: Kind::Text,
            dict: [YAML_DICT, GRAPH_DICT].concat_static(),
            seeds: seeds_graph,
            run: run_graph,
        },
        Target {
            name: "yaml_scene",
            what: "YAML scene (render::parse_yaml_scene)",
            kind: Kind::Text,
            dict: [YAML_DICT, SCENE_DICT].concat_static(),
            seeds: seeds_yaml_scene,
            run: run_yaml_scene,
        },
        Target {
            name: "scn",
            what: "the book's .scn (render::parse_scn)",
            kind: Kind::Text,
            dict: SCN_DICT,
            seeds: seeds_scn,
            run: |b| vfxgraph_render::parse_scn(&text(b)).is_ok(),
        },
        Target {
            name: "obj",
            what: "Wavefront OBJ of a YAML scene (render::obj::parse_obj)",
            kind: Kind::Text,
            dict: OBJ_DICT,
            seeds: seeds_obj,
            run: |b| vfxgraph_render::obj::parse_obj(&text(b)).is_ok(),
        },
        Target {
            name: "tracks",
            what: "tracks: the book's f.txt or native JSON (klt::Tracks::parse)",
            kind: Kind::Text,
            dict: TEXT_DICT,
            seeds: seeds_tracks,
            run: |b| Tracks::parse(&text(b)).is_ok(),
        },
        text_and_json_target!(
            "cameras",
            "cameras file, book text and JSON (formats::parse_cameras, read_json)",
            seeds_cameras,
            formats::parse_cameras,
            CameraPath
        ),
        text_and_json_target!(
            "marks",
            "marked points, book text and JSON (formats::parse_marked_points, read_json)",
            seeds_marks,
            formats::parse_marked_points,
            MarkedPoints
        ),
        Target {
            name: "points",
            what: "2-D and 3-D point lists, text and JSON (formats::parse_points2d/3d, read_json)",
            kind: Kind::Text,
            dict: TEXT_DICT,
            seeds: seeds_points,
            run: |b| {
                let t = text(b);
                let a = formats::parse_points2d(&t, "f").is_ok();
                let c = formats::parse_points3d(&t, "f").is_ok();
                let d = serde_json::from_str::<Points2d>(&t).is_ok();
                a | c | d | serde_json::from_str::<Points3d>(&t).is_ok()
            },
        },
        text_and_json_target!(
            "intrinsics",
            "intrinsics g7cam.txt and JSON (formats::parse_intrinsics, read_json)",
            seeds_intrinsics,
            formats::parse_intrinsics,
            Intrinsics
        ),
        Target {
            name: "exposure_list",
            what: "exposure list (imaging::hdr::stack::parse_exposure_list)",
            kind: Kind::Text,
            dict: &["1/", "/0", "#", "\n", " ", ".JPG", ".png", "0"],
            seeds: seeds_exposure_list,
            run: |b| vfxgraph_imaging::hdr::stack::parse_exposure_list(&text(b)).is_ok(),
        },
        Target {
            name: "colmap",
            what: "COLMAP text model: cameras, images, points3D (export::colmap::parse)",
            kind: Kind::Text,
            dict: COLMAP_DICT,
            seeds: seeds_colmap,
            run: run_colmap,
        },
        image_target!("pfm", "PFM (imaging::decode)", Pfm),
        image_target!("hdr", "Radiance .hdr (imaging::decode)", Hdr),
        image_target!("exr", "OpenEXR through our wrapper (imaging::decode)", Exr),
        image_target!(
            "png",
            "PNG (imaging::decode); chunk CRCs repaired after mutation half the time",
            Png
        ),
        image_target!("jpeg", "JPEG (imaging::decode)", Jpeg),
        image_target!("dpx", "DPX (imaging::decode)", Dpx),
        image_target!(
            "tiff",
            "TIFF (imaging::decode, the tiff crate inside)",
            Tiff
        ),
        Target {
            name: "mp4",
            what: "H.264 MP4 (video::Video::from_bytes, then the first and last frames)",
            kind: Kind::Binary,
            dict: &[],
            seeds: seeds_mp4,
            run: run_mp4,
        },
    ]
}

/// The target named `name`: one of [`all`], or the hidden [`probe`] target.
pub fn find(name: &str) -> Option<Target> {
    all()
        .into_iter()
        .chain([probe_target()])
        .find(|t| t.name == name)
}

/// The harness's self-test target: not a reader, so never listed (`--list`) nor run by default,
/// only by name (`--target probe`). Input `i` is `i` in decimal ([`Kind::Index`]); the inputs
/// named here misbehave in each way a campaign must survive, every other input is accepted when
/// even and refused when odd.
pub mod probe {
    /// The target's name.
    pub const NAME: &str = "probe";
    /// A panic escapes the reader.
    pub const PANIC: u64 = 3;
    /// An endless loop.
    pub const HANG: u64 = 5;
    /// `abort()`.
    pub const ABORT: u64 = 7;
    /// One allocation one byte over the memory bound.
    pub const ALLOC: u64 = 9;
    /// Two allocations of ¾ of the bound each, both live: every allocation under the bound, the
    /// live bytes over it.
    pub const PEAK: u64 = 11;
    /// Unbounded recursion: a stack overflow.
    pub const STACK: u64 = 13;
    /// The process stops itself (SIGSTOP): its own watchdog stops with it, so only the
    /// supervisor can end it.
    pub const STOP: u64 = 15;
    /// The reader calls `exit(0)`.
    pub const EXIT: u64 = 17;
    /// A panic the reader catches itself (contained; the input is refused).
    pub const CONTAINED: u64 = 19;
    /// Every misbehaving input, in order.
    pub const ALL: [u64; 9] = [
        PANIC, HANG, ABORT, ALLOC, PEAK, STACK, STOP, EXIT, CONTAINED,
    ];
}

fn probe_target() -> Target {
    Target {
        name: probe::NAME,
        what: "the harness's self-test (not a reader; see targets::probe)",
        kind: Kind::Index,
        dict: &[],
        seeds: |_| vec![generated("probe", "seed")],
        run: run_probe,
    }
}

fn run_probe(b: &[u8]) -> bool {
    use std::hint::black_box;
    let Some(i) = std::str::from_utf8(b)
        .ok()
        .and_then(|s| s.parse::<u64>().ok())
    else {
        return true; // the seed
    };
    match i {
        probe::PANIC => panic!("probe: a panic escaping the reader"),
        probe::HANG => loop {
            std::thread::sleep(std::time::Duration::from_millis(5));
        },
        probe::ABORT => std::process::abort(),
        probe::ALLOC => {
            let n = crate::guard::max_alloc().saturating_add(1);
            black_box(Vec::<u8>::with_capacity(n)).capacity() > 0
        }
        probe::PEAK => {
            let n = crate::guard::max_alloc() / 4 * 3;
            let a = black_box(vec![0u8; n]);
            let b = black_box(vec![0u8; n]);
            a.len() + b.len() > 0
        }
        probe::STACK => black_box(recurse(0)) > 0,
        probe::STOP => {
            // SAFETY: raise(3) with a valid signal.
            unsafe { libc::raise(libc::SIGSTOP) };
            true
        }
        probe::EXIT => std::process::exit(0),
        probe::CONTAINED => std::panic::catch_unwind(|| panic!("probe: contained")).is_ok(),
        _ => i % 2 == 0,
    }
}

/// Recurses with 4 KiB frames until the stack overflows.
fn recurse(depth: u64) -> u64 {
    let frame = std::hint::black_box([depth as u8; 4096]);
    if depth == u64::MAX {
        return 0;
    }
    recurse(depth + 1).wrapping_add(frame[(depth % 4096) as usize] as u64)
}

/// `[&[a, b], &[c]].concat()` as a `'static` slice (leaked once per call of [`all`]).
trait ConcatStatic {
    fn concat_static(&self) -> &'static [&'static str];
}

impl ConcatStatic for [&'static [&'static str]] {
    fn concat_static(&self) -> &'static [&'static str] {
        Box::leak(self.concat().into_boxed_slice())
    }
}

/// The text a reader would get: `read_to_string` refuses invalid UTF-8, so the mutator's
/// byte noise is mapped to U+FFFD to still reach the parser.
fn text(b: &[u8]) -> std::borrow::Cow<'_, str> {
    String::from_utf8_lossy(b)
}

fn read_seed(path: &Path) -> Option<Seed> {
    std::fs::read(path).ok().map(|bytes| Seed {
        name: path.display().to_string(),
        bytes,
    })
}

/// The files of `dir` (not recursive) whose names end in one of `exts`, sorted, each at most
/// `max_len` bytes.
fn files(dir: &Path, exts: &[&str], max_len: u64) -> Vec<Seed> {
    let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)
        .into_iter()
        .flatten()
        .flatten()
        .map(|e| e.path())
        .filter(|p| {
            let n = p.to_string_lossy().to_lowercase();
            exts.iter().any(|e| n.ends_with(e))
                && p.metadata()
                    .is_ok_and(|m| m.is_file() && m.len() <= max_len)
        })
        .collect();
    paths.sort();
    paths.iter().filter_map(|p| read_seed(p)).collect()
}

fn named(paths: &[PathBuf]) -> Vec<Seed> {
    paths.iter().filter_map(|p| read_seed(p)).collect()
}

fn generated(name: &str, bytes: impl Into<Vec<u8>>) -> Seed {
    Seed {
        name: format!("generated:{name}"),
        bytes: bytes.into(),
    }
}

thread_local! {
    static REGISTRY: Registry = vfxgraph_nodes::registry();
    static GRAPH_PATH: RefCell<Option<PathBuf>> = const { RefCell::new(None) };
}

fn run_graph(b: &[u8]) -> bool {
    // As if the file were graphs/fuzz.yaml (relative paths resolve against graphs/).
    let path = GRAPH_PATH.with(|p| {
        p.borrow_mut()
            .get_or_insert_with(|| SeedDirs::default().repo.join("graphs/fuzz.yaml"))
            .clone()
    });
    REGISTRY
        .with(|r| vfxgraph_engine::graph::parse(&path, &text(b), r, &Overrides::default()).is_ok())
}

fn seeds_graph(d: &SeedDirs) -> Vec<Seed> {
    let mut s = files(&d.repo.join("graphs"), &[".yaml"], 1 << 16);
    // Its node type exists only in a build with the `opencv` feature.
    s.retain(|f| !f.name.ends_with("track_opencv.yaml"));
    s.extend(files(
        &d.repo.join("crates/fuzz/seeds"),
        &[".graph.yaml"],
        1 << 16,
    ));
    s
}

fn run_yaml_scene(b: &[u8]) -> bool {
    // OBJ files named by the scene resolve against graphs/scenes/ (cube.obj).
    let dir = SeedDirs::default().repo.join("graphs/scenes");
    vfxgraph_render::parse_yaml_scene(&text(b), &dir).is_ok()
}

fn seeds_yaml_scene(d: &SeedDirs) -> Vec<Seed> {
    let mut s = files(&d.repo.join("graphs/scenes"), &[".yaml"], 1 << 16);
    s.extend(files(
        &d.repo.join("crates/fuzz/seeds"),
        &[".scene.yaml"],
        1 << 16,
    ));
    s
}

fn seeds_scn(d: &SeedDirs) -> Vec<Seed> {
    let mut s = files(&d.shared.join("book-demo"), &[".scn"], 1 << 16);
    s.extend(files(&d.repo.join("crates/fuzz/seeds"), &[".scn"], 1 << 16));
    s
}

fn seeds_obj(d: &SeedDirs) -> Vec<Seed> {
    let mut s = files(&d.repo.join("graphs/scenes"), &[".obj"], 1 << 16);
    s.extend(files(&d.repo.join("crates/fuzz/seeds"), &[".obj"], 1 << 16));
    s
}

/// A small track set with a loss, a refill and a gap.
fn sample_tracks() -> Tracks {
    let track = |id, slot, first, points: Vec<[f64; 2]>, lost| Track {
        id,
        slot,
        first,
        points,
        lost,
    };
    Tracks {
        frames: vec![10, 11, 12, 13],
        slots: 2,
        image_size: None,
        tracks: vec![
            track(
                0,
                0,
                0,
                vec![[1.5, 2.0], [1.75, 2.5]],
                Some(TrackEnd {
                    frame: 2,
                    at: [1.9, 2.7],
                    reason: LostReason::Residual,
                }),
            ),
            track(1, 1, 0, vec![[40.0, 30.0]; 4], None),
            track(2, 0, 3, vec![[7.0, 8.0]], None),
        ],
    }
}

fn seeds_tracks(d: &SeedDirs) -> Vec<Seed> {
    let t = sample_tracks();
    let mut s = vec![
        generated("tracks.txt", t.to_book()),
        generated("tracks.json", t.to_native()),
    ];
    // The head of the book's f.txt (150 features, 3 frames): its real layout, parsed quickly.
    if let Ok(f) = std::fs::read_to_string(d.shared.join("book-demo/f.txt")) {
        let head: String = f
            .lines()
            .take(1 + 3 * 151)
            .flat_map(|l| [l, "\n"])
            .collect();
        s.push(Seed {
            name: format!(
                "{} (first 3 frames)",
                d.shared.join("book-demo/f.txt").display()
            ),
            bytes: head.into_bytes(),
        });
    }
    s
}

fn sample_camera_path() -> CameraPath {
    let r = Matrix3::new(0.0, -1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0);
    CameraPath {
        frames: vec![
            FramePose {
                frame: 0,
                pose: Pose::identity(),
                focal: None,
            },
            FramePose {
                frame: 7,
                pose: Pose::new(r, Vector3::new(0.5, -2.0, 10.0)),
                focal: None,
            },
        ],
        intrinsics: None,
    }
}

fn json(v: &impl serde::Serialize) -> Vec<u8> {
    serde_json::to_vec_pretty(v).unwrap_or_default()
}

fn seeds_cameras(_: &SeedDirs) -> Vec<Seed> {
    let p = sample_camera_path();
    let mut with_k = p.clone();
    with_k.intrinsics = Some(Intrinsics::new(1228.4, 1228.4, 639.5, 359.5).with_size(1280, 720));
    vec![
        generated("cameras.txt", formats::format_cameras(&p)),
        generated("cameras.json", json(&p)),
        generated("cameras_k.json", json(&with_k)),
    ]
}

fn seeds_marks(d: &SeedDirs) -> Vec<Seed> {
    let m = MarkedPoints {
        frames: vec![
            MarkedFrame {
                frame: 68,
                points: Points2d(vec![Point2::new(100.0, 200.5), Point2::new(-3.0, 4e3)]),
            },
            MarkedFrame {
                frame: 96,
                points: Points2d(vec![Point2::new(110.0, 190.0), Point2::new(0.0, 0.0)]),
            },
        ],
    };
    let mut s = vec![
        generated("marks.txt", formats::format_marked_points(&m)),
        generated("marks.json", json(&m)),
    ];
    s.extend(named(&[
        d.shared.join("book-demo/points2d.txt"),
        d.shared.join("book-demo/calib_video_projs.txt"),
        d.shared.join("blender_plate_dev/pinhole/marks.txt"),
    ]));
    s
}

fn seeds_points(d: &SeedDirs) -> Vec<Seed> {
    let p2 = Points2d(vec![Point2::new(1420.0, 1845.0), Point2::new(-1.5, 0.25)]);
    let p3 = Points3d(vec![
        Point3::new(0.159812, 3.721392, 21.186454),
        Point3::new(-2.4, 0.4, 25.6),
    ]);
    let mut s = vec![
        generated("points2d.txt", formats::format_points2d(&p2)),
        generated("points2d.json", json(&p2)),
        generated("points3d.txt", formats::format_points3d(&p3)),
        generated("points3d.json", json(&p3)),
    ];
    s.extend(named(&[d.shared.join("book-demo/calib_projs.txt")]));
    s.extend(files(
        &d.repo.join("crates/geometry/tests/data/book"),
        &[".txt"],
        1 << 16,
    ));
    s
}

fn seeds_intrinsics(d: &SeedDirs) -> Vec<Seed> {
    let k = Intrinsics::new(1228.4, 1230.0, 639.5, 359.5);
    let mut s = vec![
        generated("k.txt", formats::format_intrinsics(&k)),
        generated("k.json", json(&k.with_size(1280, 720))),
    ];
    s.extend(named(&[
        d.shared.join("book-demo/g7cam.txt"),
        d.shared.join("blender_plate_dev/pinhole/K.txt"),
    ]));
    s
}

fn seeds_exposure_list(d: &SeedDirs) -> Vec<Seed> {
    let mut s = vec![generated(
        "list.txt",
        "# a bracket\n3\nlow.png 1/1000\nmid.png 1/60\nhigh.png 0.25\n",
    )];
    s.extend(named(&[d
        .shared
        .join("debevec_memorial/memorial.hdr_image_list.txt")]));
    s
}

/// The COLMAP target's input: the three files joined by NUL bytes.
fn run_colmap(b: &[u8]) -> bool {
    let t = text(b);
    let mut parts = t.splitn(3, '\0');
    let (c, i, p) = (
        parts.next().unwrap_or(""),
        parts.next().unwrap_or(""),
        parts.next().unwrap_or(""),
    );
    vfxgraph_exchange::colmap::parse((c, "cameras.txt"), (i, "images.txt"), (p, "points3D.txt"))
        .is_ok()
}

fn seeds_colmap(_: &SeedDirs) -> Vec<Seed> {
    use vfxgraph_exchange::{colmap, Shot};
    use vfxgraph_geometry::points::PointCloud;
    let shot = Shot {
        intrinsics: Intrinsics::new(1228.4, 1228.4, 639.5, 359.5).with_size(1280, 720),
        path: sample_camera_path(),
        cloud: Some(PointCloud {
            points: vec![[0.0, 0.0, 5.0], [1.0, -1.0, 6.0]],
            track_ids: vec![0, 1],
            errors: vec![0.5, 0.25],
            inlier_frames: Vec::new(),
        }),
        tracks: None,
        colors: None,
        image_pattern: Some("frame.%04d.png".into()),
        st_map: None,
    };
    match colmap::format(&shot) {
        Ok(m) => vec![generated(
            "colmap",
            format!("{}\0{}\0{}", m.cameras, m.images, m.points3d),
        )],
        Err(_) => Vec::new(),
    }
}

/// Small test images: an RGB gradient, a gray ramp with out-of-range values, RGBA.
fn test_images() -> Vec<Image> {
    vec![
        Image::from_fn(13, 7, 3, |x, y, c| (x * 3 + y * 5 + c) as f32 / 60.0),
        Image::from_fn(8, 8, 1, |x, y, _| x as f32 * 0.5 - y as f32 * 0.1),
        Image::from_fn(9, 5, 4, |x, y, c| ((x + 2 * y) * (c + 1)) as f32 / 40.0),
        Image::from_fn(
            40,
            3,
            3,
            |x, _, c| if c == 1 { 1e4 } else { x as f32 / 40.0 },
        ),
    ]
}

fn image_seeds(d: &SeedDirs, format: Format) -> Vec<Seed> {
    let mut s = Vec::new();
    for (k, img) in test_images().iter().enumerate() {
        let mut add = |tag: &str, r: Result<Vec<u8>, vfxgraph_imaging::ImageError>| {
            if let Ok(b) = r {
                s.push(generated(&format!("{k}{tag}.{}", format.extension()), b));
            }
        };
        match format {
            Format::Exr => {
                for (ci, compression) in [
                    ExrCompression::None,
                    ExrCompression::Zip,
                    ExrCompression::Piz,
                ]
                .into_iter()
                .enumerate()
                {
                    for (pi, precision) in [ExrPrecision::Float, ExrPrecision::Half]
                        .into_iter()
                        .enumerate()
                    {
                        let o = ExrOptions {
                            precision,
                            compression,
                        };
                        add(&format!("-c{ci}p{pi}"), encode_exr(img, &o));
                    }
                }
            }
            Format::Pfm => {
                add(
                    "-le",
                    vfxgraph_imaging::io::pfm::encode_with_byte_order(img, true),
                );
                add(
                    "-be",
                    vfxgraph_imaging::io::pfm::encode_with_byte_order(img, false),
                );
            }
            Format::Png => {
                add("-8", vfxgraph_imaging::encode(img, Format::Png));
                add("-16", vfxgraph_imaging::io::encode_png16(img));
            }
            Format::Jpeg => {
                add("-q90", vfxgraph_imaging::io::encode_jpeg(img, 90));
                add("-q20", vfxgraph_imaging::io::encode_jpeg(img, 20));
            }
            Format::Dpx => {
                use vfxgraph_imaging::io::dpx::{encode, DpxOptions, Transfer};
                for bits in [8, 10, 12, 16] {
                    for transfer in [Transfer::PrintingDensity, Transfer::Linear] {
                        let o = DpxOptions { bits, transfer };
                        add(&format!("-{bits}-{}", transfer.code()), encode(img, &o));
                    }
                }
            }
            Format::Tiff => {
                use vfxgraph_imaging::io::tiff::{encode, TiffCompression, TiffDepth, TiffOptions};
                for (di, depth) in [TiffDepth::U8, TiffDepth::U16, TiffDepth::F32]
                    .into_iter()
                    .enumerate()
                {
                    for (ci, compression) in [
                        TiffCompression::None,
                        TiffCompression::Lzw,
                        TiffCompression::Deflate,
                    ]
                    .into_iter()
                    .enumerate()
                    {
                        let o = TiffOptions { depth, compression };
                        add(&format!("-d{di}c{ci}"), encode(img, &o));
                    }
                }
            }
            other => add("", vfxgraph_imaging::encode(img, other)),
        }
    }
    let sh = &d.shared;
    match format {
        Format::Exr => {
            s.extend(files(
                &sh.join("openexr_images_subset/TestImages"),
                &[".exr"],
                80_000,
            ));
            s.extend(files(
                &sh.join("openexr_images_subset/IlmfmlmflmTest"),
                &[".exr"],
                40_000,
            ));
            s.extend(named(&[
                sh.join("openexr_images_subset/DisplayWindow/t01.exr"),
                sh.join("openexr_images_subset/MultiResolution/ColorCodedLevels.exr"),
            ]));
        }
        Format::Png => {
            s.extend(files(&d.repo.join("crates/fuzz/seeds"), &[".png"], 1 << 16));
        }
        Format::Jpeg => {
            s.extend(files(&d.repo.join("crates/fuzz/seeds"), &[".jpg"], 1 << 16));
        }
        _ => {}
    }
    s
}

/// A 32×16, 4-frame H.264 MP4 made with the project's writer (key frames 0 and 2), BT.601 or
/// BT.709, limited or full range.
fn seeds_mp4(_: &SeedDirs) -> Vec<Seed> {
    use vfxgraph_video::{ColorInfo, Matrix};
    let frames: Vec<Image> = (0..4)
        .map(|k| {
            Image::from_fn(32, 16, 3, |x, y, c| {
                ((x + 3 * k) % 32) as f32 / 40.0 + (y * (c + 1)) as f32 / 100.0
            })
        })
        .collect();
    let dir = std::env::temp_dir().join(format!("vfxgraph-fuzz-mp4-{}", std::process::id()));
    let _ = std::fs::create_dir_all(&dir);
    let mut s = Vec::new();
    for (k, (matrix, full_range)) in [(Matrix::Bt601, false), (Matrix::Bt709, true)]
        .into_iter()
        .enumerate()
    {
        let path = dir.join(format!("seed{k}.mp4"));
        let color = ColorInfo {
            matrix,
            full_range,
            matrix_from_stream: true,
        };
        if vfxgraph_video::write_mp4(&path, &frames, 24.0, 2, 30, color).is_ok() {
            if let Ok(b) = std::fs::read(&path) {
                s.push(generated(&format!("clip{k}.mp4"), b));
            }
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
    s
}

fn run_mp4(b: &[u8]) -> bool {
    let path = Path::new("fuzz.mp4");
    match vfxgraph_video::Video::from_bytes(path, b.to_vec()) {
        Ok(v) => {
            let n = v.frame_count() as i64;
            let first = v.frame(0).is_ok();
            first & v.frame(n - 1).is_ok()
        }
        Err(_) => false,
    }
}

/// Repairs the CRC of every complete PNG chunk (so mutations inside chunks reach the decoder
/// instead of its checksum test).
pub fn fix_png_crcs(data: &mut [u8]) {
    let mut i = 8;
    while i + 12 <= data.len() {
        let len = u32::from_be_bytes([data[i], data[i + 1], data[i + 2], data[i + 3]]) as usize;
        let Some(end) = (i + 8).checked_add(len).filter(|&e| e + 4 <= data.len()) else {
            break;
        };
        let crc = crc32fast::hash(&data[i + 4..end]);
        data[end..end + 4].copy_from_slice(&crc.to_be_bytes());
        i = end + 4;
    }
}
