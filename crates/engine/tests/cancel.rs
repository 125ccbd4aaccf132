//! Cancellation: a raised cancel flag skips instances that have not started, and running
//! nodes see it through `Context::cancelled`.

mod common;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use common::*;
use vfxgraph_engine::{
    exec, graph, Context, In, Mode, Node, NodeError, NodeSpec, Out, Overrides, Status,
};

const ANY: In<f64> = In::new("a", "any");
const ZERO: Out<f64> = Out::new("out", "0");

/// Spins until the run is cancelled (gives up after 20 s so a broken flag fails the test
/// instead of hanging it).
struct WaitCancel(NodeSpec);
static STARTED: AtomicBool = AtomicBool::new(false);
impl Node for WaitCancel {
    fn spec(&self) -> &NodeSpec {
        &self.0
    }
    fn run(&self, ctx: &mut Context<'_>) -> Result<(), NodeError> {
        STARTED.store(true, Ordering::SeqCst);
        let t = Instant::now();
        while t.elapsed() < Duration::from_secs(20) {
            if ctx.cancelled() {
                assert!(ctx.cancel_flag().load(Ordering::Relaxed));
                return Err(NodeError::msg("stopped: cancelled"));
            }
            std::thread::sleep(Duration::from_millis(1));
        }
        ctx.set(ZERO, 0.0);
        Ok(())
    }
}

const GRAPH: &str = "version: 1\nnodes:\n  a: {type: num, params: {value: 1}}\n  w: {type: wait_cancel, inputs: {a: a.out}}\n  b: {type: add, inputs: {a: w.out}}\n";

fn registry() -> vfxgraph_engine::Registry {
    let mut r = common::registry();
    r.register_node(WaitCancel(
        NodeSpec::new("wait_cancel", "waits for the cancel flag")
            .mode(Mode::Once)
            .input(ANY)
            .output(ZERO),
    ));
    r
}

#[test]
fn a_running_node_sees_the_flag_and_its_dependants_are_skipped() {
    let s = Scratch::new();
    let r = registry();
    let g = graph::load(&s.write("graph.yaml", GRAPH), &r, &Overrides::default()).unwrap();
    let flag = Arc::new(AtomicBool::new(false));
    let mut opts = s.opts();
    opts.cancel = Some(flag.clone());
    let raiser = std::thread::spawn(move || {
        while !STARTED.load(Ordering::SeqCst) {
            std::thread::sleep(Duration::from_millis(1));
        }
        flag.store(true, Ordering::SeqCst);
    });
    let rep = exec::run(&g, &r, &opts, &exec::Quiet).unwrap();
    raiser.join().unwrap();
    let st = |id: &str| rep.nodes.iter().find(|n| n.id == id).unwrap().clone();
    assert_eq!(st("a").status, Status::Ran);
    assert_eq!(st("w").status, Status::Failed);
    assert!(st("w").reason.contains("cancelled"), "{}", st("w").reason);
    assert_eq!(st("b").status, Status::Skipped);
}

#[test]
fn a_cancelled_run_starts_nothing_and_caches_nothing() {
    let s = Scratch::new();
    let text = "version: 1\nnodes:\n  a: {type: num, params: {value: 1}}\n  b: {type: add, inputs: {a: a.out}}\n";
    let g = s.graph(text);
    let mut opts = s.opts();
    opts.cancel = Some(Arc::new(AtomicBool::new(true)));
    let rep = exec::run(&g, &common::registry(), &opts, &exec::Quiet).unwrap();
    for n in &rep.nodes {
        assert_eq!(n.status, Status::Skipped, "{}", n.id);
        assert_eq!(n.reason, "run cancelled");
    }
    // Without the flag everything runs (nothing was cached by the cancelled run).
    let rep = s.run(text);
    assert_eq!(ran_cached(&rep, "a"), (1, 0));
    assert_eq!(ran_cached(&rep, "b"), (1, 0));
}
