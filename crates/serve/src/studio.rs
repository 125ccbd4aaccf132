//! The served state: the graph as loaded (or its diagnostics), the param overrides made from
//! the page, the last plan, the live state of a run, and the event channel.
//!
//! Param edits are kept as the engine's own [`Overrides`] (`--set node.param=value`): an edit
//! is validated by the same loader as the command line (a bad value gives its diagnostic and
//! changes nothing), and the cache keys of the edited node's dependants change exactly as for
//! `vfxgraph run --set`, so a run reruns only them. The page shows the overrides as the
//! `--set` arguments that reproduce the run from the shell. Only on request
//! ([`Studio::save_param`], the page's "save to file") is an edit written into the YAML, and
//! then only that value's text ([`crate::graph_file`]): comments and layout stay.
//!
//! After a run, the snapshot's `last_run` says whether it was stopped from the page (its
//! skipped instances are then not failures) and lists each failed instance with its message.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{SystemTime, UNIX_EPOCH};

use serde::Serialize;
use serde_json::{json, Value as Json};
use tokio::sync::broadcast;
use vfxgraph_engine::exec::{self, RunOptions};
use vfxgraph_engine::graph::{self, LoadError, Overrides};
use vfxgraph_engine::{Diagnostics, Graph, Kind, PlanReport, Registry, RunReport, Status};

use crate::events::Publisher;

/// The graph as loaded: the graph, or why it could not be.
#[derive(Clone)]
pub enum Loaded {
    /// Loaded and valid.
    Ok(Arc<Graph>),
    /// The file has problems (each with file:line:col) or cannot be read.
    Failed(Vec<DiagnosticLine>),
}

/// One problem of a graph that does not load.
#[derive(Clone, Debug, Serialize)]
pub struct DiagnosticLine {
    /// Error code (e.g. `unknown-type`).
    pub code: String,
    /// `file:line:col: message`.
    pub text: String,
    /// The graph file.
    pub file: String,
    /// 1-based line, when known.
    pub line: Option<usize>,
    /// 1-based column, when known.
    pub col: Option<usize>,
    /// The message.
    pub message: String,
    /// A hint, when there is one.
    pub help: Option<String>,
}

/// Converts the engine's diagnostics.
pub fn diagnostic_lines(d: &Diagnostics) -> Vec<DiagnosticLine> {
    let file = d.file.display().to_string();
    d.items
        .iter()
        .map(|it| {
            let (line, col) = it
                .span
                .map_or((None, None), |s| (Some(s.line), Some(s.col)));
            let at = match (line, col) {
                (Some(l), Some(c)) => format!("{file}:{l}:{c}"),
                _ => file.clone(),
            };
            DiagnosticLine {
                code: it.kind.code().to_string(),
                text: format!("{at}: {}", it.message),
                file: file.clone(),
                line,
                col,
                message: it.message.clone(),
                help: it.help.clone(),
            }
        })
        .collect()
}

/// Live counts of one node during (and after) a run.
#[derive(Clone, Debug, Default, Serialize)]
pub struct NodeLive {
    /// Instances computing now.
    pub running: usize,
    /// Instances computed.
    pub ran: usize,
    /// Instances served from the cache.
    pub cached: usize,
    /// Instances failed.
    pub failed: usize,
    /// Instances skipped (an input failed).
    pub skipped: usize,
    /// Progress of a node that runs once, in [0, 1].
    pub progress: f32,
}

struct Inner {
    sets: Vec<String>,
    loaded: Loaded,
    plan: Option<PlanReport>,
    plan_error: Option<String>,
    last_run: Option<RunReport>,
    /// The last run was stopped from the page (its skipped instances are not failures).
    last_stopped: bool,
    /// When the current (or last) run started, ms since the epoch.
    run_started_at: Option<f64>,
    live: BTreeMap<String, NodeLive>,
}

/// The studio: one graph, its cache and its clients.
pub struct Studio {
    /// The graph file, as given on the command line.
    pub graph_file: PathBuf,
    /// The cache folder.
    pub cache_dir: PathBuf,
    /// The node catalog.
    pub registry: Arc<Registry>,
    jobs: Option<usize>,
    inner: Mutex<Inner>,
    events: broadcast::Sender<Arc<str>>,
    seq: AtomicU64,
    running: AtomicBool,
    runs: AtomicU64,
    cancel: Arc<AtomicBool>,
    /// Decoded artifacts and encoded previews (see [`crate::preview`]).
    pub previews: crate::preview::PreviewCache,
}

/// Milliseconds since the Unix epoch (what the page compares with `Date.now()`).
pub fn now_ms() -> f64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64() * 1000.0)
}

impl Studio {
    /// Loads the graph (a graph that fails to load is kept as its diagnostics).
    pub fn open(
        graph_file: PathBuf,
        cache_dir: PathBuf,
        registry: Arc<Registry>,
        jobs: Option<usize>,
    ) -> Studio {
        let loaded = load(&graph_file, &registry, &[]);
        let (events, _) = broadcast::channel(4096);
        Studio {
            graph_file,
            cache_dir,
            registry,
            jobs,
            inner: Mutex::new(Inner {
                sets: vec![],
                loaded,
                plan: None,
                plan_error: None,
                last_run: None,
                last_stopped: false,
                run_started_at: None,
                live: BTreeMap::new(),
            }),
            events,
            seq: AtomicU64::new(0),
            running: AtomicBool::new(false),
            runs: AtomicU64::new(0),
            cancel: Arc::new(AtomicBool::new(false)),
            previews: crate::preview::PreviewCache::default(),
        }
    }

    fn inner(&self) -> MutexGuard<'_, Inner> {
        // A panic while holding the lock leaves plain data behind; keep serving it.
        self.inner.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// A receiver of every event published from now on.
    pub fn subscribe(&self) -> broadcast::Receiver<Arc<str>> {
        self.events.subscribe()
    }

    /// Publishes one event: `kind` plus `fields`, stamped with a sequence number and the time
    /// (`t`, ms since the epoch) at which the engine reported it.
    pub fn publish(&self, kind: &str, mut fields: Json) {
        let seq = self.seq.fetch_add(1, Ordering::Relaxed);
        if let Some(o) = fields.as_object_mut() {
            o.insert("kind".into(), json!(kind));
            o.insert("seq".into(), json!(seq));
            o.insert("t".into(), json!(now_ms()));
        }
        // No receiver is not an error: no page is open.
        let _ = self.events.send(Arc::from(fields.to_string()));
    }

    /// The graph, when it loads.
    pub fn graph(&self) -> Option<Arc<Graph>> {
        match &self.inner().loaded {
            Loaded::Ok(g) => Some(g.clone()),
            Loaded::Failed(_) => None,
        }
    }

    /// Runs finished since the studio started.
    pub fn runs(&self) -> u64 {
        self.runs.load(Ordering::SeqCst)
    }

    /// True while a run is going on.
    pub fn is_running(&self) -> bool {
        self.running.load(Ordering::SeqCst)
    }

    fn options(&self) -> RunOptions {
        RunOptions {
            jobs: self.jobs,
            cache_dir: Some(self.cache_dir.clone()),
            force: vec![],
            cancel: Some(self.cancel.clone()),
            only: None,
        }
    }

    /// Re-reads the graph file (with the current overrides) and plans it; publishes `state`.
    pub fn reload(&self) {
        let sets = self.inner().sets.clone();
        let loaded = load(&self.graph_file, &self.registry, &sets);
        self.inner().loaded = loaded;
        self.refresh_plan();
    }

    /// Plans the loaded graph against the cache; publishes `state`.
    pub fn refresh_plan(&self) {
        let (plan, err) = match self.graph() {
            Some(g) => match exec::plan(&g, &self.options()) {
                Ok(p) => (Some(p), None),
                Err(e) => (None, Some(e.to_string())),
            },
            None => (None, None),
        };
        {
            let mut i = self.inner();
            i.plan = plan;
            i.plan_error = err;
        }
        self.publish("state", json!({}));
    }

    /// Sets `node.param` to `value` (YAML text, as `--set`), or removes the override when
    /// `value` is `None`. The graph is reloaded with the new overrides; if it does not
    /// validate, nothing changes and the diagnostics are returned.
    /// A path parameter set from the page must name files in the graph's folder or the cache
    /// ([`crate::safety::confine`]): a page cannot make a run read or write elsewhere.
    fn confine_path_param(
        &self,
        g: &Graph,
        node: &str,
        param: &str,
    ) -> Result<(), Vec<DiagnosticLine>> {
        let Some(i) = g.index_of(node) else {
            return Ok(());
        };
        let n = &g.nodes[i];
        let texts = match n.spec().param_desc(param).map(|p| &p.kind) {
            Some(Kind::Path(_)) => vec![n.params.str(param)],
            Some(Kind::PathList(_)) => n.params.strs(param),
            _ => return Ok(()),
        };
        let roots = [g.dir.clone(), self.cache_dir.clone()];
        for text in texts {
            let path = vfxgraph_engine::node::resolve_path(&g.dir, text, None);
            if let Err(e) = crate::safety::confine(&path, &roots, text) {
                return Err(vec![DiagnosticLine {
                    code: "path-outside".into(),
                    text: format!("{node}.{param}: {}", e.message),
                    file: self.graph_file.display().to_string(),
                    line: None,
                    col: None,
                    message: e.message,
                    help: Some(
                        "give a path relative to the graph's folder, inside it (or edit the \
                         graph file itself)"
                            .into(),
                    ),
                }]);
            }
        }
        Ok(())
    }

    pub fn set_param(
        &self,
        node: &str,
        param: &str,
        value: Option<&str>,
    ) -> Result<(), Vec<DiagnosticLine>> {
        let prefix = format!("{node}.{param}=");
        let mut sets: Vec<String> = self
            .inner()
            .sets
            .iter()
            .filter(|s| !s.starts_with(&prefix))
            .cloned()
            .collect();
        if let Some(v) = value {
            sets.push(format!("{prefix}{v}"));
        }
        match load(&self.graph_file, &self.registry, &sets) {
            Loaded::Ok(g) => {
                if value.is_some() {
                    self.confine_path_param(&g, node, param)?;
                }
                {
                    let mut i = self.inner();
                    i.sets = sets;
                    i.loaded = Loaded::Ok(g);
                }
                self.refresh_plan();
                Ok(())
            }
            Loaded::Failed(d) => Err(d),
        }
    }

    /// Writes the override of `node.param` into the graph file (only that value's text
    /// changes, see [`crate::graph_file`]) and drops the override: the file now says it.
    /// Returns the value written.
    pub fn save_param(&self, node: &str, param: &str) -> Result<String, String> {
        let prefix = format!("{node}.{param}=");
        let sets = self.inner().sets.clone();
        let value = sets
            .iter()
            .find_map(|s| s.strip_prefix(&prefix))
            .ok_or_else(|| {
                format!("`{node}.{param}` is not edited: nothing to save to the graph file")
            })?
            .to_string();
        let edited = match load(&self.graph_file, &self.registry, &sets) {
            Loaded::Ok(g) => g,
            Loaded::Failed(d) => return Err(joined(&d)),
        };
        let want = param_text(&edited, node, param)?;
        let src = std::fs::read_to_string(&self.graph_file).map_err(|e| {
            format!(
                "cannot read the graph file `{}`: {e}",
                self.graph_file.display()
            )
        })?;
        let text = crate::graph_file::replace_param(&src, node, param, &value)?;
        let others: Vec<String> = sets
            .iter()
            .filter(|s| !s.starts_with(&prefix))
            .cloned()
            .collect();
        crate::graph_file::write_checked(&self.graph_file, &text, |tmp| {
            match load(tmp, &self.registry, &others) {
                Loaded::Ok(g) => {
                    let got = param_text(&g, node, param)?;
                    if got == want {
                        Ok(())
                    } else {
                        Err(format!(
                            "written in place, `{value}` reads back as {got}, not {want}: \
                             edit the graph file by hand"
                        ))
                    }
                }
                Loaded::Failed(d) => Err(format!(
                    "the file would not load with `{value}` written in place: {}",
                    joined(&d)
                )),
            }
        })?;
        self.inner().sets = others;
        self.reload();
        Ok(value)
    }

    /// Asks a running run to stop (finished instances stay cached).
    pub fn cancel(&self) {
        self.cancel.store(true, Ordering::SeqCst);
    }

    /// Starts a run on its own thread, unless one is going on (then `false`). The graph is
    /// re-read from disk first, so edits of the file are picked up.
    pub fn start_run(self: &Arc<Self>) -> bool {
        if self
            .running
            .compare_exchange(false, true, Ordering::SeqCst, Ordering::SeqCst)
            .is_err()
        {
            return false;
        }
        self.cancel.store(false, Ordering::SeqCst);
        let me = self.clone();
        std::thread::spawn(move || {
            me.run_now();
            let stopped = me.cancel.load(Ordering::SeqCst);
            me.inner().last_stopped = stopped;
            me.runs.fetch_add(1, Ordering::SeqCst);
            me.running.store(false, Ordering::SeqCst);
            me.publish("run_done", json!({ "stopped": stopped }));
            me.refresh_plan();
        });
        true
    }

    fn run_now(&self) {
        let sets = self.inner().sets.clone();
        let loaded = load(&self.graph_file, &self.registry, &sets);
        let g = match &loaded {
            Loaded::Ok(g) => g.clone(),
            Loaded::Failed(_) => {
                self.inner().loaded = loaded;
                return;
            }
        };
        {
            let mut i = self.inner();
            i.loaded = loaded;
            i.run_started_at = Some(now_ms());
            i.live = g
                .nodes
                .iter()
                .map(|n| (n.id.clone(), NodeLive::default()))
                .collect();
        }
        self.publish("run_started", json!({ "started_at": now_ms() }));
        let publisher = Publisher::new(self, &g);
        let result = exec::run(&g, &self.registry, &self.options(), &publisher);
        match result {
            Ok(rep) => self.inner().last_run = Some(rep),
            Err(e) => self.publish("run_error", json!({ "error": e.to_string() })),
        }
    }

    /// Applies one engine event to the live counts (called by the [`Publisher`]).
    pub(crate) fn update_live(&self, node: &str, f: impl FnOnce(&mut NodeLive)) {
        let mut i = self.inner();
        f(i.live.entry(node.to_string()).or_default());
    }

    /// Everything a page shows, as JSON (`GET /api/state`).
    pub fn snapshot(&self) -> Json {
        let i = self.inner();
        let mut out = json!({
            "file": self.graph_file.display().to_string(),
            "cache": self.cache_dir.display().to_string(),
            "sets": i.sets,
            "running": self.is_running(),
            "runs": self.runs.load(Ordering::SeqCst),
            "plan_error": i.plan_error,
            "live": i.live,
            "run_started_at": i.run_started_at,
        });
        match &i.loaded {
            Loaded::Failed(d) => {
                out["diagnostics"] = json!(d);
                out["graph"] = Json::Null;
            }
            Loaded::Ok(g) => {
                out["diagnostics"] = json!([]);
                out["graph"] = graph_json(g, &self.registry);
            }
        }
        out["plan"] = match &i.plan {
            Some(p) => json!(p.nodes),
            None => json!([]),
        };
        out["last_run"] = match &i.last_run {
            Some(r) => json!({
                "wall_seconds": r.wall_seconds,
                "nodes": r.nodes,
                "ran": r.nodes.iter().filter(|n| n.status == Status::Ran).count(),
                "failed": r.nodes.iter().any(|n| n.status == Status::Failed)
                    || (r.failed() && !i.last_stopped),
                "stopped": i.last_stopped,
                "failures": r.nodes.iter().filter(|n| n.status == Status::Failed).map(|n| json!({
                    "id": n.id, "type": n.node_type, "frame": n.frame, "message": n.reason,
                })).collect::<Vec<_>>(),
            }),
            None => Json::Null,
        };
        out
    }
}

fn joined(d: &[DiagnosticLine]) -> String {
    d.iter()
        .map(|l| l.message.clone())
        .collect::<Vec<_>>()
        .join("; ")
}

/// The value of `node.param` in `g`, as text.
fn param_text(g: &Graph, node: &str, param: &str) -> Result<String, String> {
    let i = g
        .index_of(node)
        .ok_or_else(|| format!("no node `{node}` in the graph"))?;
    Ok(g.nodes[i]
        .params
        .get(param)
        .map_or_else(|| "(none)".to_string(), |v| v.to_string()))
}

fn load(file: &std::path::Path, registry: &Registry, sets: &[String]) -> Loaded {
    let overrides = Overrides {
        set: sets.to_vec(),
        ..Overrides::default()
    };
    match graph::load(file, registry, &overrides) {
        Ok(g) => match g.check_limits(&graph::Limits::default()) {
            Ok(()) => Loaded::Ok(Arc::new(g)),
            Err(e) => Loaded::Failed(vec![DiagnosticLine {
                code: "limits".into(),
                text: format!("{}: {e}", file.display()),
                file: file.display().to_string(),
                line: None,
                col: None,
                message: e,
                help: None,
            }]),
        },
        Err(LoadError::Io { path, source }) => Loaded::Failed(vec![DiagnosticLine {
            code: "io".into(),
            text: format!("{}: cannot read the graph file: {source}", path.display()),
            file: path.display().to_string(),
            line: None,
            col: None,
            message: format!("cannot read the graph file: {source}"),
            help: None,
        }]),
        Err(LoadError::Invalid(d)) => Loaded::Failed(diagnostic_lines(&d)),
    }
}

/// The graph's nodes, edges and node-type docs (what `vfxgraph describe` prints).
fn graph_json(g: &Graph, registry: &Registry) -> Json {
    let nodes: Vec<Json> = g
        .nodes
        .iter()
        .map(|n| {
            let spec = n.spec();
            let params: Vec<Json> = spec
                .params
                .iter()
                .map(|p| {
                    let (min, max, choices) = match &p.kind {
                        Kind::Int { min, max } => (json!(min), json!(max), Json::Null),
                        Kind::Float { min, max } => (
                            if min.is_finite() {
                                json!(min)
                            } else {
                                Json::Null
                            },
                            if max.is_finite() {
                                json!(max)
                            } else {
                                Json::Null
                            },
                            Json::Null,
                        ),
                        Kind::Enum(c) => (Json::Null, Json::Null, json!(c)),
                        _ => (Json::Null, Json::Null, Json::Null),
                    };
                    json!({
                        "name": p.name,
                        "type": p.kind.to_string(),
                        "kind": param_kind(&p.kind),
                        "value": n.params.get(p.name).map(|v| v.to_string()),
                        "default": p.default.as_ref().map(|v| v.to_string()),
                        "doc": p.doc,
                        "affects_output": !p.cosmetic,
                        "min": min, "max": max, "choices": choices,
                    })
                })
                .collect();
            json!({
                "id": n.id,
                "type": spec.name,
                "doc": spec.doc,
                "version": spec.version,
                "per_frame": n.per_frame,
                "instances": g.instances_of(n),
                "line": n.span.line,
                "inputs": n.inputs.iter().map(|e| json!({
                    "port": e.port,
                    "from": g.nodes[e.from].id,
                    "from_port": e.from_port,
                    "whole_sequence": e.whole_sequence,
                })).collect::<Vec<_>>(),
                "input_ports": spec.inputs.iter().map(|p| json!({
                    "name": p.name, "type": p.display_type(), "doc": p.doc, "optional": p.optional,
                })).collect::<Vec<_>>(),
                "outputs": spec.outputs.iter().map(|p| json!({
                    "name": p.name, "type": p.ty, "doc": p.doc,
                    "type_doc": registry.artifact(p.ty).map(|a| a.doc),
                })).collect::<Vec<_>>(),
                "params": params,
            })
        })
        .collect();
    json!({
        "frames": g.frames.frames(),
        "seed": g.seed,
        "dir": g.dir.display().to_string(),
        "nodes": nodes,
    })
}

fn param_kind(t: &Kind) -> &'static str {
    match t {
        Kind::Bool => "bool",
        Kind::Int { .. } => "int",
        Kind::Float { .. } => "float",
        Kind::Enum(_) => "enum",
        Kind::Str => "string",
        Kind::Path(_) => "path",
        Kind::PathList(_) => "paths",
        Kind::FloatList { .. } => "floats",
    }
}
