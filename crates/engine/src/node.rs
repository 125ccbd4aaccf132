//! Node types: what a node declares (ports, params, mode) and what it sees when it runs.
//!
//! A node never computes its own cache key: it declares its inputs, parameters (with
//! which are `cosmetic`), version and whether it is seeded, and the engine derives the key
//! (Gaffer's pattern: a hash of exactly what the computation reads; docs/design/cache.md, "Cache
//! keys").

use std::collections::BTreeMap;
use std::fmt;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

/// Frame patterns in path parameters (defined in [`crate::frames`]), also found here.
pub use crate::frames::{
    check_frame_pattern, format_frame, has_frame_pattern, resolve_path, MAX_FRAME_WIDTH,
};

use crate::artifact::{ArtifactType, Digest, Value};
use crate::options::OptionsDecl;
use crate::param::{Kind, ParamDesc, Params, PathRole};
use crate::port::{ArtifactOf, InputDecl, InputPort, Out, OutputDecl};
use crate::stream::{Deferred, Items, Stream};

/// Whether a node type runs once, once per frame, or either (chosen by the graph).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// One instance for the whole graph.
    Once,
    /// One instance per frame of the graph's range.
    PerFrame,
    /// Per frame when the graph says `per_frame: true` or when an input is connected to a
    /// per-frame producer; once otherwise.
    Either,
}

/// A declared input or output port.
#[derive(Clone, Debug)]
pub struct PortSpec {
    /// Port name.
    pub name: &'static str,
    /// Artifact type name (an element type; see `sequence`).
    pub ty: &'static str,
    /// For inputs: the port takes the whole `sequence<ty>` of a per-frame producer rather
    /// than one element.
    pub sequence: bool,
    /// For inputs: may be left unconnected.
    pub optional: bool,
    /// For sequence inputs: the node reads the frames one at a time with
    /// [`Context::stream`], so they are computed or loaded when asked and never all held
    /// in memory (a long plate).
    pub streamed: bool,
    /// One line of documentation.
    pub doc: &'static str,
    /// The artifact type, for a port declared by a typed constant ([`crate::port`]): the
    /// registry registers it with the node. `None` for a port built from names, whose type
    /// must be registered already.
    pub artifact: Option<ArtifactOf>,
}

impl PortSpec {
    /// A port carrying one `ty` value (for a per-frame consumer: the element of its frame).
    pub fn one(name: &'static str, ty: &'static str, doc: &'static str) -> Self {
        PortSpec {
            name,
            ty,
            sequence: false,
            optional: false,
            streamed: false,
            doc,
            artifact: None,
        }
    }

    /// An input taking a whole `sequence<ty>`.
    pub fn sequence(name: &'static str, ty: &'static str, doc: &'static str) -> Self {
        PortSpec {
            name,
            ty,
            sequence: true,
            optional: false,
            streamed: false,
            doc,
            artifact: None,
        }
    }

    /// The port with its artifact type attached (see [`PortSpec::artifact`]).
    pub(crate) fn typed(mut self, artifact: ArtifactOf) -> Self {
        self.artifact = Some(artifact);
        self
    }

    /// Marks an input optional.
    pub fn optional(mut self) -> Self {
        self.optional = true;
        self
    }

    /// Marks a sequence input streamed (see [`PortSpec::streamed`]).
    pub fn streamed(mut self) -> Self {
        self.streamed = true;
        self
    }

    /// The type as shown to users: `image` or `sequence<image>`.
    pub fn display_type(&self) -> String {
        if self.sequence {
            format!("sequence<{}>", self.ty)
        } else {
            self.ty.to_string()
        }
    }
}

/// Everything a node type declares about itself.
#[derive(Clone, Debug)]
pub struct NodeSpec {
    /// Stable type name used in graph files.
    pub name: &'static str,
    /// Bumped whenever the output for the same inputs and params changes.
    pub version: u32,
    /// Documentation: what it does and which book section it implements.
    pub doc: &'static str,
    /// Input ports.
    pub inputs: Vec<PortSpec>,
    /// Output ports.
    pub outputs: Vec<PortSpec>,
    /// Parameters.
    pub params: Vec<ParamDesc>,
    /// The options structs the params come from ([`NodeSpec::options`]), in order.
    pub options: Vec<OptionsDecl>,
    /// Once, per frame, or either.
    pub mode: Mode,
    /// True if the node draws random numbers: its key then includes the graph seed and node id.
    pub seeded: bool,
    /// How many cores an instance can use: a hint for schedulers outside the engine (a farm
    /// gives an `All` task a whole machine, a `One` task one core). Never part of the key.
    pub threads: Threads,
    /// How much memory an instance needs: a hint for farms (Slurm's `--mem`, OpenJD's host
    /// requirements), never part of the key.
    pub memory: Memory,
    /// False for a node whose outputs stay out of the cache (see [`NodeSpec::uncached`]).
    pub cache_outputs: bool,
}

/// The memory one instance of a node type needs, for farm schedulers.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Memory {
    /// No hint (the farm's default: usually the whole host).
    #[default]
    Unknown,
    /// A fixed amount, in MiB (a reader of a small file, a solver of tracks).
    Fixed(u32),
    /// An image-sized need: `base_mib` plus `bytes_per_pixel` × the node's `width` ×
    /// `height` params (a renderer's buffers); a 0 (the camera's size, not known before the
    /// run) counts as 2048 × 1556 (2K full aperture).
    Image {
        /// MiB besides the image buffers (the process, scene, acceleration structure, dome).
        base_mib: u32,
        /// Bytes per pixel of all the buffers an instance holds at once.
        bytes_per_pixel: u32,
    },
}

impl Memory {
    /// The hint in MiB for an instance with `params` (`None`: no hint).
    pub fn mib(&self, params: &crate::Params) -> Option<u64> {
        match *self {
            Memory::Unknown => None,
            Memory::Fixed(m) => Some(m as u64),
            Memory::Image {
                base_mib,
                bytes_per_pixel,
            } => {
                let dim = |name: &str, default: u64| match params.get(name) {
                    Some(crate::ParamValue::Int(v)) if *v > 0 => *v as u64,
                    _ => default,
                };
                let pixels = dim("width", 2048).saturating_mul(dim("height", 1556));
                let bytes = pixels.saturating_mul(bytes_per_pixel as u64);
                Some((base_mib as u64).saturating_add(bytes.div_ceil(1 << 20)))
            }
        }
    }
}

/// The cores one instance of a node type can keep busy.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Threads {
    /// One (a reader, a writer, a cheap per-pixel operation).
    One,
    /// As many as the machine has (the default: nodes may parallelize inside).
    #[default]
    All,
}

impl NodeSpec {
    /// Starts a spec for a node that runs once, version 1, unseeded.
    pub fn new(name: &'static str, doc: &'static str) -> Self {
        NodeSpec {
            name,
            version: 1,
            doc,
            inputs: Vec::new(),
            outputs: Vec::new(),
            params: Vec::new(),
            options: Vec::new(),
            mode: Mode::Either,
            seeded: false,
            threads: Threads::All,
            memory: Memory::Unknown,
            cache_outputs: true,
        }
    }
    /// Sets the version.
    pub fn version(mut self, v: u32) -> Self {
        self.version = v;
        self
    }
    /// Sets the mode.
    pub fn mode(mut self, m: Mode) -> Self {
        self.mode = m;
        self
    }
    /// Sets the resource hint (see [`Threads`]).
    pub fn threads(mut self, t: Threads) -> Self {
        self.threads = t;
        self
    }
    /// Sets the memory hint (see [`Memory`]).
    pub fn memory(mut self, m: Memory) -> Self {
        self.memory = m;
        self
    }
    /// Marks the node seeded.
    pub fn seeded(mut self) -> Self {
        self.seeded = true;
        self
    }
    /// Keeps the node's outputs out of the cache (Gaffer's uncached compute policy): its
    /// action entry is stored — key, output digests, the files it read — so it still shows as
    /// cached and its consumers' keys still hold, but an output is recomputed from the node's
    /// params and files whenever a consumer that runs reads it (and checked against the
    /// recorded digest). For readers whose files decode about as fast as a cache object
    /// loads: a 100 KB JPEG frame decodes in a few milliseconds, where its decoded frame is a
    /// 6 MB object to encode, compress, hash and write. Only for nodes without inputs (the
    /// registry refuses others), so a recompute needs nothing but the graph.
    pub fn uncached(mut self) -> Self {
        self.cache_outputs = false;
        self
    }
    /// Adds an input: a typed constant ([`crate::port::In`], [`crate::port::OptIn`],
    /// [`crate::port::SeqIn`], [`crate::port::OptSeqIn`], [`crate::port::StreamIn`]), or a
    /// [`PortSpec`] built from names.
    pub fn input(mut self, p: impl InputDecl) -> Self {
        self.inputs.push(p.input_spec());
        self
    }
    /// Adds an output: an [`Out`] constant, or a [`PortSpec`] built from names.
    pub fn output(mut self, p: impl OutputDecl) -> Self {
        self.outputs.push(p.output_spec());
        self
    }
    /// Adds a required parameter naming a file the node reads (its content enters the key).
    pub fn input_file_param(self, name: &'static str, doc: &'static str) -> Self {
        self.param(ParamDesc::required(name, Kind::Path(PathRole::Input), doc))
    }
    /// Adds a required parameter naming a file the node writes.
    pub fn output_file_param(self, name: &'static str, doc: &'static str) -> Self {
        self.param(ParamDesc::required(name, Kind::Path(PathRole::Output), doc))
    }
    /// Adds a parameter.
    pub fn param(mut self, p: ParamDesc) -> Self {
        self.params.push(p);
        self
    }

    /// Looks up a parameter.
    pub fn param_desc(&self, name: &str) -> Option<&ParamDesc> {
        self.params.iter().find(|p| p.name == name)
    }

    /// Names of path parameters with the given role.
    pub fn path_params(&self, role: PathRole) -> impl Iterator<Item = &'static str> + '_ {
        self.params.iter().filter_map(move |p| match p.kind {
            Kind::Path(r) if r == role => Some(p.name),
            _ => None,
        })
    }

    /// Names of path-list parameters with the given role.
    pub fn path_list_params(&self, role: PathRole) -> impl Iterator<Item = &'static str> + '_ {
        self.params.iter().filter_map(move |p| match p.kind {
            Kind::PathList(r) if r == role => Some(p.name),
            _ => None,
        })
    }
}

/// A node type: a spec and a compute function.
pub trait Node: Send + Sync + 'static {
    /// The declaration.
    fn spec(&self) -> &NodeSpec;
    /// Computes the outputs from `ctx`'s inputs and params, calling [`Context::output`] once
    /// per output port. Must be deterministic given inputs, params, frame and seed.
    fn run(&self, ctx: &mut Context<'_>) -> Result<(), NodeError>;
}

/// A node's failure, shown to the user with the node id and frame.
#[derive(Debug, Clone, PartialEq)]
pub struct NodeError {
    /// What went wrong, including the chain of causes.
    pub message: String,
}

impl NodeError {
    /// An error with a message.
    pub fn msg(message: impl Into<String>) -> Self {
        NodeError {
            message: message.into(),
        }
    }
}

impl fmt::Display for NodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message)
    }
}

impl<E: std::error::Error> From<E> for NodeError {
    fn from(e: E) -> Self {
        let mut message = e.to_string();
        let mut src = e.source();
        while let Some(s) = src {
            let m = s.to_string();
            if !message.contains(&m) {
                message.push_str(": ");
                message.push_str(&m);
            }
            src = s.source();
        }
        NodeError { message }
    }
}

/// An input as handed to a running node.
#[derive(Clone, Debug)]
pub enum InputValue<'a> {
    /// One value.
    One(Value),
    /// A whole sequence: (frame, value) in frame order.
    Sequence(Vec<(i64, Value)>),
    /// A streamed sequence ([`PortSpec::streamed`]): (frame, value when read), in frame order.
    Streamed(Vec<(i64, Deferred<'a>)>),
}

static NEVER_CANCELLED: AtomicBool = AtomicBool::new(false);

/// What a running node sees: its params, inputs, frame and seed; where it puts its outputs.
pub struct Context<'a> {
    pub(crate) node_id: &'a str,
    pub(crate) frame: Option<i64>,
    pub(crate) params: &'a Params,
    pub(crate) spec: &'a NodeSpec,
    pub(crate) graph_dir: &'a Path,
    pub(crate) inputs: BTreeMap<&'static str, InputValue<'a>>,
    pub(crate) seed: u64,
    pub(crate) progress: &'a (dyn Fn(f32) + Sync),
    pub(crate) cancel: &'a AtomicBool,
    pub(crate) outputs: BTreeMap<&'static str, (Value, Vec<u8>)>,
    pub(crate) read_files: Vec<(PathBuf, Digest)>,
    pub(crate) written_files: Vec<PathBuf>,
}

impl<'a> Context<'a> {
    /// Builds a context by hand, for unit tests of a node outside a graph.
    pub fn for_test(
        spec: &'a NodeSpec,
        params: &'a Params,
        graph_dir: &'a Path,
        frame: Option<i64>,
        inputs: Vec<(&'static str, InputValue<'a>)>,
    ) -> Self {
        Context {
            node_id: "test",
            frame,
            params,
            spec,
            graph_dir,
            inputs: inputs.into_iter().collect(),
            seed: 0,
            progress: &|_| {},
            cancel: &NEVER_CANCELLED,
            outputs: BTreeMap::new(),
            read_files: Vec::new(),
            written_files: Vec::new(),
        }
    }

    /// The node's id in the graph.
    pub fn node_id(&self) -> &str {
        self.node_id
    }

    /// The frame, for a per-frame instance.
    pub fn frame(&self) -> Option<i64> {
        self.frame
    }

    /// The checked parameters, defaults filled in.
    pub fn params(&self) -> &Params {
        self.params
    }

    /// A 64-bit seed derived from the graph seed, the node id and the frame; use it to seed a
    /// PCG stream so results do not depend on scheduling.
    pub fn seed(&self) -> u64 {
        self.seed
    }

    /// True once the run was cancelled ([`RunOptions::cancel`](crate::RunOptions)): long work
    /// should stop and return an error (nothing partial is cached).
    pub fn cancelled(&self) -> bool {
        self.cancel.load(Ordering::Relaxed)
    }

    /// The run's cancel flag, for algorithms that poll an `AtomicBool` themselves.
    pub fn cancel_flag(&self) -> &AtomicBool {
        self.cancel
    }

    /// Reports progress in [0, 1] for long work.
    pub fn progress(&self, fraction: f32) {
        (self.progress)(fraction.clamp(0.0, 1.0))
    }

    /// A path parameter resolved against the graph file's folder, with the frame pattern
    /// (`%04d`, `%d`, `####`) filled in for per-frame instances.
    pub fn path(&self, param: &str) -> PathBuf {
        resolve_path(self.graph_dir, self.params.str(param), self.frame)
    }

    /// A path-list parameter, each path resolved against the graph file's folder.
    pub fn paths(&self, param: &str) -> Vec<PathBuf> {
        self.params
            .strs(param)
            .into_iter()
            .map(|t| resolve_path(self.graph_dir, t, None))
            .collect()
    }

    /// Declares a file this run reads that no path parameter names — e.g. the images a list
    /// file names (Make's discovered dependencies). Call it *before* reading the file: its
    /// content digest is taken now, recorded with the cached result, and the result counts as
    /// cached only while the file still has that digest; so an edit of the file in place reruns
    /// the node (and, if its outputs change, everything downstream). An edit racing the read is
    /// caught on the next run. Errors name the file (missing, unreadable, not a file).
    pub fn declare_input_file(&mut self, path: &Path) -> Result<(), NodeError> {
        if !self.spec.cache_outputs {
            return Err(NodeError::msg(format!(
                "internal: the uncached reader `{}` declares {}: an uncached reader's files \
                 must be path params (they name its output)",
                self.spec.name,
                path.display()
            )));
        }
        let meta = std::fs::metadata(path)
            .map_err(|e| NodeError::msg(format!("{}: {e}", path.display())))?;
        if !meta.is_file() {
            return Err(NodeError::msg(format!("{} is not a file", path.display())));
        }
        let digest = crate::fsutil::hash_file(path)
            .map_err(|e| NodeError::msg(format!("{}: {e}", path.display())))?;
        self.read_files.push((path.to_path_buf(), digest));
        Ok(())
    }

    /// The files declared by [`Context::declare_input_file`] so far, with their digests.
    pub fn declared_input_files(&self) -> &[(PathBuf, Digest)] {
        &self.read_files
    }

    /// Writes `bytes` to `path` with the project's one atomic writer (`fsutil::atomic_write`)
    /// and records the file as an output of this run, like the file of an output path param:
    /// its digest is stored with the cached result, which counts as cached only while the file
    /// still has it. For the files a writer makes beside the one its path param names
    /// (COLMAP's `images.txt`, Nuke's film-back note). Errors name the file.
    pub fn write_file(&mut self, path: &Path, bytes: &[u8]) -> Result<(), NodeError> {
        crate::fsutil::atomic_write(path, bytes)
            .map_err(|e| NodeError::msg(format!("cannot write {}: {e}", path.display())))?;
        if !self.written_files.iter().any(|p| p == path) {
            self.written_files.push(path.to_path_buf());
        }
        Ok(())
    }

    /// The files written by [`Context::write_file`] so far.
    pub fn written_files(&self) -> &[PathBuf] {
        &self.written_files
    }

    /// Reads typed input `port`: `&T` for an [`In`](crate::port::In), `Option<&T>` for an
    /// [`OptIn`](crate::port::OptIn), the frames for a [`SeqIn`](crate::port::SeqIn) or
    /// [`OptSeqIn`](crate::port::OptSeqIn), a [`Stream`] for a
    /// [`StreamIn`](crate::port::StreamIn). Errors say which port is missing or holds what.
    pub fn get<P: InputPort>(&self, port: P) -> Result<P::Value<'_>, NodeError> {
        port.read(self)
    }

    /// Sets typed output `port` (see [`Context::output`]).
    pub fn set<T: ArtifactType>(&mut self, port: Out<T>, value: T) {
        self.output(port.name(), value)
    }

    /// True if input `port` is connected.
    pub(crate) fn connected(&self, port: &str) -> bool {
        self.inputs.contains_key(port)
    }

    /// The value on input `port`, by name: the untyped form of [`Context::get`], for ports
    /// named by data.
    pub fn input<T: ArtifactType>(&self, port: &str) -> Result<&T, NodeError> {
        self.input_opt(port)?
            .ok_or_else(|| NodeError::msg(format!("input `{port}` is not connected")))
    }

    /// The value on an optional input port, `None` if unconnected.
    pub fn input_opt<T: ArtifactType>(&self, port: &str) -> Result<Option<&T>, NodeError> {
        match self.inputs.get(port) {
            None => Ok(None),
            Some(InputValue::One(v)) => v.get::<T>().map(Some).ok_or_else(|| {
                NodeError::msg(format!(
                    "input `{port}` holds {} where {} was expected",
                    v.type_name(),
                    T::NAME
                ))
            }),
            Some(InputValue::Sequence(_) | InputValue::Streamed(_)) => Err(NodeError::msg(
                format!("input `{port}` is a sequence; use Context::sequence"),
            )),
        }
    }

    /// The whole sequence on input `port`, in frame order.
    pub fn sequence<T: ArtifactType>(&self, port: &str) -> Result<Vec<(i64, &T)>, NodeError> {
        match self.inputs.get(port) {
            Some(InputValue::Sequence(items)) => items
                .iter()
                .map(|(f, v)| {
                    v.get::<T>().map(|t| (*f, t)).ok_or_else(|| {
                        NodeError::msg(format!(
                            "input `{port}` frame {f} holds {} where {} was expected",
                            v.type_name(),
                            T::NAME
                        ))
                    })
                })
                .collect(),
            Some(InputValue::Streamed(_)) => Err(NodeError::msg(format!(
                "input `{port}` is streamed; read it with Context::stream"
            ))),
            Some(InputValue::One(_)) => Err(NodeError::msg(format!(
                "input `{port}` is one value, not a sequence"
            ))),
            None => Err(NodeError::msg(format!("input `{port}` is not connected"))),
        }
    }

    /// The streamed sequence on input `port` ([`PortSpec::streamed`]), its frames read when
    /// asked for. A sequence handed over whole (a node's unit test) streams too.
    pub fn stream<T: ArtifactType>(&self, port: &str) -> Result<Stream<'_, T>, NodeError> {
        let items = match self.inputs.get(port) {
            Some(InputValue::Streamed(items)) => Items::Deferred(items),
            Some(InputValue::Sequence(items)) => Items::Ready(items),
            Some(InputValue::One(_)) => {
                return Err(NodeError::msg(format!(
                    "input `{port}` is one value, not a sequence"
                )))
            }
            None => return Err(NodeError::msg(format!("input `{port}` is not connected"))),
        };
        Ok(Stream {
            port: port.to_string(),
            items,
            _t: std::marker::PhantomData,
        })
    }

    /// Sets output `port`, by name (the untyped form of [`Context::set`]). Panics if the port is not declared or has another type (a bug in
    /// the node, not a user error).
    pub fn output<T: ArtifactType>(&mut self, port: &str, value: T) {
        let spec = self
            .spec
            .outputs
            .iter()
            .find(|p| p.name == port)
            .unwrap_or_else(|| panic!("node {} has no output `{port}`", self.spec.name));
        assert_eq!(
            spec.ty,
            T::NAME,
            "node {} output `{port}` type",
            self.spec.name
        );
        // An uncached node's outputs are neither stored nor hashed: they are named by the
        // instance's key (the run sets the digest).
        let v = if self.spec.cache_outputs {
            Value::new_encoded(value)
        } else {
            (Value::unnamed(value), Vec::new())
        };
        self.outputs.insert(spec.name, v);
    }

    /// Takes an output set earlier (for tests of nodes).
    pub fn take_output<T: ArtifactType + Clone>(&mut self, port: &str) -> Option<T> {
        self.outputs
            .get(port)
            .and_then(|(v, _)| v.get::<T>())
            .cloned()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::port::{In, OptIn, OptSeqIn, Out, SeqIn, StreamIn};

    const A: In<f64> = In::new("a", "doc a");
    const B: OptIn<i64> = OptIn::new("b", "doc b");
    const C: SeqIn<String> = SeqIn::new("c", "doc c");
    const E: OptSeqIn<f64> = OptSeqIn::new("e", "doc e");
    const F: StreamIn<f64> = StreamIn::new("f", "doc f");
    const D: Out<bool> = Out::new("d", "doc d");

    /// What a spec shows of a port, but its artifact type's registration.
    fn shown(p: &PortSpec) -> String {
        let PortSpec {
            name,
            ty,
            sequence,
            optional,
            streamed,
            doc,
            artifact: _,
        } = p;
        format!("{name} {ty} {sequence} {optional} {streamed} {doc}")
    }

    /// Typed port constants and the file-param builders declare what the long forms declare,
    /// and the typed ports carry their artifact types.
    #[test]
    fn typed_ports_are_the_long_forms() {
        let short = NodeSpec::new("n", "")
            .input(A)
            .input(B)
            .input(C)
            .input(E)
            .input(F)
            .output(D)
            .input_file_param("in", "read")
            .output_file_param("out", "written");
        let long = NodeSpec::new("n", "")
            .input(PortSpec::one("a", "float", "doc a"))
            .input(PortSpec::one("b", "int", "doc b").optional())
            .input(PortSpec::sequence("c", "string", "doc c"))
            .input(PortSpec::sequence("e", "float", "doc e").optional())
            .input(PortSpec::sequence("f", "float", "doc f").streamed())
            .output(PortSpec::one("d", "bool", "doc d"))
            .param(ParamDesc::required(
                "in",
                Kind::Path(PathRole::Input),
                "read",
            ))
            .param(ParamDesc::required(
                "out",
                Kind::Path(PathRole::Output),
                "written",
            ));
        let ports = |s: &NodeSpec| -> Vec<String> {
            s.inputs.iter().chain(&s.outputs).map(shown).collect()
        };
        assert_eq!(ports(&short), ports(&long));
        assert_eq!(format!("{:?}", short.params), format!("{:?}", long.params));
        let types: Vec<&str> = short
            .inputs
            .iter()
            .chain(&short.outputs)
            .map(|p| (p.artifact.expect("typed").0)().name)
            .collect();
        assert_eq!(types, ["float", "int", "string", "float", "float", "bool"]);
        assert!(long.inputs.iter().all(|p| p.artifact.is_none()));
    }

    /// `get` reads each kind of typed input as its untyped accessor does; `set` sets an output.
    #[test]
    fn get_and_set_typed_ports() {
        let spec = NodeSpec::new("n", "")
            .input(A)
            .input(B)
            .input(C)
            .input(E)
            .input(F)
            .output(D);
        let params = Params::default();
        let seq = || InputValue::Sequence(vec![(3, Value::new(1.5f64)), (4, Value::new(2.5f64))]);
        let mut ctx = Context::for_test(
            &spec,
            &params,
            Path::new("."),
            None,
            vec![
                ("a", InputValue::One(Value::new(0.5f64))),
                (
                    "c",
                    InputValue::Sequence(vec![(1, Value::new("x".to_string()))]),
                ),
                ("f", seq()),
            ],
        );
        assert_eq!(ctx.get(A).unwrap(), &0.5);
        assert_eq!(ctx.get(B).unwrap(), None);
        assert_eq!(ctx.get(C).unwrap(), vec![(1, &"x".to_string())]);
        assert_eq!(ctx.get(E).unwrap(), None);
        let f = ctx.get(F).unwrap();
        assert_eq!((f.len(), f.frame(1), *f.get(1).unwrap()), (2, 4, 2.5));
        ctx.set(D, true);
        assert_eq!(ctx.take_output::<bool>(D.name()), Some(true));
        let mut ctx = Context::for_test(&spec, &params, Path::new("."), None, vec![("e", seq())]);
        assert_eq!(ctx.get(E).unwrap(), Some(vec![(3, &1.5), (4, &2.5)]));
        assert!(ctx
            .get(A)
            .unwrap_err()
            .message
            .contains("`a` is not connected"));
        ctx.set(D, false);
    }
}
