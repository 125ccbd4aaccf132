//! Edges (pass 2): each `inputs:` entry resolved to a producer's output port, required inputs
//! checked; and, once per-frame resolution knows which producers run per frame, the type
//! check of each connection.

use std::collections::HashMap;

use super::nodes::Raw;
use super::Edge;
use crate::diagnostic::{suggest, Diagnostics, ErrorKind, Span};
use crate::node::NodeSpec;
use crate::yaml::Yaml;

/// Each node's resolved input edges, with the span of the reference.
pub(super) type Edges = Vec<Vec<(Edge, Span)>>;

/// Resolves the input references of every node; unresolved ones are reported and left out.
pub(super) fn connect(raws: &[Raw], d: &mut Diagnostics) -> Edges {
    let index: HashMap<&str, usize> = raws
        .iter()
        .enumerate()
        .map(|(i, r)| (r.id.as_str(), i))
        .collect();
    let mut edges: Edges = vec![Vec::new(); raws.len()];
    for (i, raw) in raws.iter().enumerate() {
        let Some(node) = &raw.node else { continue };
        let spec = node.spec();
        for (ik, iv) in &raw.inputs {
            if let Some(edge) = resolve_input(raws, &index, raw, spec, ik, iv, d) {
                edges[i].push((edge, iv.span));
            }
        }
        check_required_inputs(raw, spec, d);
    }
    edges
}

/// The edge of input entry `ik: iv` of node `raw` (of type `spec`), if it resolves.
fn resolve_input(
    raws: &[Raw],
    index: &HashMap<&str, usize>,
    raw: &Raw,
    spec: &NodeSpec,
    ik: &Yaml,
    iv: &Yaml,
    d: &mut Diagnostics,
) -> Option<Edge> {
    let port_name = ik.as_str().unwrap_or("");
    let Some(port) = spec.inputs.iter().find(|p| p.name == port_name) else {
        d.push_help(
            ErrorKind::UnknownPort,
            Some(ik.span),
            format!(
                "node `{}` ({}) has no input port `{port_name}`",
                raw.id, spec.name
            ),
            suggest(port_name, spec.inputs.iter().map(|p| p.name)).or_else(|| {
                Some(format!(
                    "its inputs are: {}",
                    spec.inputs
                        .iter()
                        .map(|p| p.name)
                        .collect::<Vec<_>>()
                        .join(", ")
                ))
            }),
        );
        return None;
    };
    let (j, src_id, src_port) = reference(index, raw, port_name, iv, d)?;
    let src_node = raws[j].node.as_ref()?;
    let Some(out) = src_node.spec().outputs.iter().find(|p| p.name == src_port) else {
        d.push_help(
            ErrorKind::UnknownPort,
            Some(iv.span),
            format!(
                "node `{src_id}` ({}) has no output port `{src_port}`",
                src_node.spec().name
            ),
            suggest(src_port, src_node.spec().outputs.iter().map(|p| p.name)),
        );
        return None;
    };
    Some(Edge {
        port: port.name,
        from: j,
        from_port: out.name,
        whole_sequence: port.sequence,
    })
}

/// The producing node (index and id) and output port that reference `iv` (`node.port`) of
/// input `port_name` of node `raw` names, if it is well written and the node exists.
fn reference<'y>(
    index: &HashMap<&str, usize>,
    raw: &Raw,
    port_name: &str,
    iv: &'y Yaml,
    d: &mut Diagnostics,
) -> Option<(usize, &'y str, &'y str)> {
    let Some(reference) = iv.as_str() else {
        d.push(
            ErrorKind::Structure,
            Some(iv.span),
            "an input is written `node.port`",
        );
        return None;
    };
    let Some((src_id, src_port)) = reference.split_once('.') else {
        d.push(
            ErrorKind::Structure,
            Some(iv.span),
            format!(
                "input `{port_name}` of node `{}`: write `node.port`, found `{reference}`",
                raw.id
            ),
        );
        return None;
    };
    let Some(&j) = index.get(src_id) else {
        d.push_help(
            ErrorKind::DanglingReference,
            Some(iv.span),
            format!(
                "input `{port_name}` of node `{}` refers to node `{src_id}`, which does not exist",
                raw.id
            ),
            suggest(src_id, index.keys().copied()),
        );
        return None;
    };
    Some((j, src_id, src_port))
}

/// Reports each required input of node `raw` (of type `spec`) that `inputs:` leaves out, at
/// its `inputs:` key (at the node's id when it has none).
fn check_required_inputs(raw: &Raw, spec: &NodeSpec, d: &mut Diagnostics) {
    for p in &spec.inputs {
        let connected = raw.inputs.iter().any(|(k, _)| k.as_str() == Some(p.name));
        if !p.optional && !connected {
            d.push(
                ErrorKind::MissingInput,
                Some(raw.inputs_span),
                format!(
                    "node `{}` ({}) needs input `{}` ({})",
                    raw.id,
                    spec.name,
                    p.name,
                    p.display_type()
                ),
            );
        }
    }
}

/// Type-checks the input edges of node `i` (of type `spec`), given which nodes run per frame
/// (`per_frame`, resolved for `i` and everything upstream of it).
pub(super) fn check_types(
    raws: &[Raw],
    edges: &Edges,
    per_frame: &[bool],
    i: usize,
    spec: &NodeSpec,
    d: &mut Diagnostics,
) {
    for (e, span) in &edges[i] {
        let Some(src) = &raws[e.from].node else {
            continue;
        };
        let out = src
            .spec()
            .outputs
            .iter()
            .find(|p| p.name == e.from_port)
            .expect("checked");
        let port = spec
            .inputs
            .iter()
            .find(|p| p.name == e.port)
            .expect("checked");
        let src_type = if per_frame[e.from] {
            format!("sequence<{}>", out.ty)
        } else {
            out.ty.to_string()
        };
        let fits = out.ty == port.ty
            && if port.sequence {
                per_frame[e.from]
            } else {
                !per_frame[e.from] || per_frame[i]
            };
        if !fits {
            let mut msg = format!(
                "type mismatch: input `{}` of node `{}` takes {}, but `{}.{}` gives {}",
                e.port,
                raws[i].id,
                port.display_type(),
                raws[e.from].id,
                e.from_port,
                src_type
            );
            if out.ty == port.ty && !port.sequence && per_frame[e.from] {
                msg.push_str(" (a node that runs once cannot take one frame of a sequence)");
            }
            d.push(ErrorKind::TypeMismatch, Some(*span), msg);
        }
    }
}
