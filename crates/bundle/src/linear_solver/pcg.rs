//! Preconditioned conjugate gradients on the reduced camera system with a block-Jacobi
//! preconditioner (Agarwal et al. 2010, section 4.3; Ceres' `ITERATIVE_SCHUR` + `SCHUR_JACOBI`).
//! Serial and in a fixed order, hence deterministic.

use nalgebra::DMatrix;

use super::sym_matvec;
use crate::schur::ReducedSystem;
use crate::structure::Structure;

/// Stopping rule of the conjugate gradients.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PcgOptions {
    /// Stop when ‖S x − b‖ ≤ `relative_tolerance`·‖b‖.
    pub relative_tolerance: f64,
    /// At most this many iterations per linear solve.
    pub max_iterations: usize,
}

impl Default for PcgOptions {
    fn default() -> Self {
        PcgOptions {
            relative_tolerance: 1e-8,
            max_iterations: 1000,
        }
    }
}

pub(crate) struct PcgSolver {
    options: PcgOptions,
}

impl PcgSolver {
    pub fn new(options: PcgOptions) -> PcgSolver {
        PcgSolver { options }
    }

    pub fn solve(&mut self, st: &Structure, sys: &ReducedSystem) -> Option<Vec<f64>> {
        let n = st.n_reduced;
        // Block-Jacobi preconditioner: inverse of every diagonal block.
        let mut precond = Vec::with_capacity(st.num_fblocks());
        for r in 0..st.num_fblocks() {
            let d = st.fblock_dim[r];
            let k = st.row_cols[r].binary_search(&(r as u32)).ok()?;
            let blk = &sys.values[st.row_start[r] + st.row_val_offset[r][k]..][..d * d];
            let m = DMatrix::from_row_slice(d, d, blk);
            precond.push(m.cholesky()?.inverse());
        }
        let apply_precond = |res: &[f64], z: &mut [f64]| {
            for (r, pinv) in precond.iter().enumerate() {
                let (d, o) = (st.fblock_dim[r], st.fblock_offset[r]);
                for u in 0..d {
                    let mut acc = 0.0;
                    for w in 0..d {
                        acc += pinv[(u, w)] * res[o + w];
                    }
                    z[o + u] = acc;
                }
            }
        };
        let b = &sys.rhs;
        let bnorm = b.iter().map(|v| v * v).sum::<f64>().sqrt();
        let mut x = vec![0.0; n];
        if bnorm == 0.0 {
            return Some(x);
        }
        let mut res = b.clone();
        let mut z = vec![0.0; n];
        apply_precond(&res, &mut z);
        let mut p = z.clone();
        let mut rz: f64 = res.iter().zip(&z).map(|(a, b)| a * b).sum();
        let mut q = vec![0.0; n];
        for _ in 0..self.options.max_iterations {
            sym_matvec(st, &sys.values, &p, &mut q);
            let pq: f64 = p.iter().zip(&q).map(|(a, b)| a * b).sum();
            if pq.is_nan() || pq <= 0.0 {
                break;
            }
            let alpha = rz / pq;
            for i in 0..n {
                x[i] += alpha * p[i];
                res[i] -= alpha * q[i];
            }
            let rnorm = res.iter().map(|v| v * v).sum::<f64>().sqrt();
            if rnorm <= self.options.relative_tolerance * bnorm {
                break;
            }
            apply_precond(&res, &mut z);
            let rz_new: f64 = res.iter().zip(&z).map(|(a, b)| a * b).sum();
            let beta = rz_new / rz;
            rz = rz_new;
            for i in 0..n {
                p[i] = z[i] + beta * p[i];
            }
        }
        x.iter().all(|v| v.is_finite()).then_some(x)
    }
}
