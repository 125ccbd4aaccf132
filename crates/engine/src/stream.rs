//! Streamed sequence inputs: a node that declares a sequence input
//! [`streamed`](crate::PortSpec::streamed) reads its frames one at a time with
//! [`Context::stream`](crate::Context::stream), each computed, loaded or recomputed when the
//! node asks and dropped when the node is done with it — so a tracker walks a 2K plate of
//! hundreds of frames holding two, where a whole `sequence<image>` in memory would take
//! gigabytes (Gaffer computes an image tile when it is pulled, Nuke a row; this is the same
//! pull, by frame).

use std::fmt;
use std::marker::PhantomData;
use std::ops::Deref;
use std::sync::Arc;

use crate::artifact::{ArtifactType, Value};
use crate::node::NodeError;

/// A value produced when asked for: one frame of a streamed input.
#[derive(Clone)]
pub struct Deferred<'a>(Arc<dyn Fn() -> Result<Value, String> + Send + Sync + 'a>);

impl<'a> Deferred<'a> {
    /// A value that `read` produces each time it is asked for.
    pub fn new(read: impl Fn() -> Result<Value, String> + Send + Sync + 'a) -> Self {
        Deferred(Arc::new(read))
    }

    /// Produces the value.
    pub fn read(&self) -> Result<Value, String> {
        (self.0)()
    }
}

impl fmt::Debug for Deferred<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("Deferred")
    }
}

/// The frames of a streamed input of element type `T`, in frame order.
pub struct Stream<'c, T> {
    pub(crate) port: String,
    pub(crate) items: Items<'c>,
    pub(crate) _t: PhantomData<fn() -> T>,
}

/// A stream's frames: read when asked (a run), or at hand (a node's unit test).
pub(crate) enum Items<'c> {
    Deferred(&'c [(i64, Deferred<'c>)]),
    Ready(&'c [(i64, Value)]),
}

impl<T: ArtifactType> Stream<'_, T> {
    /// How many frames.
    pub fn len(&self) -> usize {
        match self.items {
            Items::Deferred(d) => d.len(),
            Items::Ready(r) => r.len(),
        }
    }

    /// True when there are none.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The frame number of the `k`-th item.
    pub fn frame(&self, k: usize) -> i64 {
        match self.items {
            Items::Deferred(d) => d[k].0,
            Items::Ready(r) => r[k].0,
        }
    }

    /// The `k`-th item, read now; the error names the port and the frame.
    pub fn get(&self, k: usize) -> Result<Item<T>, NodeError> {
        let (f, port) = (self.frame(k), &self.port);
        let value = match self.items {
            Items::Deferred(d) => d[k]
                .1
                .read()
                .map_err(|e| NodeError::msg(format!("input `{port}` frame {f}: {e}")))?,
            Items::Ready(r) => r[k].1.clone(),
        };
        if value.get::<T>().is_none() {
            return Err(NodeError::msg(format!(
                "input `{port}` frame {f} holds {} where {} was expected",
                value.type_name(),
                T::NAME
            )));
        }
        Ok(Item {
            value,
            _t: PhantomData,
        })
    }
}

/// One frame of a [`Stream`], held until dropped.
pub struct Item<T> {
    value: Value,
    _t: PhantomData<fn() -> T>,
}

impl<T: ArtifactType> Deref for Item<T> {
    type Target = T;
    fn deref(&self) -> &T {
        self.value
            .get::<T>()
            .expect("the type was checked when the item was read")
    }
}
