//! The reduced camera system: Schur complement of the point blocks
//! (Triggs et al. 2000, section 6.1; Agarwal et al. 2010, section 4; Ceres' `SchurEliminator`).
//!
//! With the camera-side parameters (pose and intrinsics blocks, the "f-blocks") first and the
//! points last, the damped normal equations are `[B E; Eᵀ C] [δf; δp] = −[g_f; g_p]` with C
//! block-diagonal (one 3×3 block per point). Eliminating the points gives
//! `S δf = −g_f + E C⁻¹ g_p` with `S = B − E C⁻¹ Eᵀ`, and then `δp = C⁻¹(−g_p − Eᵀ δf)`.
//!
//! S is stored as its upper block triangle: block row r holds the blocks (r, c), c ≥ r, of the
//! f-blocks that share a point with r. Observations are kept sorted by point (then camera), and
//! S is assembled by a fixed set of groups of consecutive block rows, in parallel: each group
//! owns its rows' storage and streams through the points its rows observe, in memory order.
//! Every block entry is therefore summed by one task, in the order of the points, whatever the
//! number of threads: S is bit-identical for any thread count. Per observation pair (a, b) of a
//! point the contribution is `Jcₐᵀ (δₐᵦ I − Vₐ Jpᵦᵀ) Jcᵦ` with `Vₐ = Jpₐ C⁻¹` (2×3), which never
//! forms the 9×3 blocks of E; only pairs whose block lands in the upper triangle are visited.
//!
//! An intrinsics block shared by every camera (one lens for the shot) is numbered after all the
//! camera blocks, and its column of S is assembled point by point instead of pair by pair: with
//! `G_p = Σ_b Jpᵦᵀ Jcᵦ[k]` (3×3, over the observations of point p), the block (r, k) gains, per
//! observation a of row r, `Jcₐᵀ (Jcₐ[k] − Vₐ G_p)` — the same sum as the pairs', in O(n) per
//! point instead of O(n²). The camera blocks then keep the upper-triangle shortcut.

use rayon::prelude::*;

use super::camera_model::INTRINSICS;
use super::evaluate::Linearization;
use super::residual::CAMERA_COLUMNS as CC;
use super::structure::{RowGroup, Structure, NONE};

/// What the assembly of S reads besides the structure: the linearization, `Vₐ = Jpₐ C⁻¹` per
/// observation and the shared column's `G_p` per point ([`Structure::shared_point_sums`]).
struct Terms<'a> {
    lin: &'a Linearization,
    v: &'a [[f64; 6]],
    g: &'a [[f64; 3 * INTRINSICS]],
    /// Per f-block: its parameters are the pose's six, camera columns 0..6 (a matchmove's
    /// cameras with K held), whose block updates take a fixed-size path.
    pose_only: Vec<bool>,
}

/// The damped reduced camera system `S δf = b` (upper block triangle of S).
pub(crate) struct ReducedSystem {
    pub values: Vec<f64>,
    pub rhs: Vec<f64>,
    /// C⁻¹ per point (row-major 3×3; zero for fixed points).
    pub c_inv: Vec<[f64; 9]>,
}

/// Ceres' LM damping of one diagonal entry: λ·clamp(d) with the clamp of Ceres' Jacobi-scaled
/// diagonal ([1e-6, 1e32] on d/(1+√d)²) mapped back to unscaled units.
#[inline]
pub(crate) fn damping(lambda: f64, d: f64) -> f64 {
    let s = 1.0 + d.sqrt();
    let scaled = (d / (s * s)).clamp(1e-6, 1e32);
    lambda * scaled * s * s
}

fn inv3(m: &[f64; 9]) -> Option<[f64; 9]> {
    let [a, b, c, d, e, f, g, h, i] = *m;
    let c0 = e * i - f * h;
    let c1 = f * g - d * i;
    let c2 = d * h - e * g;
    let det = a * c0 + b * c1 + c * c2;
    if !(det.is_finite() && det.abs() > 0.0) {
        return None;
    }
    let id = 1.0 / det;
    Some([
        c0 * id,
        (c * h - b * i) * id,
        (b * f - c * e) * id,
        c1 * id,
        (a * i - c * g) * id,
        (c * d - a * f) * id,
        c2 * id,
        (b * g - a * h) * id,
        (a * e - b * d) * id,
    ])
}

impl Structure {
    /// Assembles S and its right-hand side for damping λ = 1/radius.
    pub fn assemble(&self, lin: &Linearization, lambda: f64) -> ReducedSystem {
        // Point blocks: C = JpᵀJp + D, inverted; V = Jp C⁻¹.
        let c_inv: Vec<[f64; 9]> = lin
            .jtj_p
            .par_iter()
            .enumerate()
            .map(|(p, h)| {
                if !self.point_free[p] {
                    return [0.0; 9];
                }
                let mut m = *h;
                for k in 0..3 {
                    m[4 * k] += damping(lambda, h[4 * k]);
                }
                inv3(&m).unwrap_or([0.0; 9])
            })
            .collect();
        let mut v = vec![[0.0; 6]; lin.jp.len()];
        v.par_chunks_mut(super::evaluate::CHUNK)
            .enumerate()
            .for_each(|(ci, chunk)| {
                for (k, out) in chunk.iter_mut().enumerate() {
                    let a = ci * super::evaluate::CHUNK + k;
                    let ci_ = &c_inv[self.obs_point[a] as usize];
                    let j = &lin.jp[a];
                    for row in 0..2 {
                        for col in 0..3 {
                            out[3 * row + col] = j[3 * row] * ci_[col]
                                + j[3 * row + 1] * ci_[3 + col]
                                + j[3 * row + 2] * ci_[6 + col];
                        }
                    }
                }
            });

        let g = self.shared_point_sums(lin);
        let pose_only = (0..self.fblocks.len())
            .map(|c| self.cols(c) == [0, 1, 2, 3, 4, 5])
            .collect();
        let ctx = Terms {
            lin,
            v: &v,
            g: &g,
            pose_only,
        };
        let mut values = vec![0.0; self.n_values];
        let mut rhs = vec![0.0; self.n_reduced];
        #[cfg(test)]
        if self.rowwise {
            self.assemble_rowwise(&mut values, &mut rhs, &ctx, lambda);
            self.add_priors(&mut values);
            return ReducedSystem { values, rhs, c_inv };
        }
        // Split the flat arrays into per-group slices (groups are consecutive rows).
        let mut slices: Vec<(&mut [f64], &mut [f64])> = Vec::with_capacity(self.groups.len());
        {
            let mut rest_v: &mut [f64] = &mut values;
            let mut rest_r: &mut [f64] = &mut rhs;
            for g in &self.groups {
                let v_end = self
                    .row_start
                    .get(g.rows.end)
                    .copied()
                    .unwrap_or(self.n_values);
                let r_end = self
                    .fblock_offset
                    .get(g.rows.end)
                    .copied()
                    .unwrap_or(self.n_reduced);
                let (a, b) =
                    std::mem::take(&mut rest_v).split_at_mut(v_end - self.row_start[g.rows.start]);
                let (c, d) = std::mem::take(&mut rest_r)
                    .split_at_mut(r_end - self.fblock_offset[g.rows.start]);
                slices.push((a, c));
                rest_v = b;
                rest_r = d;
            }
        }
        self.groups
            .par_iter()
            .zip(slices)
            .for_each(|(g, (vals, b))| self.assemble_group(g, vals, b, &ctx, lambda));
        self.add_priors(&mut values);
        ReducedSystem { values, rhs, c_inv }
    }

    /// Adds the priors' `JᵀJ` (constant: their coefficients) to S; their gradient and diagonal
    /// are in the linearization's `g_f` and `diag_f` already (the rhs and the damping).
    fn add_priors(&self, values: &mut [f64]) {
        for (terms, prior) in self.prior_cols.iter().zip(&self.prior_coefficients) {
            for (ta, &ca) in terms.iter().zip(prior) {
                let Some((a, ua)) = *ta else { continue };
                for (tb, &cb) in terms.iter().zip(prior) {
                    let Some((b, ub)) = *tb else { continue };
                    if b < a {
                        continue;
                    }
                    let k = self.row_cols[a]
                        .binary_search(&(b as u32))
                        .unwrap_or_else(|_| {
                            unreachable!("prior block ({a}, {b}) is in the pattern")
                        });
                    let at = self.row_start[a] + self.row_val_offset[a][k];
                    values[at + ua * self.fblock_dim[b] + ub] += ca * cb;
                }
            }
        }
    }

    /// Per point, `G_p = Σ_b Jpᵦᵀ Jcᵦ[k]` (row-major 3×[`INTRINSICS`]: point coordinate × the
    /// shared block's columns) over its observations, when a shared block is assembled
    /// point-wise (module docs); empty otherwise.
    fn shared_point_sums(&self, lin: &Linearization) -> Vec<[f64; 3 * INTRINSICS]> {
        let Some(k) = self.shared else {
            return Vec::new();
        };
        let cols = self.cols(k);
        let w1 = lin.columns;
        (0..self.point_ptr.len() - 1)
            .into_par_iter()
            .map(|p| {
                let mut g = [0.0; 3 * INTRINSICS];
                if !self.point_free[p] {
                    return g;
                }
                for &b in self.point_observations(p) {
                    let (jp, jc) = (&lin.jp[b as usize], lin.jc(b as usize));
                    for i in 0..3 {
                        for (w, &c) in cols.iter().enumerate() {
                            let c = c as usize;
                            g[INTRINSICS * i + w] += jp[i] * jc[c] + jp[3 + i] * jc[w1 + c];
                        }
                    }
                }
                g
            })
            .collect()
    }

    /// The group-wise assembly (see [`RowGroup`]); writes `vals`/`b`, the slices of the group's
    /// rows.
    fn assemble_group(
        &self,
        g: &RowGroup,
        vals: &mut [f64],
        b: &mut [f64],
        t: &Terms,
        lambda: f64,
    ) {
        let lin = t.lin;
        let v0 = self.row_start[g.rows.start];
        let b0 = self.fblock_offset[g.rows.start];
        for r in g.rows.clone() {
            let ro = self.fblock_offset[r];
            for u in 0..self.fblock_dim[r] {
                b[ro - b0 + u] = -lin.g_f[ro + u];
            }
        }
        // Block (r, c)'s offset in its row: a table for the group's rows when it is small
        // (a shot's few hundred cameras), else a binary search of the row's pattern.
        let n = self.fblocks.len();
        let table: Option<Vec<usize>> = (g.rows.len() * n <= 1 << 20).then(|| {
            let mut t = vec![usize::MAX; g.rows.len() * n];
            for r in g.rows.clone() {
                for (&c, &o) in self.row_cols[r].iter().zip(&self.row_val_offset[r]) {
                    t[(r - g.rows.start) * n + c as usize] = o;
                }
            }
            t
        });
        for &p in &g.points {
            let p = p as usize;
            for a in self.point_ptr[p]..self.point_ptr[p + 1] {
                for &r in &self.obs_fb[a] {
                    if r == NONE || !g.rows.contains(&(r as usize)) {
                        continue;
                    }
                    let r = r as usize;
                    let ro = self.fblock_offset[r] - b0;
                    let row_vals = &mut vals[self.row_start[r] - v0..];
                    self.add_observation(
                        r,
                        a,
                        row_vals,
                        &mut b[ro..ro + self.fblock_dim[r]],
                        t,
                        |c| match &table {
                            Some(t) => t[(r - g.rows.start) * n + c],
                            None => {
                                let k = self.row_cols[r].binary_search(&(c as u32)).unwrap_or_else(
                                    |_| unreachable!("block ({r}, {c}) is in the pattern"),
                                );
                                self.row_val_offset[r][k]
                            }
                        },
                    );
                }
            }
        }
        for r in g.rows.clone() {
            let ro = self.fblock_offset[r] - b0;
            let dr = self.fblock_dim[r];
            let k = self.row_cols[r]
                .binary_search(&(r as u32))
                .unwrap_or_else(|_| unreachable!("diagonal block {r} is in the pattern"));
            let blk = &mut vals[self.row_start[r] - v0 + self.row_val_offset[r][k]..][..dr * dr];
            self.damp_diagonal(r, blk, &mut b[ro..ro + dr], lin, lambda);
        }
    }

    /// Adds observation a's terms to block row r (a belongs to f-block r): the rhs term and,
    /// for every partner b of the same point whose f-blocks c ≥ r, `Jcₐᵀ (δₐᵦ I − Vₐ Jpᵦᵀ) Jcᵦ`.
    /// `block_offset(c)` gives the offset of block (r, c) in `vals`.
    #[inline]
    #[allow(clippy::too_many_arguments)]
    fn add_observation(
        &self,
        r: usize,
        a: usize,
        vals: &mut [f64],
        b: &mut [f64],
        t: &Terms,
        block_offset: impl Fn(usize) -> usize,
    ) {
        let (lin, v) = (t.lin, t.v);
        let dr = self.fblock_dim[r];
        let cols_r = self.cols(r);
        let p = self.obs_point[a] as usize;
        let jca = lin.jc(a);
        let w1 = lin.columns;
        let va = &v[a];
        let free = self.point_free[p];
        // Rows of Jcₐᵀ restricted to this block's columns.
        let mut ja = [[0.0f64; 2]; CC];
        for (u, &cu) in cols_r.iter().enumerate() {
            ja[u] = [jca[cu as usize], jca[w1 + cu as usize]];
        }
        // rhs: + Jcₐᵀ (Vₐ g_p)
        if free {
            let g = &lin.g_p[p];
            let w0 = va[0] * g[0] + va[1] * g[1] + va[2] * g[2];
            let w1 = va[3] * g[0] + va[4] * g[1] + va[5] * g[2];
            for u in 0..dr {
                b[u] += ja[u][0] * w0 + ja[u][1] * w1;
            }
        }
        if let Some(k) = self.shared {
            // The shared column, point-wise: Jcₐᵀ (Jcₐ[k] − Vₐ G_p).
            let cols_k = self.cols(k);
            let nk = cols_k.len();
            let mut m = [[0.0f64; INTRINSICS]; 2];
            for (w, &c) in cols_k.iter().enumerate() {
                m[0][w] = jca[c as usize];
                m[1][w] = jca[w1 + c as usize];
            }
            if free {
                let g = &t.g[p];
                for (row, mr) in m.iter_mut().enumerate() {
                    for (w, x) in mr[..nk].iter_mut().enumerate() {
                        *x -= va[3 * row] * g[w]
                            + va[3 * row + 1] * g[INTRINSICS + w]
                            + va[3 * row + 2] * g[2 * INTRINSICS + w];
                    }
                }
            }
            let blk = &mut vals[block_offset(k)..][..dr * nk];
            for (u, row) in blk.chunks_exact_mut(nk).enumerate() {
                let (a0, a1) = (ja[u][0], ja[u][1]);
                for (w, x) in row.iter_mut().enumerate() {
                    *x += a0 * m[0][w] + a1 * m[1][w];
                }
            }
            if r == k {
                return;
            }
        }
        let single = [a as u32];
        let partners: &[u32] = if free {
            self.upper_partners(a, p)
        } else {
            &single
        };
        for &bi in partners {
            let bi = bi as usize;
            let mut fbs = self.obs_fb[bi];
            if self.shared.is_some() {
                // The shared column is done above.
                fbs[1] = NONE;
            }
            if (fbs[0] == NONE || (fbs[0] as usize) < r)
                && (fbs[1] == NONE || (fbs[1] as usize) < r)
            {
                continue;
            }
            // Q = δ I − Vₐ Jpᵦᵀ (2×2)
            let jpb = &lin.jp[bi];
            let mut q = [0.0; 4];
            if free {
                for row in 0..2 {
                    for col in 0..2 {
                        q[2 * row + col] = -(va[3 * row] * jpb[3 * col]
                            + va[3 * row + 1] * jpb[3 * col + 1]
                            + va[3 * row + 2] * jpb[3 * col + 2]);
                    }
                }
            }
            if bi == a {
                q[0] += 1.0;
                q[3] += 1.0;
            }
            // T = Q Jcᵦ (2 × columns); the block gains Jcₐ[:, cols_r]ᵀ T[:, cols_c].
            let jcb = lin.jc(bi);
            let mut t0 = [0.0; CC];
            let mut t1 = [0.0; CC];
            for col in 0..self.columns {
                t0[col] = q[0] * jcb[col] + q[1] * jcb[w1 + col];
                t1[col] = q[2] * jcb[col] + q[3] * jcb[w1 + col];
            }
            for &c in &fbs {
                if c == NONE || (c as usize) < r {
                    continue;
                }
                let c = c as usize;
                let dc = self.fblock_dim[c];
                let blk = &mut vals[block_offset(c)..][..dr * dc];
                if dc == 9 {
                    // The common case (pose + own three intrinsics, as BAL's): columns 0..9.
                    for (u, row) in blk.chunks_exact_mut(9).enumerate() {
                        let (a0, a1) = (ja[u][0], ja[u][1]);
                        for w in 0..9 {
                            row[w] += a0 * t0[w] + a1 * t1[w];
                        }
                    }
                } else if t.pose_only[c] {
                    // A pose alone (K held): columns 0..6.
                    for (u, row) in blk.chunks_exact_mut(6).enumerate() {
                        let (a0, a1) = (ja[u][0], ja[u][1]);
                        for w in 0..6 {
                            row[w] += a0 * t0[w] + a1 * t1[w];
                        }
                    }
                } else {
                    let cols_c = self.cols(c);
                    for (u, row) in blk.chunks_exact_mut(dc).enumerate() {
                        let (a0, a1) = (ja[u][0], ja[u][1]);
                        for (x, &cw) in row.iter_mut().zip(cols_c) {
                            let cw = cw as usize;
                            *x += a0 * t0[cw] + a1 * t1[cw];
                        }
                    }
                }
            }
        }
    }

    /// Damping on the diagonal block; components held by the gauge get a unit pivot.
    fn damp_diagonal(
        &self,
        r: usize,
        blk: &mut [f64],
        b: &mut [f64],
        lin: &Linearization,
        lambda: f64,
    ) {
        let dr = self.fblock_dim[r];
        let ro = self.fblock_offset[r];
        let mask = &self.fblock_mask[r];
        for u in 0..dr {
            if mask[u] {
                for w in 0..dr {
                    blk[u * dr + w] = 0.0;
                    blk[w * dr + u] = 0.0;
                }
                blk[u * dr + u] = 1.0;
                b[u] = 0.0;
            } else {
                blk[u * dr + u] += damping(lambda, lin.diag_f[ro + u]);
            }
        }
    }

    /// Reference assembly, one block row at a time over the row's observations.
    #[cfg(test)]
    fn assemble_rowwise(&self, values: &mut [f64], rhs: &mut [f64], t: &Terms, lambda: f64) {
        let lin = t.lin;
        for r in 0..self.fblocks.len() {
            let dr = self.fblock_dim[r];
            let ro = self.fblock_offset[r];
            let base = self.row_start[r];
            for u in 0..dr {
                rhs[ro + u] = -lin.g_f[ro + u];
            }
            for &a in self.row_observations(r) {
                let offs = |c: usize| {
                    let k = self.row_cols[r].binary_search(&(c as u32)).unwrap();
                    self.row_val_offset[r][k]
                };
                self.add_observation(
                    r,
                    a as usize,
                    &mut values[base..],
                    &mut rhs[ro..ro + dr],
                    t,
                    offs,
                );
            }
            let k = self.row_cols[r].binary_search(&(r as u32)).unwrap();
            let blk = &mut values[base + self.row_val_offset[r][k]..][..dr * dr];
            self.damp_diagonal(r, blk, &mut rhs[ro..ro + dr], lin, lambda);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::evaluate::linearize;
    use crate::loss::Loss;
    use crate::synthetic::{video_like, SyntheticModel, VideoConfig};

    #[test]
    fn pointwise_shared_column_equals_the_pairwise_sums() {
        let s = video_like(&VideoConfig {
            cameras: 12,
            points: 300,
            model: SyntheticModel::Pinhole,
            ..VideoConfig::default()
        });
        let mut p = s.problem;
        // One lens for the shot, free but for cy; a duplicated observation; a fixed point.
        p.intrinsics[0].fixed = false;
        p.intrinsics[0].held[2] = true;
        for i in (0..p.observations.len()).step_by(11) {
            let mut o = p.observations[i];
            o.pixel.y -= 0.2;
            p.observations.push(o);
        }
        p.points[3].fixed = true;
        let fast = Structure::new(&p);
        assert_eq!(fast.shared, Some(fast.num_fblocks() - 1));
        assert!(fast.monotone);
        let mut general = Structure::new(&p);
        general.monotone = false;
        general.shared = None;
        general.build_pattern();
        assert_eq!(fast.row_cols, general.row_cols);
        let lin = linearize(&p, &Loss::Huber { scale: 1.0 }, &fast);
        let a = fast.assemble(&lin, 1e-3);
        let b = general.assemble(&lin, 1e-3);
        let scale = b.values.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        for (x, y) in a.values.iter().zip(&b.values) {
            assert!((x - y).abs() <= 1e-10 * scale, "{x} vs {y}");
        }
        assert_eq!(a.rhs, b.rhs);
        let mut rowwise = Structure::new(&p);
        rowwise.rowwise = true;
        let c = rowwise.assemble(&lin, 1e-3);
        assert_eq!(a.values, c.values);
        assert_eq!(a.rhs, c.rhs);
    }

    #[test]
    fn upper_triangle_shortcut_equals_the_general_path_even_with_duplicates() {
        let s = video_like(&VideoConfig {
            cameras: 10,
            points: 300,
            model: SyntheticModel::Bal,
            ..VideoConfig::default()
        });
        let mut p = s.problem;
        // The same point seen twice by one camera.
        for i in (0..p.observations.len()).step_by(7) {
            let mut o = p.observations[i];
            o.pixel.x += 0.3;
            p.observations.push(o);
        }
        let fast = Structure::new(&p);
        assert!(fast.monotone);
        let mut general = Structure::new(&p);
        general.monotone = false;
        general.build_pattern();
        assert_eq!(fast.row_cols, general.row_cols);
        let lin = linearize(&p, &Loss::Huber { scale: 1.0 }, &fast);
        let a = fast.assemble(&lin, 1e-3);
        let b = general.assemble(&lin, 1e-3);
        for (x, y) in a.values.iter().zip(&b.values) {
            assert!((x - y).abs() <= 1e-12 * (1.0 + x.abs()), "{x} vs {y}");
        }
        assert_eq!(a.rhs, b.rhs);
        general.rowwise = true;
        let c = general.assemble(&lin, 1e-3);
        assert_eq!(a.values, c.values);
        assert_eq!(a.rhs, c.rhs);
    }
}
