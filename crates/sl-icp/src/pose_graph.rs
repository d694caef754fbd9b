//! Pose-graph optimisation: spread the residual drift of pairwise registrations over all views
//! (as Open3D's multiway registration), by Levenberg-Marquardt on the node poses.

use nalgebra::{DMatrix, DVector, Isometry3, Matrix6, SMatrix, Vector6};

use crate::IcpError;
use crate::se3::{from_vector, to_vector};

/// Central-difference step of the numeric Jacobians, in rad and mm: the residuals are smooth
/// and O(1) in these units, so 1e-6 balances truncation (~h²) against rounding (~1e-16/h).
const JACOBIAN_STEP: f64 = 1e-6;

/// Initial Levenberg-Marquardt damping, relative to the diagonal of the normal matrix.
const INITIAL_DAMPING: f64 = 1e-4;

/// Damping beyond which no step can lower the cost any more: stop.
const MAX_DAMPING: f64 = 1e12;

/// A relative measurement between two nodes: `T_from_to`, with its information matrix.
#[derive(Debug, Clone, PartialEq)]
pub struct PoseGraphEdge {
    /// The node whose frame the measurement is expressed in (the registration's target).
    pub from: usize,
    /// The other node (the registration's source).
    pub to: usize,
    /// Measured `T_from_to`: maps node `to`'s coordinates into node `from`'s.
    pub measurement: Isometry3<f64>,
    /// Information of the measurement for a small motion `x -> R(ω) x + t` applied on its left,
    /// ordered (ω in rad, t in mm), e.g. [`Registration::information`](crate::Registration).
    pub information: Matrix6<f64>,
}

/// Nodes `T_world_node` and the edges between them.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PoseGraph {
    /// Node poses `T_world_node`; node 0 is held fixed and defines the world frame.
    pub nodes: Vec<Isometry3<f64>>,
    /// Relative measurements.
    pub edges: Vec<PoseGraphEdge>,
}

/// Settings of [`optimize_pose_graph`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseGraphConfig {
    /// Maximum Levenberg-Marquardt iterations. Default 100 (a ring of 36 views takes 3 to 6).
    pub max_iterations: usize,
    /// Stop when an iteration lowers the cost by less than this fraction. Default 1e-12.
    pub relative_tolerance: f64,
    /// Stop when no node moves by more than this in one iteration (rad for rotation vector
    /// components, mm for translations). Default 1e-9: a nanometre, far below any scanner.
    pub step_tolerance: f64,
}

impl Default for PoseGraphConfig {
    fn default() -> Self {
        Self {
            max_iterations: 100,
            relative_tolerance: 1e-12,
            step_tolerance: 1e-9,
        }
    }
}

/// Result of [`optimize_pose_graph`].
#[derive(Debug, Clone, PartialEq)]
pub struct PoseGraphSolution {
    /// Optimised `T_world_node`, node 0 unchanged.
    pub nodes: Vec<Isometry3<f64>>,
    /// Cost `Σ eᵀ Λ e` at the initial poses.
    pub initial_cost: f64,
    /// Cost at the optimised poses.
    pub final_cost: f64,
    /// Accepted iterations.
    pub iterations: usize,
    /// Whether a stopping test passed before `max_iterations`.
    pub converged: bool,
}

/// The residual of an edge: `to_vector(T_from^-1 T_to T_meas^-1)`, zero when the node poses
/// agree with the measurement.
fn residual(nodes: &[Isometry3<f64>], e: &PoseGraphEdge) -> Vector6<f64> {
    match (nodes.get(e.from), nodes.get(e.to)) {
        (Some(a), Some(b)) => to_vector(&(a.inverse() * b * e.measurement.inverse())),
        _ => Vector6::zeros(),
    }
}

fn cost(nodes: &[Isometry3<f64>], edges: &[PoseGraphEdge]) -> f64 {
    edges
        .iter()
        .map(|e| {
            let r = residual(nodes, e);
            r.dot(&(e.information * r))
        })
        .sum()
}

/// Optimises the node poses of `graph` (node 0 fixed) to best agree with its edges: minimises
/// `Σ eᵀ Λ e` over the edges by Levenberg-Marquardt with numeric Jacobians and a dense solve
/// (a turntable ring of 36 nodes is a 210 x 210 system).
///
/// # Errors
/// [`IcpError::BadEdge`] for an edge naming a missing node,
/// [`IcpError::PoseGraphDisconnected`] when some node is not tied to node 0 by edges.
///
/// ```
/// use nalgebra::{Isometry3, Matrix6, Vector6};
/// use sl_icp::{optimize_pose_graph, PoseGraph, PoseGraphConfig, PoseGraphEdge};
/// // Three nodes on a line 10 mm apart; the loop edge 0->2 disagrees by 0.3 mm. Rotations are
/// // made very stiff so that only the translations take up the disagreement.
/// let step = Isometry3::translation(10.0, 0.0, 0.0);
/// let information = Matrix6::from_diagonal(&Vector6::new(1e10, 1e10, 1e10, 1.0, 1.0, 1.0));
/// let edge = |from, to, m| PoseGraphEdge { from, to, measurement: m, information };
/// let graph = PoseGraph {
///     nodes: vec![Isometry3::identity(), step, step * step],
///     edges: vec![edge(0, 1, step), edge(1, 2, step), edge(0, 2, Isometry3::translation(20.3, 0.0, 0.0))],
/// };
/// let solution = optimize_pose_graph(&graph, &PoseGraphConfig::default())?;
/// // Equal weights: the 0.3 mm is shared, 0.1 mm per edge.
/// assert!((solution.nodes[2].translation.x - 20.2).abs() < 1e-6);
/// # Ok::<(), sl_icp::IcpError>(())
/// ```
pub fn optimize_pose_graph(
    graph: &PoseGraph,
    config: &PoseGraphConfig,
) -> Result<PoseGraphSolution, IcpError> {
    let n = graph.nodes.len();
    for (k, e) in graph.edges.iter().enumerate() {
        for node in [e.from, e.to] {
            if node >= n {
                return Err(IcpError::BadEdge {
                    edge: k,
                    node,
                    nodes: n,
                });
            }
        }
    }
    let nodes = graph.nodes.clone();
    let initial_cost = cost(&nodes, &graph.edges);
    if n < 2 || graph.edges.is_empty() {
        return Ok(PoseGraphSolution {
            nodes,
            initial_cost,
            final_cost: initial_cost,
            iterations: 0,
            converged: true,
        });
    }
    let dim = 6 * (n - 1);
    if let Some(node) = unreachable(n, &graph.edges) {
        return Err(IcpError::PoseGraphDisconnected { node });
    }
    let solved = levenberg_marquardt(
        nodes,
        initial_cost,
        &LmLimits {
            max_iterations: config.max_iterations,
            relative_tolerance: config.relative_tolerance,
            step_tolerance: config.step_tolerance,
        },
        |nodes| normal_equations(nodes, &graph.edges, dim),
        |nodes, delta| apply(nodes, delta),
        |nodes| cost(nodes, &graph.edges),
    );
    Ok(PoseGraphSolution {
        nodes: solved.state,
        initial_cost,
        final_cost: solved.final_cost,
        iterations: solved.iterations,
        converged: solved.converged,
    })
}

/// Stopping rules of [`levenberg_marquardt`].
pub(crate) struct LmLimits {
    /// Iterations at most.
    pub(crate) max_iterations: usize,
    /// Stop when an iteration lowers the cost by less than this fraction.
    pub(crate) relative_tolerance: f64,
    /// Stop when no parameter of a step moves by more than this.
    pub(crate) step_tolerance: f64,
}

/// What [`levenberg_marquardt`] ends with.
pub(crate) struct LmOutcome<S> {
    /// The last accepted state.
    pub(crate) state: S,
    /// Its cost.
    pub(crate) final_cost: f64,
    /// Accepted steps.
    pub(crate) iterations: usize,
    /// Whether a tolerance was met or no step could lower the cost (at a minimum to rounding).
    pub(crate) converged: bool,
}

/// Levenberg-Marquardt with multiplicative damping of the normal matrix's diagonal, shared by
/// the pose graph and the turntable model: `normal_equations(s)` gives `(JᵀJ, Jᵀr)` at `s`,
/// `step(s, δ)` applies a parameter step, `cost(s)` is the sum of squared residuals
/// (`initial_cost` = `cost(start)`).
pub(crate) fn levenberg_marquardt<S>(
    start: S,
    initial_cost: f64,
    limits: &LmLimits,
    normal_equations: impl Fn(&S) -> (DMatrix<f64>, DVector<f64>),
    step: impl Fn(&S, &DVector<f64>) -> S,
    cost: impl Fn(&S) -> f64,
) -> LmOutcome<S> {
    let mut state = start;
    let mut current = initial_cost;
    let mut lambda = INITIAL_DAMPING;
    let mut iterations = 0;
    let mut converged = false;
    for _ in 0..limits.max_iterations {
        let (h, g) = normal_equations(&state);
        let dim = g.len();
        let mut improved = false;
        while lambda < MAX_DAMPING {
            let mut damped = h.clone();
            for i in 0..dim {
                damped[(i, i)] += lambda * h[(i, i)].max(f64::MIN_POSITIVE);
            }
            let Some(chol) = damped.cholesky() else {
                lambda *= 10.0;
                continue;
            };
            let delta = -chol.solve(&g);
            let candidate = step(&state, &delta);
            let c = cost(&candidate);
            if c < current {
                let decrease = (current - c) / current.max(f64::MIN_POSITIVE);
                state = candidate;
                current = c;
                lambda = (lambda / 10.0).max(1e-12);
                improved = true;
                iterations += 1;
                if decrease < limits.relative_tolerance || delta.amax() < limits.step_tolerance {
                    converged = true;
                }
                break;
            }
            lambda *= 10.0;
        }
        if !improved {
            // No step lowers the cost: at a minimum to rounding.
            converged = true;
        }
        if converged {
            break;
        }
    }
    LmOutcome {
        state,
        final_cost: current,
        iterations,
        converged,
    }
}

/// The first node not tied to node 0 by a path of edges, if any.
pub(crate) fn unreachable(n: usize, edges: &[PoseGraphEdge]) -> Option<usize> {
    let mut seen = vec![false; n];
    let mut stack = vec![0usize];
    if let Some(s) = seen.get_mut(0) {
        *s = true;
    }
    while let Some(k) = stack.pop() {
        for e in edges {
            let other = if e.from == k {
                e.to
            } else if e.to == k {
                e.from
            } else {
                continue;
            };
            if let Some(s) = seen.get_mut(other)
                && !*s
            {
                *s = true;
                stack.push(other);
            }
        }
    }
    seen.iter().position(|&s| !s)
}

/// `T_k <- from_vector(δ_k) T_k` for nodes 1.., node 0 fixed.
fn apply(nodes: &[Isometry3<f64>], delta: &DVector<f64>) -> Vec<Isometry3<f64>> {
    nodes
        .iter()
        .enumerate()
        .map(|(k, t)| {
            if k == 0 {
                return *t;
            }
            let d = Vector6::from_iterator(
                (0..6).map(|i| delta.get(6 * (k - 1) + i).copied().unwrap_or(0.0)),
            );
            from_vector(&d) * t
        })
        .collect()
}

/// Gauss-Newton normal equations `H = Σ Jᵀ Λ J`, `g = Σ Jᵀ Λ e` with central-difference
/// Jacobians of each edge's residual with respect to the perturbations of its two nodes.
fn normal_equations(
    nodes: &[Isometry3<f64>],
    edges: &[PoseGraphEdge],
    dim: usize,
) -> (DMatrix<f64>, DVector<f64>) {
    let mut h = DMatrix::zeros(dim, dim);
    let mut g = DVector::zeros(dim);
    let mut scratch = nodes.to_vec();
    for e in edges {
        let r = residual(nodes, e);
        // Jacobian columns for (from, to); a fixed node 0 gets none.
        let mut jac = SMatrix::<f64, 6, 12>::zeros();
        for (slot, &node) in [e.from, e.to].iter().enumerate() {
            if node == 0 || e.from == e.to {
                continue;
            }
            let Some(&base) = nodes.get(node) else {
                continue;
            };
            for i in 0..6 {
                let mut d = Vector6::zeros();
                d[i] = JACOBIAN_STEP;
                let mut plus_minus = [Vector6::zeros(); 2];
                for (s, sign) in [1.0, -1.0].iter().enumerate() {
                    if let Some(t) = scratch.get_mut(node) {
                        *t = from_vector(&(d * *sign)) * base;
                    }
                    plus_minus[s] = residual(&scratch, e);
                }
                if let Some(t) = scratch.get_mut(node) {
                    *t = base;
                }
                let col = (plus_minus[0] - plus_minus[1]) / (2.0 * JACOBIAN_STEP);
                jac.column_mut(6 * slot + i).copy_from(&col);
            }
        }
        let jt_l = jac.transpose() * e.information;
        let hh = jt_l * jac;
        let gg = jt_l * r;
        for (a, &na) in [e.from, e.to].iter().enumerate() {
            if na == 0 {
                continue;
            }
            let ra = 6 * (na - 1);
            for i in 0..6 {
                g[ra + i] += gg[6 * a + i];
            }
            for (b, &nb) in [e.from, e.to].iter().enumerate() {
                if nb == 0 {
                    continue;
                }
                let rb = 6 * (nb - 1);
                for i in 0..6 {
                    for j in 0..6 {
                        h[(ra + i, rb + j)] += hh[(6 * a + i, 6 * b + j)];
                    }
                }
            }
        }
    }
    (h, g)
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use nalgebra::{Translation3, UnitQuaternion, Vector3};

    fn ring(n: usize, radius: f64) -> Vec<Isometry3<f64>> {
        // Node k: rotation by -k·360/n degrees about the y axis through (0, 0, radius).
        (0..n)
            .map(|k| {
                let r = UnitQuaternion::from_axis_angle(
                    &Vector3::y_axis(),
                    -(k as f64) * std::f64::consts::TAU / n as f64,
                );
                let c = Vector3::new(0.0, 0.0, radius);
                Isometry3::from_parts(Translation3::from(c - r * c), r)
            })
            .collect()
    }

    #[test]
    fn consistent_measurements_recover_the_truth_from_drifted_poses() {
        let truth = ring(12, 300.0);
        let info = Matrix6::from_diagonal(&Vector6::new(1e4, 1e4, 1e4, 1.0, 1.0, 1.0));
        let mut edges = Vec::new();
        for k in 0..12 {
            let (i, j) = (k, (k + 1) % 12);
            edges.push(PoseGraphEdge {
                from: i,
                to: j,
                measurement: truth[i].inverse() * truth[j],
                information: info,
            });
        }
        // Start from poses with a growing drift (as chained registrations give).
        let nodes: Vec<_> = truth
            .iter()
            .enumerate()
            .map(|(k, t)| {
                let d = Isometry3::new(
                    Vector3::new(0.2, -0.1, 0.3) * k as f64,
                    Vector3::new(0.001, 0.002, -0.001) * k as f64,
                );
                if k == 0 { *t } else { d * t }
            })
            .collect();
        let graph = PoseGraph { nodes, edges };
        let s = optimize_pose_graph(&graph, &PoseGraphConfig::default()).unwrap();
        assert!(s.converged);
        assert!(
            s.final_cost < 1e-12 * s.initial_cost.max(1.0),
            "{}",
            s.final_cost
        );
        for (got, want) in s.nodes.iter().zip(&truth) {
            assert_relative_eq!(
                got.translation.vector,
                want.translation.vector,
                epsilon = 1e-6
            );
            assert!(got.rotation.angle_to(&want.rotation) < 1e-8);
        }
    }

    #[test]
    fn loop_error_is_spread_by_information() {
        // A 4-node chain whose loop closure disagrees by 0.4 mm along x. With equal translation
        // information the least-squares answer spreads it evenly: each edge takes 0.1 mm. The
        // rotations are made 1e10 times stiffer, else turning the 30 mm lever arm of the loop
        // edge by a few µrad would be a cheaper way to absorb the 0.4 mm; their effect on the
        // translations is then below 30 mm · 0.1 mm / 1e10 = 3e-10 mm.
        let step = Isometry3::translation(0.0, 10.0, 0.0);
        let information = Matrix6::from_diagonal(&Vector6::new(1e10, 1e10, 1e10, 1.0, 1.0, 1.0));
        let edge = |from, to, m| PoseGraphEdge {
            from,
            to,
            measurement: m,
            information,
        };
        let graph = PoseGraph {
            nodes: vec![Isometry3::identity(), step, step * step, step * step * step],
            edges: vec![
                edge(0, 1, step),
                edge(1, 2, step),
                edge(2, 3, step),
                edge(3, 0, Isometry3::translation(0.4, -30.0, 0.0)),
            ],
        };
        let s = optimize_pose_graph(&graph, &PoseGraphConfig::default()).unwrap();
        for k in 1..4 {
            assert_relative_eq!(s.nodes[k].translation.x, -0.1 * k as f64, epsilon = 1e-8);
        }
        assert_relative_eq!(s.final_cost, 4.0 * 0.01, epsilon = 1e-9);
    }

    #[test]
    fn bad_graphs_are_rejected() {
        let e = PoseGraphEdge {
            from: 0,
            to: 5,
            measurement: Isometry3::identity(),
            information: Matrix6::identity(),
        };
        let g = PoseGraph {
            nodes: vec![Isometry3::identity(); 3],
            edges: vec![e.clone()],
        };
        assert!(matches!(
            optimize_pose_graph(&g, &PoseGraphConfig::default()),
            Err(IcpError::BadEdge {
                edge: 0,
                node: 5,
                ..
            })
        ));
        // Node 2 has no edge: nothing fixes it.
        let g = PoseGraph {
            nodes: vec![Isometry3::identity(); 3],
            edges: vec![PoseGraphEdge { to: 1, ..e }],
        };
        assert!(matches!(
            optimize_pose_graph(&g, &PoseGraphConfig::default()),
            Err(IcpError::PoseGraphDisconnected { node: 2 })
        ));
    }
}
