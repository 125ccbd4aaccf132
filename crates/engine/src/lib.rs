//! # vfxgraph-engine
//!
//! A generic dataflow engine: YAML graphs of typed nodes, a content-addressed cache and a
//! parallel scheduler. It knows nothing of images or cameras: node and artifact types are
//! registered by the program that uses it (in vfxgraph, the `vfxgraph-nodes` crate).
//!
//! - [`graph`]: parse and validate a graph file (all errors at once, with line:column).
//! - [`artifact`] and [`registry`]: value types with canonical encodings and content digests.
//! - [`node`]: what a node type declares and what it sees when it runs.
//! - [`port`]: typed port constants, a node's inputs and outputs declared once.
//! - [`exec`]: instances, cache keys, planning and the scheduler.
//! - [`store`]: the on-disk cache (objects + actions).

pub mod artifact;
pub mod diagnostic;
pub mod exec;
pub mod frames;
pub mod fsutil;
pub mod graph;
pub mod lease;
pub mod node;
pub mod options;
pub mod param;
pub mod port;
pub mod registry;
pub mod store;
pub mod stream;
pub mod yaml;

pub use artifact::{ArtifactType, Digest, Value};
pub use diagnostic::{Diagnostic, Diagnostics, ErrorKind, Span};
pub use exec::{
    plan, run, Observer, PlanReport, PlanStatus, RunOptions, RunReport, Status, Target,
};
pub use frames::FrameSet;
pub use graph::{load, Graph, LoadError, Overrides};
pub use node::{Context, InputValue, Memory, Mode, Node, NodeError, NodeSpec, PortSpec, Threads};
pub use options::OptionsDecl;
pub use param::{Kind, ParamCheck, ParamDesc, ParamValue, Params, PathRole};
pub use port::{In, InputPort, OptIn, OptSeqIn, Out, SeqIn, StreamIn};
pub use registry::{Registry, RunFn};
