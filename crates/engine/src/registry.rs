//! The catalog of node types and artifact types a program knows.
//!
//! The engine ships no node types of its own (it knows nothing of images or cameras);
//! `vfxgraph-nodes` fills a registry at start-up.

use std::any::TypeId;
use std::collections::BTreeMap;
use std::sync::Arc;

use crate::artifact::{decoder, ArtifactType, DecodeFn, DynArtifact};
use crate::node::{Context, Node, NodeError, NodeSpec};

/// A node's compute function, for a node type made of a spec and a plain function
/// ([`Registry::register_fn`]).
pub type RunFn = fn(&mut Context<'_>) -> Result<(), NodeError>;

/// A node type made of a spec and a plain function.
struct FnNode(NodeSpec, RunFn);

impl Node for FnNode {
    fn spec(&self) -> &NodeSpec {
        &self.0
    }
    fn run(&self, ctx: &mut Context<'_>) -> Result<(), NodeError> {
        (self.1)(ctx)
    }
}

/// What the registry knows about one artifact type.
#[derive(Clone)]
pub struct ArtifactInfo {
    /// Stable name.
    pub name: &'static str,
    /// One line of documentation.
    pub doc: &'static str,
    pub(crate) decode: DecodeFn,
    type_id: TypeId,
}

impl ArtifactInfo {
    /// The artifact type `T`.
    pub fn of<T: ArtifactType>() -> Self {
        ArtifactInfo {
            name: T::NAME,
            doc: T::DOC,
            decode: decoder::<T>(),
            type_id: TypeId::of::<T>(),
        }
    }
}

/// Node and artifact types by name.
#[derive(Clone, Default)]
pub struct Registry {
    nodes: BTreeMap<&'static str, Arc<dyn Node>>,
    artifacts: BTreeMap<&'static str, ArtifactInfo>,
    /// Node types this build lacks (behind a cargo feature), with what it takes to have them.
    unavailable: BTreeMap<&'static str, &'static str>,
}

impl Registry {
    /// An empty registry with the built-in scalar artifact types (`float`, `int`, `bool`,
    /// `string`).
    pub fn new() -> Self {
        let mut r = Registry::default();
        r.register_artifact::<f64>();
        r.register_artifact::<i64>();
        r.register_artifact::<bool>();
        r.register_artifact::<String>();
        r
    }

    /// Adds an artifact type (again: nothing). Types a typed port carries register with
    /// their node ([`Registry::register_node`]); this is for types no port declares. Two
    /// Rust types under one name panic (a programming error).
    pub fn register_artifact<T: ArtifactType>(&mut self) {
        self.add_artifact(ArtifactInfo::of::<T>());
    }

    fn add_artifact(&mut self, info: ArtifactInfo) {
        match self.artifacts.get(info.name) {
            Some(known) => assert!(
                known.type_id == info.type_id,
                "two artifact types are named `{}`",
                info.name
            ),
            None => {
                self.artifacts.insert(info.name, info);
            }
        }
    }

    /// Adds a node type made of `spec` and the function `run` (see [`Registry::register_node`]).
    pub fn register_fn(&mut self, spec: NodeSpec, run: RunFn) {
        self.register_node(FnNode(spec, run))
    }

    /// Adds a node type, and the artifact types its typed ports carry
    /// ([`PortSpec::artifact`](crate::PortSpec::artifact)); so node types register in any
    /// order. A port built from names must name a registered artifact type, and a node type
    /// name may be registered once (both programming errors, so they panic at start-up).
    pub fn register_node(&mut self, node: impl Node) {
        let spec = node.spec();
        assert!(
            spec.cache_outputs || spec.inputs.is_empty(),
            "node `{}` is uncached but has inputs: only input-less readers may be",
            spec.name
        );
        for p in spec.inputs.iter().chain(&spec.outputs) {
            if let Some(a) = p.artifact {
                self.add_artifact((a.0)());
            }
            assert!(
                self.artifacts.contains_key(p.ty),
                "node `{}` port `{}` uses unregistered artifact type `{}`",
                spec.name,
                p.name,
                p.ty
            );
        }
        let name = spec.name;
        if self.nodes.insert(name, Arc::new(node)).is_some() {
            panic!("node type `{name}` registered twice");
        }
    }

    /// Records a node type this build does not have (e.g. behind a cargo feature it was built
    /// without) and why, so that a graph naming it gets that reason instead of a bare
    /// "unknown node type".
    pub fn register_unavailable(&mut self, name: &'static str, why: &'static str) {
        self.unavailable.insert(name, why);
    }

    /// Why a node type this build lacks is missing (see [`Registry::register_unavailable`]).
    pub fn unavailable(&self, name: &str) -> Option<&'static str> {
        self.unavailable.get(name).copied()
    }

    /// The node types this build lacks, by name, with why (see
    /// [`Registry::register_unavailable`]).
    pub fn unavailable_nodes(&self) -> impl Iterator<Item = (&'static str, &'static str)> + '_ {
        self.unavailable.iter().map(|(k, v)| (*k, *v))
    }

    /// A node type by name.
    pub fn node(&self, name: &str) -> Option<&Arc<dyn Node>> {
        self.nodes.get(name)
    }

    /// All node types, by name.
    pub fn nodes(&self) -> impl Iterator<Item = &Arc<dyn Node>> {
        self.nodes.values()
    }

    /// An artifact type by name.
    pub fn artifact(&self, name: &str) -> Option<&ArtifactInfo> {
        self.artifacts.get(name)
    }

    /// All artifact types, by name.
    pub fn artifacts(&self) -> impl Iterator<Item = &ArtifactInfo> {
        self.artifacts.values()
    }

    /// Decodes stored bytes of a named type.
    pub fn decode(&self, type_name: &str, bytes: &[u8]) -> Result<Arc<dyn DynArtifact>, String> {
        let info = self
            .artifacts
            .get(type_name)
            .ok_or_else(|| format!("unknown artifact type `{type_name}`"))?;
        (info.decode)(bytes)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::artifact::{decode_json, encode_json};
    use crate::port::{In, Out};
    use crate::PortSpec;

    #[derive(Debug)]
    struct Meters(f64);

    impl ArtifactType for Meters {
        const NAME: &'static str = "meters";
        fn encode(&self, out: &mut Vec<u8>) {
            encode_json(&self.0, out)
        }
        fn decode(bytes: &[u8]) -> Result<Self, String> {
            decode_json(bytes).map(Meters)
        }
    }

    /// The same name as `Meters`, another type.
    struct Feet;

    impl ArtifactType for Feet {
        const NAME: &'static str = "meters";
        fn encode(&self, _: &mut Vec<u8>) {}
        fn decode(_: &[u8]) -> Result<Self, String> {
            Ok(Feet)
        }
    }

    const DISTANCE: In<Meters> = In::new("distance", "a distance");
    const HALF: Out<Meters> = Out::new("half", "half of it");

    fn halve(ctx: &mut Context<'_>) -> Result<(), NodeError> {
        let d = ctx.get(DISTANCE)?.0;
        ctx.set(HALF, Meters(d / 2.0));
        Ok(())
    }

    /// A node's typed ports register their artifact type, so a consumer may register before
    /// its producer, and a type registered again (by hand or by another node) is no error.
    #[test]
    fn typed_ports_register_their_artifact_types() {
        let mut r = Registry::new();
        r.register_fn(
            NodeSpec::new("halve", "").input(DISTANCE).output(HALF),
            halve,
        );
        assert_eq!(r.artifact("meters").map(|a| a.name), Some("meters"));
        r.register_artifact::<Meters>();
        r.register_fn(
            NodeSpec::new("named", "").input(PortSpec::one("d", "meters", "")),
            halve,
        );
        assert!(r.decode("meters", b"2.5").is_ok());
    }

    #[test]
    #[should_panic(expected = "two artifact types are named `meters`")]
    fn two_types_under_one_name_panic() {
        let mut r = Registry::new();
        r.register_fn(
            NodeSpec::new("halve", "").input(DISTANCE).output(HALF),
            halve,
        );
        r.register_artifact::<Feet>();
    }

    #[test]
    #[should_panic(expected = "unregistered artifact type `meters`")]
    fn a_port_by_name_needs_its_type_registered() {
        let mut r = Registry::new();
        r.register_fn(
            NodeSpec::new("named", "").input(PortSpec::one("d", "meters", "")),
            halve,
        );
    }
}
