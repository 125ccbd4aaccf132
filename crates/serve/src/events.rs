//! The engine [`Observer`] of a served run: each callback updates the studio's live counts
//! and publishes one event (`started`, `progress`, `finished`) to every open page. Events are
//! stamped with the time the engine reported them, so the page can measure how long an event
//! takes to reach its DOM.

use std::sync::Mutex;
use std::time::{Duration, Instant};

use serde_json::json;
use vfxgraph_engine::{Graph, Observer, Status};

use crate::studio::Studio;

/// Progress of one instance is published at most this often (the last value always arrives
/// with `finished`).
const PROGRESS_EVERY: Duration = Duration::from_millis(50);

/// Publishes a run's engine events.
pub struct Publisher<'a> {
    studio: &'a Studio,
    ids: Vec<String>,
    last_progress: Mutex<Vec<Option<Instant>>>,
}

impl<'a> Publisher<'a> {
    /// For a run of `graph`.
    pub fn new(studio: &'a Studio, graph: &Graph) -> Self {
        Publisher {
            studio,
            ids: graph.nodes.iter().map(|n| n.id.clone()).collect(),
            last_progress: Mutex::new(vec![None; graph.nodes.len()]),
        }
    }
}

fn status_name(s: Status) -> &'static str {
    match s {
        Status::Cached => "cached",
        Status::Ran => "ran",
        Status::Failed => "failed",
        Status::Skipped => "skipped",
    }
}

impl Observer for Publisher<'_> {
    fn started(&self, node: usize, frame: Option<i64>) {
        let id = &self.ids[node];
        self.studio.update_live(id, |l| l.running += 1);
        self.studio
            .publish("started", json!({ "node": id, "frame": frame }));
    }

    fn progress(&self, node: usize, frame: Option<i64>, fraction: f32) {
        {
            let mut last = self.last_progress.lock().unwrap_or_else(|p| p.into_inner());
            let now = Instant::now();
            if last[node].is_some_and(|t| now - t < PROGRESS_EVERY) {
                return;
            }
            last[node] = Some(now);
        }
        let id = &self.ids[node];
        if frame.is_none() {
            self.studio.update_live(id, |l| l.progress = fraction);
        }
        self.studio.publish(
            "progress",
            json!({ "node": id, "frame": frame, "fraction": fraction }),
        );
    }

    fn finished(&self, node: usize, frame: Option<i64>, status: Status, seconds: f64) {
        let id = &self.ids[node];
        self.studio.update_live(id, |l| {
            match status {
                Status::Cached => l.cached += 1,
                Status::Ran => {
                    l.running = l.running.saturating_sub(1);
                    l.ran += 1;
                }
                Status::Failed => {
                    l.running = l.running.saturating_sub(1);
                    l.failed += 1;
                }
                Status::Skipped => l.skipped += 1,
            }
            if status == Status::Ran && frame.is_none() {
                l.progress = 1.0;
            }
        });
        self.studio.publish(
            "finished",
            json!({ "node": id, "frame": frame, "status": status_name(status), "seconds": seconds }),
        );
    }
}
