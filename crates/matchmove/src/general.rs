//! A moving camera with its lens solved (an addition to the book, whose K is known, §7.1): the
//! solve that Blender's and libmv's camera solvers use — the lens refined by the bundle
//! adjustment together with the cameras — organised around the book's pinhole pipeline.
//!
//! **Rounds** ([`general_with_lens`]) of: undistort the tracks with the current lens
//! ([`crate::lens::undistort_tracks`]), solve them with the book's pinhole matchmove
//! ([`crate::pipeline::matchmove`]), then a global bundle adjustment of the *original*
//! (distorted) observations in which the shared block `[f, k1, k2]`
//! ([`vfxgraph_bundle::CameraModel::Radial`]) is free with every camera and point
//! ([`crate::global`] with a free lens). The rounds start from the focal length of the search
//! ([`crate::focal`]) when it is unknown; the second round starts from a lens close to the
//! truth, so its fragments are solved as well as a known-K shot's. When the search found a
//! second minimum nearly as good, the rounds run from it too and the better fit of the whole
//! shot is kept (a warning when they fit alike).

use vfxgraph_geometry::camera::Intrinsics;
use vfxgraph_geometry::error::{Result, VisionError};
use vfxgraph_klt::Tracks;

use crate::focal::{
    focal_search, truncated_cost, FOCAL_AMBIGUITY_RATIO, FOCAL_DISTINCT, FOCAL_FLAT_RATIO,
    MAX_FOCAL_STARTS,
};
use crate::lens::{undistort_tracks, FocalMode, LensOptions};
use crate::options::MatchmoveOptions;
use crate::pipeline::{matchmove, Solve};

/// [`matchmove_with_lens`] of a moving camera.
pub(crate) fn general_with_lens(
    tracks: &Tracks,
    k: Intrinsics,
    held: crate::adjust::Held,
    lens: &LensOptions,
    options: &MatchmoveOptions,
    progress: &(dyn Fn(&str, usize, usize) + Sync),
) -> Result<Solve> {
    if !lens.solves_lens() {
        if k.is_pinhole() {
            // The book's case: no copy of the tracks.
            return matchmove(tracks, &k, options, progress);
        }
        let und = undistort_tracks(tracks, &k)?;
        let mut solve = matchmove(&und, &k.pinhole(), options, progress)?;
        solve.path.intrinsics = Some(k);
        return Ok(solve);
    }
    let Some(global) = &options.global else {
        return Err(VisionError::InvalidInput(
            "solving the lens needs the global bundle adjustment (global_adjust: true)".into(),
        ));
    };
    let mut notes = Vec::new();
    let mut stages = Vec::new();
    let mut starts = vec![k.clone()];
    let mut search = None;
    if lens.focal == FocalMode::Unknown {
        let t0 = std::time::Instant::now();
        let found = focal_search(tracks, &k, options)?;
        stages.push(crate::report::StageTime::new("focal estimate", t0));
        notes.push(format!(
            "initial focal length {:.1} px from the tracks (the search's cost ×{:.3} at half \
             and double it)",
            found.focal, found.determinacy
        ));
        starts = std::iter::once(found.focal)
            .chain(found.others.iter().copied().take(MAX_FOCAL_STARTS - 1))
            .map(|f| Intrinsics {
                f1: f,
                f2: f * k.f2 / k.f1,
                ..k.clone()
            })
            .collect();
        search = Some(found);
    }
    // The rounds from every start; the one that fits the whole shot best is kept.
    let mut finished: Vec<(Solve, f64)> = Vec::new();
    for (i, k0) in starts.iter().enumerate() {
        let mut st = Vec::new();
        let mut nt = Vec::new();
        let r = lens_rounds(
            tracks,
            k0.clone(),
            held,
            lens,
            global,
            options,
            progress,
            &mut st,
            &mut nt,
        );
        match r {
            Ok(mut out) => {
                out.report.stages = stages.iter().cloned().chain(st).collect();
                out.report.notes.extend(notes.iter().cloned());
                out.report.notes.extend(nt);
                // The fit of the whole shot, to choose between starts (one start: no choice).
                let c = if starts.len() > 1 {
                    let lens = out.path.intrinsics.as_ref().unwrap_or(k0);
                    truncated_cost(&undistort_tracks(tracks, lens)?, &out.report)
                } else {
                    0.0
                };
                finished.push((out, c));
            }
            Err(e) if i == 0 && starts.len() == 1 => return Err(e),
            Err(_) => {}
        }
    }
    finished.sort_by(|a, b| a.1.total_cmp(&b.1));
    let mut it = finished.into_iter();
    let Some((mut out, cost)) = it.next() else {
        return Err(VisionError::Degenerate(
            "the lens rounds failed from every focal length the search found".into(),
        ));
    };
    let f = out.path.intrinsics.as_ref().map_or(k.f1, |k| k.f1);
    let mut reasons = Vec::new();
    for (other, c) in it {
        let f2 = other.path.intrinsics.as_ref().map_or(k.f1, |k| k.f1);
        out.report.notes.push(format!(
            "from the search's other minimum: focal {f2:.1} px, cost {c:.4} px (kept: {f:.1} \
             px, {cost:.4} px)"
        ));
        if c <= cost * FOCAL_AMBIGUITY_RATIO && (f2 / f).ln().abs() > FOCAL_DISTINCT.ln_1p() {
            reasons.push(format!(
                "{f2:.0} px fits the tracks as well ({c:.3} px against {cost:.3} px)"
            ));
        }
    }
    if let Some(search) = &search {
        if search.determinacy < FOCAL_FLAT_RATIO {
            reasons.push(format!(
                "its search fits half and double it within {:.1} %",
                100.0 * (search.determinacy - 1.0)
            ));
        }
        if search.at_edge {
            reasons.push(format!(
                "its search's best lies at the end of its range ({:.0} to {:.0} px)",
                search.range[0], search.range[1]
            ));
        }
    }
    warn_undetermined_focal(&mut out.report, reasons);
    Ok(out)
}

/// The rounds of the lens solve (module docs, step 2) from the intrinsics `k`: the pinhole
/// matchmove of the tracks undistorted by the current lens, then the global adjustment with
/// the lens free; the solve of the last round with the solved intrinsics.
#[allow(clippy::too_many_arguments)]
fn lens_rounds(
    tracks: &Tracks,
    mut k: Intrinsics,
    held: crate::adjust::Held,
    lens: &LensOptions,
    global: &crate::global::GlobalOptions,
    options: &MatchmoveOptions,
    progress: &(dyn Fn(&str, usize, usize) + Sync),
    stages: &mut Vec<crate::report::StageTime>,
    notes: &mut Vec<String>,
) -> Result<Solve> {
    // The rounds' lens adjustment replaces the pinhole matchmove's own global adjustment.
    let inner = MatchmoveOptions {
        global: None,
        score: false,
        ..options.clone()
    };
    let mut solve = None;
    let mut cov = None;
    for round in 0..lens.lens_rounds {
        let t0 = std::time::Instant::now();
        let und = undistort_tracks(tracks, &k)?;
        let s = matchmove(&und, &k.pinhole(), &inner, progress)?;
        stages.push(crate::report::StageTime::new(
            &format!("round {}: pinhole solve", round + 1),
            t0,
        ));
        let t0 = std::time::Instant::now();
        let poses = crate::structure::poses_by_index(&und, &s.path);
        let (poses, points, k_new, c) =
            crate::global::global_lens_adjust(tracks, &k, &poses, global, held)?;
        cov = c;
        stages.push(crate::report::StageTime::new(
            &format!("round {}: lens adjustment", round + 1),
            t0,
        ));
        notes.push(format!(
            "round {}: focal {:.2} px, {:?}",
            round + 1,
            k_new.f1,
            k_new.distortion
        ));
        k_new
            .validate()
            .map_err(|e| VisionError::Degenerate(format!("the solved lens is not usable: {e}")))?;
        k = k_new;
        solve = Some((poses, points, s));
    }
    let (poses, points, s) = solve.expect("at least one round");
    let und = undistort_tracks(tracks, &k)?;
    let mut out = crate::pipeline::finish_solve(
        &und,
        &k.pinhole(),
        &poses,
        &points,
        global.final_threshold(),
        Vec::new(),
        options.score,
    )?;
    if !held[0] {
        out.report.with_free_focal_sd(
            &und,
            &k.pinhole(),
            &poses,
            &points,
            global.final_threshold(),
        );
    }
    out.report.notes = s.report.notes;
    out.report.fragments = s.report.fragments;
    out.report.intrinsics = crate::adjust::solved_intrinsics(&k, held, cov.as_ref());
    if let Some(Err(why)) = &cov {
        out.report
            .notes
            .push(format!("no standard deviations of the intrinsics: {why}"));
    }
    out.path.intrinsics = Some(k);
    Ok(out)
}

/// A solved focal length whose standard deviation exceeds this fraction of it is not
/// determined by the shot (a warning).
pub const FOCAL_SD_WARNING: f64 = 0.05;

/// The reasons the solve's focal length is not determined by the shot, as one warning (none
/// when there is none): its standard deviation over [`FOCAL_SD_WARNING`], and `more` (the
/// search's flat profile, a second focal length that fits as well, a best at the edge of the
/// search). A camera that travels without turning (a dolly, a truck, a push) is a critical
/// motion for self-calibration (Sturm 1997; Kahl, Triggs & Åström 2000), and a plane seen from
/// two mirror-image viewpoints fits two focal lengths: the tracks fit a wide range of focal
/// lengths, and the cameras of a wrong one are wrong too.
fn warn_undetermined_focal(report: &mut crate::report::SolveReport, mut more: Vec<String>) {
    let Some(f) = report
        .intrinsics
        .iter()
        .find(|i| i.name == "focal_px" && !i.held)
    else {
        return;
    };
    if let Some(sd) = f.sd.filter(|sd| !(*sd <= FOCAL_SD_WARNING * f.value)) {
        more.insert(
            0,
            format!(
                "its standard deviation is {sd:.0} px ({:.0} %)",
                100.0 * sd / f.value
            ),
        );
    }
    if more.is_empty() {
        return;
    }
    report.warnings.push(format!(
        "the focal length ({:.0} px) is not determined by the shot: {}; a camera that travels \
         without turning, or a plane seen from a symmetric viewpoint, fits many focal lengths, \
         and the cameras of a wrong one are wrong too: give the focal length (focal: known or \
         refine)",
        f.value,
        more.join("; ")
    ));
}
