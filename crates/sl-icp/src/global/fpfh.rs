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

/// One FPFH descriptor (f32: matching compares thousands of them, where halving the bandwidth
/// matters more than precision; each sub-histogram sums to about 200).
pub type Fpfh = [f32; FPFH_BINS];

/// Every sub-histogram of an SPFH (and of the weighted neighbour part of an FPFH) sums to this,
/// as in Rusu's PCL code and Open3D, so that descriptors of points with few or many
/// neighbours compare on the same scale.
const HISTOGRAM_MASS: f32 = 100.0;

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
fn pair_angles(pa: &V3, na: &V3, pb: &V3, nb: &V3) -> Option<(f32, f32, f32)> {
    pair_angles_raw(pa, na, pb, nb).map(|(a, p, (s, c))| (a, p, s.atan2(c)))
}

/// A position or normal in f32 (the angles are binned into 11 bins: f32 is ample, and halves
/// the memory traffic of the hot loops).
type V3 = Vector3<f32>;

/// [`pair_angles`] with θ left as `(w·nt, u·nt)`, the sine and cosine (unnormalised) the angle
/// is taken from: Rusu's construction, the reference [`pair_code`] is tested against.
#[cfg(test)]
fn pair_angles_raw(pa: &V3, na: &V3, pb: &V3, nb: &V3) -> Option<(f32, f32, (f32, f32))> {
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
    if vn <= f32::EPSILON {
        return None;
    }
    let v = v / vn;
    let w = ns.cross(&v);
    Some((v.dot(nt), ns.dot(&d), (w.dot(nt), ns.dot(nt))))
}

/// Bin of `x` in `[lo, hi]` among [`BINS_PER_FEATURE`] (clamped; NaN goes to the first).
#[inline]
fn bin(x: f32, lo: f32, hi: f32) -> usize {
    // `as usize` saturates: negatives and NaN give 0.
    (((x - lo) / (hi - lo) * BINS_PER_FEATURE as f32) as usize).min(BINS_PER_FEATURE - 1)
}

/// `atan2(y, x)` to within 2e-5 rad (a minimax polynomial for atan on [0, 1] and the
/// octant fix-ups), for binning θ: an angle that close to one of the ten bin edges may fall
/// in the neighbouring bin, a change far below the noise of the normals; libm's exact atan2
/// was a sixth of the descriptors' time.
#[inline]
fn atan2_approx(y: f32, x: f32) -> f32 {
    use std::f32::consts::{FRAC_PI_2, PI};
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
                    + r2 * (-0.116_432_87 + r2 * (0.052_653_32 - r2 * 0.011_721_2)))));
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

/// Placeholder of a reverse edge's code until its pair's is copied in.
const UNSET: PairCode = PairCode::MAX - 1;

/// The code of the pair `(pa, na)`, `(pb, nb)`; the same for both orders.
///
/// The angles of [`pair_angles`] without building the frame: with unit `d`, `ca = na·d`,
/// `cb = nb·d`, the source is `a` when `ca ≥ -cb`, so `φ = max(ca, -cb)`; `|v| = |ns × d| =
/// √(1 - φ²)`; `α = (ns × d')·nt / |v|`, which is `(na × d)·nb / |v|` for either source; and
/// `w·nt = (φ ns·nt - d'·nt) / |v|` (as `w = ns × v = (φ ns - d') / |v|`), `ns·nt = na·nb`.
#[inline]
fn pair_code(pa: &V3, na: &V3, pb: &V3, nb: &V3) -> PairCode {
    let d = pb - pa;
    let len2 = d.norm_squared();
    if len2.is_nan() || len2 <= 0.0 || na.norm_squared() == 0.0 || nb.norm_squared() == 0.0 {
        return NO_PAIR;
    }
    let d = d / len2.sqrt();
    let (ca, cb) = (na.dot(&d), nb.dot(&d));
    let (phi, d_nt) = if ca >= -cb { (ca, cb) } else { (-cb, -ca) };
    let vn = (1.0 - phi * phi).max(0.0).sqrt();
    if vn <= f32::EPSILON {
        return NO_PAIR;
    }
    let c = na.dot(nb);
    let alpha = na.cross(&d).dot(nb) / vn;
    let theta = atan2_approx((phi * c - d_nt) / vn, c);
    let (a, p, t) = (
        bin(alpha, -1.0, 1.0),
        bin(phi, -1.0, 1.0),
        bin(theta, -std::f32::consts::PI, std::f32::consts::PI),
    );
    (a + BINS_PER_FEATURE * (p + BINS_PER_FEATURE * t)) as PairCode
}

/// Edges binned together by [`pair_codes`]: one SIMD register of f32 (or two).
const LANES: usize = 8;

/// [`pair_code`] of `(p, n)` with each of `(ps[l], ns[l])`, lane by lane in straight-line
/// code (selects instead of branches) so that the compiler vectorises it; `out` gets one code
/// per lane. Gives the codes of [`pair_code`] (tested) but for rounding at a bin edge.
#[inline]
fn pair_codes(p: &V3, n: &V3, ps: &[V3; LANES], ns: &[V3; LANES], out: &mut [PairCode; LANES]) {
    use std::f32::consts::{FRAC_PI_2, PI};
    let zero_n = n.norm_squared() == 0.0;
    let bins = BINS_PER_FEATURE as f32;
    let last = bins - 1.0;
    for l in 0..LANES {
        let (q, m) = (ps[l], ns[l]);
        let (dx, dy, dz) = (q.x - p.x, q.y - p.y, q.z - p.z);
        let len2 = dx * dx + dy * dy + dz * dz;
        let inv = 1.0 / len2.sqrt();
        let (dx, dy, dz) = (dx * inv, dy * inv, dz * inv);
        let ca = n.x * dx + n.y * dy + n.z * dz;
        let cb = m.x * dx + m.y * dy + m.z * dz;
        let swap = ca < -cb;
        let phi = if swap { -cb } else { ca };
        let d_nt = if swap { -ca } else { cb };
        let vn = (1.0 - phi * phi).max(0.0).sqrt();
        let c = n.x * m.x + n.y * m.y + n.z * m.z;
        // (n × d)·m
        let triple =
            (n.y * dz - n.z * dy) * m.x + (n.z * dx - n.x * dz) * m.y + (n.x * dy - n.y * dx) * m.z;
        let alpha = triple / vn;
        let (y, x) = ((phi * c - d_nt) / vn, c);
        // atan2_approx, with selects.
        let (ax, ay) = (x.abs(), y.abs());
        let (lo, hi) = (ax.min(ay), ax.max(ay));
        let r = if hi > 0.0 { lo / hi } else { 0.0 };
        let r2 = r * r;
        let a = r
            * (0.999_977_26
                + r2 * (-0.332_623_47
                    + r2 * (0.193_543_46
                        + r2 * (-0.116_432_87 + r2 * (0.052_653_32 - r2 * 0.011_721_2)))));
        let a = if ay > ax { FRAC_PI_2 - a } else { a };
        let a = if x < 0.0 { PI - a } else { a };
        let theta = if y < 0.0 { -a } else { a };
        // Bins, clamped in float (NaN goes to 0 through `max`), truncated.
        let ba = ((alpha + 1.0) * (bins / 2.0)).max(0.0).min(last) as u16;
        let bp = ((phi + 1.0) * (bins / 2.0)).max(0.0).min(last) as u16;
        let bt = ((theta + PI) * (bins / (2.0 * PI))).max(0.0).min(last) as u16;
        let code = ba + BINS_PER_FEATURE as u16 * (bp + BINS_PER_FEATURE as u16 * bt);
        // `|`, not `||`: no branch in the lane loop.
        let bad = len2.is_nan()
            | (len2 <= 0.0)
            | (vn <= f32::EPSILON)
            | (m.norm_squared() == 0.0)
            | zero_n;
        out[l] = if bad { NO_PAIR } else { code };
    }
}

/// Rows (points) per parallel task.
const ROWS_PER_TASK: usize = 256;

/// Neighbours of every point within the radius (at most `max_neighbours`, the nearest, the
/// point itself excluded), in compressed rows. Shared by the normals
/// ([`Neighbourhoods::nearest_normals`]) and the descriptors, so the cloud is searched once.
///
/// The search runs on a uniform grid of cubes one radius wide: the points are sorted by cube
/// (z, y, x), so the three cubes along x of each of a cube's nine (z, y) neighbour columns are
/// one run of the sorted points, and a point's ball lies inside those nine runs. Rows,
/// neighbours and everything built from them live in that sorted order (`order` maps back),
/// which makes each row ascending without a sort and keeps neighbours close in memory.
pub(crate) struct Neighbourhoods {
    /// Original index of each sorted position.
    order: Vec<u32>,
    /// The points in sorted order, relative to the grid's corner, in f32.
    local: Vec<V3>,
    start: Vec<u32>,
    /// Neighbours as sorted positions, ascending in each row.
    index: Vec<u32>,
    distance: Vec<f32>,
}

/// A grid cube: its (z, y, x) coordinates and its run of sorted points.
#[derive(Clone, Copy)]
struct Cube {
    key: (i32, i32, i32),
    start: usize,
    end: usize,
}

impl Neighbourhoods {
    /// Finds the neighbours of every point of `points` (finite).
    pub(crate) fn new(points: &[Point3<f64>], config: &FpfhConfig) -> Self {
        let n = points.len();
        let corner = points
            .iter()
            .fold(Vector3::repeat(f64::INFINITY), |m: Vector3<f64>, p| {
                m.inf(&p.coords)
            });
        let corner = if corner.iter().all(|v| v.is_finite()) {
            corner
        } else {
            Vector3::zeros()
        };
        let cell = config.radius;
        // Saturating casts: a non-finite point lands in an extreme cube and finds no one.
        let key_of = |p: &Point3<f64>| {
            let c = (p.coords - corner) / cell;
            (c.z.floor() as i32, c.y.floor() as i32, c.x.floor() as i32)
        };
        let keys: Vec<(i32, i32, i32)> = points.iter().map(key_of).collect();
        let mut order: Vec<u32> = (0..n as u32).collect();
        order.par_sort_unstable_by_key(|&i| (keys.get(i as usize).copied(), i));
        let local: Vec<V3> = order
            .iter()
            .map(|&i| {
                points
                    .get(i as usize)
                    .map_or_else(V3::zeros, |p| (p.coords - corner).cast::<f32>())
            })
            .collect();
        let mut cubes: Vec<Cube> = Vec::new();
        for (at, &i) in order.iter().enumerate() {
            let key = keys.get(i as usize).copied().unwrap_or_default();
            match cubes.last_mut() {
                Some(c) if c.key == key => c.end = at + 1,
                _ => cubes.push(Cube {
                    key,
                    start: at,
                    end: at + 1,
                }),
            }
        }
        let r2 = (config.radius * config.radius) as f32;
        let (xs, ys, zs): (Vec<f32>, Vec<f32>, Vec<f32>) = (
            local.iter().map(|p| p.x).collect(),
            local.iter().map(|p| p.y).collect(),
            local.iter().map(|p| p.z).collect(),
        );
        let max = config.max_neighbours;
        // The nine runs of a cube's neighbourhood, in ascending order.
        let runs = |c: &Cube| {
            let (z, y, x) = c.key;
            let mut out = [(0usize, 0usize); 9];
            for (slot, (dz, dy)) in out
                .iter_mut()
                .zip((-1..=1).flat_map(|dz| (-1..=1).map(move |dy| (dz, dy))))
            {
                let (kz, ky) = (z.saturating_add(dz), y.saturating_add(dy));
                let lo = cubes.partition_point(|d| d.key < (kz, ky, x.saturating_sub(1)));
                let hi = cubes.partition_point(|d| d.key <= (kz, ky, x.saturating_add(1)));
                if lo < hi
                    && let (Some(a), Some(b)) = (cubes.get(lo), cubes.get(hi - 1))
                {
                    *slot = (a.start, b.end);
                }
            }
            out
        };
        // One task per run of cubes; each gives its rows' lengths, neighbours and distances.
        let chunks: Vec<(Vec<u32>, Vec<u32>, Vec<f32>)> = cubes
            .par_chunks(4)
            .map(|chunk| {
                let mut lengths = Vec::new();
                let mut index = Vec::new();
                let mut distance = Vec::new();
                let mut row: Vec<(f32, u32)> = Vec::new();
                let mut d2s: Vec<f32> = Vec::new();
                for c in chunk {
                    let runs = runs(c);
                    let candidates: usize = runs.iter().map(|r| r.1 - r.0).sum();
                    row.resize(candidates.max(row.len()), (0.0, 0));
                    d2s.resize(candidates.max(d2s.len()), 0.0);
                    for i in c.start..c.end {
                        let p = local.get(i).copied().unwrap_or_else(V3::zeros);
                        let mut len = 0;
                        for &(a, b) in &runs {
                            let (Some(xr), Some(yr), Some(zr), Some(buf)) = (
                                xs.get(a..b),
                                ys.get(a..b),
                                zs.get(a..b),
                                d2s.get_mut(..b - a),
                            ) else {
                                continue;
                            };
                            // The squared distances of the run side by side (vectorised)...
                            for (((d, &x), &y), &z) in buf.iter_mut().zip(xr).zip(yr).zip(zr) {
                                let (dx, dy, dz) = (x - p.x, y - p.y, z - p.z);
                                *d = dx * dx + dy * dy + dz * dz;
                            }
                            // ...then every candidate written, the count advanced only for
                            // those inside (no branch to mispredict on the ~1/3 that are).
                            for (j, &d2) in (a..b).zip(buf.iter()) {
                                if let Some(slot) = row.get_mut(len) {
                                    *slot = (d2, j as u32);
                                }
                                len += usize::from(d2 <= r2 && d2 > 0.0);
                            }
                        }
                        let found = row.get_mut(..len).unwrap_or_default();
                        let found = if found.len() > max {
                            found.select_nth_unstable_by(max, |a, b| {
                                a.0.total_cmp(&b.0).then(a.1.cmp(&b.1))
                            });
                            let nearest = found.get_mut(..max).unwrap_or_default();
                            nearest.sort_unstable_by_key(|x| x.1);
                            nearest
                        } else {
                            found
                        };
                        lengths.push(found.len() as u32);
                        index.extend(found.iter().map(|x| x.1));
                        distance.extend(found.iter().map(|x| x.0.sqrt()));
                    }
                }
                (lengths, index, distance)
            })
            .collect();
        let total: usize = chunks.iter().map(|c| c.1.len()).sum();
        let mut start = Vec::with_capacity(n + 1);
        let mut index = Vec::with_capacity(total);
        let mut distance = Vec::with_capacity(total);
        start.push(0u32);
        for (lengths, idx, dist) in chunks {
            for l in lengths {
                let last = start.last().copied().unwrap_or(0);
                start.push(last + l);
            }
            index.extend(idx);
            distance.extend(dist);
        }
        Self {
            order,
            local,
            start,
            index,
            distance,
        }
    }

    fn len(&self) -> usize {
        self.order.len()
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

    /// Values given in sorted order, put back in the original order of the points.
    fn unsort<T: Copy>(&self, sorted: &[T], fill: T) -> Vec<T> {
        let mut out = vec![fill; self.len()];
        for (&i, v) in self.order.iter().zip(sorted) {
            if let Some(o) = out.get_mut(i as usize) {
                *o = *v;
            }
        }
        out
    }

    /// Unit normals (unoriented, in the points' original order) from the PCA of each point and
    /// its `k - 1` nearest neighbours in its row ([`fit_local_plane`], as
    /// `sl_cloud::estimate_normals` with `k` neighbours including the point); zero where no
    /// plane fits.
    pub(crate) fn nearest_normals(&self, points: &[Point3<f64>], k: usize) -> Vec<Vector3<f64>> {
        let sorted: Vec<Vector3<f64>> = (0..self.len())
            .into_par_iter()
            .with_min_len(ROWS_PER_TASK)
            .map_init(Vec::new, |buf: &mut Vec<u64>, i| {
                let (idx, dist) = self.of(i);
                // (distance, neighbour) as one integer: the bits of a positive f32 are in
                // its order, so the selection compares integers.
                buf.clear();
                buf.extend(
                    dist.iter()
                        .zip(idx)
                        .map(|(d, &j)| (u64::from(d.to_bits()) << 32) | u64::from(j)),
                );
                let keep = k.saturating_sub(1);
                if buf.len() > keep && keep > 0 {
                    buf.select_nth_unstable(keep - 1);
                }
                buf.truncate(keep);
                let original = |j: usize| self.order.get(j).map_or(usize::MAX, |&o| o as usize);
                let around = std::iter::once(original(i)).chain(
                    buf.iter()
                        .map(|&x| original((x & u64::from(u32::MAX)) as usize)),
                );
                fit_local_plane(points, around).map_or_else(Vector3::zeros, |p| p.normal)
            })
            .collect();
        self.unsort(&sorted, Vector3::zeros())
    }
}

/// Computes the FPFH descriptor of every point from its neighbours within `config.radius`.
///
/// `normals` must be unit vectors (zero where unknown: such pairs are skipped) with a sign
/// that is consistent over the cloud (see [`orient_normals_outward`](crate::orient_normals_outward));
/// `index` must be built over `points` (it is checked, and kept in the signature for
/// compatibility: the neighbours are found on a uniform grid of cubes one radius wide, which
/// for one fixed radius is several times faster than the tree). A point with no usable
/// neighbour gets an all-zero descriptor. Runs in parallel on the rayon pool; the result does
/// not depend on the number of threads.
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
    let hoods = Neighbourhoods::new(points, config);
    Ok(fpfh_of_neighbourhoods(normals, &hoods))
}

/// [`compute_fpfh`] over neighbourhoods already found (`normals` one per point, in the
/// points' order; so is the result).
///
/// The pair angles do not depend on the order of the pair, so each pair is binned once: first
/// every edge `i → j` with `j > i`, then their codes are copied to the reverse edges `j → i`
/// (the few that the neighbour cap left one-way get their own).
pub(crate) fn fpfh_of_neighbourhoods(
    normals: &[Vector3<f64>],
    hoods: &Neighbourhoods,
) -> Vec<Fpfh> {
    let n = hoods.len();
    let normal: Vec<V3> = hoods
        .order
        .iter()
        .map(|&i| {
            normals
                .get(i as usize)
                .map_or_else(V3::zeros, |v| v.cast::<f32>())
        })
        .collect();
    let code = |i: usize, j: usize| match (
        hoods.local.get(i),
        normal.get(i),
        hoods.local.get(j),
        normal.get(j),
    ) {
        (Some(p), Some(np), Some(q), Some(nq)) => pair_code(p, np, q, nq),
        _ => NO_PAIR,
    };
    // Codes of the edges to larger points, row by row.
    let forward: Vec<Vec<PairCode>> = (0..n)
        .into_par_iter()
        .step_by(ROWS_PER_TASK)
        .map(|i0| {
            let end = (i0 + ROWS_PER_TASK).min(n);
            let mut out = Vec::with_capacity(
                hoods
                    .range(i0)
                    .start
                    .abs_diff(hoods.range(end.saturating_sub(1)).end),
            );
            for i in i0..end {
                let (idx, _) = hoods.of(i);
                let split = idx.partition_point(|&j| j as usize <= i);
                out.extend(std::iter::repeat_n(UNSET, split));
                let (Some(p), Some(np)) = (hoods.local.get(i), normal.get(i)) else {
                    continue;
                };
                let mut ps = [V3::zeros(); LANES];
                let mut ns = [V3::zeros(); LANES];
                let mut lane_codes = [NO_PAIR; LANES];
                for chunk in idx.get(split..).unwrap_or(&[]).chunks(LANES) {
                    for ((q, m), &j) in ps.iter_mut().zip(ns.iter_mut()).zip(chunk) {
                        *q = hoods
                            .local
                            .get(j as usize)
                            .copied()
                            .unwrap_or_else(V3::zeros);
                        *m = normal.get(j as usize).copied().unwrap_or_else(V3::zeros);
                    }
                    pair_codes(p, np, &ps, &ns, &mut lane_codes);
                    out.extend(lane_codes.iter().take(chunk.len()));
                }
            }
            out
        })
        .collect();
    let mut codes: Vec<PairCode> = forward.concat();
    // The reverse edges get their pair's code: row `j` lists its smaller neighbours in
    // ascending order, and the forward edges `i → j` come by ascending `i`, so one cursor per
    // row finds each `i` in row `j` in a single pass (no search).
    let mut cursor: Vec<u32> = hoods.start.iter().take(n).copied().collect();
    for i in 0..n {
        let range = hoods.range(i);
        let idx = hoods.index.get(range.clone()).unwrap_or(&[]);
        let split = idx.partition_point(|&j| j as usize <= i);
        for (e, &j) in range.zip(idx).skip(split) {
            let end = hoods.range(j as usize).end;
            let Some(c) = cursor.get_mut(j as usize) else {
                continue;
            };
            while (*c as usize) < end && hoods.index.get(*c as usize).is_some_and(|&k| k < i as u32)
            {
                *c += 1;
            }
            if hoods.index.get(*c as usize) == Some(&(i as u32)) && (*c as usize) < end {
                let code = codes.get(e).copied().unwrap_or(NO_PAIR);
                if let Some(slot) = codes.get_mut(*c as usize) {
                    *slot = code;
                }
                *c += 1;
            }
        }
    }
    // SPFH of every point.
    let spfh: Vec<Fpfh> = (0..n)
        .into_par_iter()
        .with_min_len(ROWS_PER_TASK)
        .map(|i| {
            let mut counts = [0u32; FPFH_BINS];
            let mut count = 0u32;
            let range = hoods.range(i);
            let idx = hoods.index.get(range.clone()).unwrap_or(&[]);
            for (&c, &j) in codes.get(range).unwrap_or(&[]).iter().zip(idx) {
                // A reverse edge left one-way by the neighbour cap: its own code.
                let c = if c == UNSET { code(i, j as usize) } else { c };
                if c == NO_PAIR {
                    continue;
                }
                let c = usize::from(c);
                let (a, rest) = (c % BINS_PER_FEATURE, c / BINS_PER_FEATURE);
                let (p, t) = (rest % BINS_PER_FEATURE, rest / BINS_PER_FEATURE);
                for b in [a, BINS_PER_FEATURE + p, 2 * BINS_PER_FEATURE + t] {
                    if let Some(v) = counts.get_mut(b) {
                        *v += 1;
                    }
                }
                count += 1;
            }
            let scale = if count > 0 {
                HISTOGRAM_MASS / count as f32
            } else {
                0.0
            };
            counts.map(|c| c as f32 * scale)
        })
        .collect();
    // FPFH: own SPFH plus the 1/distance-weighted neighbours' SPFHs, renormalised.
    let sorted: Vec<Fpfh> = (0..n)
        .into_par_iter()
        .with_min_len(ROWS_PER_TASK)
        .map(|i| {
            let mut acc = [0.0f32; FPFH_BINS];
            let (idx, dist) = hoods.of(i);
            for (&j, &d) in idx.iter().zip(dist) {
                let Some(s) = spfh.get(j as usize) else {
                    continue;
                };
                let w = 1.0 / d;
                for (a, v) in acc.iter_mut().zip(s) {
                    *a += w * v;
                }
            }
            let own = spfh.get(i).copied().unwrap_or([0.0; FPFH_BINS]);
            let mut f = [0.0f32; FPFH_BINS];
            for k in 0..3 {
                let range = k * BINS_PER_FEATURE..(k + 1) * BINS_PER_FEATURE;
                let mass: f32 = acc.get(range.clone()).map_or(0.0, |s| s.iter().sum());
                let scale = if mass > 0.0 {
                    HISTOGRAM_MASS / mass
                } else {
                    0.0
                };
                for b in range {
                    if let (Some(o), Some(a), Some(s)) = (f.get_mut(b), acc.get(b), own.get(b)) {
                        *o = s + a * scale;
                    }
                }
            }
            f
        })
        .collect();
    hoods.unsort(&sorted, [0.0; FPFH_BINS])
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Isometry3, Vector3};

    #[test]
    fn pair_angles_do_not_depend_on_the_order_of_the_pair() {
        let (pa, pb) = (V3::new(0.0, 0.0, 0.0), V3::new(1.0, 0.2, 0.1));
        let na = V3::new(0.1, 0.0, 1.0).normalize();
        let nb = V3::new(-0.3, 0.2, 1.0).normalize();
        let a = pair_angles(&pa, &na, &pb, &nb).unwrap();
        let b = pair_angles(&pb, &nb, &pa, &na).unwrap();
        assert!((a.0 - b.0).abs() < 1e-6 && (a.1 - b.1).abs() < 1e-6);
        assert!((a.2 - b.2).abs() < 1e-6);
        assert!(pair_angles(&pa, &na, &pa, &nb).is_none());
        assert_eq!(bin(-1.0, -1.0, 1.0), 0);
        assert_eq!(bin(1.0, -1.0, 1.0), BINS_PER_FEATURE - 1);
        assert_eq!(bin(0.01, -1.0, 1.0), 5);
        assert_eq!(bin(f32::NAN, -1.0, 1.0), 0);
        assert_eq!(bin(-3.0, -1.0, 1.0), 0);
        // The fast atan2 against libm's, all around the circle.
        for k in 0..3600 {
            let t = (k as f64 / 10.0 - 180.0).to_radians();
            for r in [1e-3, 1.0, 50.0] {
                let (y, x) = ((r * t.sin()) as f32, (r * t.cos()) as f32);
                assert!((atan2_approx(y, x) - y.atan2(x)).abs() < 2e-5, "{t}");
            }
        }
        assert_eq!(atan2_approx(0.0, 0.0), 0.0);
    }

    /// Marsaglia's 32-bit xorshift from `s`: reproducible pseudo-random bits for the tests.
    fn xorshift32(mut s: u32) -> impl FnMut() -> u32 {
        move || {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            s
        }
    }

    #[test]
    fn pair_codes_agree_with_the_darboux_frame_construction() {
        // Pseudo-random unit normals and offsets; the shortcut formulas of `pair_code` give
        // the bins of Rusu's frame, except for an angle within rounding of a bin edge.
        let mut bits = xorshift32(0x2545_f491);
        let mut next = || (bits() % 20_001) as f32 / 10_000.0 - 1.0;
        let unit = |next: &mut dyn FnMut() -> f32| {
            V3::new(next(), next(), next())
                .try_normalize(1e-3)
                .unwrap_or_else(V3::z)
        };
        let edge = |x: f32, lo: f32, hi: f32| {
            let t = (x - lo) / (hi - lo) * BINS_PER_FEATURE as f32;
            (t - t.round()).abs() < 1e-3
        };
        let mut checked = 0;
        for _ in 0..20_000 {
            let (na, nb) = (unit(&mut next), unit(&mut next));
            let pa = V3::new(next(), next(), next()) * 5.0;
            let pb = V3::new(next(), next(), next()) * 5.0;
            let code = pair_code(&pa, &na, &pb, &nb);
            assert_eq!(code, pair_code(&pb, &nb, &pa, &na));
            let mut lanes = [0; LANES];
            pair_codes(&pa, &na, &[pb; LANES], &[nb; LANES], &mut lanes);
            let Some((alpha, phi, theta)) = pair_angles(&pa, &na, &pb, &nb) else {
                continue;
            };
            let pi = std::f32::consts::PI;
            if edge(alpha, -1.0, 1.0) || edge(phi, -1.0, 1.0) || edge(theta, -pi, pi) {
                continue;
            }
            let expected = bin(alpha, -1.0, 1.0)
                + BINS_PER_FEATURE * (bin(phi, -1.0, 1.0) + BINS_PER_FEATURE * bin(theta, -pi, pi));
            assert_eq!(usize::from(code), expected, "{alpha} {phi} {theta}");
            assert_eq!(lanes, [code; LANES], "{alpha} {phi} {theta}");
            checked += 1;
        }
        assert!(checked > 19_000, "{checked}");
        let z = V3::z();
        assert_eq!(pair_code(&V3::zeros(), &z, &V3::zeros(), &z), NO_PAIR);
        assert_eq!(
            pair_code(&V3::zeros(), &z, &z, &z),
            NO_PAIR,
            "normal along the line"
        );
    }

    #[test]
    fn grid_neighbourhoods_equal_a_brute_force_search() {
        // Pseudo-random points on a 0.25 mm lattice in a 40 mm box (some cubes empty, some
        // crowded, negative coordinates; squared distances exact in f32 and f64, so none is
        // rounded across the radius): every row must hold exactly the points within 4 mm
        // (itself and coincident points excluded), or with a cap of 6 the 6 nearest (compared
        // by distance: the lattice has ties).
        let mut bits = xorshift32(0x9e37_79b9);
        let mut next = || f64::from(bits() % 160) * 0.25 - 20.0;
        let pts: Vec<Point3<f64>> = (0..3000)
            .map(|_| Point3::new(next(), next() * 0.5, next().abs()))
            .collect();
        for max in [1000, 6] {
            let config = FpfhConfig {
                radius: 4.0,
                max_neighbours: max,
            };
            let hoods = Neighbourhoods::new(&pts, &config);
            let mut position = vec![0; pts.len()];
            for (at, &i) in hoods.order.iter().enumerate() {
                position[i as usize] = at;
            }
            for (i, p) in pts.iter().enumerate() {
                let mut expected: Vec<(f64, usize)> = pts
                    .iter()
                    .enumerate()
                    .map(|(j, q)| ((q - p).norm(), j))
                    .filter(|&(d, j)| j != i && d > 0.0 && d <= 4.0)
                    .collect();
                expected.sort_by(|a, b| a.0.total_cmp(&b.0));
                expected.truncate(max);
                let (idx, dist) = hoods.of(position[i]);
                assert!(idx.windows(2).all(|w| w[0] < w[1]), "rows ascending");
                let mut found: Vec<(f64, usize)> = idx
                    .iter()
                    .map(|&j| hoods.order[j as usize] as usize)
                    .map(|j| ((pts[j] - p).norm(), j))
                    .collect();
                for ((d, _), &stored) in found.iter().zip(dist) {
                    assert!((d - f64::from(stored)).abs() < 1e-5);
                }
                if max > expected.len() {
                    found.sort_by_key(|x| x.1);
                    expected.sort_by_key(|x| x.1);
                    assert_eq!(found, expected, "point {i}");
                } else {
                    found.sort_by(|a, b| a.0.total_cmp(&b.0));
                    let d = |v: &[(f64, usize)]| v.iter().map(|x| x.0).collect::<Vec<_>>();
                    assert_eq!(d(&found), d(&expected), "point {i}, cap {max}");
                }
            }
        }
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
