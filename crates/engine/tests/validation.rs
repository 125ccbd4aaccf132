//! Graph validation: one test per error kind, each asserting the reported line and column.

mod common;

use std::path::Path;

use vfxgraph_engine::{graph, Diagnostics, ErrorKind, Overrides, ParamValue};

fn errors(text: &str) -> Diagnostics {
    errors_with(text, &Overrides::default())
}

fn errors_with(text: &str, o: &Overrides) -> Diagnostics {
    match graph::parse(Path::new("g.yaml"), text, &common::registry(), o) {
        Ok(_) => panic!("graph should not validate:\n{text}"),
        Err(d) => d,
    }
}

/// The (line, column) of the only diagnostic of `kind`.
fn at(d: &Diagnostics, kind: ErrorKind) -> (usize, usize) {
    let hits: Vec<_> = d.items.iter().filter(|x| x.kind == kind).collect();
    assert_eq!(hits.len(), 1, "expected one {kind:?} in:\n{d}");
    let s = hits[0].span.expect("has a place");
    (s.line, s.col)
}

#[test]
fn valid_graph_loads() {
    let g = graph::parse(
        Path::new("g.yaml"),
        "version: 1\nframes: 1-3\nnodes:\n  r: {type: ramp}\n  s: {type: sum, inputs: {items: r.out}}\n  a: {type: add, inputs: {a: r.out}}\n",
        &common::registry(),
        &Overrides::default(),
    )
    .unwrap();
    let ids: Vec<_> = g.nodes.iter().map(|n| n.id.as_str()).collect();
    assert_eq!(ids.len(), 3);
    assert!(ids.iter().position(|&x| x == "r") < ids.iter().position(|&x| x == "s"));
    let a = &g.nodes[g.index_of("a").unwrap()];
    assert!(a.per_frame, "add infers per_frame from its per-frame input");
    assert!(!g.nodes[g.index_of("s").unwrap()].per_frame);
}

#[test]
fn unknown_node_type() {
    let d = errors("version: 1\nnodes:\n  a:\n    type: nmu\n    params: {value: 1}\n");
    assert_eq!(at(&d, ErrorKind::UnknownNodeType), (4, 11));
    let text = d.to_string();
    assert!(
        text.contains("g.yaml:4:11") && text.contains("`nmu`"),
        "{text}"
    );
    assert!(text.contains("did you mean `num`"), "{text}");
}

#[test]
fn unknown_param() {
    let d = errors("version: 1\nnodes:\n  a:\n    type: num\n    params: {value: 1, vlaue: 2}\n");
    assert_eq!(at(&d, ErrorKind::UnknownParam), (5, 24));
    assert!(d.to_string().contains("vlaue"));
}

#[test]
fn unknown_input_port() {
    let d = errors("version: 1\nnodes:\n  a: {type: num, params: {value: 1}}\n  b:\n    type: add\n    inputs:\n      a: a.out\n      c: a.out\n");
    assert_eq!(at(&d, ErrorKind::UnknownPort), (8, 7));
}

#[test]
fn unknown_output_port() {
    let d = errors("version: 1\nnodes:\n  a: {type: num, params: {value: 1}}\n  b:\n    type: add\n    inputs: {a: a.output}\n");
    assert_eq!(at(&d, ErrorKind::UnknownPort), (6, 17));
    assert!(d.to_string().contains("did you mean `out`"));
}

#[test]
fn wrong_param_type() {
    let d = errors("version: 1\nnodes:\n  a:\n    type: num\n    params:\n      value: \"high\"\n");
    assert_eq!(at(&d, ErrorKind::ParamType), (6, 14));
    assert!(d.to_string().contains("\"high\""), "{d}");
}

#[test]
fn out_of_range_param() {
    let d = errors("version: 1\nnodes:\n  a: {type: num, params: {value: 1}}\n  b:\n    type: add\n    inputs: {a: a.out}\n    params: {count: 11}\n");
    assert_eq!(at(&d, ErrorKind::ParamRange), (7, 21));
    assert!(
        d.to_string().contains("11 is outside int in [0, 10]"),
        "{d}"
    );
}

#[test]
fn missing_required_input() {
    let d = errors("version: 1\nnodes:\n  b:\n    type: add\n");
    assert_eq!(at(&d, ErrorKind::MissingInput), (3, 3));
    assert!(d.to_string().contains("needs input `a`"));
    // With an `inputs:` that leaves it out, the error points at that key.
    let d = errors(
        "version: 1\nnodes:\n  n: {type: num, params: {value: 1}}\n  b:\n    type: add\n    inputs: {b: n.out}\n",
    );
    assert_eq!(at(&d, ErrorKind::MissingInput), (6, 5));
}

#[test]
fn missing_required_param() {
    let d = errors("version: 1\nnodes:\n  a: {type: num}\n");
    assert_eq!(at(&d, ErrorKind::MissingParam), (3, 3));
}

#[test]
fn type_mismatch_between_ports() {
    // `pair` takes sequence<string>; `ramp` gives sequence<float>.
    let d = errors("version: 1\nframes: 0..=2\nnodes:\n  r: {type: ramp}\n  p:\n    type: pair\n    inputs: {items: r.out}\n");
    assert_eq!(at(&d, ErrorKind::TypeMismatch), (7, 21));
    assert!(
        d.to_string().contains("sequence<string>") && d.to_string().contains("sequence<float>")
    );
}

#[test]
fn type_mismatch_once_node_on_sequence() {
    // `sum` needs a sequence, `num` gives a single float.
    let d = errors("version: 1\nnodes:\n  a: {type: num, params: {value: 1}}\n  s: {type: sum, inputs: {items: a.out}}\n");
    assert_eq!(at(&d, ErrorKind::TypeMismatch), (4, 34));
}

#[test]
fn dangling_reference() {
    let d = errors("version: 1\nnodes:\n  a: {type: num, params: {value: 1}}\n  b:\n    type: add\n    inputs:\n      a: aa.out\n");
    assert_eq!(at(&d, ErrorKind::DanglingReference), (7, 10));
    assert!(d.to_string().contains("did you mean `a`"));
}

#[test]
fn cycle_names_its_nodes() {
    let d = errors("version: 1\nnodes:\n  x:\n    type: add\n    inputs: {a: z.out}\n  y:\n    type: add\n    inputs: {a: x.out}\n  z:\n    type: add\n    inputs: {a: y.out}\n  ok: {type: num, params: {value: 1}}\n");
    assert_eq!(at(&d, ErrorKind::Cycle), (5, 17));
    let t = d.to_string();
    assert!(t.contains("x → y → z"), "{t}");
    assert!(!t.contains("ok"), "{t}");
}

#[test]
fn duplicate_id() {
    let d = errors("version: 1\nnodes:\n  a: {type: num, params: {value: 1}}\n  b: {type: num, params: {value: 2}}\n  a: {type: num, params: {value: 3}}\n");
    assert_eq!(at(&d, ErrorKind::DuplicateId), (5, 3));
    assert!(d.to_string().contains("first declared on line 3"));
}

#[test]
fn syntax_error_has_position() {
    let d = errors("version: 1\nnodes:\n  a: {type: num, params: {value: 1}\n  b: 2\n");
    assert_eq!(d.items.len(), 1);
    assert_eq!(d.items[0].kind, ErrorKind::Syntax);
    assert!(d.items[0].span.unwrap().line >= 3);
}

#[test]
fn all_errors_reported_at_once() {
    let d = errors("version: 1\nnodes:\n  a: {type: nope}\n  b: {type: num, params: {value: x}}\n  c: {type: add, inputs: {a: q.out}}\n");
    let kinds: Vec<_> = d.items.iter().map(|x| x.kind).collect();
    assert!(kinds.contains(&ErrorKind::UnknownNodeType));
    assert!(kinds.contains(&ErrorKind::ParamType));
    assert!(kinds.contains(&ErrorKind::DanglingReference));
    // Sorted by position.
    let lines: Vec<_> = d.items.iter().map(|x| x.span.unwrap().line).collect();
    assert!(lines.windows(2).all(|w| w[0] <= w[1]), "{lines:?}");
}

#[test]
fn per_frame_needs_frames() {
    let d = errors("version: 1\nnodes:\n  r: {type: ramp}\n");
    assert_eq!(at(&d, ErrorKind::Frames), (3, 3));
    let d = errors("version: 1\nframes: 5..=1\nnodes:\n  r: {type: ramp}\n");
    assert_eq!(at(&d, ErrorKind::Frames), (2, 9));
}

#[test]
fn overrides_are_checked() {
    let text = "version: 1\nnodes:\n  a: {type: num, params: {value: 1}}\n";
    let o = Overrides {
        set: vec!["a.value=x".into(), "b.value=1".into(), "a.nope=1".into()],
        ..Default::default()
    };
    let d = errors_with(text, &o);
    assert_eq!(d.items.len(), 3, "{d}");
    assert!(d.items.iter().all(|x| x.kind == ErrorKind::Override));
    let ok = graph::parse(
        Path::new("g.yaml"),
        text,
        &common::registry(),
        &Overrides {
            set: vec!["a.value=2.5".into()],
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(ok.nodes[0].params.f64("value"), 2.5);
}

#[test]
fn unknown_keys_and_version() {
    let d =
        errors("version: 2\nnodez: {}\nnodes:\n  a: {type: num, params: {value: 1}, inptus: {}}\n");
    let kinds: Vec<_> = d
        .items
        .iter()
        .map(|x| (x.kind, x.span.unwrap().line))
        .collect();
    assert!(kinds.contains(&(ErrorKind::Structure, 1)), "{d}");
    assert!(kinds.contains(&(ErrorKind::Structure, 2)), "{d}");
    assert!(kinds.contains(&(ErrorKind::Structure, 4)), "{d}");
    assert!(d.to_string().contains("did you mean `inputs`"), "{d}");
}

/// Regression (fuzzing): a frame-pattern width from the file panicked in the formatter.
#[test]
fn too_wide_frame_pattern_is_a_range_error() {
    for path in ["f.%9223372036854775808d.txt", "f.%99999d.txt"] {
        let d = errors(&format!(
            "version: 1\nnodes:\n  r:\n    type: read_num\n    params: {{path: \"{path}\"}}\n"
        ));
        assert_eq!(at(&d, ErrorKind::ParamRange), (5, 20));
        let text = d.to_string();
        assert!(text.contains("wider than 32 digits"), "{text}");
    }
}

/// `defaults:` gives a parameter's value to every node that has it and does not set it: a
/// node's own value and `--set` win, a node without the parameter is untouched, and a
/// required parameter can come from it.
#[test]
fn graph_defaults_fill_the_params_nodes_leave_unset() {
    let text = "version: 1\nframes: 1-2\ndefaults: {offset: 2.5, value: 4, scale: 3}\nnodes:\n  \
                n: {type: num}\n  r: {type: ramp, params: {scale: 0.5}}\n  \
                a: {type: add, inputs: {a: n.out}}\n  \
                b: {type: add, inputs: {a: n.out}, params: {offset: 1}}\n  \
                c: {type: add, inputs: {a: n.out}}\n";
    let o = Overrides {
        set: vec!["c.offset=7".into()],
        ..Default::default()
    };
    let g = graph::parse(Path::new("g.yaml"), text, &common::registry(), &o).unwrap();
    let p = |id: &str, name: &str| g.nodes[g.index_of(id).unwrap()].params.f64(name);
    assert_eq!(p("n", "value"), 4.0);
    assert_eq!(p("r", "scale"), 0.5);
    assert_eq!(p("a", "offset"), 2.5);
    assert_eq!(p("b", "offset"), 1.0);
    assert_eq!(p("c", "offset"), 7.0);
}

/// Command-line defaults (`--ocio FILE`): above the graph's `defaults:`, below a node's own
/// value and `--set`; a name no node has is no error (the flag applies to any graph).
#[test]
fn command_line_defaults_rank_between_the_graphs_and_a_nodes() {
    let text =
        "version: 1\ndefaults: {offset: 2.5}\nnodes:\n  n: {type: num, params: {value: 4}}\n  \
                a: {type: add, inputs: {a: n.out}}\n  \
                b: {type: add, inputs: {a: n.out}, params: {offset: 1}}\n  \
                c: {type: add, inputs: {a: n.out}}\n";
    let o = Overrides {
        set: vec!["c.offset=7".into()],
        defaults: vec![
            ("offset".into(), ParamValue::Float(3.0)),
            ("no_such_param".into(), ParamValue::Float(1.0)),
        ],
        ..Default::default()
    };
    let g = graph::parse(Path::new("g.yaml"), text, &common::registry(), &o).unwrap();
    let p = |id: &str| g.nodes[g.index_of(id).unwrap()].params.f64("offset");
    assert_eq!((p("a"), p("b"), p("c")), (3.0, 1.0, 7.0));
    // A value of the wrong type: an error naming the node and the parameter.
    let o = Overrides {
        defaults: vec![("offset".into(), ParamValue::Str("fast".into()))],
        ..Default::default()
    };
    let Err(d) = graph::parse(Path::new("g.yaml"), text, &common::registry(), &o) else {
        panic!("a string offset was accepted");
    };
    assert!(
        d.to_string().contains("node `a`") && d.to_string().contains("offset"),
        "{d}"
    );
}

#[test]
fn graph_defaults_are_checked() {
    // A parameter no node has: named, at its value, with a suggestion.
    let d = errors("version: 1\ndefaults:\n  ofset: 1\nnodes:\n  n: {type: num, params: {value: 1}}\n  a: {type: add, inputs: {a: n.out}}\n");
    assert_eq!(at(&d, ErrorKind::UnknownParam), (3, 10));
    let text = d.to_string();
    assert!(
        text.contains("`ofset`") && text.contains("did you mean `offset`"),
        "{text}"
    );
    // A value of the wrong type for a node that takes it: at the value, naming the node.
    let d = errors("version: 1\ndefaults: {offset: fast}\nnodes:\n  n: {type: num, params: {value: 1}}\n  a: {type: add, inputs: {a: n.out}}\n");
    assert_eq!(at(&d, ErrorKind::ParamType), (2, 20));
    assert!(d.to_string().contains("node `a`"), "{d}");
    // Not a mapping.
    let d = errors("version: 1\ndefaults: [1]\nnodes:\n  n: {type: num, params: {value: 1}}\n");
    assert_eq!(at(&d, ErrorKind::Structure), (2, 11));
}
