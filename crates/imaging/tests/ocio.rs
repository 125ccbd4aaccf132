//! Every colour transform the readers, writers and previews use against OpenColorIO's own
//! (scripts/check/ocio_transforms.py, PyOpenColorIO's CPU processor, the same built-in ACES
//! studio config): each listed colour space to and from both working spaces (ACEScg and linear
//! Rec. 709) and the display/view transforms of the previews, on values that include
//! negatives, near-zero values, the log curves' toes and cuts, and highlights far above 1.
//! The error of a value is `|ours − theirs| / max(1, |theirs|)` (absolute up to 1, relative
//! above), and it must be at most 1e-4 for every value of every transform.
//!
//! The Python comes from `VFXGRAPH_PYTHON_OCIO` (default
//! `~/.cache/vfxgraph/pyenv-ocio/bin/python`), with PyOpenColorIO and numpy (`pip install
//! opencolorio numpy`). Without them the test prints a notice and passes, unless
//! `VFXGRAPH_REQUIRE_CLIENTS=1` (set by `.ci/run`), where it fails.

use serde_json::Value;
use vfxgraph_imaging::colour::{ColourConfig, BUILTIN_CONFIG};
use vfxgraph_testdata::{repo, Python};

/// The Python with the clients these checks use.
fn python() -> Python {
    Python::from_env(
        "VFXGRAPH_PYTHON_OCIO",
        "~/.cache/vfxgraph/pyenv-ocio/bin/python",
        "pip install opencolorio numpy, or set VFXGRAPH_PYTHON_OCIO",
    )
}

/// The largest error allowed: 1e-4, the bound vfxgraph promises for its colour transforms.
const BOUND: f64 = 1e-4;

fn rgb(v: &Value) -> [f32; 3] {
    let a = v.as_array().expect("an RGB triple");
    std::array::from_fn(|k| a[k].as_f64().expect("a number") as f32)
}

#[test]
fn every_transform_matches_pyopencolorio() {
    if !python().has("PyOpenColorIO, numpy") {
        return;
    }
    let out = python()
        .command()
        .arg(repo().join("scripts/check/ocio_transforms.py"))
        .arg(BUILTIN_CONFIG)
        .output()
        .expect("run python");
    assert!(
        out.status.success(),
        "ocio_transforms.py: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let doc: Value = serde_json::from_slice(&out.stdout).expect("JSON from ocio_transforms.py");
    let config = ColourConfig::builtin();
    let cases = doc["cases"].as_array().expect("cases");
    assert!(cases.len() >= 50, "{} cases", cases.len());
    let mut failures = Vec::new();
    let mut overall = 0.0f64;
    eprintln!(
        "against PyOpenColorIO {} ({}):",
        doc["ocio_version"], doc["config"]
    );
    for case in cases {
        let src = case["src"].as_str().unwrap();
        let (t, what) = match case["kind"].as_str().unwrap() {
            "colour_space" => {
                let dst = case["dst"].as_str().unwrap();
                (
                    config.transform(src, dst).unwrap(),
                    format!("{src} -> {dst}"),
                )
            }
            _ => {
                let (d, v) = (
                    case["display"].as_str().unwrap(),
                    case["view"].as_str().unwrap(),
                );
                (
                    config.display_view(src, d, v).unwrap(),
                    format!("{src} -> {d} / {v}"),
                )
            }
        };
        let inputs = case["input"].as_array().unwrap();
        let outputs = case["output"].as_array().unwrap();
        assert_eq!(inputs.len(), outputs.len());
        let mut worst = 0.0f64;
        let mut at = [0.0f32; 3];
        // A conversion between different spaces moves the values (the check is not vacuous).
        let moved = inputs
            .iter()
            .zip(outputs)
            .map(|(i, o)| {
                let (i, o) = (rgb(i), rgb(o));
                (0..3).map(|k| (i[k] - o[k]).abs()).fold(0.0f32, f32::max)
            })
            .fold(0.0f32, f32::max);
        let same = case["dst"].as_str() == Some(src);
        assert!(same || moved > 1e-3, "{what}: moves values by {moved} only");
        for (i, o) in inputs.iter().zip(outputs) {
            let ours = t.apply_rgb(rgb(i));
            let theirs = rgb(o);
            for k in 0..3 {
                let (a, b) = (ours[k] as f64, theirs[k] as f64);
                // Both NaN is agreement; one NaN is an infinite error.
                let e = if a.is_nan() && b.is_nan() {
                    0.0
                } else {
                    let e = (a - b).abs() / b.abs().max(1.0);
                    if e.is_nan() {
                        f64::INFINITY
                    } else {
                        e
                    }
                };
                if e > worst {
                    worst = e;
                    at = rgb(i);
                }
            }
        }
        eprintln!("  {worst:9.2e}  {what}");
        overall = overall.max(worst);
        if worst > BOUND {
            failures.push(format!("{what}: {worst:.3e} at input {at:?}"));
        }
    }
    eprintln!(
        "largest error {overall:.2e} over {} transforms",
        cases.len()
    );
    assert!(
        failures.is_empty(),
        "over {BOUND}:\n{}",
        failures.join("\n")
    );
}
