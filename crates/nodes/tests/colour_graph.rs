//! A colour-managed graph end to end: a LogC3 plate sequence read and written through the
//! engine with the working space and the plate's colour space stated once, in the graph's
//! `defaults:`, the writers' outputs checked against the OpenColorIO transform and against the
//! plate's own codes, and a bad colour space name reported with the node and the file.

use std::path::Path;

use vfxgraph_engine::{graph, run, Overrides, RunOptions};
use vfxgraph_imaging::colour::ColourConfig;
use vfxgraph_imaging::io::{dpx, Values};
use vfxgraph_imaging::{decode, write_image_as, Format, Image};

const LOGC3: &str = "ARRI LogC3 (EI800)";

/// A 10-bit LogC3 DPX frame: a ramp over the curve's range in each channel.
fn plate(frame: usize) -> Image {
    Image::from_fn(24, 16, 3, |x, y, c| {
        ((x * 37 + y * 61 + c * 211 + frame * 97) % 1024) as f32 / 1023.0
    })
}

fn run_graph(dir: &Path, text: &str) -> vfxgraph_engine::RunReport {
    let path = dir.join("g.yaml");
    std::fs::write(&path, text).unwrap();
    let registry = vfxgraph_nodes::registry();
    let g = graph::parse(&path, text, &registry, &Overrides::default()).unwrap_or_else(|d| {
        panic!("{d}");
    });
    run(
        &g,
        &registry,
        &RunOptions::default(),
        &vfxgraph_engine::exec::Quiet,
    )
    .unwrap()
}

#[test]
fn a_logc3_sequence_through_an_acescg_graph() {
    let dir = tempfile::tempdir().unwrap();
    for f in 1..=2 {
        let p = dir.path().join(format!("plate.{f:04}.dpx"));
        write_image_as(&p, &plate(f), Values::Codes).unwrap();
    }
    let text = format!(
        "version: 1\nframes: 1-2\ndefaults:\n  working_space: acescg\n  colour_space: \
         \"{LOGC3}\"\nnodes:\n  plate: {{type: read_image_sequence, params: {{path: \
         plate.%04d.dpx}}}}\n  back: {{type: write_image_sequence, inputs: {{sequence: \
         plate.sequence}}, params: {{path: back/f.%04d.dpx}}}}\n  lin: {{type: \
         write_image_sequence, inputs: {{sequence: plate.sequence}}, params: {{path: \
         lin/f.%04d.exr, colour_space: ACEScg}}}}\n"
    );
    let report = run_graph(dir.path(), &text);
    assert!(!report.failed(), "{:?}", report.nodes);
    let to_cg = ColourConfig::builtin().transform(LOGC3, "ACEScg").unwrap();
    for f in 1..=2usize {
        // Back in LogC3: the plate's codes (10 bits: the round trip is within 0.03 of a step).
        let bytes = std::fs::read(dir.path().join(format!("back/f.{f:04}.dpx"))).unwrap();
        let (back, _) = dpx::decode_codes(&bytes).unwrap();
        let codes = |img: &Image| -> Vec<u32> {
            img.data
                .iter()
                .map(|v| (v * 1023.0).round() as u32)
                .collect()
        };
        assert!(codes(&back) == codes(&plate(f)), "frame {f}");
        // In ACEScg: the OpenColorIO transform of the plate's codes as read.
        let bytes = std::fs::read(dir.path().join(format!("lin/f.{f:04}.exr"))).unwrap();
        let lin = decode(&bytes, Format::Exr).unwrap();
        let p = dir.path().join(format!("plate.{f:04}.dpx"));
        let mut want = vfxgraph_imaging::read_image_as(&p, Values::Codes).unwrap();
        to_cg.apply(&mut want);
        assert!(lin.data == want.data, "frame {f}");
    }
}

#[test]
fn a_bad_colour_space_names_the_node_and_the_file() {
    let dir = tempfile::tempdir().unwrap();
    write_image_as(&dir.path().join("p.dpx"), &plate(0), Values::Codes).unwrap();
    let text = "version: 1\nnodes:\n  plate: {type: read_image, params: {path: p.dpx, \
                colour_space: LogC3}}\n  out: {type: write_image, inputs: {image: \
                plate.image}, params: {path: o.exr}}\n";
    let report = run_graph(dir.path(), text);
    assert!(report.failed());
    let line = report
        .nodes
        .iter()
        .find(|n| n.status == vfxgraph_engine::Status::Failed)
        .unwrap();
    assert!(
        line.reason.contains("p.dpx")
            && line.reason.contains("`LogC3`")
            && line.reason.contains(LOGC3),
        "{}",
        line.reason
    );
}
