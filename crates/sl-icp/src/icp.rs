//! The ICP driver: association, trimming, robust weights, one solve per iteration,
//! convergence, and the final evaluation (RMSE, fitness, information matrix).

use nalgebra::{Isometry3, Matrix3, Matrix6, Point3, Rotation3, Vector3};
use rayon::prelude::*;

use crate::association::{closest, normal_shooting, projective};
use crate::metric::generalized::{Generalized, combined_information};
use crate::metric::point_to_plane::PointToPlane;
use crate::metric::point_to_point::PointToPoint;
use crate::metric::solve6;
use crate::se3::{skew, update_about};
use crate::trimming;
use crate::{Association, IcpConfig, IcpError, Metric, PreparedCloud, Trimming};

/// Fewest correspondences an iteration accepts: six unknowns need at least six equations. So a
/// cloud of fewer points cannot be registered.
pub const MIN_CORRESPONDENCES: usize = 6;

/// Points per block of the parallel sums ([`sum_in_blocks`]), and the fewest a rayon task
/// handles elsewhere: ~50 µs of work, so that handing out tasks and merging their fixed-size
/// sums costs little next to the queries.
const MIN_TASK: usize = 2048;

/// Marks a source point without a correspondence.
const NO_MATCH: u32 = u32::MAX;

/// One correspondence slot per source point: target index (or `NO_MATCH`) and squared distance.
#[derive(Debug, Clone, Copy)]
struct Pair {
    target: u32,
    d2: f64,
}

const UNMATCHED: Pair = Pair {
    target: NO_MATCH,
    d2: f64::INFINITY,
};

/// The result of a registration.
#[derive(Debug, Clone, PartialEq)]
pub struct Registration {
    /// `T_target_source`: maps source coordinates into the target frame (mm).
    pub pose: Isometry3<f64>,
    /// Root mean square Euclidean distance of the inlier correspondences at `pose`, mm.
    pub rmse: f64,
    /// Fraction of the source points with an inlier correspondence at `pose` (within the
    /// maximum distance and kept by the trimming), as Open3D's `fitness`.
    pub fitness: f64,
    /// Number of inlier correspondences at `pose`.
    pub inliers: usize,
    /// Iterations run (updates applied).
    pub iterations: usize,
    /// Whether a convergence test passed before `max_iterations`.
    pub converged: bool,
    /// Information matrix of `pose` for pose graphs, as Open3D's
    /// `get_information_matrix_from_point_clouds`: `Σ G^T G` over the inliers with
    /// `G = [-[q]x | I]`, `q` the target point. Ordered (rotation, translation) for a small
    /// motion `x -> R(ω) x + t` applied on the left of `pose`, in rad and mm.
    pub information: Matrix6<f64>,
}

/// What one iteration did (see [`Icp::step`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IcpStep {
    /// The pose after the iteration: `update * pose`.
    pub pose: Isometry3<f64>,
    /// The motion applied on the left, in the target frame.
    pub update: Isometry3<f64>,
    /// Correspondences that entered the solve.
    pub correspondences: usize,
    /// Mean squared Euclidean distance of those correspondences before the update, mm².
    pub mean_squared_distance: f64,
    /// Rotation angle of `update`, rad.
    pub rotation_change: f64,
    /// How far `update` moved the source centroid, mm.
    pub translation_change: f64,
}

/// Correspondence figures of a pose (see [`Icp::evaluate`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Evaluation {
    /// RMS Euclidean distance of the inliers, mm (0 when there is none).
    pub rmse: f64,
    /// Inliers over source points.
    pub fitness: f64,
    /// Number of inliers.
    pub inliers: usize,
    /// Information matrix, as [`Registration::information`].
    pub information: Matrix6<f64>,
}

/// A registration in progress: the two clouds, the settings and the per-point buffers, which
/// are allocated once here so that iterations do not allocate.
///
/// [`register`] is the one-call form; use `Icp` to step iterations yourself or to register
/// several initial poses against the same pair.
///
/// ```
/// use nalgebra::{Isometry3, Point3, Vector3};
/// use sl_icp::{Icp, IcpConfig, PrepareConfig, PreparedCloud, PointCloud};
/// // A wavy surface z = f(x, y), and the same surface moved by a small motion.
/// let pts: Vec<_> = (0..2500)
///     .map(|i| {
///         let (x, y) = ((i % 50) as f64, (i / 50) as f64);
///         Point3::new(x, y, 5.0 * (x / 8.0).sin() * (y / 11.0).cos())
///     })
///     .collect();
/// let target = PreparedCloud::new(&PointCloud::from_positions(pts.clone()), &PrepareConfig::default())?;
/// let truth = Isometry3::new(Vector3::new(0.5, -0.3, 0.2), Vector3::new(0.0, 0.02, 0.01));
/// let moved: Vec<_> = pts.iter().map(|p| truth.inverse() * p).collect();
/// let source = PreparedCloud::new(&PointCloud::from_positions(moved), &PrepareConfig::default())?;
/// let mut icp = Icp::new(&source, &target, &IcpConfig::default())?;
/// let step = icp.step(&Isometry3::identity())?; // one iteration
/// assert!(step.rotation_change > 0.0);
/// let result = icp.run(&Isometry3::identity())?;
/// assert!(result.converged);
/// assert!((result.pose.translation.vector - truth.translation.vector).norm() < 1e-3);
/// # Ok::<(), sl_icp::IcpError>(())
/// ```
#[derive(Debug)]
pub struct Icp<'a> {
    source: &'a PreparedCloud,
    target: &'a PreparedCloud,
    config: IcpConfig,
    pairs: Vec<Pair>,
    scratch: Vec<f64>,
    iteration: usize,
}

/// Registers `source` onto `target` from the pose `initial` (`T_target_source`).
///
/// # Errors
/// [`IcpError::InvalidParameter`] for a bad configuration or a non-finite initial pose,
/// [`IcpError::EmptyCloud`], [`IcpError::MissingNormals`] when the metric or association
/// needs normals a cloud lacks, [`IcpError::NotOrganized`] for projective association on an
/// unorganised target, [`IcpError::TooFewCorrespondences`] when the clouds do not overlap
/// within the maximum distance, [`IcpError::Degenerate`] for geometry that leaves a motion
/// free.
///
/// ```
/// use nalgebra::{Isometry3, Point3, Vector3};
/// use sl_icp::{register, IcpConfig, Metric, PrepareConfig, PreparedCloud, PointCloud};
/// let pts: Vec<_> = (0..3000)
///     .map(|i| {
///         let (x, y) = ((i % 60) as f64, (i / 60) as f64);
///         Point3::new(x, y, 4.0 * (x / 7.0).cos() + 0.05 * y * y)
///     })
///     .collect();
/// let truth = Isometry3::new(Vector3::new(1.0, 0.5, -0.4), Vector3::new(0.01, -0.02, 0.03));
/// let source: Vec<_> = pts.iter().map(|p| truth.inverse() * p).collect();
/// let prep = |p: Vec<Point3<f64>>| PreparedCloud::new(&PointCloud::from_positions(p), &PrepareConfig::default());
/// let config = IcpConfig { metric: Metric::Generalized, ..IcpConfig::default() };
/// let r = register(&prep(source)?, &prep(pts)?, &Isometry3::identity(), &config)?;
/// assert!(r.converged && r.fitness > 0.99 && r.rmse < 1e-3);
/// assert!((r.pose.rotation.angle_to(&truth.rotation)).to_degrees() < 1e-3);
/// # Ok::<(), sl_icp::IcpError>(())
/// ```
pub fn register(
    source: &PreparedCloud,
    target: &PreparedCloud,
    initial: &Isometry3<f64>,
    config: &IcpConfig,
) -> Result<Registration, IcpError> {
    Icp::new(source, target, config)?.run(initial)
}

/// Registers two raw clouds: each is downsampled to `voxel_size` (none: every point) and gets
/// the normals `config.metric` needs (the target's for point-to-plane and generalized ICP, the
/// source's too for generalized; a cloud's own normals are kept, others estimated), then
/// [`register`]. Returns the registration and how many source points took part.
///
/// ```
/// use nalgebra::{Isometry3, Point3, Vector3};
/// use sl_icp::{IcpConfig, Metric, PointCloud, register_clouds};
/// let pts: Vec<_> = (0..3000)
///     .map(|i| {
///         let (x, y) = ((i % 60) as f64, (i / 60) as f64);
///         Point3::new(x, y, 4.0 * (x / 7.0).cos() + 0.05 * y * y)
///     })
///     .collect();
/// let truth = Isometry3::new(Vector3::new(1.0, 0.5, -0.4), Vector3::new(0.01, -0.02, 0.03));
/// let source = PointCloud::from_positions(pts.iter().map(|p| truth.inverse() * p).collect());
/// let target = PointCloud::from_positions(pts);
/// let config = IcpConfig { metric: Metric::PointToPlane, ..IcpConfig::default() };
/// let (r, used) = register_clouds(&source, &target, &Isometry3::identity(), &config, None)?;
/// assert_eq!(used, 3000);
/// assert!(r.converged && r.rmse < 1e-3);
/// # Ok::<(), sl_icp::IcpError>(())
/// ```
///
/// # Errors
/// The preparation's errors (too few points for normals, a bad voxel size) and [`register`]'s.
pub fn register_clouds(
    source: &sl_cloud::PointCloud,
    target: &sl_cloud::PointCloud,
    initial: &Isometry3<f64>,
    config: &IcpConfig,
    voxel_size: Option<f64>,
) -> Result<(Registration, usize), IcpError> {
    let prepare = |cloud, needs_normals: bool| {
        PreparedCloud::new(
            cloud,
            &crate::PrepareConfig {
                voxel_size,
                normals: if needs_normals {
                    crate::NormalSource::default()
                } else {
                    crate::NormalSource::None
                },
            },
        )
    };
    let s = prepare(source, config.metric == Metric::Generalized)?;
    let t = prepare(target, config.metric != Metric::PointToPoint)?;
    t.build_index();
    Ok((register(&s, &t, initial, config)?, s.len()))
}

fn check_pose(pose: &Isometry3<f64>) -> Result<(), IcpError> {
    let finite = pose.translation.vector.iter().all(|v| v.is_finite())
        && pose.rotation.coords.iter().all(|v| v.is_finite());
    if finite {
        Ok(())
    } else {
        Err(IcpError::invalid(
            "initial",
            format!("{pose:?}"),
            "pose must be finite",
        ))
    }
}

impl<'a> Icp<'a> {
    /// Checks the inputs against the configuration and allocates the buffers (and builds the
    /// target's k-d tree if the association needs it and it is not built yet).
    ///
    /// # Errors
    /// As [`register`], for everything that can be known before iterating.
    pub fn new(
        source: &'a PreparedCloud,
        target: &'a PreparedCloud,
        config: &IcpConfig,
    ) -> Result<Self, IcpError> {
        config.validate()?;
        if source.is_empty() {
            return Err(IcpError::EmptyCloud {
                cloud: "source".into(),
            });
        }
        if target.is_empty() {
            return Err(IcpError::EmptyCloud {
                cloud: "target".into(),
            });
        }
        let need = |cloud: &PreparedCloud, name: &'static str, by: &'static str| {
            if cloud.normals().is_none() {
                Err(IcpError::MissingNormals {
                    cloud: name,
                    needed_by: by,
                })
            } else {
                Ok(())
            }
        };
        match config.metric {
            Metric::PointToPoint => {}
            Metric::PointToPlane => need(target, "target", "point-to-plane")?,
            Metric::Generalized => {
                need(source, "source", "generalized ICP")?;
                need(target, "target", "generalized ICP")?;
            }
        }
        match config.association {
            Association::ClosestPoint => target.build_index(),
            Association::Projective { .. } => {
                if target.organized().is_none() {
                    return Err(IcpError::NotOrganized);
                }
            }
            Association::NormalShooting => {
                need(source, "source", "normal shooting")?;
                need(target, "target", "normal shooting")?;
                target.build_index();
            }
        }
        let n = source.len();
        Ok(Self {
            source,
            target,
            config: *config,
            pairs: vec![UNMATCHED; n],
            scratch: Vec::with_capacity(if config.trimming == Trimming::None {
                0
            } else {
                n
            }),
            iteration: 0,
        })
    }

    /// Runs iterations from `initial` until convergence or `max_iterations`, then evaluates
    /// the final pose.
    ///
    /// # Errors
    /// As [`register`].
    pub fn run(&mut self, initial: &Isometry3<f64>) -> Result<Registration, IcpError> {
        check_pose(initial)?;
        let c = &self.config;
        let (max_it, rot_tol, trans_tol, rel_tol) = (
            c.max_iterations,
            c.rotation_tolerance,
            c.translation_tolerance,
            c.relative_error_tolerance,
        );
        let mut pose = *initial;
        let mut previous: Option<(f64, Isometry3<f64>)> = None;
        let mut converged = false;
        let mut iterations = 0;
        self.iteration = 0;
        while iterations < max_it {
            let s = self.step(&pose)?;
            pose = s.pose;
            iterations += 1;
            let small =
                |rotation: f64, translation: f64| rotation < rot_tol && translation < trans_tol;
            let small_motion = small(s.rotation_change, s.translation_change);
            let e = s.mean_squared_distance;
            // Discrete correspondences can make the last iterations hop between two poses;
            // the composition of the last two updates is then (nearly) the identity.
            let (small_change, back_and_forth) = match previous {
                Some((p, last)) => {
                    let c = pose * self.source.centroid();
                    let two = s.update * last;
                    (
                        (p - e).abs() <= rel_tol * p,
                        small(two.rotation.angle(), (two * c - c).norm()),
                    )
                }
                None => (false, false),
            };
            previous = Some((e, s.update));
            if small_motion || small_change || back_and_forth {
                converged = true;
                break;
            }
        }
        let ev = self.evaluate(&pose)?;
        Ok(Registration {
            pose,
            rmse: ev.rmse,
            fitness: ev.fitness,
            inliers: ev.inliers,
            iterations,
            converged,
            information: ev.information,
        })
    }

    /// Fills the correspondence slots for the source moved by `pose`; returns the squared
    /// distance threshold left after trimming.
    fn associate(&mut self, pose: &Isometry3<f64>) -> f64 {
        let rot: Rotation3<f64> = pose.rotation.to_rotation_matrix();
        let t = pose.translation.vector;
        let max_d2 = self.config.max_correspondence_distance.powi(2);
        let src = self.source.points();
        let tgt = self.target;
        let association = self.config.association;
        let find = |p: &Point3<f64>, i: usize| -> Option<(u32, f64)> {
            match association {
                Association::ClosestPoint => closest::find(tgt.index(), p, max_d2),
                Association::Projective { window } => {
                    projective::find(tgt.organized()?, tgt.points(), p, window)
                }
                Association::NormalShooting => {
                    let n = rot * self.source.normals()?.get(i)?;
                    normal_shooting::find(tgt.index(), tgt.points(), tgt.normals()?, p, &n, max_d2)
                }
            }
        };
        self.pairs
            .par_iter_mut()
            .zip(src.par_iter())
            .enumerate()
            .with_min_len(MIN_TASK)
            .for_each(|(i, (pair, p))| {
                let q = rot * p + t;
                *pair = match find(&q, i) {
                    Some((j, d2)) if d2 <= max_d2 => Pair { target: j, d2 },
                    _ => UNMATCHED,
                };
            });
        let mut limit = max_d2;
        if self.config.trimming != Trimming::None {
            self.scratch.clear();
            self.scratch.extend(
                self.pairs
                    .iter()
                    .filter(|p| p.target != NO_MATCH)
                    .map(|p| p.d2),
            );
            let trim = trimming::threshold(&self.config.trimming, &mut self.scratch, src.len());
            limit = limit.min(trim);
        }
        limit
    }

    /// One iteration from `pose`: correspondences, weights, solve, update.
    ///
    /// # Errors
    /// [`IcpError::TooFewCorrespondences`], [`IcpError::Degenerate`], or an invalid pose.
    pub fn step(&mut self, pose: &Isometry3<f64>) -> Result<IcpStep, IcpError> {
        check_pose(pose)?;
        let iteration = self.iteration;
        self.iteration += 1;
        let limit = self.associate(pose);
        let rot: Rotation3<f64> = pose.rotation.to_rotation_matrix();
        let t = pose.translation.vector;
        let c = pose * self.source.centroid();
        let (src, pairs) = (self.source.points(), &self.pairs);
        let tgt = self.target.points();
        let kernel = self.config.kernel;
        let n = src.len();
        // The kept correspondence of source point i: (moved source point, target point, d2).
        let kept = |i: usize| -> Option<(Point3<f64>, Point3<f64>, u32, f64)> {
            let pair = pairs.get(i)?;
            if pair.target == NO_MATCH || pair.d2 > limit {
                return None;
            }
            let p = rot * src.get(i)? + t;
            Some((p, *tgt.get(pair.target as usize)?, pair.target, pair.d2))
        };
        let metric = self.config.metric;
        let (update, tally) = match metric {
            Metric::PointToPoint => {
                let (acc, tally) = fold(n, PointToPoint::zero(), PointToPoint::merge, |acc, i| {
                    let (p, q, _, d2) = kept(i)?;
                    acc.add(&(p - c), &(q - c), kernel.weight(d2.sqrt()));
                    Some(d2)
                });
                (acc.solve(&c), tally)
            }
            Metric::PointToPlane => {
                let normals = self.target.normals().unwrap_or(&[]);
                let (acc, tally) = fold(n, PointToPlane::zero(), PointToPlane::merge, |acc, i| {
                    let (p, q, j, d2) = kept(i)?;
                    let nq = normals.get(j as usize)?;
                    let r = nq.dot(&(p - q));
                    acc.add(&(p - c), nq, r, kernel.weight(r));
                    Some(d2)
                });
                let update = solve6(&acc.h, &acc.g).map(|d| {
                    update_about(
                        &d.fixed_rows::<3>(0).into(),
                        &d.fixed_rows::<3>(3).into(),
                        &c,
                    )
                });
                (update, tally)
            }
            Metric::Generalized => {
                let sn = self.source.normals().unwrap_or(&[]);
                let tn = self.target.normals().unwrap_or(&[]);
                let eps = self.config.gicp_epsilon;
                let (acc, tally) = fold(n, Generalized::zero(), Generalized::merge, |acc, i| {
                    let (p, q, j, d2) = kept(i)?;
                    let np = rot * sn.get(i)?;
                    let m = combined_information(&np, tn.get(j as usize)?, eps)?;
                    acc.add(&(p - c), &(q - p), &m, kernel.weight(d2.sqrt()));
                    Some(d2)
                });
                let update = solve6(&acc.h, &acc.g).map(|d| {
                    update_about(
                        &d.fixed_rows::<3>(0).into(),
                        &d.fixed_rows::<3>(3).into(),
                        &c,
                    )
                });
                (update, tally)
            }
        };
        if tally.count < MIN_CORRESPONDENCES {
            return Err(IcpError::TooFewCorrespondences {
                iteration,
                found: tally.count,
                needed: MIN_CORRESPONDENCES,
            });
        }
        let update = update.ok_or(IcpError::Degenerate {
            iteration,
            metric: metric.name(),
        })?;
        Ok(IcpStep {
            pose: update * pose,
            update,
            correspondences: tally.count,
            mean_squared_distance: tally.sum_d2 / tally.count as f64,
            rotation_change: update.rotation.angle(),
            translation_change: (update * c - c).norm(),
        })
    }

    /// RMSE, fitness and information matrix of the correspondences at `pose`.
    ///
    /// # Errors
    /// Only for a non-finite pose.
    pub fn evaluate(&mut self, pose: &Isometry3<f64>) -> Result<Evaluation, IcpError> {
        check_pose(pose)?;
        let limit = self.associate(pose);
        let tgt = self.target.points();
        let pairs = &self.pairs;
        let zero = (Vector3::zeros(), Matrix3::zeros());
        let merge = |a: (Vector3<f64>, Matrix3<f64>), b: (Vector3<f64>, Matrix3<f64>)| {
            (a.0 + b.0, a.1 + b.1)
        };
        let ((sq, sqq), tally) = fold(pairs.len(), zero, merge, |acc, i| {
            let pair = pairs.get(i)?;
            if pair.target == NO_MATCH || pair.d2 > limit {
                return None;
            }
            let q = tgt.get(pair.target as usize)?.coords;
            acc.0 += q;
            acc.1 += q * q.transpose();
            Some(pair.d2)
        });
        let k = tally.count as f64;
        // Σ G^T G with G = [-[q]x | I]: [[Σ(|q|² I - q q^T), [Σq]x], [-[Σq]x, N I]].
        let mut information = Matrix6::zeros();
        let tl = Matrix3::from_diagonal_element(sqq.trace()) - sqq;
        information.fixed_view_mut::<3, 3>(0, 0).copy_from(&tl);
        information
            .fixed_view_mut::<3, 3>(0, 3)
            .copy_from(&skew(&sq));
        information
            .fixed_view_mut::<3, 3>(3, 0)
            .copy_from(&(-skew(&sq)));
        information
            .fixed_view_mut::<3, 3>(3, 3)
            .copy_from(&Matrix3::from_diagonal_element(k));
        Ok(Evaluation {
            rmse: if tally.count > 0 {
                (tally.sum_d2 / k).sqrt()
            } else {
                0.0
            },
            fitness: k / self.source.len() as f64,
            inliers: tally.count,
            information,
        })
    }
}

/// Counts and sums of squared distances of the correspondences that entered a fold.
#[derive(Debug, Clone, Copy, Default)]
struct Tally {
    count: usize,
    sum_d2: f64,
}

/// Parallel fold over `0..n` into a fixed-size accumulator; `add` returns the squared
/// distance of the correspondence it used, or `None` to skip the point.
fn fold<A, M, F>(n: usize, zero: A, merge: M, add: F) -> (A, Tally)
where
    A: Copy + Send + Sync,
    M: Fn(A, A) -> A + Sync + Send,
    F: Fn(&mut A, usize) -> Option<f64> + Sync + Send,
{
    sum_in_blocks(
        n,
        (zero, Tally::default()),
        |(a, ta), (b, tb)| {
            (
                merge(a, b),
                Tally {
                    count: ta.count + tb.count,
                    sum_d2: ta.sum_d2 + tb.sum_d2,
                },
            )
        },
        |(acc, tally), i| {
            if let Some(d2) = add(acc, i) {
                tally.count += 1;
                tally.sum_d2 += d2;
            }
        },
    )
}

/// Parallel sum over `0..n` into a fixed-size accumulator, the same bits whatever the number
/// of threads and however the work is stolen: the indices are summed in fixed blocks of
/// [`MIN_TASK`], each block in order, and the blocks' sums are merged in order. (A rayon
/// `fold` and `reduce` group the floating-point sums as the work happened to be split, so a
/// registration's last digits changed with the machine's cores, and from one run to the
/// next.)
pub(crate) fn sum_in_blocks<A, M, F>(n: usize, zero: A, merge: M, add: F) -> A
where
    A: Copy + Send + Sync,
    M: Fn(A, A) -> A,
    F: Fn(&mut A, usize) + Sync + Send,
{
    let blocks: Vec<A> = (0..n.div_ceil(MIN_TASK))
        .into_par_iter()
        .map(|b| {
            let mut acc = zero;
            for i in b * MIN_TASK..n.min((b + 1) * MIN_TASK) {
                add(&mut acc, i);
            }
            acc
        })
        .collect();
    blocks.into_iter().fold(zero, merge)
}
