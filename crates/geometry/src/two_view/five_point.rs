//! The five-point relative pose: every essential matrix consistent with five correspondences of
//! calibrated (normalized) image points, after Stewénius, Engels & Nistér, "Recent developments
//! on direct relative orientation" (ISPRS J. 2006) — Nistér's constraints (CVPR 2003 / PAMI 2004)
//! solved by a Gröbner-basis action matrix.
//!
//! Unlike the 8-point fundamental matrix of §5.7, the five-point solver is not degenerate when
//! the points lie on a plane: with K known, a planar scene still determines E (up to the twofold
//! ambiguity the homography decomposition also has), which is what footage dominated by a floor
//! or a wall needs.
//!
//! E = xX + yY + zZ + W spans the null space of the five epipolar constraints; det E = 0 and
//! 2EEᵀE − tr(EEᵀ)E = 0 give ten cubics in (x, y, z). Eliminating the ten cubic monomials
//! leaves each as a combination of the ten monomials of degree ≤ 2, which form a basis of the
//! quotient ring; multiplication by x is a 10×10 matrix whose eigenvectors are those monomials
//! evaluated at the solutions.

use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

/// Up to ten essential matrices (‖E‖ = 1) with `b[i]ᵀ E a[i] = 0` for the five correspondences
/// of normalized image points (K⁻¹x, last coordinate 1). Degenerate samples (repeated points,
/// five collinear points) give no or spurious solutions, never a panic.
pub fn essential_five_point(a: &[Vector3<f64>; 5], b: &[Vector3<f64>; 5]) -> Vec<Matrix3<f64>> {
    // Each row: the constraint bᵀEa = 0 as a linear form in E's entries (row-major).
    let mut q = SMatrix::<f64, 9, 9>::zeros();
    for i in 0..5 {
        let (x, y) = (a[i], b[i]);
        for r in 0..3 {
            for c in 0..3 {
                q[(i, 3 * r + c)] = y[r] * x[c];
            }
        }
    }
    if !q.iter().all(|v| v.is_finite()) {
        return Vec::new();
    }
    let svd = q.svd(false, true);
    let Some(vt) = svd.v_t else {
        return Vec::new();
    };
    // The four right singular vectors of the smallest singular values span the null space.
    let mut order: Vec<usize> = (0..9).collect();
    order.sort_by(|&i, &j| svd.singular_values[j].total_cmp(&svd.singular_values[i]));
    let basis: Vec<Matrix3<f64>> = order[5..]
        .iter()
        .map(|&r| Matrix3::from_fn(|i, j| vt[(r, 3 * i + j)]))
        .collect();
    // E's entries as polynomials x·X + y·Y + z·Z + W.
    let e: [[Poly; 3]; 3] = std::array::from_fn(|i| {
        std::array::from_fn(|j| {
            let mut p = Poly::zero();
            p.c[mono(1, 0, 0)] = basis[0][(i, j)];
            p.c[mono(0, 1, 0)] = basis[1][(i, j)];
            p.c[mono(0, 0, 1)] = basis[2][(i, j)];
            p.c[mono(0, 0, 0)] = basis[3][(i, j)];
            p
        })
    });
    let mut rows: Vec<Poly> = Vec::with_capacity(10);
    // det E.
    rows.push(
        e[0][0]
            .mul(&e[1][1].mul(&e[2][2]).sub(&e[1][2].mul(&e[2][1])))
            .sub(&e[0][1].mul(&e[1][0].mul(&e[2][2]).sub(&e[1][2].mul(&e[2][0]))))
            .add(&e[0][2].mul(&e[1][0].mul(&e[2][1]).sub(&e[1][1].mul(&e[2][0])))),
    );
    // EEᵀ and its trace.
    let eet: [[Poly; 3]; 3] = std::array::from_fn(|i| {
        std::array::from_fn(|j| (0..3).fold(Poly::zero(), |s, k| s.add(&e[i][k].mul(&e[j][k]))))
    });
    let trace = eet[0][0].add(&eet[1][1]).add(&eet[2][2]);
    for (eet_i, e_i) in eet.iter().zip(&e) {
        for (j, e_ij) in e_i.iter().enumerate() {
            let eete = (0..3).fold(Poly::zero(), |s, k| s.add(&eet_i[k].mul(&e[k][j])));
            rows.push(eete.scale(2.0).sub(&trace.mul(e_ij)));
        }
    }
    // Columns 0..10: the cubic monomials; 10..20: the basis of the quotient ring.
    let mut m1 = SMatrix::<f64, 10, 10>::zeros();
    let mut m2 = SMatrix::<f64, 10, 10>::zeros();
    for (r, p) in rows.iter().enumerate() {
        for c in 0..10 {
            m1[(r, c)] = p.c[c];
            m2[(r, c)] = p.c[10 + c];
        }
    }
    let Some(g) = m1.lu().solve(&m2) else {
        return Vec::new();
    };
    if !g.iter().all(|v| v.is_finite()) {
        return Vec::new();
    }
    // Row i of g: cubic_i = −g[i]·basis. Multiplication by x maps each basis monomial to a
    // cubic (reduced by g) or to another basis monomial.
    let mut action = SMatrix::<f64, 10, 10>::zeros();
    for (row, cubic) in [
        mono(3, 0, 0),
        mono(2, 1, 0),
        mono(2, 0, 1),
        mono(1, 2, 0),
        mono(1, 1, 1),
        mono(1, 0, 2),
    ]
    .into_iter()
    .enumerate()
    {
        for c in 0..10 {
            action[(row, c)] = -g[(cubic, c)];
        }
    }
    // x·x = x², x·y = xy, x·z = xz, x·1 = x (basis indices 0, 1, 2, 6).
    for (row, target) in [(6, 0), (7, 1), (8, 2), (9, 6)] {
        action[(row, target)] = 1.0;
    }
    let mut out = Vec::new();
    let eig = action.complex_eigenvalues();
    let scale = action.amax().max(1.0);
    for lambda in eig.iter() {
        if lambda.im.abs() > 1e-8 * scale.max(lambda.re.abs()) {
            continue;
        }
        let Some(v) = eigenvector(&action, lambda.re) else {
            continue;
        };
        if v[9].abs() < 1e-12 * v.amax() {
            continue;
        }
        let (x, y, z) = (v[6] / v[9], v[7] / v[9], v[8] / v[9]);
        let em = basis[0] * x + basis[1] * y + basis[2] * z + basis[3];
        let n = em.norm();
        if n.is_finite() && n > 0.0 {
            out.push(em / n);
        }
    }
    out
}

/// The eigenvector of `a` for the real eigenvalue `lambda`, by two steps of inverse iteration.
fn eigenvector(a: &SMatrix<f64, 10, 10>, lambda: f64) -> Option<SVector<f64, 10>> {
    let shift = lambda + 1e-10 * lambda.abs().max(1.0);
    let lu = (a - SMatrix::<f64, 10, 10>::identity() * shift).lu();
    let mut v = SVector::<f64, 10>::from_fn(|i, _| 1.0 + 0.1 * i as f64);
    for _ in 0..3 {
        let w = lu.solve(&v)?;
        let n = w.norm();
        if !(n.is_finite() && n > 0.0) {
            return None;
        }
        v = w / n;
    }
    Some(v)
}

/// A polynomial of degree ≤ 3 in (x, y, z), coefficients indexed by [`mono`].
#[derive(Clone, Copy)]
struct Poly {
    c: [f64; 20],
}

/// Exponents of the twenty monomials in the solver's order: the ten cubics, then the ten of
/// degree ≤ 2 (x², xy, xz, y², yz, z², x, y, z, 1).
const MONOMIALS: [(u8, u8, u8); 20] = [
    (3, 0, 0),
    (2, 1, 0),
    (2, 0, 1),
    (1, 2, 0),
    (1, 1, 1),
    (1, 0, 2),
    (0, 3, 0),
    (0, 2, 1),
    (0, 1, 2),
    (0, 0, 3),
    (2, 0, 0),
    (1, 1, 0),
    (1, 0, 1),
    (0, 2, 0),
    (0, 1, 1),
    (0, 0, 2),
    (1, 0, 0),
    (0, 1, 0),
    (0, 0, 1),
    (0, 0, 0),
];

/// Index of x^a y^b z^c in [`MONOMIALS`] (a + b + c ≤ 3).
const fn mono(a: u8, b: u8, c: u8) -> usize {
    let mut i = 0;
    while i < 20 {
        let m = MONOMIALS[i];
        if m.0 == a && m.1 == b && m.2 == c {
            return i;
        }
        i += 1;
    }
    panic!("monomial of degree over 3")
}

/// Product table: `PRODUCT[i][j]` is the index of monomial i times monomial j, or 255 when the
/// degree exceeds 3.
const PRODUCT: [[u8; 20]; 20] = {
    let mut t = [[255u8; 20]; 20];
    let mut i = 0;
    while i < 20 {
        let mut j = 0;
        while j < 20 {
            let (a, b) = (MONOMIALS[i], MONOMIALS[j]);
            if a.0 + a.1 + a.2 + b.0 + b.1 + b.2 <= 3 {
                t[i][j] = mono(a.0 + b.0, a.1 + b.1, a.2 + b.2) as u8;
            }
            j += 1;
        }
        i += 1;
    }
    t
};

impl Poly {
    fn zero() -> Self {
        Poly { c: [0.0; 20] }
    }

    fn add(&self, o: &Poly) -> Poly {
        Poly {
            c: std::array::from_fn(|i| self.c[i] + o.c[i]),
        }
    }

    fn sub(&self, o: &Poly) -> Poly {
        Poly {
            c: std::array::from_fn(|i| self.c[i] - o.c[i]),
        }
    }

    fn scale(&self, s: f64) -> Poly {
        Poly {
            c: self.c.map(|v| v * s),
        }
    }

    /// The product; terms of degree over 3 never arise in the solver (their factors' degrees
    /// add to at most 3) and are dropped.
    fn mul(&self, o: &Poly) -> Poly {
        let mut r = Poly::zero();
        for (i, &a) in self.c.iter().enumerate() {
            if a == 0.0 {
                continue;
            }
            for (j, &b) in o.c.iter().enumerate() {
                let k = PRODUCT[i][j];
                if b != 0.0 && k != 255 {
                    r.c[k as usize] += a * b;
                }
            }
        }
        r
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rotation::axis_angle_to_r;
    use crate::synthetic::gaussian;
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64;

    fn skew(t: &Vector3<f64>) -> Matrix3<f64> {
        Matrix3::new(0.0, -t.z, t.y, t.z, 0.0, -t.x, -t.y, t.x, 0.0)
    }

    /// Five points seen by [I|0] and [R|t]; `planar`: on the plane z = 4 + 0.2x.
    fn sample(
        rng: &mut Pcg64,
        planar: bool,
    ) -> ([Vector3<f64>; 5], [Vector3<f64>; 5], Matrix3<f64>) {
        let r =
            axis_angle_to_r(&Vector3::new(gaussian(rng), gaussian(rng), gaussian(rng)).scale(0.2));
        let t = Vector3::new(gaussian(rng), gaussian(rng), gaussian(rng) * 0.3).normalize();
        let mut a = [Vector3::zeros(); 5];
        let mut b = [Vector3::zeros(); 5];
        for i in 0..5 {
            let (x, y) = (rng.random_range(-1.5..1.5), rng.random_range(-1.0..1.0));
            let z = if planar {
                4.0 + 0.2 * x
            } else {
                rng.random_range(3.0..6.0)
            };
            let p = Vector3::new(x, y, z);
            let q = r * p + t;
            a[i] = p / p.z;
            b[i] = q / q.z;
        }
        let e = skew(&t) * r;
        (a, b, e / e.norm())
    }

    fn closest(es: &[Matrix3<f64>], truth: &Matrix3<f64>) -> f64 {
        es.iter()
            .map(|e| (e - truth).norm().min((e + truth).norm()))
            .fold(f64::INFINITY, f64::min)
    }

    #[test]
    fn exact_at_zero_noise_general_and_planar() {
        let mut rng = Pcg64::seed_from_u64(5);
        for planar in [false, true] {
            let mut worst: f64 = 0.0;
            for _ in 0..200 {
                let (a, b, e) = sample(&mut rng, planar);
                let es = essential_five_point(&a, &b);
                assert!(!es.is_empty() && es.len() <= 10);
                for m in &es {
                    for i in 0..5 {
                        assert!(b[i].dot(&(m * a[i])).abs() < 1e-8);
                    }
                }
                worst = worst.max(closest(&es, &e));
            }
            assert!(worst < 1e-6, "planar {planar}: {worst}");
        }
    }

    #[test]
    fn every_solution_is_an_essential_matrix() {
        let mut rng = Pcg64::seed_from_u64(6);
        for _ in 0..50 {
            let (a, b, _) = sample(&mut rng, false);
            for e in essential_five_point(&a, &b) {
                let s = e.singular_values();
                let mut s: Vec<f64> = s.iter().copied().collect();
                s.sort_by(f64::total_cmp);
                assert!(s[0] < 1e-8 && (s[1] - s[2]).abs() < 1e-8, "{s:?}");
            }
        }
    }

    #[test]
    fn degenerate_samples_give_no_panic() {
        let p = Vector3::new(0.1, 0.2, 1.0);
        assert!(essential_five_point(&[p; 5], &[p; 5]).len() <= 10);
        let nan = Vector3::new(f64::NAN, 0.0, 1.0);
        assert!(essential_five_point(&[nan; 5], &[p; 5]).is_empty());
    }
}
