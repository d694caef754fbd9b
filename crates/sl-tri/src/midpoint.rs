//! Midpoint triangulation: the point halfway between the closest points of the camera ray
//! and the projector ray (both undistorted), in closed form.

use nalgebra::Vector3;

use crate::stereo::Stereo;

/// The midpoint (camera frame, mm), or `None` for parallel rays or a closest point behind
/// either device.
#[inline]
pub(crate) fn midpoint(s: &Stereo, ray: &Vector3<f64>, xp: f64, yp: f64) -> Option<Vector3<f64>> {
    let d1 = *ray;
    let d2 = s.r_cp * Vector3::new(xp, yp, 1.0);
    let w0 = -s.c_p;
    let a = d1.dot(&d1);
    let b = d1.dot(&d2);
    let c = d2.dot(&d2);
    let d = d1.dot(&w0);
    let e = d2.dot(&w0);
    let den = a * c - b * b;
    let t1 = (b * e - c * d) / den;
    let t2 = (a * e - b * d) / den;
    if !(t1 > 0.0 && t2 > 0.0 && t1.is_finite() && t2.is_finite()) {
        return None;
    }
    Some((d1 * t1 + s.c_p + d2 * t2) * 0.5)
}
