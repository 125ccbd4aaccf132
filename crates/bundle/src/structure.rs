//! The fixed block structure of a bundle-adjustment problem, built once per solve
//! ([`Structure::new`]): the camera-side parameter blocks of the reduced camera system (the
//! "f-blocks": poses and free intrinsics, a shared intrinsics block numbered last), the
//! observations sorted by point, and the upper block pattern of the Schur complement S with
//! the groups of block rows its assembly ([`crate::schur`]) works through.

use rayon::prelude::*;

use super::camera_model::INTRINSICS;
use super::problem::Problem;
use super::residual::CAMERA_COLUMNS as CC;

pub(crate) const NONE: u32 = u32::MAX;

/// What a reduced (camera-side) block parameterises: some of the [`CC`] local camera columns
/// `[ω, t, k]` of its observations. A camera's pose and its own (unshared) free intrinsics form
/// one block of up to 6 + 7 parameters; an intrinsics block shared by several cameras is a
/// block of its own (columns 6.. of its model's parameters).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct FBlock {
    /// The camera whose pose (and exclusive intrinsics) this block holds.
    pub camera: Option<usize>,
    /// The intrinsics block updated by columns 6.. of this block, if any.
    pub intrinsics: Option<usize>,
}

/// Consecutive block rows `rows` of S and the points (ascending) observed in any of them.
/// A group streams through its points' observations in memory order, so the Schur assembly
/// reads the per-observation data sequentially instead of jumping from point to point.
pub(crate) struct RowGroup {
    pub(crate) rows: std::ops::Range<usize>,
    pub(crate) points: Vec<u32>,
}

/// Number of row groups (fixed, so the work split never depends on the thread count; the
/// order of the sums inside each block does not depend on it either).
pub(crate) const ROW_GROUPS: usize = 64;

/// The fixed block structure of a problem (built once per solve).
pub(crate) struct Structure {
    pub fblocks: Vec<FBlock>,
    pub fblock_dim: Vec<usize>,
    pub fblock_offset: Vec<usize>,
    /// Local camera columns (0..[`CC`]) of each f-block's parameters, `fblock_dim` of them.
    pub fblock_cols: Vec<[u8; CC]>,
    /// Components of each f-block held constant by the gauge.
    pub fblock_mask: Vec<[bool; CC]>,
    /// Camera columns any observation uses: 6 + the largest intrinsics block's parameters
    /// (9 for the pinhole and BAL models, whose Jacobians then cost what they did before the
    /// lens blocks).
    pub columns: usize,
    pub n_reduced: usize,
    /// Internal observation order → index in `Problem::observations`. Observations are
    /// processed sorted by point so that the partners of an observation are contiguous in
    /// memory (the Schur assembly reads them once per pair).
    pub perm: Vec<u32>,
    /// Per observation (internal order): its camera's f-block and its shared-intrinsics f-block (NONE if absent).
    pub obs_fb: Vec<[u32; 2]>,
    pub point_free: Vec<bool>,
    /// Point of each observation.
    pub obs_point: Vec<u32>,
    pub(crate) point_ptr: Vec<usize>,
    pub(crate) point_obs: Vec<u32>,
    /// True when the camera f-blocks come first in camera order and at most one shared
    /// intrinsics block follows them: observations of a point being sorted by camera, only the
    /// partners from an observation onwards can land in a camera block of the upper triangle of
    /// its row (the shared column is assembled point-wise, see [`Structure::shared`]).
    pub(crate) monotone: bool,
    /// The f-block of the intrinsics block shared by every camera, numbered last, whose column
    /// of S is assembled point-wise (module docs); `None` otherwise.
    pub(crate) shared: Option<usize>,
    /// Per observation: the first observation of its point in the same camera (duplicated
    /// observations of a point in one camera must all pair with each other).
    pub(crate) upper_start: Vec<u32>,
    pub(crate) row_ptr: Vec<usize>,
    pub(crate) row_obs: Vec<u32>,
    /// Groups of consecutive block rows assembled by one task, with the points they touch.
    pub(crate) groups: Vec<RowGroup>,
    /// Assemble row by row instead of by groups (the reference path, for tests).
    #[cfg(test)]
    pub rowwise: bool,
    /// Upper block pattern: for each row, its column blocks (sorted) and value offsets.
    pub row_cols: Vec<Vec<u32>>,
    pub row_val_offset: Vec<Vec<usize>>,
    /// Start of each row's values in the flat value array, and its total length.
    pub row_start: Vec<usize>,
    pub n_values: usize,
    /// Per prior of the problem ([`super::Prior`]), per term: the f-block and local column it
    /// moves, `None` for a held parameter or a fixed block (the term is constant).
    pub prior_cols: Vec<Vec<Option<(usize, usize)>>>,
    /// Per prior, its terms' coefficients (the constant Jacobian).
    pub prior_coefficients: Vec<Vec<f64>>,
}

impl Structure {
    /// Builds the f-block numbering, the incidence lists and the pattern of S.
    pub fn new(problem: &Problem) -> Structure {
        let masks = problem.pose_masks();
        let mut users = vec![0usize; problem.intrinsics.len()];
        for c in &problem.cameras {
            users[c.intrinsics] += 1;
        }
        let mut fblocks = Vec::new();
        let mut fblock_dim = Vec::new();
        let mut fblock_cols = Vec::new();
        let mut fblock_mask = Vec::new();
        let mut cam_fb = vec![NONE; problem.cameras.len()];
        let mut shared_fb = vec![NONE; problem.intrinsics.len()];
        for (i, c) in problem.cameras.iter().enumerate() {
            let k = c.intrinsics;
            let intr_free = !problem.intrinsics[k].fixed;
            let mut cols = [0u8; CC];
            let mut mask = [false; CC];
            let mut d = 0;
            if !c.fixed && masks[i].iter().any(|m| !m) {
                for u in 0..6 {
                    cols[d] = u as u8;
                    mask[d] = masks[i][u];
                    d += 1;
                }
            }
            let exclusive = intr_free && users[k] == 1;
            if exclusive {
                for u in 0..problem.intrinsics[k].num_params() {
                    cols[d] = (6 + u) as u8;
                    mask[d] = problem.intrinsics[k].held[u];
                    d += 1;
                }
            }
            if d > 0 {
                cam_fb[i] = fblocks.len() as u32;
                fblocks.push(FBlock {
                    camera: Some(i),
                    intrinsics: exclusive.then_some(k),
                });
                fblock_dim.push(d);
                fblock_cols.push(cols);
                fblock_mask.push(mask);
            }
        }
        // Shared intrinsics blocks after every camera block (in order of first use).
        for c in &problem.cameras {
            let k = c.intrinsics;
            if !problem.intrinsics[k].fixed && users[k] > 1 && shared_fb[k] == NONE {
                shared_fb[k] = fblocks.len() as u32;
                fblocks.push(FBlock {
                    camera: None,
                    intrinsics: Some(k),
                });
                let n = problem.intrinsics[k].num_params();
                let (mut cols, mut mask) = ([0u8; CC], [false; CC]);
                for u in 0..n {
                    cols[u] = (6 + u) as u8;
                    mask[u] = problem.intrinsics[k].held[u];
                }
                fblock_dim.push(n);
                fblock_cols.push(cols);
                fblock_mask.push(mask);
            }
        }
        let n_shared = fblocks.iter().filter(|b| b.camera.is_none()).count();
        // The point-wise column needs every observation to carry the one shared block.
        let shared = match problem.cameras.first() {
            Some(c0)
                if n_shared == 1
                    && problem
                        .cameras
                        .iter()
                        .all(|c| c.intrinsics == c0.intrinsics) =>
            {
                Some(shared_fb[c0.intrinsics] as usize)
            }
            _ => None,
        };
        let mut fblock_offset = Vec::with_capacity(fblocks.len());
        let mut n_reduced = 0;
        for d in &fblock_dim {
            fblock_offset.push(n_reduced);
            n_reduced += d;
        }
        // Point-major order: bucket by point (stable), then by camera within each point.
        let (by_point_ptr, mut perm) = csr(
            problem.points.len(),
            problem
                .observations
                .iter()
                .enumerate()
                .map(|(i, o)| (o.point, i as u32)),
        );
        for w in by_point_ptr.windows(2) {
            perm[w[0]..w[1]].sort_by_key(|&i| problem.observations[i as usize].camera);
        }
        let obs = |k: &u32| &problem.observations[*k as usize];
        let obs_fb: Vec<[u32; 2]> = perm
            .iter()
            .map(obs)
            .map(|o| {
                let c = &problem.cameras[o.camera];
                [cam_fb[o.camera], shared_fb[c.intrinsics]]
            })
            .collect();
        let point_free: Vec<bool> = problem.points.iter().map(|p| !p.fixed).collect();

        let (point_ptr, point_obs) = csr(
            problem.points.len(),
            perm.iter()
                .map(obs)
                .enumerate()
                .map(|(i, o)| (o.point, i as u32)),
        );
        let (row_ptr, row_obs) = csr(
            fblocks.len(),
            obs_fb.iter().enumerate().flat_map(|(i, fb)| {
                fb.iter()
                    .filter(|b| **b != NONE)
                    .map(move |b| (*b as usize, i as u32))
            }),
        );

        let mut upper_start: Vec<u32> = Vec::with_capacity(perm.len());
        for k in 0..perm.len() {
            let same = k > 0 && {
                let (o, q) = (obs(&perm[k]), obs(&perm[k - 1]));
                (o.point, o.camera) == (q.point, q.camera)
            };
            upper_start.push(if same { upper_start[k - 1] } else { k as u32 });
        }
        let columns = 6 + problem
            .intrinsics
            .iter()
            .map(|k| k.num_params())
            .max()
            .unwrap_or(0);
        // Where every free intrinsics parameter sits: (f-block, local column).
        let mut intr_col = vec![[None; INTRINSICS]; problem.intrinsics.len()];
        for (b, fb) in fblocks.iter().enumerate() {
            if let Some(k) = fb.intrinsics {
                for d in 0..fblock_dim[b] {
                    let c = fblock_cols[b][d] as usize;
                    if c >= 6 && !fblock_mask[b][d] {
                        intr_col[k][c - 6] = Some((b, d));
                    }
                }
            }
        }
        let prior_cols = problem
            .priors
            .iter()
            .map(|p| {
                p.terms
                    .iter()
                    .map(|t| intr_col[t.intrinsics][t.param])
                    .collect()
            })
            .collect();
        let prior_coefficients = problem
            .priors
            .iter()
            .map(|p| p.terms.iter().map(|t| t.coefficient).collect())
            .collect();
        let mut st = Structure {
            prior_cols,
            prior_coefficients,
            columns,
            fblocks,
            fblock_dim,
            fblock_offset,
            fblock_cols,
            fblock_mask,
            n_reduced,
            obs_fb,
            point_free,
            obs_point: perm.iter().map(obs).map(|o| o.point as u32).collect(),
            perm,
            point_ptr,
            point_obs,
            monotone: n_shared == 0 || shared.is_some(),
            shared,
            upper_start,
            groups: Vec::new(),
            #[cfg(test)]
            rowwise: false,
            row_ptr,
            row_obs,
            row_cols: Vec::new(),
            row_val_offset: Vec::new(),
            row_start: Vec::new(),
            n_values: 0,
        };
        st.build_pattern();
        st.build_groups();
        st
    }

    fn build_groups(&mut self) {
        let nf = self.fblocks.len();
        let total = self.row_obs.len().max(1);
        let target = total.div_ceil(ROW_GROUPS);
        let mut bounds = vec![0];
        let mut acc = 0;
        for r in 0..nf {
            acc += self.row_observations(r).len();
            if acc >= target && r + 1 < nf {
                bounds.push(r + 1);
                acc = 0;
            }
        }
        bounds.push(nf);
        bounds.dedup();
        let this = &*self;
        self.groups = bounds
            .par_windows(2)
            .map(|w| {
                let mut points: Vec<u32> = (w[0]..w[1])
                    .flat_map(|r| {
                        this.row_observations(r)
                            .iter()
                            .map(|&a| this.obs_point[a as usize])
                    })
                    .collect();
                points.sort_unstable();
                points.dedup();
                RowGroup {
                    rows: w[0]..w[1],
                    points,
                }
            })
            .collect();
    }

    pub(crate) fn build_pattern(&mut self) {
        let nf = self.fblocks.len();
        // The blocks a prior couples (its terms' f-blocks, pairwise).
        let mut prior_partners: Vec<Vec<u32>> = vec![Vec::new(); nf];
        for terms in &self.prior_cols {
            for &(a, _) in terms.iter().flatten() {
                for &(b, _) in terms.iter().flatten() {
                    if b >= a {
                        prior_partners[a].push(b as u32);
                    }
                }
            }
        }
        let this = &*self;
        let row_cols: Vec<Vec<u32>> = (0..nf)
            .into_par_iter()
            .map_init(
                || vec![false; nf],
                |mark, r| {
                    let mut cols = Vec::new();
                    for &a in this.row_observations(r) {
                        let p = this.obs_point[a as usize] as usize;
                        let partners: &[u32] = if this.point_free[p] {
                            this.upper_partners(a as usize, p)
                        } else {
                            std::slice::from_ref(&a)
                        };
                        for &b in partners {
                            for &c in &this.obs_fb[b as usize] {
                                if c != NONE && c as usize >= r && !mark[c as usize] {
                                    mark[c as usize] = true;
                                    cols.push(c);
                                }
                            }
                        }
                    }
                    for &c in &prior_partners[r] {
                        if !mark[c as usize] {
                            mark[c as usize] = true;
                            cols.push(c);
                        }
                    }
                    if !mark[r] {
                        // A block with no observations still gets its diagonal.
                        cols.push(r as u32);
                    }
                    for &c in &cols {
                        mark[c as usize] = false;
                    }
                    cols.sort_unstable();
                    cols
                },
            )
            .collect();
        let mut row_val_offset = Vec::with_capacity(nf);
        let mut row_start = Vec::with_capacity(nf);
        let mut n = 0;
        for (r, cols) in row_cols.iter().enumerate() {
            row_start.push(n);
            let mut offs = Vec::with_capacity(cols.len());
            let mut local = 0;
            for &c in cols {
                offs.push(local);
                local += self.fblock_dim[r] * self.fblock_dim[c as usize];
            }
            n += local;
            row_val_offset.push(offs);
        }
        self.row_cols = row_cols;
        self.row_val_offset = row_val_offset;
        self.row_start = row_start;
        self.n_values = n;
    }

    pub fn num_fblocks(&self) -> usize {
        self.fblocks.len()
    }

    /// Observations of point p.
    pub fn point_observations(&self, p: usize) -> &[u32] {
        &self.point_obs[self.point_ptr[p]..self.point_ptr[p + 1]]
    }

    /// The observations of a's point that can contribute to the upper triangle of the row of
    /// a's f-block r: all of them in general, those from a onwards when `monotone`.
    #[inline]
    pub(crate) fn upper_partners(&self, a: usize, p: usize) -> &[u32] {
        if self.monotone {
            // Internal order is point-major, so point p's observations are the internal
            // indices point_ptr[p]..point_ptr[p + 1] and a sits among them.
            &self.point_obs[self.upper_start[a] as usize..self.point_ptr[p + 1]]
        } else {
            self.point_observations(p)
        }
    }

    /// Observations touching f-block r.
    pub fn row_observations(&self, r: usize) -> &[u32] {
        &self.row_obs[self.row_ptr[r]..self.row_ptr[r + 1]]
    }

    /// The local camera columns of f-block b.
    #[inline]
    pub fn cols(&self, b: usize) -> &[u8] {
        &self.fblock_cols[b][..self.fblock_dim[b]]
    }

    /// Which of the camera columns of an observation with f-blocks `fb` are not optimised.
    pub fn obs_mask(&self, fb: [u32; 2]) -> [bool; CC] {
        let mut m = [true; CC];
        for b in fb {
            if b != NONE {
                let b = b as usize;
                for (u, &c) in self.cols(b).iter().enumerate() {
                    m[c as usize] = self.fblock_mask[b][u];
                }
            }
        }
        m
    }
}

/// Compressed rows from (row, value) pairs, keeping the input order within a row.
fn csr<T: Copy + Default>(
    n: usize,
    items: impl Iterator<Item = (usize, T)> + Clone,
) -> (Vec<usize>, Vec<T>) {
    let mut ptr = vec![0usize; n + 1];
    for (r, _) in items.clone() {
        ptr[r + 1] += 1;
    }
    for i in 0..n {
        ptr[i + 1] += ptr[i];
    }
    let mut fill = ptr.clone();
    let mut out = vec![T::default(); ptr[n]];
    for (r, v) in items {
        out[fill[r]] = v;
        fill[r] += 1;
    }
    (ptr, out)
}
