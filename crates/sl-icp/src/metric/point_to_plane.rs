//! Point-to-plane: the distance of each source point to the tangent plane of its target point,
//! linearised in a small motion `(ω, v)` about a centre `c` and solved as a 6x6 system.
//!
//! With `a = p - c`, `r = n·(p - q)`: `r(ω, v) ≈ r + (a × n)·ω + n·v`.

use nalgebra::{Matrix6, Vector3, Vector6};

/// The normal equations `H = Σ w J J^T`, `g = Σ w J r`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct PointToPlane {
    pub(crate) h: Matrix6<f64>,
    pub(crate) g: Vector6<f64>,
}

impl PointToPlane {
    pub(crate) fn zero() -> Self {
        Self {
            h: Matrix6::zeros(),
            g: Vector6::zeros(),
        }
    }

    /// Adds a source point at `a` (relative to the centre) with plane residual `r` against a
    /// target plane of unit normal `n`, weight `w`.
    #[inline]
    pub(crate) fn add(&mut self, a: &Vector3<f64>, n: &Vector3<f64>, r: f64, w: f64) {
        let axn = a.cross(n);
        let j = Vector6::new(axn.x, axn.y, axn.z, n.x, n.y, n.z);
        let wj = w * j;
        self.h.ger(1.0, &wj, &j, 1.0);
        self.g += wj * r;
    }

    pub(crate) fn merge(mut self, o: Self) -> Self {
        self.h += o.h;
        self.g += o.g;
        self
    }
}
