//! Limits on what a graph may ask for, checked when it is loaded (`vfxgraph check`) rather
//! than discovered by a run that fills the disk: the number of node instances (a frame range
//! typed `0..1000000` for `0..100`) and the memory one instance declares it needs (a render
//! at 65536 × 65536). Each refusal gives the figure and the flag that allows it.

use super::Graph;

/// The default bound on a graph's node instances: a 10 000-frame shot of 25 per-frame nodes.
pub const DEFAULT_MAX_INSTANCES: u64 = 250_000;
/// The default bound on one instance's declared memory, in GiB.
pub const DEFAULT_MAX_INSTANCE_GIB: u64 = 64;

/// What a graph may ask for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limits {
    /// Node instances of the whole graph.
    pub max_instances: u64,
    /// Memory one instance declares ([`crate::Memory`]), in GiB.
    pub max_instance_gib: u64,
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            max_instances: DEFAULT_MAX_INSTANCES,
            max_instance_gib: DEFAULT_MAX_INSTANCE_GIB,
        }
    }
}

impl Graph {
    /// `Err` naming the figure, the limit and the flag that raises it when the graph asks for
    /// more than `limits` allow.
    pub fn check_limits(&self, limits: &Limits) -> Result<(), String> {
        let n = self.instance_count() as u64;
        if n > limits.max_instances {
            let per_frame = self.nodes.iter().filter(|g| g.per_frame).count();
            return Err(format!(
                "the graph has {n} node instances ({per_frame} per-frame nodes × {} frames, \
                 and {} others), over the limit of {}; check the frame range, or raise the \
                 limit with --max-instances {n}",
                self.frames.len(),
                self.nodes.len() - per_frame,
                limits.max_instances
            ));
        }
        let limit_mib = limits.max_instance_gib.saturating_mul(1024);
        for node in &self.nodes {
            if let Some(mib) = node.spec().memory.mib(&node.params) {
                if mib > limit_mib {
                    let gib = mib.div_ceil(1024);
                    return Err(format!(
                        "node `{}` ({}) declares {gib} GiB for one instance (its image size), \
                         over the limit of {} GiB; check its size, or raise the limit with \
                         --max-instance-memory {gib}",
                        node.id,
                        node.spec().name,
                        limits.max_instance_gib
                    ));
                }
            }
        }
        Ok(())
    }
}
