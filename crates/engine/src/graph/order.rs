//! Order: cycles reported (Kosaraju's strongly connected components, iterative: a chain of
//! 100 000 nodes must not overflow the stack), a topological order that
//! keeps the file's order where dependencies allow, and the checked nodes built in it.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use petgraph::algo::kosaraju_scc;
use petgraph::graphmap::DiGraphMap;

use super::edges::Edges;
use super::nodes::Raw;
use super::{Edge, GraphNode};
use crate::diagnostic::{Diagnostics, ErrorKind};
use crate::param::Params;

/// Reports each cycle (a strongly connected component of several nodes, or a node reading
/// itself); returns, per node, whether it is on one.
pub(super) fn find_cycles(raws: &[Raw], edges: &Edges, d: &mut Diagnostics) -> Vec<bool> {
    let mut g: DiGraphMap<usize, ()> = DiGraphMap::new();
    for i in 0..raws.len() {
        g.add_node(i);
    }
    for (i, es) in edges.iter().enumerate() {
        for (e, _) in es {
            g.add_edge(e.from, i, ());
        }
    }
    let mut cycles: Vec<Vec<usize>> = kosaraju_scc(&g)
        .into_iter()
        .filter(|scc| scc.len() > 1 || g.contains_edge(scc[0], scc[0]))
        .map(|mut scc| {
            scc.sort_unstable();
            scc
        })
        .collect();
    // Reported in the file's order, whatever order the components were found in.
    cycles.sort_unstable();
    let mut cyclic = vec![false; raws.len()];
    for members in &cycles {
        for &m in members {
            cyclic[m] = true;
        }
        report_cycle(raws, edges, members, d);
    }
    cyclic
}

/// Reports the cycle through `members` (sorted), at its first member's edge into the cycle.
fn report_cycle(raws: &[Raw], edges: &Edges, members: &[usize], d: &mut Diagnostics) {
    let names: Vec<&str> = members.iter().map(|&m| raws[m].id.as_str()).collect();
    let first = members[0];
    let span = edges[first]
        .iter()
        .find(|(e, _)| members.contains(&e.from))
        .map(|(_, s)| *s)
        .unwrap_or(raws[first].id_span);
    d.push(
        ErrorKind::Cycle,
        Some(span),
        format!("the graph has a cycle through nodes {}", names.join(" → ")),
    );
}

/// A topological order that keeps the file's order where dependencies allow (Kahn's
/// algorithm, always taking the earliest-declared ready node); nodes on cycles go last.
pub(super) fn topological(edges: &Edges, cyclic: &[bool]) -> Vec<usize> {
    let n = edges.len();
    let mut indegree = vec![0usize; n];
    let mut consumers: Vec<Vec<usize>> = vec![Vec::new(); n];
    for (i, es) in edges.iter().enumerate() {
        for (e, _) in es {
            indegree[i] += 1;
            consumers[e.from].push(i);
        }
    }
    let mut ready: BinaryHeap<Reverse<usize>> =
        (0..n).filter(|&i| indegree[i] == 0).map(Reverse).collect();
    let mut order = Vec::with_capacity(n);
    while let Some(Reverse(i)) = ready.pop() {
        order.push(i);
        for &c in &consumers[i] {
            indegree[c] -= 1;
            if indegree[c] == 0 {
                ready.push(Reverse(c));
            }
        }
    }
    order.extend((0..n).filter(|&i| cyclic[i]));
    order
}

/// The checked nodes of a valid graph in `order`, their edges renumbered to it and sorted by
/// port.
pub(super) fn checked_nodes(
    raws: &[Raw],
    edges: &Edges,
    order: &[usize],
    per_frame: &[bool],
) -> Vec<GraphNode> {
    let mut new_index = vec![0usize; raws.len()];
    for (pos, &i) in order.iter().enumerate() {
        new_index[i] = pos;
    }
    let mut nodes = Vec::with_capacity(raws.len());
    for &i in order {
        let raw = &raws[i];
        let mut inputs: Vec<Edge> = edges[i]
            .iter()
            .map(|(e, _)| Edge {
                from: new_index[e.from],
                ..e.clone()
            })
            .collect();
        inputs.sort_by_key(|e| e.port);
        nodes.push(GraphNode {
            id: raw.id.clone(),
            node: raw.node.clone().expect("valid graph"),
            params: Params::new(raw.params.clone()),
            per_frame: per_frame[i],
            inputs,
            span: raw.id_span,
        });
    }
    nodes
}
