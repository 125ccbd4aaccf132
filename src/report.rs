//! Human-readable output: diagnostics, tables, node docs, Graphviz.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::io::IsTerminal;

use vfxgraph_engine::exec::{PlanReport, RunReport};
use vfxgraph_engine::store::{EntrySummary, Store};
use vfxgraph_engine::{Diagnostics, Graph, NodeSpec, PlanStatus, Registry, Status};

/// Prints every diagnostic with its source snippet (miette), then a count.
pub fn print_diagnostics(d: &Diagnostics) {
    let theme = if std::io::stderr().is_terminal() {
        miette::GraphicalTheme::unicode()
    } else {
        miette::GraphicalTheme::unicode_nocolor()
    };
    let handler = miette::GraphicalReportHandler::new_themed(theme);
    // Each report's first line is `file:line:col: error[kind]: message`, then the snippet.
    for report in d.reports() {
        let mut out = String::new();
        match handler.render_report(&mut out, &report) {
            Ok(()) => eprintln!("{out}"),
            Err(_) => eprintln!("{report}"),
        }
    }
    eprintln!(
        "{}: {} problem{} found",
        d.file.display(),
        d.items.len(),
        if d.items.len() == 1 { "" } else { "s" }
    );
}

/// Prints the failed instances with their causes.
pub fn print_failures(r: &RunReport) {
    for line in failure_lines(r) {
        eprintln!("{line}");
    }
    let skipped = r
        .nodes
        .iter()
        .filter(|n| n.status == Status::Skipped)
        .count();
    if skipped > 0 {
        eprintln!("{skipped} instance(s) skipped because an input failed");
    }
}

/// Most distinct errors printed per node; the rest are counted.
const ERRORS_PER_NODE: usize = 3;

/// One line per distinct error of a node, with the frames that failed with it (a plate that
/// cannot be decoded is one line, not one per frame), at most [`ERRORS_PER_NODE`] a node.
fn failure_lines(r: &RunReport) -> Vec<String> {
    // (node, reason) → frames, in report order.
    let mut groups: Vec<(&str, &str, &str, Vec<i64>, bool)> = Vec::new();
    for n in r.nodes.iter().filter(|n| n.status == Status::Failed) {
        match groups.iter_mut().find(|g| g.0 == n.id && g.2 == n.reason) {
            Some(g) => g.3.extend(n.frame),
            None => groups.push((
                &n.id,
                &n.node_type,
                &n.reason,
                n.frame.into_iter().collect(),
                n.frame.is_none(),
            )),
        }
    }
    let mut out = Vec::new();
    let mut shown: Vec<(&str, usize)> = Vec::new();
    for (id, ty, reason, frames, once) in &groups {
        let count = match shown.iter_mut().find(|s| s.0 == *id) {
            Some(s) => {
                s.1 += 1;
                s.1
            }
            None => {
                shown.push((id, 1));
                1
            }
        };
        if count > ERRORS_PER_NODE {
            continue;
        }
        let at = match (once, frames.len()) {
            (true, _) | (_, 0) => String::new(),
            (_, 1) => format!(" frame {}", frames[0]),
            (_, k) => format!(
                " frames {} ({k} frames)",
                vfxgraph_engine::FrameSet::from_frames(frames.clone())
            ),
        };
        out.push(format!("error: node `{id}` ({ty}){at} failed: {reason}"));
    }
    for (id, k) in shown {
        if k > ERRORS_PER_NODE {
            out.push(format!(
                "… and {} more distinct errors of node `{id}` (`--json` lists every instance)",
                k - ERRORS_PER_NODE
            ));
        }
    }
    out
}

/// The closing table: node, instances, cached, ran, failed, seconds.
pub fn print_table(r: &RunReport) {
    let totals = r.totals();
    let w = totals.iter().map(|t| t.id.len()).max().unwrap_or(4).max(4);
    println!(
        "{:<w$}  {:>9}  {:>6}  {:>6}  {:>6}  {:>9}",
        "node", "instances", "cached", "ran", "failed", "seconds"
    );
    for t in &totals {
        println!(
            "{:<w$}  {:>9}  {:>6}  {:>6}  {:>6}  {:>9.3}",
            t.id, t.instances, t.cached, t.ran, t.failed, t.seconds
        );
    }
    let ran: usize = totals.iter().map(|t| t.ran).sum();
    let cached: usize = totals.iter().map(|t| t.cached).sum();
    println!(
        "{} instances: {ran} ran, {cached} cached, {} failed or skipped; {:.3} s wall",
        r.nodes.len(),
        r.nodes.len() - ran - cached,
        r.wall_seconds
    );
}

/// The plan, one line per node (per-frame nodes summarised, with the first reasons).
pub fn print_plan(p: &PlanReport) {
    let mut i = 0;
    while i < p.nodes.len() {
        let id = &p.nodes[i].id;
        let mut j = i;
        while j < p.nodes.len() && &p.nodes[j].id == id {
            j += 1;
        }
        let group = &p.nodes[i..j];
        let count = |s: PlanStatus| group.iter().filter(|n| n.status == s).count();
        let (c, r, b) = (
            count(PlanStatus::Cached),
            count(PlanStatus::Run),
            count(PlanStatus::Blocked),
        );
        if group.len() == 1 {
            let n = &group[0];
            println!(
                "{:<16} {:<8} {}",
                n.id,
                format!("{:?}", n.status).to_lowercase(),
                n.reason
            );
        } else {
            println!(
                "{:<16} {} frames: {c} cached, {r} run, {b} blocked",
                id,
                group.len()
            );
            let mut reasons: BTreeMap<&str, Vec<i64>> = BTreeMap::new();
            for n in group.iter().filter(|n| n.status != PlanStatus::Cached) {
                reasons
                    .entry(&n.reason)
                    .or_default()
                    .push(n.frame.unwrap_or(0));
            }
            // By their first frame, in numeric order (not the reasons' text order, which put
            // "frame 100" before "frame 20").
            let mut reasons: Vec<(&str, Vec<i64>)> = reasons.into_iter().collect();
            reasons.sort_by_key(|(_, frames)| frames.iter().min().copied());
            for (reason, frames) in reasons {
                let set = vfxgraph_engine::FrameSet::from_frames(frames);
                println!("{:<16}   frames {set}: {reason}", "");
            }
        }
        i = j;
    }
}

/// `vfxgraph nodes`.
pub fn print_nodes(registry: &Registry) {
    let w = registry
        .nodes()
        .map(|n| n.spec().name.len())
        .max()
        .unwrap_or(8);
    for n in registry.nodes() {
        let s = n.spec();
        println!("{:<w$}  {}", s.name, first_sentence(s.doc));
    }
}

/// The first sentence: up to a ". " followed by a capital letter (so "ch. 6" does not end it).
pub fn first_sentence(doc: &str) -> &str {
    let b = doc.as_bytes();
    for i in 0..b.len().saturating_sub(2) {
        if b[i] == b'.' && b[i + 1] == b' ' && b[i + 2].is_ascii_uppercase() {
            return &doc[..i];
        }
    }
    doc.trim_end_matches('.')
}

/// `vfxgraph describe TYPE`.
pub fn print_describe(s: &NodeSpec, registry: &Registry) {
    println!("{} (version {})", s.name, s.version);
    println!("  {}", s.doc);
    let mode = match s.mode {
        vfxgraph_engine::Mode::Once => "once",
        vfxgraph_engine::Mode::PerFrame => "per frame",
        vfxgraph_engine::Mode::Either => {
            "once, or per frame (`per_frame: true`, a per-frame input, or a frame pattern in a path)"
        }
    };
    println!("  runs: {mode}{}", if s.seeded { "; seeded" } else { "" });
    let ty_doc = |t: &str| registry.artifact(t).map(|a| a.doc).unwrap_or("");
    if !s.inputs.is_empty() {
        println!("inputs:");
        for p in &s.inputs {
            println!(
                "  {:<14} {:<20} {}{}",
                p.name,
                p.display_type(),
                p.doc,
                if p.optional { " (optional)" } else { "" }
            );
        }
    }
    if !s.outputs.is_empty() {
        println!("outputs:");
        for p in &s.outputs {
            println!("  {:<14} {:<20} {}", p.name, p.ty, p.doc);
            let d = ty_doc(p.ty);
            if !d.is_empty() {
                println!("  {:<14} {:<20} ({d})", "", "");
            }
        }
    }
    if !s.params.is_empty() {
        println!("params:");
        for p in &s.params {
            let default = p
                .default
                .as_ref()
                .map(|d| format!("default {d}"))
                .unwrap_or_else(|| "required".into());
            let cosmetic = if !p.cosmetic {
                ""
            } else {
                "; does not affect output"
            };
            println!("  {:<14} {} ({default}{cosmetic})", p.name, p.kind);
            if !p.doc.is_empty() {
                println!("  {:<14} {}", "", p.doc);
            }
        }
    }
}

fn dot_escape(s: &str) -> String {
    s.replace('\\', "\\\\").replace('"', "\\\"")
}

/// Graphviz dot of the graph, each node coloured by its plan.
pub fn dot(g: &Graph, p: &PlanReport) -> String {
    let mut out = String::from("digraph vfxgraph {\n  rankdir=LR;\n  node [shape=box, style=\"rounded,filled\", fontname=\"Helvetica\"];\n");
    for n in &g.nodes {
        let mine: Vec<_> = p.nodes.iter().filter(|x| x.id == n.id).collect();
        let all = |s: PlanStatus| mine.iter().all(|x| x.status == s);
        let (color, label) = if all(PlanStatus::Cached) {
            ("palegreen", "cached")
        } else if mine.iter().any(|x| x.status == PlanStatus::Run) {
            ("orange", "run")
        } else {
            ("lightgray", "blocked")
        };
        let frames = if n.per_frame {
            format!("\\n× {} frames", g.frames.len())
        } else {
            String::new()
        };
        let _ = writeln!(
            out,
            "  \"{}\" [label=\"{}\\n{}{}\\n({label})\", fillcolor={color}];",
            dot_escape(&n.id),
            dot_escape(&n.id),
            n.spec().name,
            frames
        );
    }
    for n in &g.nodes {
        for e in &n.inputs {
            let _ = writeln!(
                out,
                "  \"{}\" -> \"{}\" [label=\"{}→{}\"{}];",
                dot_escape(&g.nodes[e.from].id),
                dot_escape(&n.id),
                e.from_port,
                e.port,
                if e.whole_sequence { ", style=bold" } else { "" }
            );
        }
    }
    out.push_str("}\n");
    out
}

pub fn human_bytes(b: u64) -> String {
    const UNITS: [&str; 5] = ["B", "KiB", "MiB", "GiB", "TiB"];
    let mut v = b as f64;
    let mut u = 0;
    while v >= 1024.0 && u + 1 < UNITS.len() {
        v /= 1024.0;
        u += 1;
    }
    if u == 0 {
        format!("{b} B")
    } else {
        format!("{v:.1} {}", UNITS[u])
    }
}

pub fn print_cache_ls(entries: &[EntrySummary]) {
    println!(
        "{:<14} {:<16} {:<22} {:>7} {:>10} {:>9}",
        "key", "node", "type", "frame", "size", "seconds"
    );
    for e in entries {
        println!(
            "{:<14} {:<16} {:<22} {:>7} {:>10} {:>9.3}",
            &e.key[..12.min(e.key.len())],
            e.entry.node_id,
            e.entry.node_type,
            e.entry
                .frame
                .map(|f| f.to_string())
                .unwrap_or_else(|| "-".into()),
            human_bytes(e.bytes),
            e.entry.seconds
        );
    }
    println!("{} entries", entries.len());
}

pub fn print_cache_du(store: &Store) {
    for (ty, (n, bytes)) in store.usage_by_type() {
        println!("{ty:<20} {n:>8} objects {:>12}", human_bytes(bytes));
    }
    let (bytes, files) = store.disk_usage_detail();
    println!(
        "{:<20} {:>8} files   {:>12}",
        "total on disk",
        files,
        human_bytes(bytes)
    );
}

#[cfg(test)]
mod tests {
    use super::*;
    use vfxgraph_engine::exec::InstanceReport;

    fn failed(id: &str, frame: Option<i64>, reason: &str) -> InstanceReport<Status> {
        InstanceReport {
            id: id.into(),
            node_type: "read_video".into(),
            frame,
            status: Status::Failed,
            reason: reason.into(),
            seconds: 0.0,
        }
    }

    #[test]
    fn one_error_line_per_node_and_reason_with_its_frames() {
        let mut nodes: Vec<_> = (0..40)
            .map(|f| failed("plate", Some(f), "clip.mp4: unsupported codec"))
            .collect();
        nodes.push(failed("plate", Some(41), "clip.mp4: frame 41 is corrupt"));
        nodes.push(failed("solve", None, "no start"));
        for k in 0..5 {
            nodes.push(failed("grade", Some(k), &format!("error {k}")));
        }
        let r = RunReport {
            nodes,
            wall_seconds: 0.0,
        };
        let lines = failure_lines(&r);
        assert_eq!(
            lines[0],
            "error: node `plate` (read_video) frames 0-39 (40 frames) failed: clip.mp4: \
             unsupported codec"
        );
        assert_eq!(
            lines[1],
            "error: node `plate` (read_video) frame 41 failed: clip.mp4: frame 41 is corrupt"
        );
        assert_eq!(
            lines[2],
            "error: node `solve` (read_video) failed: no start"
        );
        assert_eq!(lines.len(), 3 + 3 + 1, "{lines:#?}");
        assert!(lines[6].starts_with("… and 2 more distinct errors of node `grade`"));
    }
}
