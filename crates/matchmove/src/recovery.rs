//! No single point of failure (not in the book, whose solve stops at the first fragment it
//! cannot start): a fragment whose start fails is retried with every frame pair, then split in
//! two halves that share their middle frame; the longest run of solved pieces is what
//! the pipeline (`matchmove`) joins, and the extension stage registers the other frames to its
//! structure. Only a shot no part of which starts is an error ([`no_start_error`]), naming
//! every piece, why it failed, and what to try.

use vfxgraph_geometry::camera::Intrinsics;
use vfxgraph_geometry::error::VisionError;
use vfxgraph_klt::Tracks;

use crate::fragment::{solve_fragment, FragmentSolution};
use crate::fragments;
use crate::fragments::Fragment;
use crate::options::MatchmoveOptions;
use crate::pair::PairOptions;
use crate::structure::derive_seed;

/// A piece of the shot: solved, or the fragment and why it could not be started.
pub(crate) type Piece = std::result::Result<FragmentSolution, (Fragment, VisionError)>;

/// What became of one fragment: its pieces in order (itself, or the halves it was split into),
/// each solved or with the error that stopped it, and the retries taken.
pub(crate) struct Attempt {
    pub(crate) pieces: Vec<Piece>,
    pub(crate) notes: Vec<String>,
}

/// Shortest piece a failing fragment is split into, frames.
const MIN_PIECE_FRAMES: usize = 6;

/// Solves a fragment; a fragment whose start fails is retried with every frame pair (when the
/// options search a stride), then split in two halves that share their middle frame (each
/// solved the same way, down to [`MIN_PIECE_FRAMES`]).
pub(crate) fn solve_with_retries(
    tracks: &Tracks,
    k: &Intrinsics,
    frag: &Fragment,
    options: &MatchmoveOptions,
    seed: u64,
    depth: u64,
) -> Attempt {
    let describe = |f: &Fragment| format!("{}..{}", tracks.frames[f.first], tracks.frames[f.last]);
    let mut notes = Vec::new();
    let first = solve_fragment(tracks, k, frag, &options.pair, &options.refine, seed);
    let err = match first {
        Ok(s) => {
            return Attempt {
                pieces: vec![Ok(s)],
                notes,
            }
        }
        Err(e) => e,
    };
    if matches!(err, VisionError::NoParallax(_)) {
        return Attempt {
            pieces: vec![Err((frag.clone(), err))],
            notes,
        };
    }
    if options.pair.stride > 1 {
        let all = PairOptions {
            stride: 1,
            ..options.pair.clone()
        };
        if let Ok(s) = solve_fragment(tracks, k, frag, &all, &options.refine, seed) {
            notes.push(format!(
                "frames {}: started from every frame pair (the stride of {} found none: {err})",
                describe(frag),
                options.pair.stride
            ));
            return Attempt {
                pieces: vec![Ok(s)],
                notes,
            };
        }
    }
    if frag.len() >= 2 * MIN_PIECE_FRAMES - 1 && depth < 3 {
        let mid = (frag.first + frag.last) / 2;
        let halves = [
            fragments::fragment_of(tracks, frag.first, mid, false),
            fragments::fragment_of(tracks, mid, frag.last, frag.is_last),
        ];
        notes.push(format!(
            "frames {} split at {} ({err})",
            describe(frag),
            tracks.frames[mid]
        ));
        let mut pieces = Vec::new();
        for (h, half) in halves.iter().enumerate() {
            let a = solve_with_retries(
                tracks,
                k,
                half,
                options,
                derive_seed(seed, 20 + h as u64, depth),
                depth + 1,
            );
            pieces.extend(a.pieces);
            notes.extend(a.notes);
        }
        return Attempt { pieces, notes };
    }
    Attempt {
        pieces: vec![Err((frag.clone(), err))],
        notes,
    }
}

/// The longest run (in frames) of consecutive solved pieces, the earliest on ties, as a range
/// of piece indices (empty when no piece was solved).
pub(crate) fn longest_run(pieces: &[Piece]) -> std::ops::Range<usize> {
    let mut best: Option<(usize, usize, usize)> = None; // (frames, start, end)
    let mut i = 0;
    while i < pieces.len() {
        if pieces[i].is_err() {
            i += 1;
            continue;
        }
        let start = i;
        let mut frames = 1;
        while let Some(Ok(s)) = pieces.get(i) {
            frames += s.fragment.len() - 1;
            i += 1;
        }
        if best.is_none_or(|b| frames > b.0) {
            best = Some((frames, start, i));
        }
    }
    best.map_or(0..0, |(_, start, end)| start..end)
}

/// A fragment's error without what names the fragment (`fragment of frames a..b (n
/// features): `), so that pieces failing alike compare equal.
fn same_reason(text: &str) -> String {
    match (text.find("fragment of frames"), text.find("): ")) {
        (Some(i), Some(j)) if j > i => format!("{}{}", &text[..i], &text[j + 3..]),
        _ => text.to_string(),
    }
}

/// The error of a shot no part of which could be started: which frames, why, what to try.
pub(crate) fn no_start_error(tracks: &Tracks, pieces: &[Piece]) -> VisionError {
    // Consecutive pieces that failed for the same reason are one line: a shot of 2-frame
    // tracks would otherwise list every frame.
    let mut groups: Vec<(usize, usize, usize, String, String)> = Vec::new(); // first, last, n, key, text
    for (f, e) in pieces.iter().filter_map(|p| p.as_ref().err()) {
        let text = e.to_string();
        let key = same_reason(&text);
        match groups.last_mut() {
            Some(g) if g.3 == key && g.1 == f.first => {
                g.1 = f.last;
                g.2 += 1;
            }
            _ => groups.push((f.first, f.last, 1, key, text)),
        }
    }
    let reasons: Vec<String> = groups
        .iter()
        .map(|(first, last, n, key, text)| {
            let (a, b) = (tracks.frames[*first], tracks.frames[*last]);
            if *n == 1 {
                format!("frames {a}..{b}: {text}")
            } else {
                format!("frames {a}..{b} ({n} fragments): {key}")
            }
        })
        .collect();
    let all_flat = pieces
        .iter()
        .all(|p| matches!(p, Err((_, VisionError::NoParallax(_)))));
    let advice = if all_flat {
        "the camera shows no parallax anywhere: solve it as a nodal pan (motion solve: tripod), \
         or give a shot whose camera moves"
    } else {
        "track more features (or a longer shot), check that K (or the lens) is right, or lower \
         min_frames so that fragments are shorter"
    };
    let text = format!(
        "no part of the shot could be started — {}; {advice}",
        reasons.join("; ")
    );
    if all_flat {
        VisionError::NoParallax(text)
    } else {
        VisionError::Degenerate(text)
    }
}

#[cfg(test)]
mod tests {
    use super::same_reason;

    #[test]
    fn fragments_failing_alike_have_one_reason() {
        let a = "no parallax: fragment of frames 0..1 (30 features): no frame pair whose \
                 features moved more than 4 px";
        let b = "no parallax: fragment of frames 7..8 (41 features): no frame pair whose \
                 features moved more than 4 px";
        assert_eq!(same_reason(a), same_reason(b));
        assert_eq!(
            same_reason(a),
            "no parallax: no frame pair whose features moved more than 4 px"
        );
        let c = "degenerate: fragment of frames 7..8 (41 features): none of 3 frame pairs gave \
                 a consistent reconstruction";
        assert_ne!(same_reason(a), same_reason(c));
        assert_eq!(same_reason("too few tracks"), "too few tracks");
    }
}
