//! Instances: a graph expanded into one instance per node that runs once and one per frame
//! for a per-frame node, with the instances each reads; and the role of each instance when a
//! run is restricted to some [`Target`]s.

use std::ops::Range;

use super::{ExecError, Target};
use crate::graph::{Edge, Graph};

/// Where an input's value comes from.
#[derive(Clone, Debug)]
pub(super) enum DepKind {
    /// One instance.
    One(usize),
    /// A whole sequence: these instances, in frame order.
    Seq(Range<usize>),
}

/// An input of an instance.
#[derive(Clone, Debug)]
pub(super) struct Dep {
    pub(super) port: &'static str,
    pub(super) from_port: &'static str,
    pub(super) kind: DepKind,
}

/// One instance of a node.
#[derive(Clone, Debug)]
pub(super) struct Inst {
    pub(super) node: usize,
    pub(super) frame: Option<i64>,
    pub(super) deps: Vec<Dep>,
    /// Distinct instances this one reads.
    pub(super) upstream: Vec<usize>,
    /// Distinct instances that read this one.
    pub(super) downstream: Vec<usize>,
}

/// What a run does with an instance.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Role {
    /// Served from the cache or computed.
    Compute,
    /// An input of a selected instance: served from the cache only.
    CacheOnly,
    /// Not selected and not read by a selected instance: not visited.
    Unneeded,
}

/// ` frame F` for a per-frame instance, nothing for one that runs once (used in reasons).
pub(super) fn frame_suffix(frame: Option<i64>) -> String {
    frame.map(|f| format!(" frame {f}")).unwrap_or_default()
}

/// The role of each instance for a selection (`None`: everything computes).
pub(super) fn roles(
    graph: &Graph,
    insts: &[Inst],
    only: Option<&[Target]>,
) -> Result<Vec<Role>, ExecError> {
    let Some(targets) = only else {
        return Ok(vec![Role::Compute; insts.len()]);
    };
    let mut role = vec![Role::Unneeded; insts.len()];
    for t in targets {
        select_target(graph, insts, t, &mut role)?;
    }
    // An instance's upstream comes before it in `insts`: one backward pass closes the set.
    for i in (0..insts.len()).rev() {
        if role[i] != Role::Unneeded {
            for &u in &insts[i].upstream {
                if role[u] == Role::Unneeded {
                    role[u] = Role::CacheOnly;
                }
            }
        }
    }
    Ok(role)
}

/// Marks the instances target `t` selects as [`Role::Compute`].
fn select_target(
    graph: &Graph,
    insts: &[Inst],
    t: &Target,
    role: &mut [Role],
) -> Result<(), ExecError> {
    let node = graph
        .index_of(&t.node)
        .ok_or_else(|| ExecError::UnknownNode(t.node.clone()))?;
    let frames = check_target_frames(graph, node, t)?;
    for (i, inst) in insts.iter().enumerate().filter(|(_, x)| x.node == node) {
        if frames
            .as_ref()
            .is_none_or(|fs| inst.frame.is_some_and(|f| fs.contains(&f)))
        {
            role[i] = Role::Compute;
        }
    }
    Ok(())
}

/// A target's frames, checked against the node's mode and the graph's frames.
pub(super) fn check_target_frames(
    graph: &Graph,
    node: usize,
    t: &Target,
) -> Result<Option<Vec<i64>>, ExecError> {
    let Some(frames) = &t.frames else {
        return Ok(None);
    };
    if !graph.nodes[node].per_frame {
        return Err(ExecError::NotPerFrame(t.node.clone()));
    }
    if let Some(&frame) = frames.iter().find(|f| !graph.frames.frames().contains(f)) {
        return Err(ExecError::FrameOutOfRange {
            node: t.node.clone(),
            frame,
            range: graph.frames.to_string(),
        });
    }
    Ok(Some(frames.clone()))
}

/// The instances of `graph` in graph order (a node's instances in frame order), and the range
/// of instances of each node.
pub(super) fn expand(graph: &Graph) -> (Vec<Inst>, Vec<Range<usize>>) {
    let frames = graph.frames.frames();
    let mut ranges = Vec::with_capacity(graph.nodes.len());
    let mut insts: Vec<Inst> = Vec::new();
    for (n, node) in graph.nodes.iter().enumerate() {
        let start = insts.len();
        let frame_list: Vec<Option<i64>> = if node.per_frame {
            frames.iter().map(|&f| Some(f)).collect()
        } else {
            vec![None]
        };
        for (fi, frame) in frame_list.into_iter().enumerate() {
            let deps: Vec<Dep> = node
                .inputs
                .iter()
                .map(|e| dep_of(graph, &ranges, e, fi))
                .collect();
            insts.push(Inst {
                node: n,
                frame,
                upstream: upstream_of(&deps),
                deps,
                downstream: Vec::new(),
            });
        }
        ranges.push(start..insts.len());
    }
    link_downstream(&mut insts);
    (insts, ranges)
}

/// The dependency of the `fi`-th instance of a node on its input edge `e`.
fn dep_of(graph: &Graph, ranges: &[Range<usize>], e: &Edge, fi: usize) -> Dep {
    let r: &Range<usize> = &ranges[e.from];
    let kind = if e.whole_sequence {
        DepKind::Seq(r.clone())
    } else if graph.nodes[e.from].per_frame {
        DepKind::One(r.start + fi)
    } else {
        DepKind::One(r.start)
    };
    Dep {
        port: e.port,
        from_port: e.from_port,
        kind,
    }
}

/// The distinct instances `deps` read, sorted.
fn upstream_of(deps: &[Dep]) -> Vec<usize> {
    let mut upstream: Vec<usize> = deps
        .iter()
        .flat_map(|d| match &d.kind {
            DepKind::One(i) => *i..*i + 1,
            DepKind::Seq(r) => r.clone(),
        })
        .collect();
    upstream.sort_unstable();
    upstream.dedup();
    upstream
}

/// Fills each instance's `downstream` from the others' `upstream`.
fn link_downstream(insts: &mut [Inst]) {
    for i in 0..insts.len() {
        for k in 0..insts[i].upstream.len() {
            let u = insts[i].upstream[k];
            insts[u].downstream.push(i);
        }
    }
}
