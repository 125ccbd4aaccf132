//! Per-frame resolution: in topological order, whether each node runs once or per frame — by
//! its type's mode, its `per_frame:` key, or (either-mode nodes) inferred from its inputs and
//! frame-pattern paths — with each node's input types checked as soon as it is resolved.

use super::edges::{self, Edges};
use super::nodes::Raw;
use crate::diagnostic::{Diagnostics, ErrorKind, Span};
use crate::frames::FrameSet;
use crate::node::{has_frame_pattern, Mode, NodeSpec};
use crate::param::{Kind, ParamValue};

/// Per node: whether it runs per frame (nodes without a type or on a cycle: false).
pub(super) fn resolve(
    raws: &[Raw],
    edges: &Edges,
    order: &[usize],
    cyclic: &[bool],
    frames: &FrameSet,
    d: &mut Diagnostics,
) -> Vec<bool> {
    let mut per_frame = vec![false; raws.len()];
    for &i in order {
        let raw = &raws[i];
        let Some(node) = &raw.node else { continue };
        if cyclic[i] {
            continue;
        }
        let spec = node.spec();
        let inferred = inferred(raw, spec, edges, &per_frame, i);
        per_frame[i] = by_mode(spec, raw.per_frame, inferred, d);
        edges::check_types(raws, edges, &per_frame, i, spec, d);
        if per_frame[i] && frames.is_empty() && !d.items.iter().any(|x| x.kind == ErrorKind::Frames)
        {
            d.push(
                ErrorKind::Frames,
                Some(raw.id_span),
                format!(
                    "node `{}` runs per frame, but the graph has no `frames:` range",
                    raw.id
                ),
            );
        }
    }
    per_frame
}

/// Either-mode nodes run per frame when fed one frame of a sequence, or when a path
/// parameter holds a frame pattern (`%04d`, `####`).
fn inferred(raw: &Raw, spec: &NodeSpec, edges: &Edges, per_frame: &[bool], i: usize) -> bool {
    edges[i]
        .iter()
        .any(|(e, _)| !e.whole_sequence && per_frame[e.from]) || spec.params.iter().any(|p| {
        matches!(p.kind, Kind::Path(_))
            && matches!(raw.params.get(p.name), Some(ParamValue::Str(s)) if has_frame_pattern(s))
    })
}

/// Whether a node of type `spec` runs per frame, given its `per_frame:` key (a key its mode
/// contradicts is reported) and what its inputs imply.
fn by_mode(
    spec: &NodeSpec,
    written: Option<(bool, Span)>,
    inferred: bool,
    d: &mut Diagnostics,
) -> bool {
    match (spec.mode, written) {
        (Mode::Once, Some((true, sp))) => {
            d.push(
                ErrorKind::Structure,
                Some(sp),
                format!("node type `{}` cannot run per frame", spec.name),
            );
            false
        }
        (Mode::PerFrame, Some((false, sp))) => {
            d.push(
                ErrorKind::Structure,
                Some(sp),
                format!("node type `{}` always runs per frame", spec.name),
            );
            true
        }
        (Mode::Once, _) => false,
        (Mode::PerFrame, _) => true,
        (Mode::Either, Some((b, _))) => b,
        (Mode::Either, None) => inferred,
    }
}
