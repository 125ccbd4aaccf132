//! Progress bars (indicatif): one per node that computes, created when it starts.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::Duration;

use indicatif::{MultiProgress, ProgressBar, ProgressDrawTarget, ProgressStyle};
use vfxgraph_engine::{Graph, Observer, Status};

/// Draws bars on stderr (nothing when stderr is not a terminal, or when quiet).
pub struct Bars {
    multi: MultiProgress,
    names: Vec<String>,
    instances: Vec<usize>,
    finished: Vec<AtomicUsize>,
    bars: Mutex<Vec<Option<ProgressBar>>>,
}

impl Bars {
    pub fn new(g: &Graph, quiet: bool) -> Self {
        let target = if quiet {
            ProgressDrawTarget::hidden()
        } else {
            ProgressDrawTarget::stderr()
        };
        Bars {
            multi: MultiProgress::with_draw_target(target),
            names: g.nodes.iter().map(|n| n.id.clone()).collect(),
            instances: g.nodes.iter().map(|n| g.instances_of(n)).collect(),
            finished: g.nodes.iter().map(|_| AtomicUsize::new(0)).collect(),
            bars: Mutex::new(vec![None; g.nodes.len()]),
        }
    }

    pub fn finish(&self) {
        for b in self.bars.lock().expect("bars").iter().flatten() {
            b.finish();
        }
        let _ = self.multi.clear();
    }

    /// Once-nodes measure progress in thousandths; per-frame nodes in instances.
    fn bar(&self, node: usize) -> ProgressBar {
        let mut bars = self.bars.lock().expect("bars");
        if let Some(b) = &bars[node] {
            return b.clone();
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
        b.enable_steady_tick(Duration::from_millis(200));
        bars[node] = Some(b.clone());
        b
    }
}

impl Observer for Bars {
    fn started(&self, node: usize, _frame: Option<i64>) {
        self.bar(node);
    }

    fn progress(&self, node: usize, frame: Option<i64>, fraction: f32) {
        if frame.is_none() {
            self.bar(node).set_position((fraction * 1000.0) as u64);
        }
    }

    fn finished(&self, node: usize, _frame: Option<i64>, status: Status, _seconds: f64) {
        self.finished[node].fetch_add(1, Ordering::Relaxed);
        let bars = self.bars.lock().expect("bars");
        if let Some(b) = &bars[node] {
            if self.instances[node] > 1 {
                b.inc(1);
            } else if status == Status::Ran {
                b.set_position(1000);
            }
        }
    }
}
