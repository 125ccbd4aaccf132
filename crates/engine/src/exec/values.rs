//! Lazy loading: the value of a resolved instance's output, read when a consumer runs — from
//! memory, else from the store (verified), else recomputed if it was lost from the cache; an
//! uncached node's ([`NodeSpec::uncached`](crate::NodeSpec::uncached)) is computed for each
//! read and never kept.

use std::sync::atomic::Ordering;

use super::instances::{frame_suffix, Role};
use super::keys::uncached_digest;
use super::schedule::Runner;
use crate::artifact::{Digest, Value};

impl Runner<'_> {
    /// The value of output `port` of a resolved instance: in memory, else loaded from the
    /// store (verified), else recomputed.
    pub(super) fn value(&self, j: usize, port: &str) -> Result<Value, String> {
        if let Some(v) = self.state[j].values.lock().expect("values lock").get(port) {
            return Ok(v.clone());
        }
        let done = self.state[j]
            .done
            .get()
            .ok_or_else(|| "internal: input read before it was resolved".to_string())?;
        let digest = *done
            .digests
            .get(port)
            .ok_or_else(|| format!("internal: no output `{port}`"))?;
        let spec = self.setup.graph.nodes[self.setup.insts[j].node].spec();
        let static_port = spec
            .outputs
            .iter()
            .find(|p| p.name == port)
            .map(|p| p.name)
            .ok_or_else(|| format!("internal: unknown port `{port}`"))?;
        if !spec.cache_outputs {
            return self.compute_uncached(j, static_port, digest);
        }
        if let Some(v) = self.load_stored(j, static_port, &digest) {
            return Ok(v);
        }
        self.recompute(j, static_port, digest)
    }

    /// Keeps `v` in memory as output `port` of instance `j` if another consumer will read it.
    fn keep(&self, j: usize, port: &'static str, v: &Value) {
        if self.state[j].consumers_left.load(Ordering::Acquire) > 1 {
            self.state[j]
                .values
                .lock()
                .expect("values lock")
                .insert(port, v.clone());
        }
    }

    /// Output `port` of instance `j` read from the store, if it is there and decodes.
    fn load_stored(&self, j: usize, port: &'static str, digest: &Digest) -> Option<Value> {
        let store = self.setup.store.as_ref()?;
        let (ty, bytes) = store.get_object(digest)?;
        match self.registry.decode(&ty, &bytes) {
            Ok(data) => {
                let v = Value::from_parts(data, *digest);
                self.keep(j, port, &v);
                Some(v)
            }
            Err(e) => {
                tracing::warn!("cached {ty} {} does not decode: {e}", digest.short());
                None
            }
        }
    }

    /// Output `port` of instance `j`, lost from the cache (deleted or corrupt), recomputed.
    /// Deterministic nodes give the same bytes; anything else is reported rather than
    /// silently mixed.
    fn recompute(&self, j: usize, port: &'static str, digest: Digest) -> Result<Value, String> {
        let up = &self.setup.insts[j];
        let id = &self.setup.graph.nodes[up.node].id;
        if self.setup.role[j] == Role::CacheOnly {
            return Err(format!(
                "the cached output `{port}` of `{id}`{} is missing from the cache, and only the \
                 selected instances may run",
                frame_suffix(up.frame)
            ));
        }
        tracing::info!("recomputing `{id}` (its cached output was lost)");
        let outputs = self.compute(j)?;
        let (v, bytes) = outputs
            .outputs
            .get(port)
            .ok_or_else(|| format!("internal: no output `{port}`"))?;
        if v.digest() != digest {
            return Err(format!(
                "the cached output of `{id}` was lost, and recomputing it gave different bytes \
                 (is the node deterministic?); run again"
            ));
        }
        if let Some(store) = self.setup.store.as_ref() {
            let _ = store.put_object(&digest, v.type_name(), bytes);
        }
        self.keep(j, port, v);
        Ok(v.clone())
    }

    /// Output `port` of instance `j` of an uncached node, computed now for the consumer that
    /// reads it and not kept (every reader computes it again: the node's policy). Its files
    /// are checked against the key that named the output, so a file changed during the run
    /// is an error, not a mix of two versions. An error names the node and frame.
    fn compute_uncached(&self, j: usize, port: &str, digest: Digest) -> Result<Value, String> {
        let up = &self.setup.insts[j];
        let at = format!(
            "`{}`{}",
            self.setup.graph.nodes[up.node].id,
            frame_suffix(up.frame)
        );
        let mut outputs = self.compute(j).map_err(|e| format!("{at}: {e}"))?.outputs;
        let (v, _) = outputs
            .remove(port)
            .ok_or_else(|| format!("internal: no output `{port}`"))?;
        let now = self.setup.key(j, |_, _| None)?;
        if uncached_digest(&now.key, port) != digest {
            return Err(format!("{at}: its files changed during the run; run again"));
        }
        Ok(v.named(digest))
    }
}
