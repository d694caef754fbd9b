"""The figures of issue 17 for one or more meshes of the same merged cloud: vertices, the RMS of
all vertices to the true spheres, split into vertices supported by data (within --support-mm of
a cloud point) and the others, and the area-weighted RMS (the squared error integrated over each
triangle by the 6-point degree-4 Gauss rule of Dunavant 1985), split the same way by each
quadrature point. Same selection as `poisson_open3d.py` (points
within `select_mm` of a true sphere).

    /work/peers/bin/python benches/peers/mesh_figures.py /work/wt/data/merged.ply \
        --truth /work/wt/data/truth.json OUT_A/mesh.ply OUT_B/mesh.ply [/tmp/poisson-peers/open3d.ply]
"""
import argparse
import json
import os

import numpy as np
import open3d as o3d

from poisson_open3d import sphere_errors


_A, _B = (0.108103018168070, 0.445948490915965), (0.816847572980459, 0.091576213509771)
GAUSS6 = [((_A[0], _A[1], _A[1]), 0.223381589678011), ((_A[1], _A[0], _A[1]), 0.223381589678011),
          ((_A[1], _A[1], _A[0]), 0.223381589678011), ((_B[0], _B[1], _B[1]), 0.109951743655322),
          ((_B[1], _B[0], _B[1]), 0.109951743655322), ((_B[1], _B[1], _B[0]), 0.109951743655322)]


def rms(e, w=None):
    if len(e) == 0:
        return float("nan")
    if w is None:
        return float(np.sqrt(np.mean(e**2)))
    return float(np.sqrt(np.sum(w * e**2) / np.sum(w)))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("cloud")
    ap.add_argument("meshes", nargs="+")
    ap.add_argument("--truth", required=True)
    ap.add_argument("--support-mm", type=float, default=1.0)
    args = ap.parse_args()
    truth = json.load(open(args.truth))
    cloud = o3d.io.read_point_cloud(args.cloud)
    for path in args.meshes:
        mesh = o3d.io.read_triangle_mesh(path)
        v = np.asarray(mesh.vertices)
        t = np.asarray(mesh.triangles)
        err, sel = sphere_errors(v, truth)
        near = np.asarray(o3d.geometry.PointCloud(o3d.utility.Vector3dVector(v))
                          .compute_point_cloud_distance(cloud)) <= args.support_mm
        p0, p1, p2 = v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]
        tri_area = 0.5 * np.linalg.norm(np.cross(p1 - p0, p2 - p0), axis=1)
        c, area = [], []
        for (l0, l1, l2), w in GAUSS6:
            c.append(l0 * p0 + l1 * p1 + l2 * p2)
            area.append(w * tri_area)
        c, area = np.concatenate(c), np.concatenate(area)
        cerr, csel = sphere_errors(c, truth)
        cnear = np.asarray(o3d.geometry.PointCloud(o3d.utility.Vector3dVector(c))
                           .compute_point_cloud_distance(cloud)) <= args.support_mm
        print(f"{path}: {len(v)} vertices, {len(t)} triangles, {os.path.getsize(path)} bytes")
        print(f"  vertices: all {rms(err[sel]):.4f} mm ({sel.sum()}), supported "
              f"{rms(err[sel & near]):.4f} mm ({(sel & near).sum()}), unsupported "
              f"{rms(err[sel & ~near]):.4f} mm ({(sel & ~near).sum()})")
        print(f"  area-weighted: all {rms(cerr[csel], area[csel]):.4f} mm, supported "
              f"{rms(cerr[csel & cnear], area[csel & cnear]):.4f} mm "
              f"({area[csel & cnear].sum():.0f} mm2), unsupported "
              f"{rms(cerr[csel & ~cnear], area[csel & ~cnear]):.4f} mm ({area[csel & ~cnear].sum():.0f} mm2)")
        rep = os.path.join(os.path.dirname(path), "report.json")
        if os.path.exists(rep):
            f = json.load(open(rep))["figures"]
            if "rms_to_truth_area_mm" in f:
                print(f"  report.json: area-weighted RMS (sl-metrology) {f['rms_to_truth_area_mm']:.4f} mm, "
                      f"vertices {f['rms_to_truth_vertices_mm']:.4f} mm")


if __name__ == "__main__":
    main()
