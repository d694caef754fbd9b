//! Generalized ICP, plane-to-plane (Segal, Haehnel & Thrun 2009).
//!
//! Each point is a Gaussian with covariance `C = I - (1 - ε) n n^T` (variance `ε` along its
//! unit normal `n`, 1 along the surface; the identity where the normal is unknown). The
//! residual `d = q - p` of a pair is weighted by `M = (C_q + R C_p R^T)^-1`; linearising the
//! motion `(ω, v)` about a centre `c` with `a = p - c` gives `d(ω, v) ≈ d + [a]x ω - v`, i.e.
//! `J = [[a]x | -I]`, and Gauss-Newton solves `(Σ J^T M J) δ = -Σ J^T M d`.

use std::ops::AddAssign;

use nalgebra::{Matrix3, Matrix6, Vector3, Vector6};

use crate::se3::skew;

/// The normal equations of generalized ICP.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Generalized {
    pub(crate) h: Matrix6<f64>,
    pub(crate) g: Vector6<f64>,
}

/// `M = (C_q + C_p)^-1` for the plane covariances of unit normals `np` (already rotated into
/// the target frame) and `nq`; zero normals give an isotropic side.
#[inline]
pub(crate) fn combined_information(
    np: &Vector3<f64>,
    nq: &Vector3<f64>,
    epsilon: f64,
) -> Option<Matrix3<f64>> {
    let s = 1.0 - epsilon;
    let c = Matrix3::from_diagonal_element(2.0) - s * (np * np.transpose() + nq * nq.transpose());
    c.try_inverse()
}

impl Generalized {
    pub(crate) fn zero() -> Self {
        Self {
            h: Matrix6::zeros(),
            g: Vector6::zeros(),
        }
    }

    /// Adds the pair with source at `a` (relative to the centre), residual `d = q - p` and
    /// information `m`, weight `w`.
    #[inline]
    pub(crate) fn add(&mut self, a: &Vector3<f64>, d: &Vector3<f64>, m: &Matrix3<f64>, w: f64) {
        let ax = skew(a);
        let wm = w * m;
        let axm = ax * wm; // [a]x M
        let tl = -(axm * ax); // [a]x^T M [a]x = -[a]x M [a]x
        let tr = axm; // [a]x^T M (-I) = [a]x M
        let bl = -(wm * ax); // (-I) M [a]x
        self.h.fixed_view_mut::<3, 3>(0, 0).add_assign(&tl);
        self.h.fixed_view_mut::<3, 3>(0, 3).add_assign(&tr);
        self.h.fixed_view_mut::<3, 3>(3, 0).add_assign(&bl);
        self.h.fixed_view_mut::<3, 3>(3, 3).add_assign(&wm);
        let md = wm * d;
        let top = -a.cross(&md);
        self.g += Vector6::new(top.x, top.y, top.z, -md.x, -md.y, -md.z);
    }

    pub(crate) fn merge(mut self, o: Self) -> Self {
        self.h += o.h;
        self.g += o.g;
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn normal_matrix_equals_explicit_jacobian_product() {
        // Compare the hand-expanded blocks with J^T M J and J^T M d built from J = [[a]x | -I].
        let a = Vector3::new(0.3, -1.2, 2.5);
        let d = Vector3::new(0.01, -0.02, 0.05);
        let m = combined_information(
            &Vector3::new(0.0, 0.6, 0.8),
            &Vector3::new(0.0, 0.0, 1.0),
            1e-3,
        )
        .unwrap();
        let mut acc = Generalized::zero();
        acc.add(&a, &d, &m, 2.0);
        let mut j = nalgebra::Matrix3x6::zeros();
        j.fixed_view_mut::<3, 3>(0, 0).copy_from(&skew(&a));
        j.fixed_view_mut::<3, 3>(0, 3)
            .copy_from(&(-Matrix3::identity()));
        assert_relative_eq!(acc.h, 2.0 * j.transpose() * m * j, epsilon = 1e-9);
        assert_relative_eq!(acc.g, 2.0 * j.transpose() * m * d, epsilon = 1e-12);
        // The information of two coplanar points is large along the normal: ~1/(2ε).
        let n = Vector3::z();
        let m = combined_information(&n, &n, 1e-3).unwrap();
        assert_relative_eq!(m[(2, 2)], 1.0 / 2e-3, max_relative = 1e-12);
        assert_relative_eq!(m[(0, 0)], 0.5, max_relative = 1e-12);
    }
}
