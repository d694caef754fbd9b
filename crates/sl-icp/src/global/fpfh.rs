//! Fast Point Feature Histograms (Rusu, Blodow & Beetz, "Fast Point Feature Histograms (FPFH)
//! for 3D registration", ICRA 2009).
//!
//! For a point `p` and each neighbour `q` within `radius`, the Darboux frame of the pair gives
//! three angles (α, φ, θ); the simplified histogram (SPFH) of `p` bins each angle into 11 bins
//! (33 in all, each sub-histogram summing to 100). The FPFH of `p` is its SPFH plus the
//! distance-weighted mean of its neighbours' SPFHs, each sub-histogram of that mean scaled to
//! sum to 100 as well. Hand-written rather than taken from a crate: no maintained Rust crate
//! computes FPFH, and this loop is the hot part of global registration.

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;
use sl_cloud::KdIndex;

use crate::IcpError;

/// Bins per angle.
const BINS_PER_FEATURE: usize = 11;

/// Length of an FPFH descriptor: three angles, 11 bins each.
pub const FPFH_BINS: usize = 3 * BINS_PER_FEATURE;

/// One FPFH descriptor (f32: it is compared in a k-d tree of 33 dimensions, where halving the
/// bandwidth matters more than precision; each sub-histogram sums to about 200).
pub type Fpfh = [f32; FPFH_BINS];

/// Every sub-histogram of an SPFH (and of the weighted neighbour part of an FPFH) sums to this,
/// as in Rusu's PCL code and Open3D, so that descriptors of points with few or many
/// neighbours compare on the same scale.
const HISTOGRAM_MASS: f64 = 100.0;

/// Settings of [`compute_fpfh`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FpfhConfig {
    /// Neighbourhood radius, mm. Default 10 mm: five times the default 2 mm voxel, the ratio
    /// Rusu and Open3D's examples use; wide enough to see the shape of a bunny's flank,
    /// narrow enough to stay inside the overlap of two views.
    pub radius: f64,
    /// At most this many neighbours (the nearest) per point. Default 100, as Open3D's
    /// examples: a 10 mm ball holds about 80 points of a 2 mm voxel grid on a surface.
    pub max_neighbours: usize,
}

impl Default for FpfhConfig {
    fn default() -> Self {
        Self {
            radius: 10.0,
            max_neighbours: 100,
        }
    }
}

impl FpfhConfig {
    pub(crate) fn validate(&self) -> Result<(), IcpError> {
        if !(self.radius.is_finite() && self.radius > 0.0) {
            return Err(IcpError::invalid(
                "fpfh.radius",
                self.radius,
                "must be finite and > 0 (mm)",
            ));
        }
        if self.max_neighbours < 2 {
            return Err(IcpError::invalid(
                "fpfh.max_neighbours",
                self.max_neighbours,
                "must be at least 2",
            ));
        }
        Ok(())
    }
}

/// The three angles of the pair `(ps, ns)`, `(pt, nt)` in Rusu's Darboux frame, with the
/// source of the frame chosen as the point whose normal makes the smaller angle with the
/// line joining them (so that the result does not depend on the order of the pair):
/// `α = v·nt` in [-1, 1], `φ = u·d` in [-1, 1], `θ = atan2(w·nt, u·nt)` in [-π, π], with
/// `u = ns`, `v = u × d / |u × d|`, `w = u × v`, `d` the unit vector from source to target.
/// `None` when the points coincide or the normal lies along the line.
#[inline]
fn pair_angles(
    pa: &Point3<f64>,
    na: &Vector3<f64>,
    pb: &Point3<f64>,
    nb: &Vector3<f64>,
) -> Option<(f64, f64, f64)> {
    let d = pb - pa;
    let len = d.norm();
    if len <= 0.0 {
        return None;
    }
    let d = d / len;
    // Source: the larger cosine between its normal and the line toward the other point.
    let (ns, nt, d) = if na.dot(&d) >= -nb.dot(&d) {
        (na, nb, d)
    } else {
        (nb, na, -d)
    };
    let v = ns.cross(&d);
    let vn = v.norm();
    if vn <= f64::EPSILON {
        return None;
    }
    let v = v / vn;
    let w = ns.cross(&v);
    Some((v.dot(nt), ns.dot(&d), w.dot(nt).atan2(ns.dot(nt))))
}

/// Bin of `x` in `[lo, hi]` among [`BINS_PER_FEATURE`] (clamped).
#[inline]
fn bin(x: f64, lo: f64, hi: f64) -> usize {
    let b = ((x - lo) / (hi - lo) * BINS_PER_FEATURE as f64).floor();
    if b.is_nan() || b < 0.0 {
        0
    } else {
        (b as usize).min(BINS_PER_FEATURE - 1)
    }
}

/// Neighbours of every point within the radius (at most `max_neighbours`, the nearest, the
/// point itself excluded), in compressed rows.
struct Neighbourhoods {
    start: Vec<u32>,
    index: Vec<u32>,
    distance: Vec<f32>,
}

impl Neighbourhoods {
    fn of(&self, i: usize) -> (&[u32], &[f32]) {
        let (a, b) = (
            self.start.get(i).copied().unwrap_or(0) as usize,
            self.start.get(i + 1).copied().unwrap_or(0) as usize,
        );
        (
            self.index.get(a..b).unwrap_or(&[]),
            self.distance.get(a..b).unwrap_or(&[]),
        )
    }
}

fn neighbourhoods(points: &[Point3<f64>], index: &KdIndex, config: &FpfhConfig) -> Neighbourhoods {
    let lists: Vec<Vec<(u32, f32)>> = points
        .par_iter()
        .enumerate()
        .with_min_len(256)
        .map(|(i, p)| {
            let mut found = index.radius_unsorted(p, config.radius);
            found.retain(|n| n.index != i && n.distance_squared > 0.0);
            if found.len() > config.max_neighbours {
                found.select_nth_unstable_by(config.max_neighbours, |a, b| {
                    a.distance_squared.total_cmp(&b.distance_squared)
                });
                found.truncate(config.max_neighbours);
            }
            found
                .iter()
                .map(|n| (n.index as u32, n.distance_squared.sqrt() as f32))
                .collect()
        })
        .collect();
    let total: usize = lists.iter().map(Vec::len).sum();
    let mut start = Vec::with_capacity(points.len() + 1);
    let mut idx = Vec::with_capacity(total);
    let mut distance = Vec::with_capacity(total);
    start.push(0);
    for list in lists {
        for (j, d) in list {
            idx.push(j);
            distance.push(d);
        }
        start.push(idx.len() as u32);
    }
    Neighbourhoods {
        start,
        index: idx,
        distance,
    }
}

/// Computes the FPFH descriptor of every point from its neighbours within `config.radius`.
///
/// `normals` must be unit vectors (zero where unknown: such pairs are skipped) with a sign
/// that is consistent over the cloud (see [`orient_normals_outward`](crate::orient_normals_outward));
/// `index` must be built over `points`. A point with no usable neighbour gets an all-zero
/// descriptor. Runs in parallel on the rayon pool; the result does not depend on the number
/// of threads.
///
/// # Errors
/// [`IcpError::InvalidParameter`] for a bad configuration, or when `normals` or `index` do not
/// match `points` in length.
///
/// ```
/// use nalgebra::{Point3, Vector3};
/// use sl_cloud::KdIndex;
/// use sl_icp::{compute_fpfh, FpfhConfig};
/// // A flat grid: every pair of points has the same angles, so every descriptor is the same
/// // spike (one bin per angle), whatever the neighbourhood.
/// let pts: Vec<Point3<f64>> = (0..900).map(|i| Point3::new((i % 30) as f64, (i / 30) as f64, 0.0)).collect();
/// let normals = vec![Vector3::z(); pts.len()];
/// let f = compute_fpfh(&pts, &normals, &KdIndex::new(&pts)?, &FpfhConfig { radius: 3.0, max_neighbours: 50 })?;
/// assert_eq!(f.len(), 900);
/// let peaks = f[465].iter().filter(|&&v| v > 1.0).count();
/// assert_eq!(peaks, 3);
/// assert!((f[465].iter().sum::<f32>() - 600.0).abs() < 1e-2);
/// # Ok::<(), sl_icp::IcpError>(())
/// ```
pub fn compute_fpfh(
    points: &[Point3<f64>],
    normals: &[Vector3<f64>],
    index: &KdIndex,
    config: &FpfhConfig,
) -> Result<Vec<Fpfh>, IcpError> {
    config.validate()?;
    if normals.len() != points.len() {
        return Err(IcpError::invalid(
            "normals",
            format!("{} normals for {} points", normals.len(), points.len()),
            "one normal per point needed",
        ));
    }
    if index.len() != points.len() {
        return Err(IcpError::invalid(
            "index",
            format!("{} points indexed for {}", index.len(), points.len()),
            "the index must be built over the same points",
        ));
    }
    let hoods = neighbourhoods(points, index, config);
    // SPFH of every point, in f64 while summing.
    let spfh: Vec<[f64; FPFH_BINS]> = (0..points.len())
        .into_par_iter()
        .with_min_len(256)
        .map(|i| {
            let mut h = [0.0; FPFH_BINS];
            let (Some(p), Some(n)) = (points.get(i), normals.get(i)) else {
                return h;
            };
            if n.norm_squared() == 0.0 {
                return h;
            }
            let (idx, _) = hoods.of(i);
            let mut count = 0usize;
            let add = |h: &mut [f64; FPFH_BINS], b: [usize; 3]| {
                for (k, b) in b.iter().enumerate() {
                    if let Some(v) = h.get_mut(k * BINS_PER_FEATURE + b) {
                        *v += 1.0;
                    }
                }
            };
            for &j in idx {
                let (Some(q), Some(m)) = (points.get(j as usize), normals.get(j as usize)) else {
                    continue;
                };
                if m.norm_squared() == 0.0 {
                    continue;
                }
                if let Some((alpha, phi, theta)) = pair_angles(p, n, q, m) {
                    let bins = [
                        bin(alpha, -1.0, 1.0),
                        bin(phi, -1.0, 1.0),
                        bin(theta, -std::f64::consts::PI, std::f64::consts::PI),
                    ];
                    add(&mut h, bins);
                    count += 1;
                }
            }
            if count > 0 {
                let scale = HISTOGRAM_MASS / count as f64;
                for v in &mut h {
                    *v *= scale;
                }
            }
            h
        })
        .collect();
    // FPFH: own SPFH plus the 1/distance-weighted neighbours' SPFHs, renormalised.
    let out = (0..points.len())
        .into_par_iter()
        .with_min_len(256)
        .map(|i| {
            let mut acc = [0.0f64; FPFH_BINS];
            let (idx, dist) = hoods.of(i);
            for (&j, &d) in idx.iter().zip(dist) {
                let Some(s) = spfh.get(j as usize) else {
                    continue;
                };
                let w = 1.0 / f64::from(d);
                for (a, v) in acc.iter_mut().zip(s) {
                    *a += w * v;
                }
            }
            let own = spfh.get(i).copied().unwrap_or([0.0; FPFH_BINS]);
            let mut f = [0.0f32; FPFH_BINS];
            for k in 0..3 {
                let range = k * BINS_PER_FEATURE..(k + 1) * BINS_PER_FEATURE;
                let mass: f64 = acc.get(range.clone()).map_or(0.0, |s| s.iter().sum());
                let scale = if mass > 0.0 {
                    HISTOGRAM_MASS / mass
                } else {
                    0.0
                };
                for b in range {
                    if let (Some(o), Some(a), Some(s)) = (f.get_mut(b), acc.get(b), own.get(b)) {
                        *o = (s + a * scale) as f32;
                    }
                }
            }
            f
        })
        .collect();
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Isometry3, Vector3};

    #[test]
    fn pair_angles_do_not_depend_on_the_order_of_the_pair() {
        let (pa, pb) = (Point3::new(0.0, 0.0, 0.0), Point3::new(1.0, 0.2, 0.1));
        let na = Vector3::new(0.1, 0.0, 1.0).normalize();
        let nb = Vector3::new(-0.3, 0.2, 1.0).normalize();
        let a = pair_angles(&pa, &na, &pb, &nb).unwrap();
        let b = pair_angles(&pb, &nb, &pa, &na).unwrap();
        assert!((a.0 - b.0).abs() < 1e-12 && (a.1 - b.1).abs() < 1e-12);
        assert!((a.2 - b.2).abs() < 1e-12);
        assert!(pair_angles(&pa, &na, &pa, &nb).is_none());
        assert_eq!(bin(-1.0, -1.0, 1.0), 0);
        assert_eq!(bin(1.0, -1.0, 1.0), BINS_PER_FEATURE - 1);
        assert_eq!(bin(0.01, -1.0, 1.0), 5);
    }

    #[test]
    fn descriptors_are_unchanged_by_a_rigid_motion() {
        // A wavy patch with normals from the analytic surface z = f(x, y).
        let f = |x: f64, y: f64| 4.0 * (x / 6.0).sin() * (y / 9.0).cos();
        let mut pts = Vec::new();
        let mut normals = Vec::new();
        for i in 0..40 {
            for j in 0..40 {
                let (x, y) = (i as f64, j as f64);
                pts.push(Point3::new(x, y, f(x, y)));
                let fx = 4.0 / 6.0 * (x / 6.0).cos() * (y / 9.0).cos();
                let fy = -4.0 / 9.0 * (x / 6.0).sin() * (y / 9.0).sin();
                normals.push(Vector3::new(-fx, -fy, 1.0).normalize());
            }
        }
        let config = FpfhConfig {
            radius: 4.0,
            max_neighbours: 1000,
        };
        let a = compute_fpfh(&pts, &normals, &KdIndex::new(&pts).unwrap(), &config).unwrap();
        let m = Isometry3::new(Vector3::new(30.0, -5.0, 2.0), Vector3::new(0.4, -0.9, 2.0));
        let moved: Vec<_> = pts.iter().map(|p| m * p).collect();
        let moved_n: Vec<_> = normals.iter().map(|n| m * n).collect();
        let b = compute_fpfh(&moved, &moved_n, &KdIndex::new(&moved).unwrap(), &config).unwrap();
        // Only angles that fall on a bin edge can change bin, by rounding: the descriptors
        // agree to a small fraction of their mass (600).
        let worst = a
            .iter()
            .zip(&b)
            .map(|(x, y)| x.iter().zip(y).map(|(u, v)| (u - v).abs()).sum::<f32>())
            .fold(0.0f32, f32::max);
        assert!(worst < 0.05 * 600.0, "{worst}");
        // Curved points do not all share one descriptor.
        assert!(
            a.iter()
                .any(|x| x.iter().zip(&a[0]).any(|(u, v)| (u - v).abs() > 1.0))
        );
        for d in &a[..10] {
            let s: f32 = d.iter().sum();
            assert!((s - 600.0).abs() < 1e-2, "{s}");
        }
    }
}
