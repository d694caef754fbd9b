//! The quadric error of Garland & Heckbert ("Surface simplification using quadric error
//! metrics", SIGGRAPH 1997): the weighted sum of squared distances to a set of planes, which
//! [`decimate`](crate::decimate) and [`simplify`](crate::simplify) carry at every vertex and add
//! up over each collapse.

use nalgebra::{Matrix3, Point3, Vector3};

/// A symmetric quadric `Q(x) = xᵀAx + 2bᵀx + c` (A's upper triangle, b, c) and the summed
/// weight `w` of its planes (their area, for the mean squared distance `Q(x) / w`).
///
/// `decimate` and `simplify` each had a quadric of their own; they are this one type now, but
/// the two kept their arithmetic to the last bit (their meshes are unchanged), so two pieces
/// come in two kinds:
///
/// - a plane's quadric: [`plane`](Self::plane) (`simplify`) weighs each entry as
///   `w·nᵢ·nⱼ`, [`plane_outer`](Self::plane_outer) (`decimate`) forms `n nᵀ` first and weighs
///   it after, `(nᵢ·nⱼ)·w`: the same quadric up to rounding;
/// - the best position of a merged vertex: [`best_pulled`](Self::best_pulled) (`simplify`)
///   pulls the minimum weakly towards the edge's midpoint, can hold it to a plane, and
///   returns the *mean* squared distance; [`best`](Self::best) (`decimate`) takes the
///   unregularised minimum only when `A` is well conditioned, and returns the *summed* error.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Quadric {
    a: [f64; 6],
    b: [f64; 3],
    c: f64,
    w: f64,
}

impl Quadric {
    /// The squared distance to the plane through `p` with unit normal `n`, times `w`, each
    /// entry weighed first (`w·nᵢ·nⱼ`; `simplify`'s rounding).
    pub(crate) fn plane(n: Vector3<f64>, p: &Point3<f64>, w: f64) -> Self {
        let d = -n.dot(&p.coords);
        Self {
            a: [
                w * n.x * n.x,
                w * n.x * n.y,
                w * n.x * n.z,
                w * n.y * n.y,
                w * n.y * n.z,
                w * n.z * n.z,
            ],
            b: [w * n.x * d, w * n.y * d, w * n.z * d],
            c: w * d * d,
            w,
        }
    }

    /// The same plane's quadric as [`plane`](Self::plane), with `n nᵀ` formed first and
    /// weighed after (`(nᵢ·nⱼ)·w`; `decimate`'s rounding).
    pub(crate) fn plane_outer(n: Vector3<f64>, p: &Point3<f64>, w: f64) -> Self {
        let d = -n.dot(&p.coords);
        let a = n * n.transpose() * w;
        let b = n * d * w;
        Self {
            a: [
                a[(0, 0)],
                a[(0, 1)],
                a[(0, 2)],
                a[(1, 1)],
                a[(1, 2)],
                a[(2, 2)],
            ],
            b: [b.x, b.y, b.z],
            c: d * d * w,
            w,
        }
    }

    /// Adds `o` to this quadric.
    pub(crate) fn add(&mut self, o: &Self) {
        for k in 0..6 {
            self.a[k] += o.a[k];
        }
        for k in 0..3 {
            self.b[k] += o.b[k];
        }
        self.c += o.c;
        self.w += o.w;
    }

    /// The sum of this quadric and `o`.
    pub(crate) fn sum(&self, o: &Self) -> Self {
        let mut s = *self;
        s.add(o);
        s
    }

    /// `Q(p)`, the summed weighted squared distance (at least 0).
    pub(crate) fn eval(&self, p: &Point3<f64>) -> f64 {
        let [a00, a01, a02, a11, a12, a22] = self.a;
        let (x, y, z) = (p.x, p.y, p.z);
        let q = x * (a00 * x + a01 * y + a02 * z)
            + y * (a01 * x + a11 * y + a12 * z)
            + z * (a02 * x + a12 * y + a22 * z)
            + 2.0 * (self.b[0] * x + self.b[1] * y + self.b[2] * z)
            + self.c;
        q.max(0.0)
    }

    /// The mean squared distance at `p`: `Q(p) / w` (0 without weight).
    pub(crate) fn mean(&self, p: &Point3<f64>) -> f64 {
        if self.w > 0.0 {
            self.eval(p) / self.w
        } else {
            0.0
        }
    }

    /// `A` as a full symmetric matrix.
    fn matrix(&self) -> Matrix3<f64> {
        let [a00, a01, a02, a11, a12, a22] = self.a;
        Matrix3::new(a00, a01, a02, a01, a11, a12, a02, a12, a22)
    }

    /// `decimate`'s position of least error for merging the vertices at `p` and `q`, and its
    /// summed error `Q(x)`: the solution of `A x = −b` when `A` is well conditioned
    /// (`|det A| > 1e-9 (tr A)³`) and that lies within twice the edge's length of its
    /// midpoint, else the best of the two ends and the midpoint.
    pub(crate) fn best(&self, p: &Point3<f64>, q: &Point3<f64>) -> (Point3<f64>, f64) {
        let a = self.matrix();
        let scale = a.trace().abs().max(f64::MIN_POSITIVE);
        if a.determinant().abs() > 1e-9 * scale.powi(3)
            && let Some(inv) = a.try_inverse()
        {
            let x = Point3::from(-(inv * Vector3::from(self.b)));
            // Keep the optimum near the edge: far away it is a sign of a near-singular system.
            let reach = (q - p).norm() * 2.0;
            if (x - nalgebra::center(p, q)).norm() <= reach {
                return (x, self.eval(&x));
            }
        }
        [*p, *q, nalgebra::center(p, q)]
            .into_iter()
            .map(|x| (x, self.eval(&x)))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .unwrap_or((*p, 0.0))
    }

    /// `simplify`'s position of least error for merging the vertices at `p` and `q` (the
    /// minimum of `Q` pulled towards the midpoint with the weight `pull · w`) and its mean
    /// squared distance; with `plane = Some((g, h))`, the least error on the plane `g·x = h`.
    /// Falls back to the unconstrained position when the constraint cannot be met near the
    /// edge, and to the best of the two ends and the midpoint when the system is singular or
    /// its answer lies further than the edge's length from the midpoint.
    pub(crate) fn best_pulled(
        &self,
        p: &Point3<f64>,
        q: &Point3<f64>,
        pull: f64,
        plane: Option<(Vector3<f64>, f64)>,
    ) -> (Point3<f64>, f64) {
        let m = nalgebra::center(p, q);
        let reach = (q - p).norm_squared();
        let l = pull * self.w;
        let [a00, a01, a02, a11, a12, a22] = self.a;
        let (a00, a11, a22) = (a00 + l, a11 + l, a22 + l);
        // The inverse of the symmetric 3×3 matrix by its cofactors.
        let c00 = a11 * a22 - a12 * a12;
        let c01 = a02 * a12 - a01 * a22;
        let c02 = a01 * a12 - a02 * a11;
        let det = a00 * c00 + a01 * c01 + a02 * c02;
        if det.abs() > f64::MIN_POSITIVE {
            let c11 = a00 * a22 - a02 * a02;
            let c12 = a01 * a02 - a00 * a12;
            let c22 = a00 * a11 - a01 * a01;
            let inv = |r: [f64; 3]| {
                Vector3::new(
                    (c00 * r[0] + c01 * r[1] + c02 * r[2]) / det,
                    (c01 * r[0] + c11 * r[1] + c12 * r[2]) / det,
                    (c02 * r[0] + c12 * r[1] + c22 * r[2]) / det,
                )
            };
            let x0 = Point3::from(inv([
                -self.b[0] + l * m.x,
                -self.b[1] + l * m.y,
                -self.b[2] + l * m.z,
            ]));
            let near = |x: &Point3<f64>| {
                x.coords.iter().all(|c| c.is_finite()) && (x - m).norm_squared() <= reach
            };
            if let Some((g, h)) = plane {
                // Lagrange: x = x0 + A⁻¹g (h − g·x0) / (g·A⁻¹g).
                let y = inv([g.x, g.y, g.z]);
                let gy = g.dot(&y);
                if gy > 0.0 {
                    let x = x0 + y * ((h - g.dot(&x0.coords)) / gy);
                    if near(&x) {
                        return (x, self.mean(&x));
                    }
                }
            }
            if near(&x0) {
                return (x0, self.mean(&x0));
            }
        }
        [*p, *q, m]
            .into_iter()
            .map(|x| (x, self.mean(&x)))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .unwrap_or((m, 0.0))
    }
}

#[cfg(test)]
mod tests {
    use approx::assert_relative_eq;

    use super::*;

    /// Three planes through (1, 2, 3): both best positions find the corner, at zero error (up
    /// to the round-off of `c`, about 1e-15 here), and both roundings of a plane's quadric
    /// evaluate alike (to round-off).
    #[test]
    fn three_planes_meet_at_the_best_position() {
        let corner = Point3::new(1.0, 2.0, 3.0);
        let normals = [
            Vector3::new(1.0, 0.0, 0.0),
            Vector3::new(0.6, 0.8, 0.0),
            Vector3::new(0.0, 0.6, 0.8),
        ];
        let (mut weighed, mut outer) = (Quadric::default(), Quadric::default());
        for (n, w) in normals.iter().zip([1.0, 2.0, 0.5]) {
            weighed.add(&Quadric::plane(*n, &corner, w));
            outer.add(&Quadric::plane_outer(*n, &corner, w));
        }
        let (p, q) = (Point3::new(0.5, 2.0, 3.0), Point3::new(1.5, 2.1, 2.9));
        let (x, err) = outer.best(&p, &q);
        assert_relative_eq!(x, corner, epsilon = 1e-12);
        assert!(err < 1e-12, "{err}");
        let (x, err) = weighed.best_pulled(&p, &q, 0.0, None);
        assert_relative_eq!(x, corner, epsilon = 1e-12);
        assert!(err < 1e-12, "{err}");
        let far = Point3::new(4.0, -1.0, 7.0);
        assert_relative_eq!(weighed.eval(&far), outer.eval(&far), max_relative = 1e-14);
        assert_relative_eq!(
            weighed.mean(&far),
            weighed.eval(&far) / 3.5,
            max_relative = 1e-14
        );
    }
}
