//! Point-to-point: the weighted least-squares rigid motion between matched points in closed
//! form (Arun, Huang & Blostein 1987; Umeyama 1991 for the reflection fix), by SVD of the 3x3
//! cross-covariance.

use nalgebra::{Isometry3, Matrix3, Point3, Translation3, UnitQuaternion, Vector3};

/// A singular value of the cross-covariance below this fraction of the largest means the
/// matched points are (nearly) collinear, which leaves the rotation about that line free.
const COLLINEAR_RATIO: f64 = 1e-12;

/// Weighted sums of matched pairs `(a, b)` = (source, target) relative to a common centre.
#[derive(Debug, Clone, Copy)]
pub(crate) struct PointToPoint {
    w: f64,
    sa: Vector3<f64>,
    sb: Vector3<f64>,
    sab: Matrix3<f64>,
}

impl PointToPoint {
    pub(crate) fn zero() -> Self {
        Self {
            w: 0.0,
            sa: Vector3::zeros(),
            sb: Vector3::zeros(),
            sab: Matrix3::zeros(),
        }
    }

    /// Adds the pair `a -> b` (both relative to the centre) with weight `w`.
    #[inline]
    pub(crate) fn add(&mut self, a: &Vector3<f64>, b: &Vector3<f64>, w: f64) {
        self.w += w;
        self.sa += w * a;
        self.sb += w * b;
        self.sab += (w * a) * b.transpose();
    }

    pub(crate) fn merge(mut self, o: Self) -> Self {
        self.w += o.w;
        self.sa += o.sa;
        self.sb += o.sb;
        self.sab += o.sab;
        self
    }

    /// The motion that best maps the `a`s onto the `b`s, as a motion of absolute coordinates
    /// (pairs were taken relative to `centre`); `None` if degenerate.
    pub(crate) fn solve(&self, centre: &Point3<f64>) -> Option<Isometry3<f64>> {
        if self.w.is_nan() || self.w <= 0.0 {
            return None;
        }
        let ma = self.sa / self.w;
        let mb = self.sb / self.w;
        // Σ w (a - ma)(b - mb)^T
        let s = self.sab - (self.w * ma) * mb.transpose();
        let svd = s.svd(true, true);
        let (u, v_t) = (svd.u?, svd.v_t?);
        let sv = svd.singular_values;
        if sv.max().is_nan()
            || sv.max() <= 0.0
            || sv
                .iter()
                .filter(|&&x| x > sv.max() * COLLINEAR_RATIO)
                .count()
                < 2
        {
            return None;
        }
        // S = U Σ V^T maps... the rotation maximising tr(R S) is R = V D U^T.
        let v = v_t.transpose();
        let d = (v * u.transpose()).determinant().signum();
        let r = v * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * u.transpose();
        let rot = UnitQuaternion::from_matrix(&r);
        // b = R (a - ma) + mb in centred coordinates; x = a + c.
        let t = mb - rot * ma + centre.coords - rot * centre.coords;
        Some(Isometry3::from_parts(Translation3::from(t), rot))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn recovers_a_known_motion_exactly() {
        let truth = Isometry3::new(Vector3::new(3.0, -1.0, 2.0), Vector3::new(0.4, -0.7, 1.1));
        let c = Point3::new(5.0, 5.0, 5.0);
        let mut acc = PointToPoint::zero();
        for i in 0..20 {
            let x = Point3::new(
                (i * 7 % 5) as f64,
                (i * 3 % 11) as f64,
                (i % 4) as f64 * 2.0,
            );
            let y = truth * x;
            acc.add(&(x - c), &(y - c), 1.0 + i as f64 * 0.1);
        }
        let got = acc.solve(&c).unwrap();
        assert_relative_eq!(got, truth, epsilon = 1e-10);
        // Collinear points leave a rotation free.
        let mut line = PointToPoint::zero();
        for i in 0..5 {
            let x = Vector3::new(i as f64, 0.0, 0.0);
            line.add(&x, &x, 1.0);
        }
        assert!(line.solve(&Point3::origin()).is_none());
        assert!(PointToPoint::zero().solve(&c).is_none());
    }
}
