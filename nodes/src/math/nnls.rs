//! Non-negative least squares by Lawson and Hanson's active-set method (Solving Least
//! Squares Problems, 1974, ch. 23): minimise ‖A x − b‖ subject to x ≥ 0.
//!
//! Steps:
//! 1. Start with every variable held at zero (the active set) and x = 0.
//! 2. The gradient w = Aᵀ(b − A x) says which held variable would lower the residual when
//!    released; stop when none has w_j above the tolerance.
//! 3. Release the one with the largest w_j and solve the unconstrained least-squares
//!    problem on the released (passive) variables.
//! 4. If that solution has a non-positive entry, step from x towards it only as far as
//!    stays feasible, hold the variables that reached zero again, and re-solve (inner
//!    loop); otherwise accept it and go to 2.
//!
//! The sub-problems are solved by SVD with a relative singular-value cut-off, so rank
//! deficiency (two joints moving a vertex identically) yields the minimum-norm solution
//! instead of a blow-up.

use nalgebra::{DMatrix, DVector};

/// Why a non-negative least-squares problem could not be solved.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum NnlsError {
    /// `A` has no rows or columns, or `b` does not match `A`'s rows.
    #[error("NNLS needs a non-empty matrix and a right-hand side of its row count ({rows} × {cols} with {rhs} values)")]
    Shape {
        /// Rows of `A`.
        rows: usize,
        /// Columns of `A`.
        cols: usize,
        /// Entries of `b`.
        rhs: usize,
    },
    /// `A` or `b` holds NaN or infinity.
    #[error("NNLS input holds a non-finite number")]
    NonFinite,
}

/// Result of [`nnls`].
#[derive(Debug, Clone, PartialEq)]
pub struct NnlsSolution {
    /// The non-negative minimiser.
    pub x: DVector<f64>,
    /// ‖A x − b‖ at the solution.
    pub residual_norm: f64,
}

/// Solves min ‖A x − b‖, x ≥ 0 (see the module docs for the steps).
pub fn nnls(a: &DMatrix<f64>, b: &DVector<f64>) -> Result<NnlsSolution, NnlsError> {
    let (rows, cols) = a.shape();
    if rows == 0 || cols == 0 || b.len() != rows {
        return Err(NnlsError::Shape { rows, cols, rhs: b.len() });
    }
    if a.iter().chain(b.iter()).any(|v| !v.is_finite()) {
        return Err(NnlsError::NonFinite);
    }
    let scale = a.iter().fold(0.0f64, |m, v| m.max(v.abs())).max(f64::MIN_POSITIVE);
    let tolerance = 10.0 * f64::EPSILON * scale * scale * rows.max(cols) as f64 * b.amax().max(1.0);
    let mut x = DVector::<f64>::zeros(cols);
    let mut passive = vec![false; cols];
    // Lawson and Hanson bound the outer loop by 3n; the bound only matters for degenerate
    // input, where it returns the best feasible point found.
    for _ in 0..3 * cols {
        let w = a.transpose() * (b - a * &x);
        let Some((t, _)) = (0..cols)
            .filter(|&j| !passive[j] && w[j] > tolerance)
            .map(|j| (j, w[j]))
            .max_by(|l, r| l.1.total_cmp(&r.1))
        else {
            break;
        };
        passive[t] = true;
        loop {
            let s = passive_least_squares(a, b, &passive);
            let blocking: Vec<usize> = (0..cols).filter(|&j| passive[j] && s[j] <= 0.0).collect();
            if blocking.is_empty() {
                x = s;
                break;
            }
            let alpha = blocking
                .iter()
                .map(|&j| {
                    let denominator = x[j] - s[j];
                    if denominator > 0.0 { x[j] / denominator } else { 0.0 }
                })
                .fold(1.0f64, f64::min);
            x += (s - &x) * alpha;
            for j in 0..cols {
                if passive[j] && x[j] <= tolerance {
                    passive[j] = false;
                    x[j] = 0.0;
                }
            }
            if !passive.iter().any(|p| *p) {
                break;
            }
        }
    }
    let residual_norm = (a * &x - b).norm();
    Ok(NnlsSolution { x, residual_norm })
}

/// Unconstrained least squares on the passive columns (others zero).
fn passive_least_squares(a: &DMatrix<f64>, b: &DVector<f64>, passive: &[bool]) -> DVector<f64> {
    let columns: Vec<usize> = (0..passive.len()).filter(|&j| passive[j]).collect();
    let sub = a.select_columns(&columns);
    let svd = sub.svd(true, true);
    let cutoff = svd.singular_values.max() * 1e-12 * columns.len().max(a.nrows()) as f64;
    let mut out = DVector::zeros(passive.len());
    // `solve` only fails when U or Vᵀ were not computed, and both were requested above.
    if let Ok(s) = svd.solve(b, cutoff) {
        for (k, &j) in columns.iter().enumerate() {
            out[j] = s[k];
        }
    }
    out
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;

    /// A small deterministic generator so the cases are reproducible without a crate.
    fn lcg(seed: &mut u64) -> f64 {
        *seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((*seed >> 11) as f64) / ((1u64 << 53) as f64) * 2.0 - 1.0
    }

    #[test]
    fn agrees_with_the_nnls_crate_on_random_problems() {
        let mut seed = 7u64;
        for case in 0..200 {
            let rows = 3 + case % 9;
            let cols = 1 + case % 7;
            let a = DMatrix::from_fn(rows, cols, |_, _| lcg(&mut seed));
            let b = DVector::from_fn(rows, |_, _| lcg(&mut seed));
            let ours = nnls(&a, &b).unwrap();
            let a_nd = ndarray::Array2::from_shape_fn((rows, cols), |(i, j)| a[(i, j)]);
            let b_nd = ndarray::Array1::from_shape_fn(rows, |i| b[i]);
            let (x_ref, r_ref) = ::nnls::nnls(a_nd.view(), b_nd.view());
            assert!((ours.residual_norm - r_ref).abs() < 1e-8, "case {case}: {} vs {r_ref}", ours.residual_norm);
            for j in 0..cols {
                assert!(ours.x[j] >= 0.0);
                assert!((ours.x[j] - x_ref[j]).abs() < 1e-6, "case {case} x{j}: {} vs {}", ours.x[j], x_ref[j]);
            }
        }
    }

    #[test]
    fn textbook_case_and_degenerate_inputs() {
        // min ‖(x₁ − 2, x₁ − 1, x₂ − 1)‖: x₁ = 1.5, x₂ = 1, residual √0.5.
        let a = DMatrix::from_row_slice(3, 2, &[1.0, 0.0, 1.0, 0.0, 0.0, 1.0]);
        let b = DVector::from_row_slice(&[2.0, 1.0, 1.0]);
        let s = nnls(&a, &b).unwrap();
        assert!((s.x[0] - 1.5).abs() < 1e-12 && (s.x[1] - 1.0).abs() < 1e-12);
        assert!((s.residual_norm - 0.5f64.sqrt()).abs() < 1e-12);
        // A wanted negative value is held at zero.
        let s = nnls(&DMatrix::from_row_slice(1, 1, &[1.0]), &DVector::from_row_slice(&[-3.0])).unwrap();
        assert_eq!(s.x[0], 0.0);
        // Identical columns: still feasible and optimal.
        let a = DMatrix::from_row_slice(2, 2, &[1.0, 1.0, 2.0, 2.0]);
        let s = nnls(&a, &DVector::from_row_slice(&[1.0, 2.0])).unwrap();
        assert!(s.residual_norm < 1e-9 && s.x.iter().all(|v| *v >= 0.0));
        assert!(nnls(&DMatrix::zeros(0, 2), &DVector::zeros(0)).is_err());
        assert!(nnls(&a, &DVector::from_row_slice(&[f64::NAN, 1.0])).is_err());
    }
}
