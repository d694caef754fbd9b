"""What the bunny peer scripts (`icp_bunny.py`, `global_bunny.py`) share: the shared scans in
millimetres with their `bun.conf` poses, and the error of an estimated pose.

Conventions, identical to sl-icp's tests, benches and examples:
  * scans converted from metres to millimetres (x1000); every length is in mm;
  * bun.conf: p_world = R(q)^T p + t (quaternion scalar-last), so T_world_scan = (R^T, 1000 t);
  * error of an estimate T against T_ref: rotation angle of R_ref^T R (deg); translation
    |t - t_ref| (mm); RMS displacement sqrt(mean |T p - T_ref p|^2) over the given points.
"""
import os

import numpy as np
import open3d as o3d
from scipy.spatial.transform import Rotation

MM_PER_M = 1000.0


def bunny_dir(what):
    """The folder of the bunny scans under $SL_DATA, or None (saying what is skipped)."""
    data = os.environ.get("SL_DATA")
    if not data:
        print("SL_DATA not set: skipping %s" % what)
        return None
    return os.path.join(data, "bunny")


def load(directory, name):
    """The scan `name` (e.g. "bun045") in mm and its pose T_world_scan from bun.conf."""
    pcd = o3d.io.read_point_cloud(os.path.join(directory, name + ".ply"))
    pts = np.asarray(pcd.points) * MM_PER_M
    with open(os.path.join(directory, "bun.conf")) as f:
        for line in f:
            w = line.split()
            if w and w[0] == "bmesh" and w[1] == name + ".ply":
                t = np.array([float(v) for v in w[2:5]]) * MM_PER_M
                q = [float(v) for v in w[5:9]]  # qx qy qz qw (scalar last)
                T = np.eye(4)
                T[:3, :3] = Rotation.from_quat(q).as_matrix().T
                T[:3, 3] = t
                return pts, T
    raise SystemExit(f"{name} not in bun.conf")


def pose_error(T, T_ref, pts):
    """(rotation deg, translation mm, RMS displacement mm over `pts`) of T against T_ref."""
    dR = T_ref[:3, :3].T @ T[:3, :3]
    angle = np.degrees(np.arccos(np.clip((np.trace(dR) - 1) / 2, -1, 1)))
    trans = np.linalg.norm(T[:3, 3] - T_ref[:3, 3])
    d = (pts @ T[:3, :3].T + T[:3, 3]) - (pts @ T_ref[:3, :3].T + T_ref[:3, 3])
    return angle, trans, np.sqrt((d ** 2).sum(1).mean())
