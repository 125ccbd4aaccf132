//! Helpers for the nodes' unit tests.

use std::collections::BTreeMap;

use vfxgraph_engine::{NodeSpec, ParamValue, Params};

/// The spec of a registered node type.
pub fn spec(name: &str) -> NodeSpec {
    crate::registry()
        .node(name)
        .unwrap_or_else(|| panic!("no node type `{name}`"))
        .spec()
        .clone()
}

/// The node's defaults with `set` applied, each value checked against its declared type (as
/// graph validation would).
pub fn params(spec: &NodeSpec, set: &[(&str, ParamValue)]) -> Params {
    let mut values: BTreeMap<String, ParamValue> = spec
        .params
        .iter()
        .filter_map(|p| p.default.clone().map(|d| (p.name.to_string(), d)))
        .collect();
    for (k, v) in set {
        let ps = spec
            .param_desc(k)
            .unwrap_or_else(|| panic!("node {} has no param `{k}`", spec.name));
        let checked = vfxgraph_engine::param::check(&ps.kind, v.clone())
            .unwrap_or_else(|e| panic!("param `{k}`: {e:?}"));
        values.insert(k.to_string(), checked);
    }
    Params::new(values)
}
