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
use sl_cloud::{KdIndex, fit_local_plane};

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
#[cfg(test)]
fn pair_angles(
    pa: &Point3<f64>,
    na: &Vector3<f64>,
    pb: &Point3<f64>,
    nb: &Vector3<f64>,
) -> Option<(f64, f64, f64)> {
    pair_angles_raw(pa, na, pb, nb).map(|(a, p, (s, c))| (a, p, s.atan2(c)))
}

/// [`pair_angles`] with θ left as `(w·nt, u·nt)`, the sine and cosine (unnormalised) the angle
/// is taken from.
#[inline]
fn pair_angles_raw(
    pa: &Point3<f64>,
    na: &Vector3<f64>,
    pb: &Point3<f64>,
    nb: &Vector3<f64>,
) -> Option<(f64, f64, (f64, f64))> {
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
    Some((v.dot(nt), ns.dot(&d), (w.dot(nt), ns.dot(nt))))
}

/// Bin of `x` in `[lo, hi]` among [`BINS_PER_FEATURE`] (clamped; NaN goes to the first).
#[inline]
fn bin(x: f64, lo: f64, hi: f64) -> usize {
    // `as usize` saturates: negatives and NaN give 0.
    (((x - lo) / (hi - lo) * BINS_PER_FEATURE as f64) as usize).min(BINS_PER_FEATURE - 1)
}

/// `atan2(y, x)` to within 1e-5 rad (a minimax polynomial for atan on [0, 1] and the
/// octant fix-ups), for binning θ: an angle that close to one of the ten bin edges may fall
/// in the neighbouring bin, a change far below the noise of the normals; libm's exact atan2
/// was a sixth of the descriptors' time.
#[inline]
fn atan2_approx(y: f64, x: f64) -> f64 {
    use std::f64::consts::{FRAC_PI_2, PI};
    let (ax, ay) = (x.abs(), y.abs());
    let (lo, hi) = if ax < ay { (ax, ay) } else { (ay, ax) };
    if hi == 0.0 {
        return 0.0;
    }
    let r = lo / hi;
    let r2 = r * r;
    let mut a = r
        * (0.999_977_26
            + r2 * (-0.332_623_47
                + r2 * (0.193_543_46
                    + r2 * (-0.116_432_87 + r2 * (0.052_653_32 - r2 * 0.011_721_20)))));
    if ay > ax {
        a = FRAC_PI_2 - a;
    }
    if x < 0.0 {
        a = PI - a;
    }
    if y < 0.0 { -a } else { a }
}

/// The three bins of a pair packed in one code (`α + 11 φ + 121 θ`), or [`NO_PAIR`].
type PairCode = u16;

/// Code of a pair that gives no angles (coincident points, a normal along the line, a zero
/// normal).
const NO_PAIR: PairCode = PairCode::MAX;

/// The code of the pair `(pa, na)`, `(pb, nb)`; the same for both orders.
#[inline]
fn pair_code(pa: &Point3<f64>, na: &Vector3<f64>, pb: &Point3<f64>, nb: &Vector3<f64>) -> PairCode {
    if na.norm_squared() == 0.0 || nb.norm_squared() == 0.0 {
        return NO_PAIR;
    }
    let Some((alpha, phi, (sin_theta, cos_theta))) = pair_angles_raw(pa, na, pb, nb) else {
        return NO_PAIR;
    };
    let theta = atan2_approx(sin_theta, cos_theta);
    let (a, p, t) = (
        bin(alpha, -1.0, 1.0),
        bin(phi, -1.0, 1.0),
        bin(theta, -std::f64::consts::PI, std::f64::consts::PI),
    );
    (a + BINS_PER_FEATURE * (p + BINS_PER_FEATURE * t)) as PairCode
}

/// Neighbours of every point within the radius (at most `max_neighbours`, the nearest, the
/// point itself excluded), in compressed rows, each row ordered by point index. Shared by the
/// normals ([`Neighbourhoods::nearest_normals`]) and the descriptors, so the cloud is searched
/// once.
pub(crate) struct Neighbourhoods {
    start: Vec<u32>,
    index: Vec<u32>,
    distance: Vec<f32>,
}

impl Neighbourhoods {
    /// Searches `index` (built over `points`) around every point.
    pub(crate) fn new(points: &[Point3<f64>], index: &KdIndex, config: &FpfhConfig) -> Self {
        let lists: Vec<Vec<(u32, f32)>> = points
            .par_iter()
            .enumerate()
            .with_min_len(256)
            .map(|(i, p)| {
                let mut found = index.radius_unsorted(p, config.radius);
                found.retain(|n| n.index != i && n.distance_squared > 0.0);
                if found.len() > config.max_neighbours {
                    found.select_nth_unstable_by(config.max_neighbours, |a, b| {
                        a.distance_squared
                            .total_cmp(&b.distance_squared)
                            .then(a.index.cmp(&b.index))
                    });
                    found.truncate(config.max_neighbours);
                }
                let mut row: Vec<(u32, f32)> = found
                    .iter()
                    .map(|n| (n.index as u32, n.distance_squared.sqrt() as f32))
                    .collect();
                row.sort_unstable_by_key(|x| x.0);
                row
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
        Self {
            start,
            index: idx,
            distance,
        }
    }

    fn range(&self, i: usize) -> std::ops::Range<usize> {
        self.start.get(i).copied().unwrap_or(0) as usize
            ..self.start.get(i + 1).copied().unwrap_or(0) as usize
    }

    fn of(&self, i: usize) -> (&[u32], &[f32]) {
        let r = self.range(i);
        (
            self.index.get(r.clone()).unwrap_or(&[]),
            self.distance.get(r).unwrap_or(&[]),
        )
    }

    /// Position of the edge `i → j` in the rows, if `j` is a neighbour of `i`.
    fn edge(&self, i: usize, j: u32) -> Option<usize> {
        let r = self.range(i);
        let row = self.index.get(r.clone())?;
        row.binary_search(&j).ok().map(|k| r.start + k)
    }

    /// Unit normals (unoriented) from the PCA of each point and its `k - 1` nearest
    /// neighbours in its row ([`fit_local_plane`], as `sl_cloud::estimate_normals` with `k`
    /// neighbours including the point); zero where no plane fits.
    pub(crate) fn nearest_normals(&self, points: &[Point3<f64>], k: usize) -> Vec<Vector3<f64>> {
        (0..points.len())
            .into_par_iter()
            .with_min_len(256)
            .map_init(Vec::new, |buf: &mut Vec<(f32, u32)>, i| {
                let (idx, dist) = self.of(i);
                buf.clear();
                buf.extend(dist.iter().copied().zip(idx.iter().copied()));
                let keep = k.saturating_sub(1);
                if buf.len() > keep && keep > 0 {
                    buf.select_nth_unstable_by(keep - 1, |a, b| {
                        a.0.total_cmp(&b.0).then(a.1.cmp(&b.1))
                    });
                }
                buf.truncate(keep);
                let around = std::iter::once(i).chain(buf.iter().map(|x| x.1 as usize));
                fit_local_plane(points, around).map_or_else(Vector3::zeros, |p| p.normal)
            })
            .collect()
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
    let hoods = Neighbourhoods::new(points, index, config);
    Ok(fpfh_of_neighbourhoods(points, normals, &hoods))
}

/// [`compute_fpfh`] over neighbourhoods already found (`normals` one per point).
///
/// The pair angles do not depend on the order of the pair, so each pair is binned once: first
/// every edge `i → j` with `j > i`, then each point's histogram reads its edges to smaller
/// points from their reverse edges (computing the few that the neighbour cap left one-way).
pub(crate) fn fpfh_of_neighbourhoods(
    points: &[Point3<f64>],
    normals: &[Vector3<f64>],
    hoods: &Neighbourhoods,
) -> Vec<Fpfh> {
    let n = points.len();
    let code =
        |i: usize, j: usize| match (points.get(i), normals.get(i), points.get(j), normals.get(j)) {
            (Some(p), Some(np), Some(q), Some(nq)) => pair_code(p, np, q, nq),
            _ => NO_PAIR,
        };
    // Codes of the edges to larger points, row by row.
    let forward: Vec<Vec<PairCode>> = (0..n)
        .into_par_iter()
        .with_min_len(256)
        .map(|i| {
            let (idx, _) = hoods.of(i);
            idx.iter()
                .map(|&j| {
                    if j as usize > i {
                        code(i, j as usize)
                    } else {
                        NO_PAIR
                    }
                })
                .collect()
        })
        .collect();
    let codes: Vec<PairCode> = forward.into_iter().flatten().collect();
    // SPFH of every point, in f64 while summing.
    let spfh: Vec<[f64; FPFH_BINS]> = (0..n)
        .into_par_iter()
        .with_min_len(256)
        .map(|i| {
            let mut h = [0.0; FPFH_BINS];
            let mut count = 0usize;
            let range = hoods.range(i);
            let idx = hoods.index.get(range.clone()).unwrap_or(&[]);
            for (e, &j) in range.zip(idx) {
                let c = if j as usize > i {
                    codes.get(e).copied().unwrap_or(NO_PAIR)
                } else {
                    match hoods.edge(j as usize, i as u32) {
                        Some(back) => codes.get(back).copied().unwrap_or(NO_PAIR),
                        None => code(i, j as usize),
                    }
                };
                if c == NO_PAIR {
                    continue;
                }
                let c = usize::from(c);
                let (a, rest) = (c % BINS_PER_FEATURE, c / BINS_PER_FEATURE);
                let (p, t) = (rest % BINS_PER_FEATURE, rest / BINS_PER_FEATURE);
                for b in [a, BINS_PER_FEATURE + p, 2 * BINS_PER_FEATURE + t] {
                    if let Some(v) = h.get_mut(b) {
                        *v += 1.0;
                    }
                }
                count += 1;
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
    (0..n)
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
        .collect()
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
        assert_eq!(bin(f64::NAN, -1.0, 1.0), 0);
        assert_eq!(bin(-3.0, -1.0, 1.0), 0);
        // The fast atan2 against libm's, all around the circle.
        for k in 0..3600 {
            let t = (k as f64 / 10.0 - 180.0).to_radians();
            for r in [1e-3, 1.0, 50.0] {
                let (y, x) = (r * t.sin(), r * t.cos());
                assert!((atan2_approx(y, x) - y.atan2(x)).abs() < 1e-5, "{t}");
            }
        }
        assert_eq!(atan2_approx(0.0, 0.0), 0.0);
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
