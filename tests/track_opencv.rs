//! `graphs/track_opencv.yaml` end to end (only with the `opencv` feature): `klt_track` and
//! `klt_track_opencv` side by side on Middlebury RubberWhale, both written in both formats.
#![cfg(feature = "opencv")]

use std::path::Path;
use std::process::Command;

use serde_json::Value as Json;

#[test]
fn track_opencv_graph_runs_both_trackers() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let tmp = tempfile::tempdir().unwrap();
    let graph = root.join("graphs/track_opencv.yaml");
    let Some(g) = vfxgraph_testdata::graph_with_data(&graph, tmp.path()) else {
        return;
    };
    let out = Command::new(env!("CARGO_BIN_EXE_vfxgraph"))
        .current_dir(tmp.path())
        .arg("run")
        .arg("--json")
        .arg(&g)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: Json = serde_json::from_slice(&out.stdout).unwrap();
    let nodes = v["nodes"].as_array().unwrap();
    assert!(nodes.iter().all(|n| n["status"] == "ran"), "{nodes:?}");
    let o = tmp.path().join("out/track_opencv");
    let mut counts = Vec::new();
    for who in ["ours", "opencv"] {
        let book = std::fs::read_to_string(o.join(who).join("f.txt")).unwrap();
        assert!(book.starts_with("Features per frame = 150"), "{who}");
        let t: Json =
            serde_json::from_slice(&std::fs::read(o.join(who).join("tracks.json")).unwrap())
                .unwrap();
        assert_eq!(t["frames"], serde_json::json!([10, 11]), "{who}");
        counts.push(t["tracks"].as_array().unwrap().len());
        for f in ["draw.10.png", "draw.11.png"] {
            assert!(o.join(who).join(f).exists(), "{who} {f}");
        }
    }
    // 150 slots each, a few refilled after a loss.
    assert!(
        counts.iter().all(|&n| (150..=180).contains(&n)),
        "{counts:?}"
    );
}
