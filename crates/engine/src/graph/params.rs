//! Params: read from a node's `params:` and checked against its type's declaration, then the
//! `--set node.param=value` overrides, then the graph's `defaults:` (for every node that has
//! the parameter), then the node type's defaults (a required param left unset is reported).

use std::collections::{BTreeMap, HashMap};

use super::nodes::Raw;
use crate::diagnostic::{suggest, Diagnostics, ErrorKind, Span};
use crate::node::NodeSpec;
use crate::param::{self, Kind, ParamCheck, ParamValue};
use crate::yaml::Yaml;

/// Reads and checks the params of `raw` (of type `spec`) from its `params:` value.
pub(super) fn read(raw: &mut Raw, spec: &NodeSpec, params_y: Option<&Yaml>, d: &mut Diagnostics) {
    let id = raw.id.as_str();
    let mut given: BTreeMap<String, (ParamValue, Option<Span>)> = BTreeMap::new();
    if let Some(py) = params_y {
        match py.as_map() {
            Some(m) => given_params(id, spec, m, &mut given, d),
            None if py.is_null() => {}
            None => d.push(
                ErrorKind::Structure,
                Some(py.span),
                format!("`params` of node `{id}` must be a mapping"),
            ),
        }
    }
    for (pname, (v, span)) in given {
        let ps = spec.param_desc(&pname).expect("checked above");
        check_param(d, id, &pname, &ps.kind, v, span, &mut raw.params);
    }
}

/// The params of node `id` that `m` gives and its type declares, as written.
fn given_params(
    id: &str,
    spec: &NodeSpec,
    m: &[(Yaml, Yaml)],
    given: &mut BTreeMap<String, (ParamValue, Option<Span>)>,
    d: &mut Diagnostics,
) {
    for (pk, pv) in m {
        let pname = pk.as_str().unwrap_or("");
        let Some(ps) = spec.param_desc(pname) else {
            d.push_help(
                ErrorKind::UnknownParam,
                Some(pk.span),
                format!("node `{id}` ({}) has no parameter `{pname}`", spec.name),
                suggest(pname, spec.params.iter().map(|p| p.name)),
            );
            continue;
        };
        match param::from_yaml(pv) {
            Ok(v) => {
                given.insert(ps.name.to_string(), (v, Some(pv.span)));
            }
            Err(e) => d.push(
                ErrorKind::ParamType,
                Some(pv.span),
                format!("parameter `{pname}` of node `{id}`: {e}"),
            ),
        }
    }
}

fn check_param(
    d: &mut Diagnostics,
    id: &str,
    pname: &str,
    ty: &Kind,
    v: ParamValue,
    span: Option<Span>,
    out: &mut BTreeMap<String, ParamValue>,
) {
    match param::check(ty, v) {
        Ok(v) => {
            out.insert(pname.to_string(), v);
        }
        Err(ParamCheck::Type(e)) => d.push(
            ErrorKind::ParamType,
            span,
            format!("parameter `{pname}` of node `{id}`: {e}"),
        ),
        Err(ParamCheck::Range(e)) => d.push(
            ErrorKind::ParamRange,
            span,
            format!("parameter `{pname}` of node `{id}`: {e}"),
        ),
    }
}

/// Applies the `--set node.param=value` overrides `set`, in order; `ids` are every declared
/// node id (for suggestions).
pub(super) fn apply_overrides(
    raws: &mut [Raw],
    set: &[String],
    ids: &HashMap<String, Span>,
    d: &mut Diagnostics,
) {
    for s in set {
        apply_set(raws, s, ids, d);
    }
}

/// Applies one `--set` override `s`.
fn apply_set(raws: &mut [Raw], s: &str, ids: &HashMap<String, Span>, d: &mut Diagnostics) {
    let Some((nid, pname, value)) = split_set(s) else {
        d.push(
            ErrorKind::Override,
            None,
            format!("--set `{s}`: expected node.param=value"),
        );
        return;
    };
    let Some(raw) = raws.iter_mut().find(|r| r.id == nid) else {
        d.push_help(
            ErrorKind::Override,
            None,
            format!("--set `{s}`: no node `{nid}` in the graph"),
            suggest(nid, ids.keys().map(String::as_str)),
        );
        return;
    };
    let Some(node) = &raw.node else { return };
    let spec = node.spec();
    let Some(ps) = spec.param_desc(pname) else {
        d.push_help(
            ErrorKind::Override,
            None,
            format!(
                "--set `{s}`: node `{nid}` ({}) has no parameter `{pname}`",
                spec.name
            ),
            suggest(pname, spec.params.iter().map(|p| p.name)),
        );
        return;
    };
    match param::parse_cli(value) {
        Ok(v) => match param::check(&ps.kind, v) {
            Ok(v) => {
                raw.params.insert(pname.to_string(), v);
            }
            Err(ParamCheck::Type(e) | ParamCheck::Range(e)) => {
                d.push(ErrorKind::Override, None, format!("--set `{s}`: {e}"))
            }
        },
        Err(e) => d.push(ErrorKind::Override, None, format!("--set `{s}`: {e}")),
    }
}

/// `node.param=value` split into its three parts.
fn split_set(s: &str) -> Option<(&str, &str, &str)> {
    let (lhs, value) = s.split_once('=')?;
    let (nid, pname) = lhs.split_once('.')?;
    Some((nid, pname, value))
}

/// Fills in the defaults of params left unset; a required one left unset is reported.
pub(super) fn fill_defaults(
    raws: &mut [Raw],
    command_line: &[(String, ParamValue)],
    graph_defaults: &[(String, ParamValue, Span)],
    d: &mut Diagnostics,
) {
    let mut used = vec![false; graph_defaults.len()];
    let mut all_params: Vec<&'static str> = Vec::new();
    for raw in raws {
        let Some(node) = &raw.node else { continue };
        for ps in &node.spec().params {
            all_params.push(ps.name);
            let given = graph_defaults
                .iter()
                .enumerate()
                .find(|(_, (n, _, _))| n == ps.name);
            if let Some((i, _)) = given {
                used[i] = true;
            }
            if raw.params.contains_key(ps.name) {
                continue;
            }
            if let Some((name, v)) = command_line.iter().find(|(n, _)| n == ps.name) {
                let id = raw.id.clone();
                check_param(d, &id, name, &ps.kind, v.clone(), None, &mut raw.params);
                continue;
            }
            if let Some((_, (name, v, span))) = given {
                let id = raw.id.clone();
                check_param(
                    d,
                    &id,
                    name,
                    &ps.kind,
                    v.clone(),
                    Some(*span),
                    &mut raw.params,
                );
                continue;
            }
            match &ps.default {
                Some(v) => {
                    raw.params.insert(ps.name.to_string(), v.clone());
                }
                None => d.push(
                    ErrorKind::MissingParam,
                    Some(raw.id_span),
                    format!(
                        "node `{}` ({}) needs parameter `{}` ({})",
                        raw.id,
                        node.spec().name,
                        ps.name,
                        ps.kind
                    ),
                ),
            }
        }
    }
    for ((name, _, span), used) in graph_defaults.iter().zip(used) {
        if !used {
            d.push_help(
                ErrorKind::UnknownParam,
                Some(*span),
                format!("`defaults` names `{name}`, a parameter no node of the graph has"),
                suggest(name, all_params.iter().copied()),
            );
        }
    }
}
