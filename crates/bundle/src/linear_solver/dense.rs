//! Dense Cholesky of the reduced camera system (Ceres' `DENSE_SCHUR`; Triggs et al. 2000, 6.1),
//! with faer's blocked factorisation run sequentially so the result never depends on threads.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt;
use faer::{Conj, Mat, Par};

use crate::schur::ReducedSystem;
use crate::structure::Structure;

/// Dense solver state: the matrix buffer, reused between iterations.
pub(crate) struct DenseSolver {
    mat: Mat<f64>,
}

impl DenseSolver {
    pub fn new(st: &Structure) -> DenseSolver {
        DenseSolver {
            mat: Mat::zeros(st.n_reduced, st.n_reduced),
        }
    }

    pub fn solve(&mut self, st: &Structure, sys: &ReducedSystem) -> Option<Vec<f64>> {
        let n = st.n_reduced;
        self.mat.fill(0.0);
        for r in 0..st.num_fblocks() {
            let (dr, ro) = (st.fblock_dim[r], st.fblock_offset[r]);
            for (k, &c) in st.row_cols[r].iter().enumerate() {
                let c = c as usize;
                let (dc, co) = (st.fblock_dim[c], st.fblock_offset[c]);
                let blk = &sys.values[st.row_start[r] + st.row_val_offset[r][k]..][..dr * dc];
                for u in 0..dr {
                    for w in 0..dc {
                        // Lower triangle only is read by the factorisation.
                        self.mat[(co + w, ro + u)] = blk[u * dc + w];
                    }
                }
            }
        }
        let par = Par::Seq;
        let mut buf = MemBuffer::new(llt::factor::cholesky_in_place_scratch::<f64>(
            n,
            par,
            Default::default(),
        ));
        llt::factor::cholesky_in_place(
            self.mat.as_mut(),
            Default::default(),
            par,
            MemStack::new(&mut buf),
            Default::default(),
        )
        .ok()?;
        let mut rhs = Mat::from_fn(n, 1, |i, _| sys.rhs[i]);
        let mut buf = MemBuffer::new(llt::solve::solve_in_place_scratch::<f64>(n, 1, par));
        llt::solve::solve_in_place_with_conj(
            self.mat.as_ref(),
            Conj::No,
            rhs.as_mut(),
            par,
            MemStack::new(&mut buf),
        );
        let x: Vec<f64> = (0..n).map(|i| rhs[(i, 0)]).collect();
        x.iter().all(|v| v.is_finite()).then_some(x)
    }
}
