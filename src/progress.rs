//! Progress bars (indicatif): one per node that computes, created when it starts.
//!
//! The bars are redrawn by one ticker thread, whatever the graph's size (a steady tick per bar
//! would start a thread per node), and only while they are shown: hidden bars (quiet, JSON, or
//! stderr not a terminal) start no thread and make no bar.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use indicatif::{MultiProgress, ProgressBar, ProgressDrawTarget, ProgressStyle};
use vfxgraph_engine::{Graph, Observer, Status};

/// How often the ticker redraws the running bars (their spinners and clocks).
const TICK: Duration = Duration::from_millis(200);

/// Draws bars on stderr (nothing when stderr is not a terminal, or when quiet).
pub struct Bars {
    multi: MultiProgress,
    names: Vec<String>,
    instances: Vec<usize>,
    finished: Vec<AtomicUsize>,
    /// Each node's bar, once it has started; the ticker's running set.
    bars: Arc<Mutex<Vec<Option<ProgressBar>>>>,
    /// Stops the ticker.
    stop: Arc<AtomicBool>,
    ticker: Mutex<Option<JoinHandle<()>>>,
}

impl Bars {
    pub fn new(g: &Graph, quiet: bool) -> Self {
        let target = if quiet {
            ProgressDrawTarget::hidden()
        } else {
            ProgressDrawTarget::stderr()
        };
        let multi = MultiProgress::with_draw_target(target);
        let bars: Arc<Mutex<Vec<Option<ProgressBar>>>> =
            Arc::new(Mutex::new(vec![None; g.nodes.len()]));
        let stop = Arc::new(AtomicBool::new(false));
        let ticker = (!multi.is_hidden()).then(|| {
            let (bars, stop) = (Arc::clone(&bars), Arc::clone(&stop));
            std::thread::Builder::new()
                .name("progress".into())
                .spawn(move || {
                    while !stop.load(Ordering::Relaxed) {
                        std::thread::sleep(TICK);
                        let running: Vec<ProgressBar> = bars
                            .lock()
                            .map(|b| {
                                b.iter()
                                    .flatten()
                                    .filter(|b| !b.is_finished())
                                    .cloned()
                                    .collect()
                            })
                            .unwrap_or_default();
                        for b in running {
                            b.tick();
                        }
                    }
                })
                .ok()
        });
        Bars {
            multi,
            names: g.nodes.iter().map(|n| n.id.clone()).collect(),
            instances: g.nodes.iter().map(|n| g.instances_of(n)).collect(),
            finished: g.nodes.iter().map(|_| AtomicUsize::new(0)).collect(),
            bars,
            stop,
            ticker: Mutex::new(ticker.flatten()),
        }
    }

    /// Whether bars are drawn at all.
    fn shown(&self) -> bool {
        !self.multi.is_hidden()
    }

    pub fn finish(&self) {
        self.stop_ticker();
        for b in self.bars.lock().expect("bars").iter().flatten() {
            b.finish();
        }
        let _ = self.multi.clear();
    }

    fn stop_ticker(&self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.ticker.lock().ok().and_then(|mut t| t.take()) {
            let _ = t.join();
        }
    }

    /// Once-nodes measure progress in thousandths; per-frame nodes in instances. `None` when
    /// the bars are hidden.
    fn bar(&self, node: usize) -> Option<ProgressBar> {
        if !self.shown() {
            return None;
        }
        let mut bars = self.bars.lock().expect("bars");
        if let Some(b) = &bars[node] {
            return Some(b.clone());
        }
        let per_frame = self.instances[node] > 1;
        let len = if per_frame {
            self.instances[node] as u64
        } else {
            1000
        };
        let style = if per_frame {
            "{prefix:>16} {bar:30} {pos}/{len} frames  {elapsed_precise} eta {eta}"
        } else {
            "{prefix:>16} {bar:30} {percent:>3}%  {elapsed_precise}"
        };
        let b = self.multi.add(ProgressBar::new(len));
        b.set_style(
            ProgressStyle::with_template(style)
                .unwrap_or_else(|_| ProgressStyle::default_bar())
                .progress_chars("█▉▊▋▌▍▎▏ "),
        );
        b.set_prefix(self.names[node].clone());
        if per_frame {
            b.set_position(self.finished[node].load(Ordering::Relaxed) as u64);
        }
        bars[node] = Some(b.clone());
        Some(b)
    }
}

impl Drop for Bars {
    fn drop(&mut self) {
        self.stop_ticker();
    }
}

impl Observer for Bars {
    fn started(&self, node: usize, _frame: Option<i64>) {
        self.bar(node);
    }

    fn progress(&self, node: usize, frame: Option<i64>, fraction: f32) {
        if frame.is_none() {
            if let Some(b) = self.bar(node) {
                b.set_position((fraction * 1000.0) as u64);
            }
        }
    }

    fn finished(&self, node: usize, _frame: Option<i64>, status: Status, _seconds: f64) {
        let done = self.finished[node].fetch_add(1, Ordering::Relaxed) + 1;
        let bars = self.bars.lock().expect("bars");
        if let Some(b) = &bars[node] {
            if self.instances[node] > 1 {
                b.inc(1);
                if done >= self.instances[node] {
                    b.finish();
                }
            } else {
                if status == Status::Ran {
                    b.set_position(1000);
                }
                b.finish();
            }
        }
    }
}
