//! Cache keys: an instance's key (blake3 over its node type and version, output-affecting
//! params, input digests, input-file digests, frame and seed, in that order) with the
//! components kept to explain the next rerun; and whether the store holds a valid entry for a
//! key.

use std::path::Path;

use super::instances::{Dep, DepKind};
use super::records::InstanceRecord;
use super::setup::RunSetup;
use crate::artifact::{sequence_digest, Digest};
use crate::graph::GraphNode;
use crate::node::NodeSpec;
use crate::store::{ActionEntry, Store};

/// An instance's cache key and the components it was built from.
pub(super) struct KeyParts {
    pub(super) key: Digest,
    pub(super) record: InstanceRecord,
}

impl RunSetup<'_> {
    /// Builds the key of instance `i` given a way to read upstream output digests.
    pub(super) fn key(
        &self,
        i: usize,
        digest_of: impl Fn(usize, &str) -> Option<Digest>,
    ) -> Result<KeyParts, String> {
        let inst = &self.insts[i];
        let gn = &self.graph.nodes[inst.node];
        let spec = gn.spec();
        let mut h = blake3::Hasher::new();
        hash_node(&mut h, spec, gn);
        let mut record = InstanceRecord::default();
        for d in &inst.deps {
            let digest = self.input_digest(d, &digest_of)?;
            h.update(b"in\0");
            h.update(d.port.as_bytes());
            h.update(&[0]);
            h.update(&digest.0);
            record.inputs.insert(d.port.to_string(), digest.to_hex());
        }
        self.hash_input_files(&mut h, i, &mut record)?;
        if let Some(f) = inst.frame {
            h.update(b"frame\0");
            h.update(&f.to_le_bytes());
        }
        if spec.seeded {
            h.update(b"seed\0");
            h.update(&self.graph.seed.to_le_bytes());
            h.update(gn.id.as_bytes());
        }
        let key = Digest(*h.finalize().as_bytes());
        record.key = key.to_hex();
        Ok(KeyParts { key, record })
    }

    /// The digest of input `d`: its producer's output, or the digest of a whole sequence's.
    fn input_digest(
        &self,
        d: &Dep,
        digest_of: &impl Fn(usize, &str) -> Option<Digest>,
    ) -> Result<Digest, String> {
        let no_value = || format!("input `{}` has no value", d.port);
        match &d.kind {
            DepKind::One(j) => digest_of(*j, d.from_port).ok_or_else(no_value),
            DepKind::Seq(r) => {
                let mut elems = Vec::with_capacity(r.len());
                for j in r.clone() {
                    let dg = digest_of(j, d.from_port).ok_or_else(no_value)?;
                    elems.push((self.insts[j].frame.unwrap_or(0), dg));
                }
                Ok(sequence_digest(elems.iter().map(|(f, d)| (*f, d))))
            }
        }
    }

    /// Hashes the content of instance `i`'s input files into `h`, recording each.
    fn hash_input_files(
        &self,
        h: &mut blake3::Hasher,
        i: usize,
        record: &mut InstanceRecord,
    ) -> Result<(), String> {
        for (param, path) in self.input_files(i) {
            let digest = self.hasher.hash(&path).map_err(|e| {
                format!(
                    "param `{param}`: cannot read input file {}: {e}",
                    path.display()
                )
            })?;
            h.update(b"file\0");
            h.update(&digest.0);
            record
                .files
                .insert(path.display().to_string(), digest.to_hex());
        }
        Ok(())
    }

    /// A valid cache entry for `key`: objects present (unless the node is uncached), written
    /// files unchanged; else why there is none.
    pub(super) fn lookup(&self, i: usize, key: &Digest) -> Result<ActionEntry, Miss> {
        let Some(store) = &self.store else {
            return Err(Miss::Disabled);
        };
        if self.forced[self.insts[i].node] {
            return Err(Miss::Forced);
        }
        let Some(entry) = store.get_action(key) else {
            return Err(Miss::NoEntry);
        };
        if self.graph.nodes[self.insts[i].node].spec().cache_outputs {
            check_objects(store, &entry).map_err(Miss::Stale)?;
        }
        // The files this instance writes, where this graph writes them: the same action in
        // another folder (a graph copied beside its twin, sharing the cache) has its own files.
        let expected = self.output_files(i);
        if expected.len() != entry.files.len() {
            return Err(Miss::Stale(
                "output files differ from the cached entry".into(),
            ));
        }
        if let Some(p) = expected
            .iter()
            .find(|p| !entry.files.iter().any(|f| f.path == **p))
        {
            return Err(Miss::Stale(format!(
                "output file {} was not written by the cached entry",
                p.display()
            )));
        }
        for f in &entry.files {
            self.check_file(&f.path, &f.digest, "output file", "was modified")
                .map_err(Miss::Stale)?;
        }
        for f in &entry.node_files {
            self.check_file(&f.path, &f.digest, "output file", "was modified")
                .map_err(Miss::Stale)?;
        }
        for f in &entry.read_files {
            self.check_file(&f.path, &f.digest, "input file", "changed")
                .map_err(Miss::Stale)?;
        }
        Ok(entry)
    }

    /// `Ok` if file `path` still has digest `hex`; else why not (`{what} … {changed}`, or
    /// `{what} … is missing`).
    fn check_file(&self, path: &Path, hex: &str, what: &str, changed: &str) -> Result<(), String> {
        match self.hasher.hash(path) {
            Ok(d) if d.to_hex() == hex => Ok(()),
            Ok(_) => Err(format!("{what} {} {changed}", path.display())),
            Err(_) => Err(format!("{what} {} is missing", path.display())),
        }
    }
}

/// The digest of output `port` of an uncached node's instance with key `key`: its name,
/// not its content's hash. An uncached node has no inputs and is deterministic, so its key
/// (type, version, params, the content of its files, frame, seed) fixes its outputs, and
/// naming them by it lets the run resolve the instance without computing it: the values are
/// computed when a consumer reads them (Gaffer names a file reader's output by its file name
/// and params in the same way).
pub(crate) fn uncached_digest(key: &Digest, port: &str) -> Digest {
    let mut h = blake3::Hasher::new();
    h.update(b"vfxgraph-uncached-output-v1\0");
    h.update(&key.0);
    h.update(port.as_bytes());
    Digest(*h.finalize().as_bytes())
}

/// The key's header: format tag, node type, version and the output-affecting params.
fn hash_node(h: &mut blake3::Hasher, spec: &NodeSpec, gn: &GraphNode) {
    h.update(b"vfxgraph-key-v1\0");
    h.update(spec.name.as_bytes());
    h.update(&[0]);
    h.update(&spec.version.to_le_bytes());
    let mut buf = Vec::new();
    for p in spec.params.iter().filter(|p| !p.cosmetic) {
        if let Some(v) = gn.params.get(p.name) {
            buf.clear();
            crate::param::canonical(v, &mut buf);
            h.update(p.name.as_bytes());
            h.update(&[0]);
            h.update(&buf);
        }
    }
}

/// Why a cache lookup found no entry to serve.
#[derive(Clone, Debug, PartialEq)]
pub(super) enum Miss {
    /// The run uses no cache.
    Disabled,
    /// The node is `--force`d.
    Forced,
    /// No entry has the key: why is found by comparing the key's parts with the last run's
    /// records ([`RunSetup::explain`]).
    NoEntry,
    /// An entry whose outputs or files are gone or changed: what is wrong with it.
    Stale(String),
}

impl Miss {
    /// What the miss says by itself (`None` for [`Miss::NoEntry`], which the records explain).
    pub(super) fn reason(&self) -> Option<&str> {
        match self {
            Miss::Disabled => Some("cache disabled"),
            Miss::Forced => Some("forced"),
            Miss::NoEntry => None,
            Miss::Stale(why) => Some(why),
        }
    }
}

/// `Ok` if every output object of `entry` is in the store.
fn check_objects(store: &Store, entry: &ActionEntry) -> Result<(), String> {
    for o in &entry.outputs {
        match Digest::from_hex(&o.digest) {
            Some(d) if store.has_object(&d) => {}
            _ => return Err(format!("cached output `{}` is missing", o.port)),
        }
    }
    Ok(())
}
