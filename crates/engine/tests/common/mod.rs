//! Small node types for testing the engine on its own (floats and text files).
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::sync::{Condvar, Mutex};
use std::time::Duration;

use vfxgraph_engine::{
    exec, graph, Context, Graph, Kind, Mode, Node, NodeError, NodeSpec, Overrides, ParamDesc,
    ParamValue, PathRole, PortSpec, Registry, RunOptions, RunReport,
};
use vfxgraph_engine::{In, OptIn, Out, SeqIn, StreamIn};

const OUT: Out<f64> = Out::new("out", "");
const A: In<f64> = In::new("a", "");
const OPTIONAL_A: OptIn<f64> = OptIn::new("a", "");
const B: OptIn<f64> = OptIn::new("b", "");
const ITEMS: SeqIn<f64> = SeqIn::new("items", "");
const STREAMED_ITEMS: StreamIn<f64> = StreamIn::new("items", "");

pub struct Num(NodeSpec);
impl Node for Num {
    fn spec(&self) -> &NodeSpec {
        &self.0
    }
    fn run(&self, ctx: &mut Context<'_>) -> Result<(), NodeError> {
        let v = ctx.params().f64("value");
        ctx.set(OUT, v);
        Ok(())
    }
}

pub struct Add(NodeSpec);
impl Node for Add {
    fn spec(&self) -> &NodeSpec {
        &self.0
    }
    fn run(&self, ctx: &mut Context<'_>) -> Result<(), NodeError> {
        let a = *ctx.get(A)?;
        let b = ctx.get(B)?.copied().unwrap_or(0.0);
        let v = a + b + ctx.params().f64("offset");
        ctx.set(OUT, v);
        Ok(())
    }
}

pub struct Round(pub NodeSpec);
impl Node for Round {
    fn spec(&self) -> &NodeSpec {
        &self.0
    }
    fn run(&self, ctx: &mut Context<'_>) -> Result<(), NodeError> {
        let a = ctx.get(A)?.round();
        ctx.set(OUT, a);
        Ok(())
    }
}

pub struct Ramp(NodeSpec);
impl Node for Ramp {
    fn spec(&self) -> &NodeSpec {
        &self.0
    }
    fn run(&self, ctx: &mut Context<'_>) -> Result<(), NodeError> {
        let f = ctx.frame().expect("per frame") as f64;
        let v = f * ctx.params().f64("scale");
        ctx.set(OUT, v);
        Ok(())
    }
}

pub struct Sum(NodeSpec);
impl Node for Sum {
    fn spec(&self) -> &NodeSpec {
        &self.0
    }
    fn run(&self, ctx: &mut Context<'_>) -> Result<(), NodeError> {
        let v: f64 = ctx.get(ITEMS)?.iter().map(|(_, x)| **x).sum();
        ctx.set(OUT, v);
        Ok(())
    }
}

pub struct ReadNum(NodeSpec);
impl Node for ReadNum {
    fn spec(&self) -> &NodeSpec {
        &self.0
    }
    fn run(&self, ctx: &mut Context<'_>) -> Result<(), NodeError> {
        let p = ctx.path("path");
        let text = std::fs::read_to_string(&p)
            .map_err(|e| NodeError::msg(format!("{}: {e}", p.display())))?;
        let v: f64 = text
            .trim()
            .parse()
            .map_err(|e| NodeError::msg(format!("{}: {e}", p.display())))?;
        ctx.set(OUT, v);
        Ok(())
    }
}

/// How many times `read_num_counted` has computed (only the streaming test uses it).
pub static COUNTED_READS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

/// `read_num`, uncached, counting its computations in [`COUNTED_READS`].
pub struct ReadNumCounted(pub ReadNum);
impl Node for ReadNumCounted {
    fn spec(&self) -> &NodeSpec {
        self.0.spec()
    }
    fn run(&self, ctx: &mut Context<'_>) -> Result<(), NodeError> {
        COUNTED_READS.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
        self.0.run(ctx)
    }
}

/// Sums every other item of a streamed sequence (items 0, 2, …): the frames it skips must
/// never be computed.
pub struct SumEveryOther(NodeSpec);
impl Node for SumEveryOther {
    fn spec(&self) -> &NodeSpec {
        &self.0
    }
    fn run(&self, ctx: &mut Context<'_>) -> Result<(), NodeError> {
        let items = ctx.get(STREAMED_ITEMS)?;
        let mut v = 0.0;
        for k in (0..items.len()).step_by(2) {
            v += *items.get(k)?;
        }
        ctx.set(OUT, v);
        Ok(())
    }
}

/// Sums the numbers in the files a list file names (one relative name per line): the named
/// files are declared at run time, as a list-file reader must.
pub struct SumListed(NodeSpec);
impl Node for SumListed {
    fn spec(&self) -> &NodeSpec {
        &self.0
    }
    fn run(&self, ctx: &mut Context<'_>) -> Result<(), NodeError> {
        let list = ctx.path("list");
        let text = std::fs::read_to_string(&list)
            .map_err(|e| NodeError::msg(format!("{}: {e}", list.display())))?;
        let dir = list.parent().unwrap().to_path_buf();
        let mut v = 0.0;
        for name in text.lines().filter(|l| !l.trim().is_empty()) {
            let p = dir.join(name.trim());
            ctx.declare_input_file(&p)?;
            let t = std::fs::read_to_string(&p).map_err(|e| NodeError::msg(e.to_string()))?;
            v += t
                .trim()
                .parse::<f64>()
                .map_err(|e| NodeError::msg(e.to_string()))?;
        }
        ctx.set(OUT, v);
        Ok(())
    }
}

/// Sums the numbers in the files of a path-list param.
pub struct SumPaths(NodeSpec);
impl Node for SumPaths {
    fn spec(&self) -> &NodeSpec {
        &self.0
    }
    fn run(&self, ctx: &mut Context<'_>) -> Result<(), NodeError> {
        let mut v = 0.0;
        for p in ctx.paths("paths") {
            let t = std::fs::read_to_string(&p).map_err(|e| NodeError::msg(e.to_string()))?;
            v += t
                .trim()
                .parse::<f64>()
                .map_err(|e| NodeError::msg(e.to_string()))?;
        }
        ctx.set(OUT, v);
        Ok(())
    }
}

/// `write_num`; with `true` (`write_num_note`) it also writes a note beside its file, both
/// through `Context::write_file`.
pub struct WriteNum(NodeSpec, bool);
impl Node for WriteNum {
    fn spec(&self) -> &NodeSpec {
        &self.0
    }
    fn run(&self, ctx: &mut Context<'_>) -> Result<(), NodeError> {
        let v = *ctx.get(A)?;
        let (path, text) = (ctx.path("path"), format!("{v}\n"));
        if self.1 {
            ctx.write_file(&path.with_extension("note"), b"a note\n")?;
            ctx.write_file(&path, text.as_bytes())?;
        } else {
            vfxgraph_engine::fsutil::atomic_write(&path, text.as_bytes())?;
        }
        Ok(())
    }
}

pub struct Fail(NodeSpec);
impl Node for Fail {
    fn spec(&self) -> &NodeSpec {
        &self.0
    }
    fn run(&self, _ctx: &mut Context<'_>) -> Result<(), NodeError> {
        Err(NodeError::msg("this node always fails"))
    }
}

pub struct Rand(NodeSpec);
impl Node for Rand {
    fn spec(&self) -> &NodeSpec {
        &self.0
    }
    fn run(&self, ctx: &mut Context<'_>) -> Result<(), NodeError> {
        let v = (ctx.seed() >> 11) as f64 / (1u64 << 53) as f64;
        ctx.set(OUT, v);
        Ok(())
    }
}

/// Two instances must be inside `run` at the same time to pass; gives up after 10 s.
pub struct Rendezvous(NodeSpec);
pub static BARRIER: (Mutex<usize>, Condvar) = (Mutex::new(0), Condvar::new());
impl Node for Rendezvous {
    fn spec(&self) -> &NodeSpec {
        &self.0
    }
    fn run(&self, ctx: &mut Context<'_>) -> Result<(), NodeError> {
        let (lock, cv) = &BARRIER;
        let mut arrived = lock.lock().unwrap();
        *arrived += 1;
        cv.notify_all();
        let (guard, timeout) = cv
            .wait_timeout_while(arrived, Duration::from_secs(10), |n| *n < 2)
            .unwrap();
        drop(guard);
        if timeout.timed_out() {
            return Err(NodeError::msg(
                "partner never arrived: nodes did not run concurrently",
            ));
        }
        ctx.set(OUT, 1.0f64);
        Ok(())
    }
}

pub fn registry() -> Registry {
    let f = || Kind::Float {
        min: -1e9,
        max: 1e9,
    };
    let mut r = Registry::new();
    r.register_node(Num(NodeSpec::new("num", "a constant")
        .mode(Mode::Once)
        .param(ParamDesc::required("value", f(), "the value"))
        .param(
            ParamDesc::optional(
                "label",
                Kind::Str,
                ParamValue::Str(String::new()),
                "cosmetic",
            )
            .cosmetic(),
        )
        .output(OUT)));
    r.register_node(Add(NodeSpec::new("add", "a + b + offset")
        .param(ParamDesc::optional(
            "offset",
            f(),
            ParamValue::Float(0.0),
            "",
        ))
        .param(ParamDesc::optional(
            "count",
            Kind::Int { min: 0, max: 10 },
            ParamValue::Int(1),
            "",
        ))
        .input(A)
        .input(B)
        .output(OUT)));
    r.register_node(Round(
        NodeSpec::new("round", "round to integer")
            .input(A)
            .output(OUT),
    ));
    r.register_node(Ramp(
        NodeSpec::new("ramp", "frame × scale")
            .mode(Mode::PerFrame)
            .param(ParamDesc::optional(
                "scale",
                f(),
                ParamValue::Float(1.0),
                "",
            ))
            .output(OUT),
    ));
    r.register_node(Sum(NodeSpec::new("sum", "sum of a sequence")
        .mode(Mode::Once)
        .input(ITEMS)
        .output(OUT)));
    // A number from a text file named by the `path` param.
    let read_num = |name, doc| {
        NodeSpec::new(name, doc)
            .input_file_param("path", "")
            .output(OUT)
    };
    r.register_node(ReadNum(read_num("read_num", "a number from a text file")));
    r.register_node(ReadNum(
        read_num(
            "read_num_uncached",
            "read_num, its outputs kept out of the cache",
        )
        .uncached(),
    ));
    r.register_node(ReadNumCounted(ReadNum(
        read_num(
            "read_num_counted",
            "read_num_uncached, counting its computations",
        )
        .uncached(),
    )));
    r.register_node(SumEveryOther(
        NodeSpec::new(
            "sum_every_other",
            "sum of every other item of a streamed sequence",
        )
        .mode(Mode::Once)
        .input(STREAMED_ITEMS)
        .output(OUT),
    ));
    r.register_node(SumListed(
        NodeSpec::new("sum_listed", "sum of the numbers in the files a list names")
            .mode(Mode::Once)
            .param(ParamDesc::required("list", Kind::Path(PathRole::Input), ""))
            .output(OUT),
    ));
    r.register_node(SumPaths(
        NodeSpec::new("sum_paths", "sum of the numbers in the listed files")
            .mode(Mode::Once)
            .param(ParamDesc::required(
                "paths",
                Kind::PathList(PathRole::Input),
                "",
            ))
            .output(OUT),
    ));
    for (name, note) in [("write_num", false), ("write_num_note", true)] {
        r.register_node(WriteNum(
            NodeSpec::new(name, "a number to a text file (and a note beside it)")
                .param(ParamDesc::required(
                    "path",
                    Kind::Path(PathRole::Output),
                    "",
                ))
                .input(A),
            note,
        ));
    }
    r.register_node(Fail(
        NodeSpec::new("fail", "always fails")
            .input(OPTIONAL_A)
            .output(OUT),
    ));
    r.register_node(Rand(
        NodeSpec::new("rand", "a seeded random number")
            .seeded()
            .output(OUT),
    ));
    r.register_node(Rendezvous(
        NodeSpec::new("rendezvous", "waits for a partner")
            .mode(Mode::Once)
            .param(ParamDesc::optional(
                "name",
                Kind::Str,
                ParamValue::Str(String::new()),
                "",
            ))
            .output(OUT),
    ));
    r.register_node(Sequence2(
        NodeSpec::new("pair", "sequence of a pair")
            .mode(Mode::Once)
            .input(PortSpec::sequence("items", "string", ""))
            .output(OUT),
    ));
    r
}

pub struct Sequence2(NodeSpec);
impl Node for Sequence2 {
    fn spec(&self) -> &NodeSpec {
        &self.0
    }
    fn run(&self, ctx: &mut Context<'_>) -> Result<(), NodeError> {
        ctx.set(OUT, 0.0f64);
        Ok(())
    }
}

/// A scratch folder holding a graph file.
pub struct Scratch {
    pub dir: tempfile::TempDir,
}

impl Scratch {
    pub fn new() -> Self {
        Scratch {
            dir: tempfile::tempdir().unwrap(),
        }
    }
    pub fn path(&self, name: &str) -> PathBuf {
        self.dir.path().join(name)
    }
    pub fn write(&self, name: &str, text: &str) -> PathBuf {
        let p = self.path(name);
        if let Some(parent) = p.parent() {
            std::fs::create_dir_all(parent).unwrap();
        }
        std::fs::write(&p, text).unwrap();
        p
    }
    pub fn graph(&self, text: &str) -> Graph {
        let p = self.write("graph.yaml", text);
        load(&p)
    }
    pub fn opts(&self) -> RunOptions {
        RunOptions {
            jobs: Some(2),
            cache_dir: Some(self.path(".vfxgraph")),
            force: vec![],
            cancel: None,
            only: None,
        }
    }
    pub fn run(&self, text: &str) -> RunReport {
        let g = self.graph(text);
        exec::run(&g, &registry(), &self.opts(), &exec::Quiet).unwrap()
    }
}

pub fn load(p: &Path) -> Graph {
    match graph::load(p, &registry(), &Overrides::default()) {
        Ok(g) => g,
        Err(e) => panic!("{e}"),
    }
}

/// Statuses of node `id` as (ran, cached).
pub fn ran_cached(r: &RunReport, id: &str) -> (usize, usize) {
    (
        r.count(id, vfxgraph_engine::Status::Ran),
        r.count(id, vfxgraph_engine::Status::Cached),
    )
}
