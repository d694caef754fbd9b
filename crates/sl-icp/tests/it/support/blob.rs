//! A bumpy closed blob about 80 mm across, asymmetric enough to have one correct alignment:
//! the synthetic shape of the registration tests (shared by tests and `slscan`'s tests with
//! `#[path]`).
#![allow(dead_code)] // each includer uses what it needs

use nalgebra::{Point3, Vector3};

/// `n` points of the blob (mm) on a golden-angle spiral.
pub(crate) fn blob(n: usize) -> Vec<Point3<f64>> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let y = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let (r, t) = ((1.0 - y * y).sqrt(), golden * i as f64);
            let d = Vector3::new(r * t.cos(), y, r * t.sin());
            let bump = 6.0 * (3.0 * d.x).sin() * (2.0 * d.y + 0.5).cos()
                + 5.0 * (4.0 * d.z * d.x).sin()
                + 8.0 * (d.y - 0.6).max(0.0);
            Point3::from(d * (40.0 + bump))
        })
        .collect()
}
