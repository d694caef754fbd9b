#!/usr/bin/env python3
"""Peer figures for sl-icp: bun045 registered onto bun000 with Open3D and small_gicp.

What it measures (printed as one table, medians and minima over RUNS runs):
  * Open3D 0.20 point-to-plane ICP, 1 mm voxels, normals from 20 neighbours, 5 mm max
    distance, from the "5 deg off" start; ICP time and preprocessing time apart.
  * Open3D generalized ICP, 2 mm voxels, 5 mm max distance (covariances from 20 neighbours,
    inside the ICP call), same start.
  * small_gicp GICP, 2 mm voxels, 5 mm max distance, 2 threads, preprocessing included
    (small_gicp.align), same start.
  * Open3D point-to-point ICP, 1 mm voxels, from the raw scan poses (34 deg / 53 mm off),
    with 5 mm and with 20 mm max distance.

Conventions, identical to sl-icp's tests, bench and `examples/bunny.rs` (scans in mm with
their bun.conf poses, the pose error: `common.py`):
  * the reference T_000_045 = T_world_000^-1 T_world_045;
  * start "5 deg off" = T_ref * P, P a 5 deg rotation about the +y axis of bun045 through the
    centroid of its (full-resolution) points: 5.00 deg / 5.36 mm by the definition below;
  * the error's translation |t - t_ref| tells how far the origin of bun045's frame is
    misplaced; its RMS displacement is over bun045's points.

Run (not in CI; needs open3d and small_gicp, e.g. `pip install open3d small_gicp`):
    SL_DATA=/work/shared/data /tmp/peers/bin/python benches/peers/icp_bunny.py
Our side of the table: `SL_DATA=... cargo run --release -p sl-icp --example bunny`
(and the criterion bench `cargo bench -p sl-icp --bench bunny`).
"""
import os
import statistics
import sys
import time

import numpy as np
import open3d as o3d
import small_gicp
from scipy.spatial.transform import Rotation

from common import bunny_dir, load, pose_error

RUNS = 21


def cloud(pts):
    p = o3d.geometry.PointCloud()
    p.points = o3d.utility.Vector3dVector(pts)
    return p


def timed(f):
    t0 = time.perf_counter()
    r = f()
    return r, (time.perf_counter() - t0) * 1e3


def main():
    d = bunny_dir("the bunny peer figures")
    if d is None:
        return
    tgt, T0 = load(d, "bun000")
    src, T45 = load(d, "bun045")
    T_ref = np.linalg.inv(T0) @ T45
    c = src.mean(0)
    P = np.eye(4)
    R5 = Rotation.from_rotvec(np.radians(5.0) * np.array([0.0, 1.0, 0.0])).as_matrix()
    P[:3, :3] = R5
    P[:3, 3] = c - R5 @ c
    T_start = T_ref @ P
    T_raw = np.eye(4)
    print("open3d %s, small_gicp, threads: %d" % (o3d.__version__, os.cpu_count()))
    print("start: %.2f deg / %.2f mm (rms %.2f mm); raw poses: %.2f deg / %.2f mm (rms %.2f mm)"
          % (pose_error(T_start, T_ref, src) + pose_error(T_raw, T_ref, src)))
    reg = o3d.pipelines.registration
    knn20 = o3d.geometry.KDTreeSearchParamKNN(20)

    def prep(voxel, normals):
        s = cloud(src).voxel_down_sample(voxel)
        t = cloud(tgt).voxel_down_sample(voxel)
        if normals:
            s.estimate_normals(knn20)
            t.estimate_normals(knn20)
        return s, t

    cases = [
        ("open3d point-to-plane 1 mm, 5 mm", 1.0, True, T_start,
         lambda s, t, T: reg.registration_icp(s, t, 5.0, T, reg.TransformationEstimationPointToPlane())),
        ("open3d generalized 2 mm, 5 mm", 2.0, False, T_start,
         lambda s, t, T: reg.registration_generalized_icp(s, t, 5.0, T, reg.TransformationEstimationForGeneralizedICP())),
        ("raw: open3d point-to-point 1 mm, 5 mm", 1.0, False, T_raw,
         lambda s, t, T: reg.registration_icp(s, t, 5.0, T, reg.TransformationEstimationPointToPoint())),
        ("raw: open3d point-to-point 1 mm, 20 mm", 1.0, False, T_raw,
         lambda s, t, T: reg.registration_icp(s, t, 20.0, T, reg.TransformationEstimationPointToPoint())),
    ]
    header = "%-40s %9s %9s %9s %9s %6s %8s %8s %8s %7s" % (
        "case", "prep med", "icp med", "icp min", "total med", "iters", "rot deg", "trans mm", "rms mm", "fitness")
    print(header)
    for name, voxel, normals, T, run in cases:
        preps, icps, res = [], [], None
        for _ in range(RUNS):
            (s, t), tp = timed(lambda: prep(voxel, normals))
            res, ti = timed(lambda: run(s, t, T))
            preps.append(tp)
            icps.append(ti)
        e = pose_error(res.transformation, T_ref, src)
        totals = [a + b for a, b in zip(preps, icps)]
        # Open3D does not report its iteration count.
        print("%-40s %9.1f %9.1f %9.1f %9.1f %6s %8.3f %8.3f %8.3f %7.3f" % (
            name, statistics.median(preps), statistics.median(icps), min(icps),
            statistics.median(totals), "-", *e, res.fitness))
    # small_gicp: preprocessing (voxel grid, 10-neighbour covariances, k-d trees) included.
    times, res = [], None
    for _ in range(RUNS):
        res, ti = timed(lambda: small_gicp.align(
            tgt, src, T_start, registration_type="GICP", downsampling_resolution=2.0,
            max_correspondence_distance=5.0, num_threads=2))
        times.append(ti)
    e = pose_error(res.T_target_source, T_ref, src)
    print("%-40s %9s %9.1f %9.1f %9.1f %6d %8.3f %8.3f %8.3f %7s" % (
        "small_gicp GICP 2 mm, 5 mm, 2 threads", "incl.", statistics.median(times), min(times),
        statistics.median(times), res.iterations, *e, "-"))


if __name__ == "__main__":
    sys.exit(main())
