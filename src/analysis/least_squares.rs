//! Nonlinear least squares for `calibrate`'s joint fit: Levenberg–Marquardt steps on a
//! Jacobian estimated by finite differences, and the covariance of the fitted parameters.
//!
//! The problem: parameters θ (one fragment factor per zone), residuals e(θ) (predicted −
//! sampled grade, one per matched drawpoint-period), minimise S = Σ e². Near θ the
//! residuals are linear, e(θ + Δ) ≈ e + J Δ, J the Jacobian ∂e/∂θ. The Gauss–Newton step
//! solves JᵀJ Δ = −Jᵀe; Levenberg–Marquardt adds λ diag(JᵀJ) to JᵀJ, which shortens the
//! step and turns it towards steepest descent where the linear model is not trusted.
//!
//! # Covariance
//! With A = JᵀJ and σ̂² = S / (n − K) (n rows, K parameters), the usual covariance of θ̂ is
//! σ̂² A⁻¹. It assumes the rows' errors are independent. A drawpoint's errors are not: the
//! markers it draws spread over neighbouring periods, and the same wide or narrow IMZ
//! shifts all its periods together. The cluster-robust ("sandwich") covariance treats each
//! drawpoint as one cluster g, A⁻¹ (Σ_g J_gᵀ e_g e_gᵀ J_g) A⁻¹ × G / (G − 1), G clusters.
//! [`Linearised::covariance`] gives both; `calibrate` reports the larger variance.

use nalgebra::{DMatrix, DVector};

/// The residuals and their Jacobian over the rows common to every run they were made from.
#[derive(Debug, Clone)]
pub struct Linearised {
    /// Residual e per row.
    pub e: DVector<f64>,
    /// Jacobian ∂e/∂θ, one row per residual, one column per parameter.
    pub j: DMatrix<f64>,
    /// Cluster (drawpoint) of each row.
    pub cluster: Vec<usize>,
}

impl Linearised {
    /// The Levenberg–Marquardt step Δ for damping λ: (A + λ diag A) Δ = −Jᵀe, A = JᵀJ.
    /// None when the system is singular (a parameter that no row responds to).
    pub fn step(&self, lambda: f64) -> Option<DVector<f64>> {
        let mut a = self.j.transpose() * &self.j;
        for k in 0..a.nrows() {
            a[(k, k)] *= 1.0 + lambda;
        }
        let g = self.j.transpose() * &self.e;
        a.cholesky().map(|c| -c.solve(&g))
    }

    /// A⁻¹ = (JᵀJ)⁻¹, or None when singular.
    pub fn inverse_normal(&self) -> Option<DMatrix<f64>> {
        (self.j.transpose() * &self.j).try_inverse()
    }

    /// The plain covariance σ̂² A⁻¹ and the cluster-robust one (module docs), with the
    /// residuals `e` at the fitted θ̂ (this Jacobian's rows). None when singular or when
    /// there are no more rows than parameters.
    pub fn covariance(&self, e: &DVector<f64>) -> Option<(DMatrix<f64>, DMatrix<f64>)> {
        let (n, k) = self.j.shape();
        if n <= k {
            return None;
        }
        let inv = self.inverse_normal()?;
        let plain = &inv * (e.norm_squared() / (n - k) as f64);
        let groups = self.cluster.iter().max().map_or(0, |m| m + 1);
        let mut score = DMatrix::<f64>::zeros(groups, k);
        for r in 0..n {
            for c in 0..k {
                score[(self.cluster[r], c)] += self.j[(r, c)] * e[r];
            }
        }
        let used = (0..groups)
            .filter(|&g| score.row(g).iter().any(|v| *v != 0.0))
            .count();
        let meat = score.transpose() * &score;
        let scale = if used > 1 {
            used as f64 / (used - 1) as f64
        } else {
            1.0
        };
        Some((plain, &inv * meat * &inv * scale))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On a linear problem e = J θ − y the Gauss–Newton step (λ = 0) lands on the least
    /// squares solution in one step, and the plain covariance is σ̂² (JᵀJ)⁻¹.
    #[test]
    fn gauss_newton_solves_a_linear_problem_in_one_step() {
        let j = DMatrix::from_row_slice(4, 2, &[1.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0, -1.0]);
        let y = DVector::from_column_slice(&[1.0, 2.0, 3.2, -0.9]);
        let theta0 = DVector::from_column_slice(&[0.0, 0.0]);
        let lin = Linearised {
            e: &j * &theta0 - &y,
            j: j.clone(),
            cluster: vec![0, 1, 2, 3],
        };
        let step = lin.step(0.0).unwrap();
        let normal = (j.transpose() * &j).try_inverse().unwrap();
        let exact = &normal * j.transpose() * &y;
        assert!((&step - &exact).norm() < 1e-12, "{step} against {exact}");
        // Damping shortens the step.
        assert!(lin.step(1.0).unwrap().norm() < step.norm());
        let e = &j * &exact - &y;
        let (plain, robust) = lin.covariance(&e).unwrap();
        let want = &normal * (e.norm_squared() / 2.0);
        assert!((&plain - &want).norm() < 1e-12);
        assert!(robust.iter().all(|v| v.is_finite()));
        // Rows that are one cluster each and a parameter no row responds to.
        let flat = Linearised {
            e: lin.e.clone(),
            j: DMatrix::from_row_slice(4, 2, &[1.0, 0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 0.0]),
            cluster: vec![0; 4],
        };
        assert!(flat.step(0.0).is_none() && flat.covariance(&e).is_none());
    }
}
