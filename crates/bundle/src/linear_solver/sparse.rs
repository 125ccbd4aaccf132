//! Sparse Cholesky of the reduced camera system (Ceres' `SPARSE_SCHUR`; Agarwal et al. 2010):
//! faer's supernodal LLᵀ with an approximate-minimum-degree ordering. The symbolic factorisation
//! is computed once per solve (the pattern of S does not change between iterations); the numeric
//! one runs sequentially so results never depend on the thread count.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, SymbolicCholesky, SymmetricOrdering,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, Mat, Par, Side};

use crate::error::BundleError;
use crate::schur::ReducedSystem;
use crate::structure::Structure;

/// Sparse solver state: the upper-triangular CSC pattern of S, where each of its values comes
/// from in the block storage, and the symbolic factorisation.
pub(crate) struct SparseSolver {
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    src: Vec<usize>,
    values: Vec<f64>,
    symbolic: SymbolicCholesky<usize>,
    l_values: Vec<f64>,
}

impl SparseSolver {
    pub fn new(st: &Structure) -> Result<SparseSolver, BundleError> {
        let nf = st.num_fblocks();
        let n = st.n_reduced;
        // Transpose the block pattern: for each column block, the row blocks above it.
        let mut col_rows: Vec<Vec<(u32, u32)>> = vec![Vec::new(); nf];
        for r in 0..nf {
            for (k, &c) in st.row_cols[r].iter().enumerate() {
                col_rows[c as usize].push((r as u32, k as u32));
            }
        }
        let mut col_ptr = Vec::with_capacity(n + 1);
        let mut row_idx = Vec::new();
        let mut src = Vec::new();
        col_ptr.push(0);
        for c in 0..nf {
            let (dc, co) = (st.fblock_dim[c], st.fblock_offset[c]);
            for w in 0..dc {
                for &(r, k) in &col_rows[c] {
                    let r = r as usize;
                    let (dr, ro) = (st.fblock_dim[r], st.fblock_offset[r]);
                    let base = st.row_start[r] + st.row_val_offset[r][k as usize];
                    let rows = if r == c { w + 1 } else { dr };
                    for u in 0..rows {
                        row_idx.push(ro + u);
                        src.push(base + u * dc + w);
                    }
                }
                col_ptr.push(row_idx.len());
                debug_assert_eq!(co + w + 1, col_ptr.len() - 1);
            }
        }
        let symbolic = {
            let pattern = SymbolicSparseColMatRef::new_checked(n, n, &col_ptr, None, &row_idx);
            factorize_symbolic_cholesky(
                pattern,
                Side::Upper,
                SymmetricOrdering::Amd,
                CholeskySymbolicParams::default(),
            )
            .map_err(|e| BundleError::LinearSolver(format!("symbolic factorisation: {e:?}")))?
        };
        let l_values = vec![0.0; symbolic.len_val()];
        let values = vec![0.0; src.len()];
        Ok(SparseSolver {
            col_ptr,
            row_idx,
            src,
            values,
            symbolic,
            l_values,
        })
    }

    pub fn solve(&mut self, st: &Structure, sys: &ReducedSystem) -> Option<Vec<f64>> {
        let n = st.n_reduced;
        for (v, &s) in self.values.iter_mut().zip(&self.src) {
            *v = sys.values[s];
        }
        let pattern =
            SymbolicSparseColMatRef::new_checked(n, n, &self.col_ptr, None, &self.row_idx);
        let a = SparseColMatRef::new(pattern, &self.values);
        let par = Par::Seq;
        let mut buf = MemBuffer::new(
            self.symbolic
                .factorize_numeric_llt_scratch::<f64>(par, Default::default()),
        );
        let llt = self
            .symbolic
            .factorize_numeric_llt(
                &mut self.l_values,
                a,
                Side::Upper,
                Default::default(),
                par,
                MemStack::new(&mut buf),
                Default::default(),
            )
            .ok()?;
        let mut rhs = Mat::from_fn(n, 1, |i, _| sys.rhs[i]);
        let mut buf = MemBuffer::new(self.symbolic.solve_in_place_scratch::<f64>(1, par));
        llt.solve_in_place_with_conj(Conj::No, rhs.as_mut(), par, MemStack::new(&mut buf));
        let x: Vec<f64> = (0..n).map(|i| rhs[(i, 0)]).collect();
        x.iter().all(|v| v.is_finite()).then_some(x)
    }
}
