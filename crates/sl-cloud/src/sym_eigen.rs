//! Closed-form eigen-solver for symmetric 3x3 matrices (covariances), after D. Eberly,
//! "A Robust Eigensolver for 3x3 Symmetric Matrices" (Geometric Tools, 2014): trigonometric
//! eigenvalues, eigenvectors from cross products of the rows of `A - λI`, with the well
//! separated eigenvalue solved first so that nearly repeated ones stay accurate.

use nalgebra::Vector3;

/// A symmetric 3x3 matrix stored as its upper triangle `[a00, a01, a02, a11, a12, a22]`.
pub(crate) type Sym3 = [f64; 6];

/// Eigenvalues in ascending order and the unit eigenvector of the smallest one.
#[derive(Debug, Clone, Copy)]
pub(crate) struct SmallestEigen {
    pub(crate) values: [f64; 3],
    pub(crate) vector: Vector3<f64>,
}

fn rows(a: &Sym3, lambda: f64) -> [Vector3<f64>; 3] {
    let [a00, a01, a02, a11, a12, a22] = *a;
    [
        Vector3::new(a00 - lambda, a01, a02),
        Vector3::new(a01, a11 - lambda, a12),
        Vector3::new(a02, a12, a22 - lambda),
    ]
}

/// Unit vector in the null space of `A - λI`, assuming `λ` is a simple eigenvalue: the largest
/// cross product of two rows. `None` if all rows vanish.
fn null_vector(a: &Sym3, lambda: f64) -> Option<Vector3<f64>> {
    let [r0, r1, r2] = rows(a, lambda);
    let c = [r0.cross(&r1), r0.cross(&r2), r1.cross(&r2)];
    let best = c
        .iter()
        .copied()
        .max_by(|x, y| x.norm_squared().total_cmp(&y.norm_squared()))?;
    let n2 = best.norm_squared();
    (n2 > 0.0 && n2.is_finite()).then(|| best / n2.sqrt())
}

/// Any unit vector orthogonal to unit `w`.
fn orthogonal(w: &Vector3<f64>) -> Vector3<f64> {
    let u = if w.x.abs() > w.y.abs() {
        Vector3::new(-w.z, 0.0, w.x)
    } else {
        Vector3::new(0.0, w.z, -w.y)
    };
    u.normalize()
}

fn mul(a: &Sym3, v: &Vector3<f64>) -> Vector3<f64> {
    let [a00, a01, a02, a11, a12, a22] = *a;
    Vector3::new(
        a00 * v.x + a01 * v.y + a02 * v.z,
        a01 * v.x + a11 * v.y + a12 * v.z,
        a02 * v.x + a12 * v.y + a22 * v.z,
    )
}

/// Eigenvalues (ascending) and the eigenvector of the smallest, for a symmetric matrix with
/// finite entries. For a multiple of the identity every vector is an eigenvector; `z` is
/// returned.
pub(crate) fn smallest_eigen(m: &Sym3) -> SmallestEigen {
    // Scale to max |entry| = 1: keeps the cubic well conditioned and avoids overflow.
    let scale = m.iter().fold(0.0f64, |s, v| s.max(v.abs()));
    if scale.is_nan() || scale <= 0.0 || !scale.is_finite() {
        return SmallestEigen {
            values: [0.0; 3],
            vector: Vector3::z(),
        };
    }
    let a: Sym3 = m.map(|v| v / scale);
    let [a00, a01, a02, a11, a12, a22] = a;
    let q = (a00 + a11 + a22) / 3.0;
    let (b00, b11, b22) = (a00 - q, a11 - q, a22 - q);
    let p2 = (b00 * b00 + b11 * b11 + b22 * b22 + 2.0 * (a01 * a01 + a02 * a02 + a12 * a12)) / 6.0;
    let p = p2.sqrt();
    if p < f64::EPSILON {
        // A is (numerically) q I.
        return SmallestEigen {
            values: [q * scale; 3],
            vector: Vector3::z(),
        };
    }
    // half determinant of B = (A - qI) / p, in [-1, 1] up to rounding.
    let det = b00 * (b11 * b22 - a12 * a12) - a01 * (a01 * b22 - a12 * a02)
        + a02 * (a01 * a12 - b11 * a02);
    let r = (det / (2.0 * p * p2)).clamp(-1.0, 1.0);
    let phi = r.acos() / 3.0;
    let beta2 = 2.0 * phi.cos();
    let beta0 = 2.0 * (phi + 2.0 * std::f64::consts::FRAC_PI_3).cos();
    let beta1 = -(beta0 + beta2);
    let values = [q + p * beta0, q + p * beta1, q + p * beta2];
    let vector = if r < 0.0 {
        // The smallest eigenvalue is the well separated one: solve it directly.
        null_vector(&a, values[0])
    } else {
        // The largest is well separated: find it, then solve the 2x2 problem in its
        // orthogonal complement for the smallest.
        null_vector(&a, values[2]).map(|w| {
            let u = orthogonal(&w);
            let v = w.cross(&u);
            let (au, av) = (mul(&a, &u), mul(&a, &v));
            let (m00, m01, m11) = (u.dot(&au) - values[0], u.dot(&av), v.dot(&av) - values[0]);
            // Null vector of [[m00, m01], [m01, m11]] from its longer row.
            let (x, y) = if m00 * m00 >= m11 * m11 {
                (-m01, m00)
            } else {
                (m11, -m01)
            };
            let e = u * x + v * y;
            let n = e.norm();
            if n > 0.0 { e / n } else { u }
        })
    }
    .unwrap_or_else(Vector3::z);
    SmallestEigen {
        values: values.map(|v| v * scale),
        vector,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use nalgebra::{Matrix3, Rotation3};
    use proptest::prelude::*;

    fn to_sym(m: &Matrix3<f64>) -> Sym3 {
        [
            m[(0, 0)],
            m[(0, 1)],
            m[(0, 2)],
            m[(1, 1)],
            m[(1, 2)],
            m[(2, 2)],
        ]
    }

    /// R diag(l) R^T: eigenvalues l, eigenvectors the columns of R.
    fn build(l: [f64; 3], r: &Rotation3<f64>) -> Matrix3<f64> {
        r.matrix() * Matrix3::from_diagonal(&Vector3::from(l)) * r.matrix().transpose()
    }

    #[test]
    fn recovers_known_decomposition() {
        let r = Rotation3::from_scaled_axis(Vector3::new(0.3, -1.1, 0.7));
        let m = build([0.01, 2.0, 5.0], &r);
        let e = smallest_eigen(&to_sym(&m));
        // Tolerances: a few ulps of the largest eigenvalue (the closed form loses no more).
        assert_relative_eq!(e.values[0], 0.01, epsilon = 1e-13);
        assert_relative_eq!(e.values[1], 2.0, epsilon = 1e-13);
        assert_relative_eq!(e.values[2], 5.0, epsilon = 1e-13);
        let want = r * Vector3::x();
        assert_relative_eq!(e.vector.dot(&want).abs(), 1.0, epsilon = 1e-12);
    }

    #[test]
    fn degenerate_cases() {
        // Zero, identity, and a plane (two equal large eigenvalues, smallest zero).
        assert_eq!(smallest_eigen(&[0.0; 6]).values, [0.0; 3]);
        let e = smallest_eigen(&[3.0, 0.0, 0.0, 3.0, 0.0, 3.0]);
        assert_relative_eq!(e.values[0], 3.0, epsilon = 1e-15);
        let e = smallest_eigen(&[1.0, 0.0, 0.0, 1.0, 0.0, 0.0]);
        assert_relative_eq!(e.vector.z.abs(), 1.0, epsilon = 1e-15);
        // A line: smallest two equal; any vector orthogonal to the line is right.
        let e = smallest_eigen(&[0.0, 0.0, 0.0, 0.0, 0.0, 4.0]);
        assert_relative_eq!(e.vector.z, 0.0, epsilon = 1e-15);
        assert_relative_eq!(e.vector.norm(), 1.0, epsilon = 1e-15);
    }

    proptest! {
        /// Against nalgebra's iterative solver, an independent implementation.
        #[test]
        fn agrees_with_nalgebra(
            axis in prop::array::uniform3(-3.0f64..3.0),
            l in prop::array::uniform3(0.0f64..10.0),
            scale_exp in -6i32..6,
        ) {
            let scale = 10f64.powi(scale_exp);
            let r = Rotation3::from_scaled_axis(Vector3::from(axis));
            let m = build(l, &r) * scale;
            let e = smallest_eigen(&to_sym(&m));
            let reference = m.symmetric_eigen();
            let mut want: Vec<f64> = reference.eigenvalues.iter().copied().collect();
            want.sort_by(f64::total_cmp);
            // Eigenvalues: absolute error a small multiple of eps * |A|.
            let tol = 1e-12 * 10.0 * scale;
            for i in 0..3 {
                prop_assert!((e.values[i] - want[i]).abs() <= tol, "{:?} vs {:?}", e.values, want);
            }
            // Eigenvector: residual |A v - λ0 v| small relative to |A| (meaningful even when
            // λ0 is repeated, where the vector itself is not unique).
            let resid = (m * e.vector - e.vector * e.values[0]).norm();
            prop_assert!(resid <= 1e-9 * 10.0 * scale, "residual {resid}");
            prop_assert!((e.vector.norm() - 1.0).abs() < 1e-12);
        }
    }
}
