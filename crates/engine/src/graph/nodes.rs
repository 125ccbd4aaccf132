//! Node entries (pass 1): each id checked, its keys sorted out, its type looked up in the
//! registry and its params read, into a [`Raw`] node the later passes complete.

use std::collections::{BTreeMap, HashMap};
use std::sync::Arc;

use super::params;
use crate::diagnostic::{suggest, Diagnostics, ErrorKind, Span};
use crate::node::Node;
use crate::param::ParamValue;
use crate::registry::Registry;
use crate::yaml::{resolve_scalar, Scalar, Yaml};

/// A node as declared, before its edges are resolved.
pub(super) struct Raw<'y> {
    pub(super) id: String,
    pub(super) id_span: Span,
    /// Its type, if known.
    pub(super) node: Option<Arc<dyn Node>>,
    /// Checked params (file, then overrides, then defaults).
    pub(super) params: BTreeMap<String, ParamValue>,
    /// `per_frame:` as written, with where.
    pub(super) per_frame: Option<(bool, Span)>,
    /// `inputs:` entries, port to `node.port`.
    pub(super) inputs: Vec<(&'y Yaml, &'y Yaml)>,
    /// Where `inputs:` is written (the id's span when it is not).
    pub(super) inputs_span: Span,
}

/// The node entries that can be checked further, and every declared id with where it was
/// first declared.
pub(super) fn read<'y>(
    node_entries: &'y [(Yaml, Yaml)],
    registry: &Registry,
    d: &mut Diagnostics,
) -> (Vec<Raw<'y>>, HashMap<String, Span>) {
    let mut raws: Vec<Raw> = Vec::new();
    let mut first_seen: HashMap<String, Span> = HashMap::new();
    for (k, v) in node_entries {
        let Some(id) = check_id(k, &mut first_seen, d) else {
            continue;
        };
        let Some(body) = v.as_map() else {
            d.push(
                ErrorKind::Structure,
                Some(v.span),
                format!(
                    "node `{id}` must be a mapping with `type`, found {}",
                    v.shape()
                ),
            );
            continue;
        };
        raws.push(read_node(id, k, body, registry, d));
    }
    (raws, first_seen)
}

/// The id of the entry keyed `k`, unless it is not a plain name or a duplicate (reported).
/// An id with other characters is reported but still checked further.
fn check_id<'y>(
    k: &'y Yaml,
    first_seen: &mut HashMap<String, Span>,
    d: &mut Diagnostics,
) -> Option<&'y str> {
    let Some(id) = k.as_str() else {
        d.push(
            ErrorKind::Structure,
            Some(k.span),
            "a node id must be a plain name",
        );
        return None;
    };
    if let Some(first) = first_seen.get(id) {
        d.push(
            ErrorKind::DuplicateId,
            Some(k.span),
            format!(
                "duplicate node id `{id}` (first declared on line {})",
                first.line
            ),
        );
        return None;
    }
    first_seen.insert(id.to_string(), k.span);
    if id.is_empty()
        || !id
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
    {
        d.push(
            ErrorKind::Structure,
            Some(k.span),
            format!("node id `{id}` may use only letters, digits, `_` and `-`"),
        );
    }
    Some(id)
}

/// Node `id` (keyed `k`) from its mapping `body`: keys, type and params.
fn read_node<'y>(
    id: &str,
    k: &'y Yaml,
    body: &'y [(Yaml, Yaml)],
    registry: &Registry,
    d: &mut Diagnostics,
) -> Raw<'y> {
    let mut raw = Raw {
        id: id.to_string(),
        id_span: k.span,
        node: None,
        params: BTreeMap::new(),
        per_frame: None,
        inputs: Vec::new(),
        inputs_span: k.span,
    };
    let (type_y, params_y) = read_keys(&mut raw, body, d);
    let Some(type_y) = type_y else {
        d.push(
            ErrorKind::Structure,
            Some(k.span),
            format!("node `{id}` has no `type`"),
        );
        return raw;
    };
    let Some(node) = node_type(id, type_y, registry, d) else {
        return raw;
    };
    params::read(&mut raw, node.spec(), params_y, d);
    raw.node = Some(node);
    raw
}

/// Sorts out the keys of a node's `body`: `inputs` and `per_frame` go into `raw`; the
/// `type` and `params` values are returned.
fn read_keys<'y>(
    raw: &mut Raw<'y>,
    body: &'y [(Yaml, Yaml)],
    d: &mut Diagnostics,
) -> (Option<&'y Yaml>, Option<&'y Yaml>) {
    let id = raw.id.clone();
    let mut type_y = None;
    let mut params_y = None;
    for (bk, bv) in body {
        match bk.as_str().unwrap_or("") {
            "type" => type_y = Some(bv),
            "params" => params_y = Some(bv),
            "inputs" => {
                raw.inputs_span = bk.span;
                match bv.as_map() {
                    Some(m) => raw.inputs = m.iter().map(|(a, b)| (a, b)).collect(),
                    None if bv.is_null() => {}
                    None => d.push(
                        ErrorKind::Structure,
                        Some(bv.span),
                        format!("`inputs` of node `{id}` must map input ports to `node.port`"),
                    ),
                }
            }
            "per_frame" => match bv.as_str().map(|t| resolve_scalar(t, true)) {
                Some(Scalar::Bool(b)) => raw.per_frame = Some((b, bv.span)),
                _ => d.push(
                    ErrorKind::Structure,
                    Some(bv.span),
                    "`per_frame` must be true or false",
                ),
            },
            "doc" | "label" | "description" => {}
            other => d.push_help(
                ErrorKind::Structure,
                Some(bk.span),
                format!("unknown key `{other}` in node `{id}`"),
                suggest(other, ["type", "params", "inputs", "per_frame", "doc"]),
            ),
        }
    }
    (type_y, params_y)
}

/// The node type `type_y` names, or `None` (reported, with a suggestion or the reason a
/// build lacks it).
fn node_type(
    id: &str,
    type_y: &Yaml,
    registry: &Registry,
    d: &mut Diagnostics,
) -> Option<Arc<dyn Node>> {
    let type_name = type_y.as_str().unwrap_or("");
    if let Some(node) = registry.node(type_name) {
        return Some(node.clone());
    }
    let (message, help) = match registry.unavailable(type_name) {
        Some(why) => (
            format!("unknown node type `{type_name}` for node `{id}`: {why}"),
            None,
        ),
        None => (
            format!("unknown node type `{type_name}` for node `{id}`"),
            suggest(type_name, registry.nodes().map(|n| n.spec().name))
                .or(Some("`vfxgraph nodes` lists the node types".to_string())),
        ),
    };
    d.push_help(ErrorKind::UnknownNodeType, Some(type_y.span), message, help);
    None
}
