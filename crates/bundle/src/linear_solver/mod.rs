//! Solvers for the reduced camera system `S δf = b` (Agarwal et al. 2010, section 4; Ceres'
//! `DENSE_SCHUR`, `SPARSE_SCHUR` and `ITERATIVE_SCHUR`).
//!
//! The kind is an option of the solve with an automatic default: dense Cholesky while the reduced
//! system is small, sparse Cholesky (faer, AMD ordering, supernodal) beyond.

use serde::{Deserialize, Serialize};

use super::schur::ReducedSystem;
use super::structure::Structure;

pub mod dense;
pub mod pcg;
pub mod sparse;

/// Reduced systems up to this many unknowns are factored densely by [`LinearSolverKind::Auto`].
pub const AUTO_DENSE_MAX: usize = 600;

/// [`LinearSolverKind::DenseSchur`] refuses reduced systems larger than this (the matrix alone
/// would take n²·8 bytes: 3.2 GB at this size).
pub const DENSE_MAX: usize = 20_000;

/// Which linear solver factors the reduced camera system (Ceres' `linear_solver_type`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum LinearSolverKind {
    /// Dense below [`AUTO_DENSE_MAX`] unknowns, sparse above.
    #[default]
    Auto,
    /// Dense Cholesky of S (Ceres' `DENSE_SCHUR`).
    DenseSchur,
    /// Sparse Cholesky of S with a fill-reducing ordering (Ceres' `SPARSE_SCHUR`).
    SparseSchur,
    /// Conjugate gradients on S with a block-Jacobi preconditioner (Ceres' `ITERATIVE_SCHUR`
    /// with `SCHUR_JACOBI`, here on the explicit S).
    IterativeSchur,
}

impl LinearSolverKind {
    /// Parses `auto|dense|sparse|iterative`, for command lines.
    pub fn parse(text: &str) -> Option<LinearSolverKind> {
        match text.to_ascii_lowercase().as_str() {
            "auto" => Some(LinearSolverKind::Auto),
            "dense" | "dense_schur" => Some(LinearSolverKind::DenseSchur),
            "sparse" | "sparse_schur" => Some(LinearSolverKind::SparseSchur),
            "iterative" | "iterative_schur" | "pcg" => Some(LinearSolverKind::IterativeSchur),
            _ => None,
        }
    }

    /// The concrete kind [`Auto`](LinearSolverKind::Auto) resolves to for `n` unknowns.
    pub fn resolve(self, n: usize) -> LinearSolverKind {
        match self {
            LinearSolverKind::Auto if n <= AUTO_DENSE_MAX => LinearSolverKind::DenseSchur,
            LinearSolverKind::Auto => LinearSolverKind::SparseSchur,
            k => k,
        }
    }
}

/// A linear solver with the state it keeps between iterations (e.g. the symbolic factorisation).
pub(crate) enum LinearSolver {
    Dense(dense::DenseSolver),
    Sparse(Box<sparse::SparseSolver>),
    Iterative(pcg::PcgSolver),
}

impl LinearSolver {
    /// Prepares the solver of `kind` (already resolved) for the structure.
    pub fn new(
        kind: LinearSolverKind,
        st: &Structure,
        pcg: pcg::PcgOptions,
    ) -> Result<LinearSolver, super::BundleError> {
        if st.n_reduced == 0 {
            return Ok(LinearSolver::Dense(dense::DenseSolver::new(st)));
        }
        Ok(match kind.resolve(st.n_reduced) {
            LinearSolverKind::DenseSchur | LinearSolverKind::Auto => {
                if st.n_reduced > DENSE_MAX {
                    return Err(super::BundleError::InvalidProblem(format!(
                        "dense Schur with {} unknowns (more than {DENSE_MAX}); use the sparse solver",
                        st.n_reduced
                    )));
                }
                LinearSolver::Dense(dense::DenseSolver::new(st))
            }
            LinearSolverKind::SparseSchur => {
                LinearSolver::Sparse(Box::new(sparse::SparseSolver::new(st)?))
            }
            LinearSolverKind::IterativeSchur => LinearSolver::Iterative(pcg::PcgSolver::new(pcg)),
        })
    }

    /// Solves `S x = b`; `None` when S is not numerically positive definite (the LM loop then
    /// treats the step as failed and increases the damping).
    pub fn solve(&mut self, st: &Structure, sys: &ReducedSystem) -> Option<Vec<f64>> {
        if st.n_reduced == 0 {
            return Some(Vec::new());
        }
        match self {
            LinearSolver::Dense(s) => s.solve(st, sys),
            LinearSolver::Sparse(s) => s.solve(st, sys),
            LinearSolver::Iterative(s) => s.solve(st, sys),
        }
    }
}

/// `y = S x` using the upper block triangle (serial, fixed order).
pub(crate) fn sym_matvec(st: &Structure, values: &[f64], x: &[f64], y: &mut [f64]) {
    y.iter_mut().for_each(|v| *v = 0.0);
    for r in 0..st.num_fblocks() {
        let (dr, ro) = (st.fblock_dim[r], st.fblock_offset[r]);
        for (k, &c) in st.row_cols[r].iter().enumerate() {
            let c = c as usize;
            let (dc, co) = (st.fblock_dim[c], st.fblock_offset[c]);
            let blk = &values[st.row_start[r] + st.row_val_offset[r][k]..][..dr * dc];
            for u in 0..dr {
                let row = &blk[u * dc..(u + 1) * dc];
                let mut acc = 0.0;
                for w in 0..dc {
                    acc += row[w] * x[co + w];
                }
                y[ro + u] += acc;
                if c != r {
                    let xu = x[ro + u];
                    for w in 0..dc {
                        y[co + w] += row[w] * xu;
                    }
                }
            }
        }
    }
}
