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
            .param_spec(k)
            .unwrap_or_else(|| panic!("node {} has no param `{k}`", spec.name));
        let checked = ps
            .ty
            .check(v.clone())
            .unwrap_or_else(|e| panic!("param `{k}`: {e:?}"));
        values.insert(k.to_string(), checked);
    }
    Params::new(values)
}

/// Options struct `T`'s params as node `node` declares them: each of `T`'s params is in the
/// node's spec with the same type, default and doc, and the node's declared defaults read back
/// into `T` give `T::default()` (so no default is written anywhere but `T`'s `Default`).
/// Returns the names of `T`'s params.
pub fn check_defaults<T>(node: &str) -> Vec<&'static str>
where
    T: vfxgraph_params::Options + Default + PartialEq + std::fmt::Debug,
{
    let sp = spec(node);
    for d in T::params() {
        let declared = sp
            .param_spec(d.name)
            .unwrap_or_else(|| panic!("node {node} lacks param `{}`", d.name));
        let want: vfxgraph_engine::ParamSpec = d.into();
        assert_eq!(declared.ty, want.ty, "{node}.{}", want.name);
        assert_eq!(declared.default, want.default, "{node}.{}", want.name);
        assert_eq!(declared.doc, want.doc, "{node}.{}", want.name);
    }
    let read = T::read(&params(&sp, &[])).unwrap_or_else(|e| panic!("{node}: {e}"));
    assert_eq!(read, T::default(), "{node}: declared defaults read back");
    T::params().iter().map(|d| d.name).collect()
}
