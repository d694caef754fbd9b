//! The per-pixel pass of a triangulation: inputs gathered [`LANES`] pixels at a time, the
//! method's branch-free lane kernel, then the filters and the status of each pixel.
//!
//! Hand-written for memory speed, because this loop is the whole cost of a triangulation:
//! - the inputs are streamed once in structure-of-arrays form (the camera's [`RayTable`]
//!   `xs`/`ys`, the map's `col`/`row`/`quality`/`invalid`), with no per-pixel allocation;
//! - the methods' arithmetic runs on [`LANES`] independent pixels without branches, inside
//!   `pulp`'s runtime dispatch, so that it is compiled for AVX2 + FMA and vectorised where the
//!   CPU has them (the SSE2 baseline would do two lanes at a time, without FMA);
//! - the rare pixels the branch-free form does not settle (no convergence in the fixed number
//!   of Newton steps) take the general scalar path, so the answers are those of the careful
//!   solver;
//! - the reprojection error is evaluated only where it is free (ray–plane: from the last
//!   Newton step; optimal: needed anyway) or a filter needs it;
//! - Newton on the projector surface starts from the depths of the previous lane groups of
//!   the row (extrapolated), so two steps reach the tolerance instead of three;
//! - results go straight into the output vectors: the caller collects blocks of [`BLOCK`]
//!   pixels in parallel through an indexed iterator (each block written once, in place) and
//!   flattens them without a copy.

use nalgebra::{Point3, Vector3};
use sl_camera::RayTable;
use sl_codec::{Axis, CorrespondenceMap, InvalidReason};

use crate::linear::{LinearOneAxisState, linear_lanes, linear_one_axis_lanes};
use crate::midpoint::midpoint_lanes;
use crate::optimal::refine;
use crate::options::Solver;
use crate::ray_plane::{SurfaceLanes, ray_surface_depth, ray_surface_lanes};
use crate::stereo::Stereo;
use crate::undistort::{UndistortWarm, undistort_lanes};
use crate::{PointStatus, TriConfig};

/// Pixels per lane group: 8 `f64`s are two AVX2 registers (or one AVX-512), enough
/// independent work to hide the latency of the divisions.
pub(crate) const LANES: usize = 8;

/// Pixels computed per runtime dispatch and per item of the parallel collect: large enough
/// that the dispatch, the per-item overhead of the collect and the cold Newton start of the
/// block's first lane group are negligible, small enough that the block's results stay in L1
/// (128 · 29 bytes).
pub(crate) const BLOCK: usize = 128;

/// The method of a lane loop, as a const generic parameter ([`crate::Method`] resolved against
/// the map's axes).
const RAY_PLANE_COLUMN: u8 = 0;
/// Ray–plane on the projector rows.
const RAY_PLANE_ROW: u8 = 1;
/// [`crate::Method::Linear`].
const LINEAR: u8 = 2;
/// [`crate::Method::Midpoint`].
const MIDPOINT: u8 = 3;
/// [`crate::Method::Optimal`].
const OPTIMAL: u8 = 4;
/// [`crate::Method::Linear`] on a map that codes the projector columns only.
const LINEAR_COLUMN: u8 = 5;
/// [`crate::Method::Linear`] on a map that codes the projector rows only.
const LINEAR_ROW: u8 = 6;

/// Points of a lane group (camera frame, mm) and whether each lane has one.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct PointLanes {
    pub(crate) x: [f64; LANES],
    pub(crate) y: [f64; LANES],
    pub(crate) z: [f64; LANES],
    pub(crate) ok: [bool; LANES],
}

/// The point of a pixel without one.
const NO_POINT: Point3<f64> = Point3::new(f64::NAN, f64::NAN, f64::NAN);

/// The output slices of one block of pixels (equal lengths, at most [`BLOCK`]).
pub(crate) struct BlockOut<'o> {
    pub(crate) points: &'o mut [Point3<f64>],
    pub(crate) reprojection: &'o mut [f32],
    pub(crate) status: &'o mut [PointStatus],
}

/// Depths of the same lanes in the two previous lane groups (NaN where none), the warm start
/// of the surface solve.
struct WarmStart {
    t1: [f64; LANES],
    t2: [f64; LANES],
    /// The previous group's undistorted projector points (linear, midpoint).
    proj: UndistortWarm,
    /// The previous group's other projector coordinate (one-axis linear).
    linear: LinearOneAxisState,
}

impl WarmStart {
    /// The guess for the current group: linear extrapolation from the two previous groups
    /// (error 64·t'' for lanes 8 px apart: ~0.03 mm on a wall inclined by 45° at 450 mm),
    /// the previous group alone, or NaN (the solver's pinhole start).
    #[inline(always)]
    fn guess(&self) -> [f64; LANES] {
        let mut g = [f64::NAN; LANES];
        for l in 0..LANES {
            let (a, b) = (self.t1[l], self.t2[l]);
            let e = 2.0 * a - b;
            g[l] = if e.is_finite() { e } else { a };
        }
        g
    }

    #[inline(always)]
    fn push(&mut self, t: &[f64; LANES], ok: &[bool; LANES]) {
        self.t2 = self.t1;
        for l in 0..LANES {
            self.t1[l] = if ok[l] { t[l] } else { f64::NAN };
        }
    }
}

/// Everything the pass reads.
pub(crate) struct Pass<'a> {
    pub(crate) stereo: &'a Stereo,
    pub(crate) rays: &'a RayTable,
    pub(crate) map: &'a CorrespondenceMap,
    pub(crate) options: &'a TriConfig,
    /// The method resolved against the axes the map codes.
    pub(crate) solver: Solver,
    pub(crate) width: usize,
    pub(crate) arch: pulp::Arch,
}

/// Lane inputs of one group.
#[derive(Clone, Copy, Debug)]
struct Gathered {
    rx: [f64; LANES],
    ry: [f64; LANES],
    c: [f64; LANES],
    r: [f64; LANES],
    u: [f64; LANES],
    v: [f64; LANES],
    /// Status before solving: `Valid` for a pixel to solve, else its final status.
    pre: [PointStatus; LANES],
}

impl Gathered {
    /// Nothing to solve: every lane `NotDecoded`.
    const EMPTY: Self = Self {
        rx: [f64::NAN; LANES],
        ry: [f64::NAN; LANES],
        c: [f64::NAN; LANES],
        r: [f64::NAN; LANES],
        u: [0.0; LANES],
        v: [0.0; LANES],
        pre: [PointStatus::NotDecoded; LANES],
    };
}

impl Pass<'_> {
    /// Computes the block of pixels starting at `start` into `out` (every entry written).
    #[inline]
    pub(crate) fn block(&self, start: usize, out: BlockOut<'_>) {
        self.arch.dispatch(BlockJob {
            pass: self,
            start,
            out,
        });
    }

    /// Whether the reprojection filter is on (the error is then needed for every point).
    #[inline(always)]
    fn error_needed(&self) -> bool {
        self.options.max_reprojection_px.is_finite()
    }

    /// The lane inputs of the group starting at pixel `base` (column `x0`, row `y0`), into
    /// `g` (every field written; in place, because returning the 392-byte struct cost a
    /// `memcpy` call per group): a branch-free loop over fixed-size arrays for a full group
    /// (the common case), a checked one at the map's end.
    #[inline(always)]
    fn gather(&self, base: usize, (x0, y0): (usize, usize), g: &mut Gathered) {
        let (xs, ys) = (self.rays.xs(), self.rays.ys());
        let m = self.map;
        let w = self.width.max(1);
        let range = base..base + LANES;
        let full = (
            xs.get(range.clone())
                .and_then(|s| <&[f64; LANES]>::try_from(s).ok()),
            ys.get(range.clone())
                .and_then(|s| <&[f64; LANES]>::try_from(s).ok()),
            m.col
                .get(range.clone())
                .and_then(|s| <&[f32; LANES]>::try_from(s).ok()),
            m.row
                .get(range.clone())
                .and_then(|s| <&[f32; LANES]>::try_from(s).ok()),
            m.quality
                .get(range.clone())
                .and_then(|s| <&[f32; LANES]>::try_from(s).ok()),
            m.invalid
                .get(range)
                .and_then(|s| <&[InvalidReason; LANES]>::try_from(s).ok()),
        );
        if let (Some(xs), Some(ys), Some(col), Some(row), Some(q), Some(inv)) = full
            && w >= LANES
        {
            // Pixel coordinates in f64 arithmetic (integer to f64 conversions of 64-bit
            // values are not vector instructions before AVX-512).
            let (x0, y0, wf) = (x0 as f64, y0 as f64, w as f64);
            for l in 0..LANES {
                let xl = x0 + l as f64;
                let wrap = xl >= wf;
                let u = if wrap { xl - wf } else { xl };
                let v = if wrap { y0 + 1.0 } else { y0 };
                let pre = self.status_before(xs[l], col[l], row[l], q[l], inv[l]);
                let keep = pre == PointStatus::Valid;
                g.pre[l] = pre;
                g.rx[l] = if keep { xs[l] } else { f64::NAN };
                g.ry[l] = if keep { ys[l] } else { f64::NAN };
                g.c[l] = f64::from(col[l]);
                g.r[l] = f64::from(row[l]);
                g.u[l] = u;
                g.v[l] = v;
            }
            return;
        }
        *g = Gathered::EMPTY;
        let (mut x, mut y) = (x0, y0);
        for l in 0..LANES {
            let i = base + l;
            let (u, v) = (x as f64, y as f64);
            x += 1;
            if x == w {
                (x, y) = (0, y + 1);
            }
            let (Some(&rx), Some(&ry), Some(&c), Some(&r), Some(&q), Some(&inv)) = (
                xs.get(i),
                ys.get(i),
                m.col.get(i),
                m.row.get(i),
                m.quality.get(i),
                m.invalid.get(i),
            ) else {
                continue;
            };
            g.pre[l] = self.status_before(rx, c, r, q, inv);
            if g.pre[l] == PointStatus::Valid {
                (g.rx[l], g.ry[l]) = (rx, ry);
                (g.c[l], g.r[l]) = (f64::from(c), f64::from(r));
                (g.u[l], g.v[l]) = (u, v);
            }
        }
    }

    /// A pixel's status before solving: `Valid` if it is to be solved.
    #[inline(always)]
    fn status_before(&self, rx: f64, c: f32, r: f32, q: f32, inv: InvalidReason) -> PointStatus {
        let o = self.options;
        let coordinates = self.solver.has_coordinates(c, r);
        if !(inv.is_valid() && coordinates) {
            PointStatus::NotDecoded
        } else if !(q >= o.min_quality) {
            PointStatus::LowQuality
        } else if !rx.is_finite() {
            PointStatus::NoSolution
        } else {
            PointStatus::Valid
        }
    }

    /// Ray–plane on the lanes, the general solver for lanes that need it.
    #[inline(always)]
    fn surface(
        &self,
        g: &Gathered,
        axis: Axis,
        warm: &mut WarmStart,
    ) -> (PointLanes, [f64; LANES]) {
        let target = if axis == Axis::Column { &g.c } else { &g.r };
        let observed = if axis == Axis::Column { &g.r } else { &g.c };
        let SurfaceLanes {
            mut t,
            mut other,
            ok,
        } = ray_surface_lanes(self.stereo, axis, &g.rx, &g.ry, target, &warm.guess());
        let mut out = PointLanes::default();
        for l in 0..LANES {
            out.ok[l] = ok[l];
            if !ok[l] && g.pre[l] == PointStatus::Valid {
                match ray_surface_depth(self.stereo, g.rx[l], g.ry[l], target[l], axis) {
                    Some(hit) => {
                        (t[l], other[l]) = (hit.t, hit.other);
                        out.ok[l] = true;
                    }
                    None => out.ok[l] = false,
                }
            }
        }
        warm.push(&t, &out.ok);
        let mut error = [0.0; LANES];
        for l in 0..LANES {
            out.x[l] = t[l] * g.rx[l];
            out.y[l] = t[l] * g.ry[l];
            out.z[l] = t[l];
            // The point is on the pixel's ray (camera residual zero) and on the decoded
            // surface (that residual below 1e-9 px): only the other coordinate, when
            // decoded, can disagree.
            let d = other[l] - observed[l];
            error[l] = if d.is_finite() {
                (0.5 * d * d).sqrt()
            } else {
                0.0
            };
        }
        (out, error)
    }

    /// Projector validity of the lanes' points and, when asked, their reprojection errors.
    /// (Non-short-circuit `&` on the lane booleans and the test of `with_error` outside the
    /// lane loops keep the loops free of branches, so that they are vectorised.)
    #[inline(always)]
    fn project(&self, g: &Gathered, p: &mut PointLanes, with_error: bool) -> [f64; LANES] {
        let s = self.stereo;
        let mut error = [f64::NAN; LANES];
        let mut qx = [0.0; LANES];
        let mut qy = [0.0; LANES];
        for l in 0..LANES {
            let q = s.to_proj([p.x[l], p.y[l], p.z[l]]);
            let iq = 1.0 / q[2];
            (qx[l], qy[l]) = (q[0] * iq, q[1] * iq);
            p.ok[l] =
                p.ok[l] & (p.z[l] > 0.0) & (q[2] > 0.0) & s.proj.in_valid_region(qx[l], qy[l]);
        }
        if with_error {
            for l in 0..LANES {
                let iz = 1.0 / p.z[l];
                let pc = s.cam.project_normalised(p.x[l] * iz, p.y[l] * iz);
                let pp = s.proj.project_normalised(qx[l], qy[l]);
                let (du, dv) = (pc.x - g.u[l], pc.y - g.v[l]);
                // A coordinate the map does not code (one-axis linear) has no residual.
                let (dc, dr) = (pp.x - g.c[l], pp.y - g.r[l]);
                let dc = if g.c[l].is_finite() { dc } else { 0.0 };
                let dr = if g.r[l].is_finite() { dr } else { 0.0 };
                error[l] = (0.5 * (du * du + dv * dv + dc * dc + dr * dr)).sqrt();
            }
        }
        error
    }

    /// Undistorted projector points of the lanes to solve (NaN for the others).
    #[inline(always)]
    fn projector_points(&self, g: &Gathered, warm: &mut WarmStart) -> ([f64; LANES], [f64; LANES]) {
        let mut c = [f64::NAN; LANES];
        let mut r = [f64::NAN; LANES];
        for l in 0..LANES {
            let solve = g.pre[l] == PointStatus::Valid;
            c[l] = if solve { g.c[l] } else { f64::NAN };
            r[l] = if solve { g.r[l] } else { f64::NAN };
        }
        undistort_lanes(&self.stereo.proj, &c, &r, &mut warm.proj)
    }

    /// Linear with the one coded coordinate on `axis` (see `linear.rs`).
    #[inline(always)]
    fn linear_one_axis(&self, g: &Gathered, axis: Axis, warm: &mut WarmStart) -> PointLanes {
        let mut target = if axis == Axis::Column { g.c } else { g.r };
        for l in 0..LANES {
            if g.pre[l] != PointStatus::Valid {
                target[l] = f64::NAN;
            }
        }
        let WarmStart { proj, linear, .. } = warm;
        linear_one_axis_lanes(self.stereo, linear, &g.rx, &g.ry, &target, proj)
    }

    /// Optimal: ray–plane start on the column, Gauss–Newton per lane.
    #[inline(always)]
    fn optimal(&self, g: &Gathered, warm: &mut WarmStart) -> (PointLanes, [f64; LANES]) {
        let (mut p, _) = self.surface(g, Axis::Column, warm);
        let mut error = [f64::NAN; LANES];
        for l in 0..LANES {
            if !(p.ok[l] && g.pre[l] == PointStatus::Valid) {
                p.ok[l] = false;
                continue;
            }
            let start = Vector3::new(p.x[l], p.y[l], p.z[l]);
            let refined = refine(
                self.stereo,
                start,
                (g.u[l], g.v[l]),
                (g.c[l], g.r[l]),
                self.options.optimal_iterations,
            );
            match refined {
                Some(refined) => {
                    let q = refined.p;
                    (p.x[l], p.y[l], p.z[l]) = (q.x, q.y, q.z);
                    error[l] = refined.reprojection;
                }
                None => p.ok[l] = false,
            }
        }
        (p, error)
    }

    /// One lane group: solve, then the filters.
    #[inline(always)]
    fn group<const M: u8>(
        &self,
        base: usize,
        xy: (usize, usize),
        g: &mut Gathered,
        out: BlockOut<'_>,
        warm: &mut WarmStart,
    ) {
        self.gather(base, xy, g);
        let g = &*g;
        let BlockOut {
            points,
            reprojection,
            status,
        } = out;
        let lanes = points
            .iter_mut()
            .zip(reprojection.iter_mut())
            .zip(status.iter_mut())
            .enumerate();
        if g.pre.iter().all(|s| *s != PointStatus::Valid) {
            for (l, ((p, e), s)) in lanes {
                (*p, *e, *s) = (NO_POINT, f32::NAN, g.pre[l % LANES]);
            }
            warm.push(&[f64::NAN; LANES], &[false; LANES]);
            return;
        }
        let with_error = self.error_needed();
        let (p, error) = match M {
            RAY_PLANE_COLUMN => self.surface(g, Axis::Column, warm),
            RAY_PLANE_ROW => self.surface(g, Axis::Row, warm),
            LINEAR | MIDPOINT => {
                let (xp, yp) = self.projector_points(g, warm);
                let mut p = if M == LINEAR {
                    linear_lanes(self.stereo, &g.rx, &g.ry, &xp, &yp)
                } else {
                    midpoint_lanes(self.stereo, &g.rx, &g.ry, &xp, &yp)
                };
                let e = self.project(g, &mut p, with_error);
                (p, e)
            }
            LINEAR_COLUMN | LINEAR_ROW => {
                let axis = if M == LINEAR_COLUMN {
                    Axis::Column
                } else {
                    Axis::Row
                };
                let mut p = self.linear_one_axis(g, axis, warm);
                let e = self.project(g, &mut p, with_error);
                (p, e)
            }
            _ => self.optimal(g, warm),
        };
        // The filters, as selects per lane, written straight into the output.
        let o = self.options;
        for (l, ((p_out, e_out), s_out)) in lanes {
            let l = l % LANES;
            let (pre, ok, z, e) = (g.pre[l], p.ok[l], p.z[l], error[l]);
            let st = if pre != PointStatus::Valid {
                pre
            } else if !ok {
                PointStatus::NoSolution
            } else if !(z >= o.min_depth_mm && z <= o.max_depth_mm) {
                PointStatus::OutOfDepthRange
            } else if with_error && !(e <= o.max_reprojection_px) {
                PointStatus::Reprojection
            } else {
                PointStatus::Valid
            };
            *s_out = st;
            *e_out = if pre == PointStatus::Valid && ok {
                e as f32
            } else {
                f32::NAN
            };
            *p_out = if st == PointStatus::Valid {
                Point3::new(p.x[l], p.y[l], z)
            } else {
                NO_POINT
            };
        }
    }
}

/// One block as a `pulp` operation: `with_simd` is inlined (with everything it calls, all
/// `#[inline(always)]`) into a function compiled for the detected instruction set.
struct BlockJob<'p, 'a, 'o> {
    pass: &'p Pass<'a>,
    start: usize,
    out: BlockOut<'o>,
}

impl pulp::WithSimd for BlockJob<'_, '_, '_> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) -> Self::Output {
        let one_axis = match self.pass.solver {
            Solver::LinearOneAxis(axis) => axis,
            _ => Axis::Column,
        };
        let mut warm = WarmStart {
            t1: [f64::NAN; LANES],
            t2: [f64::NAN; LANES],
            proj: UndistortWarm::default(),
            linear: LinearOneAxisState::new(self.pass.stereo, one_axis),
        };
        let (pass, start, out) = (self.pass, self.start, self.out);
        // One loop per method, each compiled with only its method's code (the method is a
        // constant of the loop: no dispatch per lane group, and the register allocation of
        // one method is not burdened by the others').
        match self.pass.solver {
            Solver::RayPlane(Axis::Column) => {
                run::<RAY_PLANE_COLUMN>(pass, start, out, &mut warm);
            }
            Solver::RayPlane(Axis::Row) => {
                run::<RAY_PLANE_ROW>(pass, start, out, &mut warm);
            }
            Solver::Linear => run::<LINEAR>(pass, start, out, &mut warm),
            Solver::LinearOneAxis(Axis::Column) => {
                run::<LINEAR_COLUMN>(pass, start, out, &mut warm);
            }
            Solver::LinearOneAxis(Axis::Row) => run::<LINEAR_ROW>(pass, start, out, &mut warm),
            Solver::Midpoint => run::<MIDPOINT>(pass, start, out, &mut warm),
            Solver::Optimal => run::<OPTIMAL>(pass, start, out, &mut warm),
        }
    }
}

/// The lane groups of the block starting at pixel `start`, with method `M`.
#[inline(always)]
fn run<const M: u8>(pass: &Pass<'_>, start: usize, out: BlockOut<'_>, warm: &mut WarmStart) {
    let BlockOut {
        points,
        reprojection,
        status,
    } = out;
    let chunks = points
        .chunks_mut(LANES)
        .zip(reprojection.chunks_mut(LANES))
        .zip(status.chunks_mut(LANES));
    // Pixel coordinates of each group's first pixel, kept up to date rather than divided
    // out per group (an integer division costs tens of cycles).
    let w = pass.width.max(1);
    let (mut x, mut y) = (start % w, start / w);
    let mut g = Gathered::EMPTY;
    for (k, ((points, reprojection), status)) in chunks.enumerate() {
        let out = BlockOut {
            points,
            reprojection,
            status,
        };
        pass.group::<M>(start + k * LANES, (x, y), &mut g, out, warm);
        x += LANES;
        while x >= w {
            (x, y) = (x - w, y + 1);
        }
    }
}
