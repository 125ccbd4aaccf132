//! Running: the scheduler that resolves every instance on a rayon pool as soon as its inputs
//! are resolved — served from the cache, or computed and stored — and the run's report.

use std::collections::{BTreeMap, HashMap};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, OnceLock};
use std::time::{Duration, Instant};

use super::compute::Computed;
use super::instances::{frame_suffix, Role};
use super::keys::{uncached_digest, KeyParts, Miss};
use super::records::InstanceRecord;
use super::report::{InstanceReport, Observer, RunReport, Status};
use super::setup::RunSetup;
use super::{ExecError, RunOptions};
use crate::artifact::{Digest, Value};
use crate::graph::Graph;
use crate::lease::{Holder, Lease};
use crate::registry::Registry;
use crate::store::ActionEntry;

/// How an instance was resolved.
pub(super) struct Resolution {
    pub(super) status: Status,
    pub(super) reason: String,
    pub(super) seconds: f64,
    pub(super) digests: BTreeMap<&'static str, Digest>,
}

impl Resolution {
    /// A resolution without outputs (skipped or failed).
    fn empty(status: Status, reason: String, seconds: f64) -> Self {
        Resolution {
            status,
            reason,
            seconds,
            digests: BTreeMap::new(),
        }
    }
}

/// What waiting for an action's lease gave.
enum Leased {
    /// Compute it (holding its lease, if the cache has leases).
    Compute(Option<Lease>),
    /// Another run computed it meanwhile: its entry.
    Served(ActionEntry),
    /// The run was cancelled while waiting.
    Cancelled,
}

/// The run state of one instance.
pub(super) struct InstanceState {
    /// Upstream instances not yet resolved.
    pending: AtomicUsize,
    /// Downstream instances that have not finished yet.
    pub(super) consumers_left: AtomicUsize,
    pub(super) done: OnceLock<Resolution>,
    /// Output values kept in memory for consumers still to come.
    pub(super) values: Mutex<BTreeMap<&'static str, Value>>,
}

/// A run in progress.
pub(super) struct Runner<'a> {
    pub(super) setup: RunSetup<'a>,
    pub(super) cancel: Arc<AtomicBool>,
    pub(super) registry: &'a Registry,
    pub(super) state: Vec<InstanceState>,
    pub(super) observer: &'a dyn Observer,
    /// This run's key components, per node and frame key, saved at the end.
    pub(super) new_records: Mutex<HashMap<usize, BTreeMap<String, InstanceRecord>>>,
}

/// Runs a graph: every instance is served from the cache or computed, in parallel. Node
/// failures do not abort the run: they are reported, their dependants skipped, and independent
/// branches finish (and are cached).
pub fn run(
    graph: &Graph,
    registry: &Registry,
    opts: &RunOptions,
    observer: &dyn Observer,
) -> Result<RunReport, ExecError> {
    let t0 = Instant::now();
    let setup = RunSetup::new(graph, opts)?;
    let state = initial_state(&setup);
    let runner = Runner {
        setup,
        cancel: opts.cancel.clone().unwrap_or_default(),
        registry,
        state,
        observer,
        new_records: Mutex::new(HashMap::new()),
    };
    let pool = thread_pool(opts.jobs)?;
    pool.install(|| {
        rayon::scope(|s| {
            for i in 0..runner.setup.insts.len() {
                if runner.setup.insts[i].upstream.is_empty()
                    && runner.setup.role[i] != Role::Unneeded
                {
                    runner.schedule(s, i);
                }
            }
        })
    });
    runner.save_records();
    runner.setup.hasher.save();
    Ok(RunReport {
        nodes: runner.report(),
        wall_seconds: t0.elapsed().as_secs_f64(),
    })
}

/// Each instance's state before the run: all upstream pending, all needed consumers to come.
fn initial_state(c: &RunSetup) -> Vec<InstanceState> {
    c.insts
        .iter()
        .map(|inst| InstanceState {
            pending: AtomicUsize::new(inst.upstream.len()),
            consumers_left: AtomicUsize::new(
                inst.downstream
                    .iter()
                    .filter(|&&d| c.role[d] != Role::Unneeded)
                    .count(),
            ),
            done: OnceLock::new(),
            values: Mutex::new(BTreeMap::new()),
        })
        .collect()
}

/// A pool of `jobs` worker threads (`None`: one per core).
fn thread_pool(jobs: Option<usize>) -> Result<rayon::ThreadPool, ExecError> {
    let mut builder = rayon::ThreadPoolBuilder::new();
    if let Some(j) = jobs {
        builder = builder.num_threads(j.max(1));
    }
    builder.build().map_err(|e| ExecError::Pool {
        jobs: jobs.unwrap_or(0),
        reason: e.to_string(),
    })
}

impl<'a> Runner<'a> {
    /// Resolves instance `i` on the pool, then releases its inputs' values and schedules the
    /// consumers it was the last input of.
    fn schedule<'s>(&'s self, s: &rayon::Scope<'s>, i: usize) {
        s.spawn(move |s| {
            self.resolve(i);
            for &u in &self.setup.insts[i].upstream {
                if self.state[u].consumers_left.fetch_sub(1, Ordering::AcqRel) == 1 {
                    self.state[u].values.lock().expect("values lock").clear();
                }
            }
            for &d in &self.setup.insts[i].downstream {
                if self.setup.role[d] != Role::Unneeded
                    && self.state[d].pending.fetch_sub(1, Ordering::AcqRel) == 1
                {
                    self.schedule(s, d);
                }
            }
        });
    }

    pub(super) fn finish(&self, i: usize, done: Resolution) {
        let inst = &self.setup.insts[i];
        self.observer
            .finished(inst.node, inst.frame, done.status, done.seconds);
        let _ = self.state[i].done.set(done);
    }

    /// The digest of output `port` of instance `j`, if it is resolved with outputs.
    fn resolved_digest(&self, j: usize, port: &str) -> Option<Digest> {
        self.state[j]
            .done
            .get()
            .and_then(|d| d.digests.get(port).copied())
    }

    /// Resolves instance `i`: skipped, served from the cache, or computed.
    fn resolve(&self, i: usize) {
        if self.cancel.load(Ordering::Relaxed) {
            let done = Resolution::empty(Status::Skipped, "run cancelled".into(), 0.0);
            return self.finish(i, done);
        }
        if let Some(reason) = self.failed_upstream(i) {
            return self.finish(i, Resolution::empty(Status::Skipped, reason, 0.0));
        }
        let parts = match self.setup.key(i, |j, port| self.resolved_digest(j, port)) {
            Ok(p) => p,
            Err(e) => return self.finish(i, Resolution::empty(Status::Failed, e, 0.0)),
        };
        if !self.setup.graph.nodes[self.setup.insts[i].node]
            .spec()
            .cache_outputs
        {
            return self.resolve_uncached(i, parts);
        }
        let miss = match self.setup.lookup(i, &parts.key) {
            Ok(entry) => return self.serve_cached(i, parts, &entry, "cache hit"),
            Err(m) => m,
        };
        if self.setup.role[i] == Role::CacheOnly {
            let why = miss.reason().unwrap_or("no entry");
            let reason = format!(
                "an input of the selected instances is not in the cache ({why}); \
                 it must run first (a missing farm dependency, or a cleaned cache)"
            );
            return self.finish(i, Resolution::empty(Status::Failed, reason, 0.0));
        }
        self.run_instance(i, parts, &miss);
    }

    /// Why instance `i` cannot run, if an input failed or was skipped.
    fn failed_upstream(&self, i: usize) -> Option<String> {
        let &j = self.setup.insts[i].upstream.iter().find(|&&j| {
            self.state[j]
                .done
                .get()
                .is_none_or(|d| matches!(d.status, Status::Failed | Status::Skipped))
        })?;
        let up = &self.setup.insts[j];
        Some(format!(
            "upstream `{}`{} did not complete",
            self.setup.graph.nodes[up.node].id,
            frame_suffix(up.frame)
        ))
    }

    /// Resolves instance `i` from its valid cache entry, without loading its values.
    fn serve_cached(&self, i: usize, parts: KeyParts, entry: &ActionEntry, reason: &str) {
        if let Some(store) = &self.setup.store {
            store.touch_action(&parts.key);
        }
        let spec = self.setup.graph.nodes[self.setup.insts[i].node].spec();
        let digests = spec
            .outputs
            .iter()
            .filter_map(|p| {
                entry
                    .outputs
                    .iter()
                    .find(|o| o.port == p.name)
                    .and_then(|o| Digest::from_hex(&o.digest))
                    .map(|d| (p.name, d))
            })
            .collect();
        self.remember(i, parts.record);
        self.finish(
            i,
            Resolution {
                status: Status::Cached,
                reason: reason.into(),
                seconds: 0.0,
                digests,
            },
        );
    }

    /// The lease to compute instance `i` (`None`: compute without one), or the entry another
    /// run computed while this one waited for its lease, or the run was cancelled meanwhile.
    fn take_lease(&self, i: usize, key: &Digest) -> Leased {
        let Some(store) = &self.setup.store else {
            return Leased::Compute(None);
        };
        if self.setup.forced[self.setup.insts[i].node] {
            return Leased::Compute(None);
        }
        loop {
            match store.try_lease(key) {
                Ok(Some(lease)) => {
                    // Finished by another run between the miss and the lease?
                    return match self.setup.lookup(i, key) {
                        Ok(entry) => Leased::Served(entry),
                        Err(_) => Leased::Compute(Some(lease)),
                    };
                }
                Ok(None) => {}
                // A cache whose leases cannot be written (read-only) still runs.
                Err(e) => {
                    tracing::debug!("no lease for {}: {e}", key.to_hex());
                    return Leased::Compute(None);
                }
            }
            let mut nap = Duration::from_millis(5);
            loop {
                if self.cancel.load(Ordering::Relaxed) {
                    return Leased::Cancelled;
                }
                match store.lease_holder(key) {
                    Holder::None => break,
                    Holder::Stale => {
                        store.break_lease(key);
                        break;
                    }
                    Holder::Live => {
                        std::thread::sleep(nap);
                        nap = (nap * 2).min(Duration::from_millis(200));
                    }
                }
            }
            if let Ok(entry) = self.setup.lookup(i, key) {
                return Leased::Served(entry);
            }
        }
    }

    /// Resolves an instance of an uncached node without computing it: its outputs are named
    /// by its key ([`uncached_digest`]) and computed when a consumer reads them. Its action
    /// entry (no objects) is what makes the next run report it cached.
    fn resolve_uncached(&self, i: usize, parts: KeyParts) {
        let spec = self.setup.graph.nodes[self.setup.insts[i].node].spec();
        let digests: BTreeMap<_, _> = spec
            .outputs
            .iter()
            .map(|p| (p.name, uncached_digest(&parts.key, p.name)))
            .collect();
        let (status, reason) = match self.setup.lookup(i, &parts.key) {
            Ok(_) => {
                if let Some(store) = &self.setup.store {
                    store.touch_action(&parts.key);
                }
                (Status::Cached, "cache hit".to_string())
            }
            Err(miss) => {
                let reason = self.setup.explain(i, &parts, &miss);
                if let Err(e) = self.store_uncached(i, &parts.key, &digests) {
                    let reason = format!("its entry could not be cached: {e}");
                    return self.finish(i, Resolution::empty(Status::Failed, reason, 0.0));
                }
                (Status::Ran, format!("{reason} (read when a consumer runs)"))
            }
        };
        self.remember(i, parts.record);
        let done = Resolution {
            status,
            reason,
            seconds: 0.0,
            digests,
        };
        self.finish(i, done);
    }

    /// Computes instance `i` (a cache miss for reason `miss`) and stores its result.
    fn run_instance(&self, i: usize, parts: KeyParts, miss: &Miss) {
        let _lease = match self.take_lease(i, &parts.key) {
            Leased::Compute(lease) => lease,
            Leased::Served(entry) => {
                return self.serve_cached(i, parts, &entry, "computed by a concurrent run")
            }
            Leased::Cancelled => {
                let done = Resolution::empty(Status::Skipped, "run cancelled".into(), 0.0);
                return self.finish(i, done);
            }
        };
        let reason = self.setup.explain(i, &parts, miss);
        let inst = &self.setup.insts[i];
        self.observer.started(inst.node, inst.frame);
        let t = Instant::now();
        match self.compute(i) {
            Ok(computed) => {
                let seconds = t.elapsed().as_secs_f64();
                self.finish_computed(i, parts, computed, reason, seconds);
            }
            Err(e) => {
                let seconds = t.elapsed().as_secs_f64();
                self.finish(i, Resolution::empty(Status::Failed, e, seconds));
            }
        }
    }

    /// Stores what instance `i` computed, keeps its values for its consumers, and resolves it.
    fn finish_computed(
        &self,
        i: usize,
        parts: KeyParts,
        computed: Computed,
        reason: String,
        seconds: f64,
    ) {
        let digests = computed
            .outputs
            .iter()
            .map(|(k, (v, _))| (*k, v.digest()))
            .collect();
        if let Err(e) = self.store_outputs(i, &parts.key, &computed, seconds) {
            // The cache stays as it was (writes are atomic; an entry is written after
            // its objects), and the run says so: exit code 1, not a silent miss.
            let reason = format!("ran, but its result could not be cached: {e}");
            return self.finish(i, Resolution::empty(Status::Failed, reason, seconds));
        }
        {
            let mut vals = self.state[i].values.lock().expect("values lock");
            if self.state[i].consumers_left.load(Ordering::Acquire) > 0 {
                for (k, (v, _)) in computed.outputs {
                    vals.insert(k, v);
                }
            }
        }
        self.remember(i, parts.record);
        self.finish(
            i,
            Resolution {
                status: Status::Ran,
                reason,
                seconds,
                digests,
            },
        );
    }

    /// One report line per visited instance, in graph order.
    fn report(&self) -> Vec<InstanceReport<Status>> {
        self.setup
            .insts
            .iter()
            .enumerate()
            .filter(|(i, _)| self.setup.role[*i] != Role::Unneeded)
            .map(|(i, inst)| {
                let gn = &self.setup.graph.nodes[inst.node];
                let d = self.state[i].done.get();
                InstanceReport {
                    id: gn.id.clone(),
                    node_type: gn.spec().name.to_string(),
                    frame: inst.frame,
                    status: d.map_or(Status::Skipped, |d| d.status),
                    reason: d.map_or_else(|| "not reached".to_string(), |d| d.reason.clone()),
                    seconds: d.map_or(0.0, |d| d.seconds),
                }
            })
            .collect()
    }
}
