"""The figures of issue 17 for one or more meshes of the same merged cloud: vertices, the RMS of
all vertices to the true spheres, split into vertices supported by data (within --support-mm of
a cloud point) and the others, and the area-weighted RMS (the squared error integrated over each
triangle by the 6-point degree-4 Gauss rule of Dunavant 1985), split the same way by each
quadrature point. Same selection as `poisson_open3d.py` (points
within `select_mm` of a true sphere).

The RMS to the truth mixes two things: the error the cloud already has (on the default scan a
rigid displacement of about 0.1 mm from the calibration, the same for both spheres) and the
error the mesh adds. So the spheres fitted to the cloud are printed too, and for each mesh, where
the data is: the RMS of its vertices and of its area to those fitted spheres (the error the
mesh adds to the cloud's surface) and the RMS of the cloud's own error field at its vertices
(the truth error of the fitted sphere at each vertex's direction: what the vertices' RMS to the
truth would be if the mesh lay exactly on the cloud's surface). The last depends only on where
the vertices are.

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


def fit_spheres(points, truth):
    """Least-squares sphere (algebraic, Kasa) through the points within select of each true sphere."""
    fits = []
    for s in [f for f in truth["features"] if f["type"] == "sphere"]:
        c = np.asarray(s["centre_mm"])
        q = points[np.abs(np.linalg.norm(points - c, axis=1) - s["radius_mm"]) <= s.get("select_mm", 2.0)]
        a = np.c_[2 * q, np.ones(len(q))]
        x = np.linalg.lstsq(a, (q**2).sum(1), rcond=None)[0]
        fits.append((x[:3], float(np.sqrt(x[3] + x[:3] @ x[:3])), c, s["radius_mm"]))
    return fits


def fitted_errors(points, fits):
    """Per point: signed distance to the nearest fitted sphere, and the truth error of that fitted
    sphere at the point's direction (the cloud's error field there)."""
    best = np.full(len(points), np.inf)
    field = np.zeros(len(points))
    for c, r, tc, tr in fits:
        d = points - c
        rr = np.linalg.norm(d, axis=1)
        on = c + d / rr[:, None] * r
        e = np.linalg.norm(on - tc, axis=1) - tr
        closer = np.abs(rr - r) < np.abs(best)
        best = np.where(closer, rr - r, best)
        field = np.where(closer, e, field)
    return best, field


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("cloud")
    ap.add_argument("meshes", nargs="+")
    ap.add_argument("--truth", required=True)
    ap.add_argument("--support-mm", type=float, default=1.0)
    args = ap.parse_args()
    truth = json.load(open(args.truth))
    cloud = o3d.io.read_point_cloud(args.cloud)
    cp = np.asarray(cloud.points)
    fits = fit_spheres(cp, truth)
    own, _ = fitted_errors(cp, fits)
    for c, r, tc, tr in fits:
        print(f"cloud: sphere fitted at {np.round(c - tc, 4)} mm from the true centre, radius "
              f"{r - tr:+.4f} mm")
    print(f"cloud: RMS to the fitted spheres {rms(own):.4f} mm")
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
        vown, vfield = fitted_errors(v, fits)
        cown, _ = fitted_errors(c, fits)
        vs, cs = sel & near, csel & cnear
        print(f"  where the data is, to the spheres fitted to the cloud: vertices {rms(vown[vs]):.4f} mm, "
              f"area-weighted {rms(cown[cs], area[cs]):.4f} mm; the cloud's own truth error at "
              f"these vertices {rms(vfield[vs]):.4f} mm")
        rep = os.path.join(os.path.dirname(path), "report.json")
        if os.path.exists(rep):
            f = json.load(open(rep))["figures"]
            if "rms_to_truth_area_mm" in f:
                print(f"  report.json: area-weighted RMS (sl-metrology) {f['rms_to_truth_area_mm']:.4f} mm, "
                      f"vertices {f['rms_to_truth_vertices_mm']:.4f} mm")


if __name__ == "__main__":
    main()
