//! Typed ports: each port of a node type declared once, as a constant that carries its name,
//! its documentation and its artifact type.
//!
//! ```
//! use vfxgraph_engine::{Context, In, NodeError, NodeSpec, Out, Registry};
//!
//! const DISTANCE: In<f64> = In::new("distance", "a distance, metres");
//! const HALF: Out<f64> = Out::new("half", "half of it");
//!
//! fn run_halve(ctx: &mut Context<'_>) -> Result<(), NodeError> {
//!     let d = *ctx.get(DISTANCE)?;
//!     ctx.set(HALF, d / 2.0);
//!     Ok(())
//! }
//!
//! let mut r = Registry::new();
//! r.register_fn(
//!     NodeSpec::new("halve", "Halves a distance.").input(DISTANCE).output(HALF),
//!     run_halve,
//! );
//! assert_eq!(r.node("halve").unwrap().spec().inputs[0].name, "distance");
//! ```
//!
//! The spec built from a constant is the data the rest of the engine reads ([`PortSpec`]: the
//! name graph files connect, the type name validation checks); the constant also carries how to
//! register its artifact type, so registering a node registers the types of its ports
//! ([`Registry::register_node`](crate::Registry::register_node)) and no registration order
//! matters.
//!
//! The kinds: [`In`] (one value; for a per-frame consumer the value of its frame), [`OptIn`]
//! (may be left unconnected), [`SeqIn`] (the whole sequence of a per-frame producer),
//! [`OptSeqIn`] (the same, optional), [`StreamIn`] (a sequence read a frame at a time) and [`Out`].

use std::fmt;
use std::marker::PhantomData;

use crate::artifact::ArtifactType;
use crate::node::{Context, NodeError, PortSpec};
use crate::registry::ArtifactInfo;
use crate::stream::Stream;

/// How to describe (and so register) the artifact type of a typed port.
#[derive(Clone, Copy)]
pub struct ArtifactOf(pub(crate) fn() -> ArtifactInfo);

impl ArtifactOf {
    /// The artifact type `T`.
    pub fn of<T: ArtifactType>() -> Self {
        ArtifactOf(ArtifactInfo::of::<T>)
    }
}

impl fmt::Debug for ArtifactOf {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "ArtifactOf({})", (self.0)().name)
    }
}

/// What [`NodeSpec::input`](crate::NodeSpec::input) takes: a typed input constant, or a
/// [`PortSpec`] built from data (a test's ad-hoc node).
pub trait InputDecl {
    /// The port's declaration.
    fn input_spec(self) -> PortSpec;
}

/// What [`NodeSpec::output`](crate::NodeSpec::output) takes: an [`Out`] constant, or a
/// [`PortSpec`] built from data.
pub trait OutputDecl {
    /// The port's declaration.
    fn output_spec(self) -> PortSpec;
}

impl InputDecl for PortSpec {
    fn input_spec(self) -> PortSpec {
        self
    }
}

impl OutputDecl for PortSpec {
    fn output_spec(self) -> PortSpec {
        self
    }
}

/// A typed input port, read with [`Context::get`]; `Value` is what the read returns.
pub trait InputPort: InputDecl + Copy {
    /// The value a run reads: `&T`, `Option<&T>`, `Vec<(frame, &T)>` or a [`Stream`].
    type Value<'c>;
    /// Reads the port's value from `ctx`.
    fn read<'c>(self, ctx: &'c Context<'_>) -> Result<Self::Value<'c>, NodeError>;
}

macro_rules! port_kind {
    ($(#[$doc:meta])* $kind:ident) => {
        $(#[$doc])*
        pub struct $kind<T> {
            name: &'static str,
            doc: &'static str,
            _t: PhantomData<fn() -> T>,
        }

        impl<T> $kind<T> {
            /// A port named `name` (what graph files connect), documented by `doc`.
            pub const fn new(name: &'static str, doc: &'static str) -> Self {
                $kind {
                    name,
                    doc,
                    _t: PhantomData,
                }
            }

            /// The port's name.
            pub const fn name(&self) -> &'static str {
                self.name
            }

            /// The port's documentation.
            pub const fn doc(&self) -> &'static str {
                self.doc
            }
        }

        impl<T> Clone for $kind<T> {
            fn clone(&self) -> Self {
                *self
            }
        }

        impl<T> Copy for $kind<T> {}

        impl<T> fmt::Debug for $kind<T> {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                write!(f, "{}({})", stringify!($kind), self.name)
            }
        }
    };
}

port_kind! {
    /// An input carrying one `T` (for a per-frame consumer: the element of its frame);
    /// [`Context::get`] gives `&T`.
    In
}
port_kind! {
    /// An input carrying one `T` that may be left unconnected; [`Context::get`] gives
    /// `Option<&T>`.
    OptIn
}
port_kind! {
    /// An input taking the whole sequence of `T` of a per-frame producer; [`Context::get`]
    /// gives `Vec<(frame, &T)>` in frame order.
    SeqIn
}
port_kind! {
    /// A sequence input like [`SeqIn`] that may be left unconnected; [`Context::get`] gives
    /// `None` when it is, else the sequence.
    OptSeqIn
}
port_kind! {
    /// A sequence input of `T` read a frame at a time ([`PortSpec::streamed`]), so a long
    /// plate is never held in memory whole; [`Context::get`] gives a [`Stream`].
    StreamIn
}
port_kind! {
    /// An output carrying one `T`, set with [`Context::set`].
    Out
}

impl<T: ArtifactType> In<T> {
    fn spec(self) -> PortSpec {
        PortSpec::one(self.name, T::NAME, self.doc).typed(ArtifactOf::of::<T>())
    }
}

impl<T: ArtifactType> InputDecl for In<T> {
    fn input_spec(self) -> PortSpec {
        self.spec()
    }
}

impl<T: ArtifactType> InputPort for In<T> {
    type Value<'c> = &'c T;
    fn read<'c>(self, ctx: &'c Context<'_>) -> Result<&'c T, NodeError> {
        ctx.input(self.name)
    }
}

impl<T: ArtifactType> InputDecl for OptIn<T> {
    fn input_spec(self) -> PortSpec {
        In::<T>::new(self.name, self.doc).spec().optional()
    }
}

impl<T: ArtifactType> InputPort for OptIn<T> {
    type Value<'c> = Option<&'c T>;
    fn read<'c>(self, ctx: &'c Context<'_>) -> Result<Option<&'c T>, NodeError> {
        ctx.input_opt(self.name)
    }
}

impl<T: ArtifactType> InputDecl for SeqIn<T> {
    fn input_spec(self) -> PortSpec {
        PortSpec::sequence(self.name, T::NAME, self.doc).typed(ArtifactOf::of::<T>())
    }
}

impl<T: ArtifactType> InputPort for SeqIn<T> {
    type Value<'c> = Vec<(i64, &'c T)>;
    fn read<'c>(self, ctx: &'c Context<'_>) -> Result<Vec<(i64, &'c T)>, NodeError> {
        ctx.sequence(self.name)
    }
}

impl<T: ArtifactType> InputDecl for OptSeqIn<T> {
    fn input_spec(self) -> PortSpec {
        SeqIn::<T>::new(self.name, self.doc).input_spec().optional()
    }
}

impl<T: ArtifactType> InputPort for OptSeqIn<T> {
    type Value<'c> = Option<Vec<(i64, &'c T)>>;
    fn read<'c>(self, ctx: &'c Context<'_>) -> Result<Option<Vec<(i64, &'c T)>>, NodeError> {
        if ctx.connected(self.name) {
            ctx.sequence(self.name).map(Some)
        } else {
            Ok(None)
        }
    }
}

impl<T: ArtifactType> InputDecl for StreamIn<T> {
    fn input_spec(self) -> PortSpec {
        SeqIn::<T>::new(self.name, self.doc).input_spec().streamed()
    }
}

impl<T: ArtifactType> InputPort for StreamIn<T> {
    type Value<'c> = Stream<'c, T>;
    fn read<'c>(self, ctx: &'c Context<'_>) -> Result<Stream<'c, T>, NodeError> {
        ctx.stream(self.name)
    }
}

impl<T: ArtifactType> OutputDecl for Out<T> {
    fn output_spec(self) -> PortSpec {
        PortSpec::one(self.name, T::NAME, self.doc).typed(ArtifactOf::of::<T>())
    }
}
