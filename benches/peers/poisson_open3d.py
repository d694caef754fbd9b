"""Open3D's screened Poisson reconstruction beside ours, on the same merged cloud, same run.

    cargo run --release --example slscan -- scan --out out/scan
    cargo build --release --example slscan
    /work/peers/bin/python benches/peers/poisson_open3d.py out/scan/merged.ply \
        --truth out/scan/truth.json --slscan target/release/examples/slscan [--repeat 3]

Times `create_from_point_cloud_poisson(depth=9)` (Open3D's defaults otherwise: width 0,
scale 1.1, linear_fit False, all cores) and, with --slscan, `slscan mesh CLOUD --out DIR
--depth 9` (wall time of the whole command, reading and writing files included, and the
reconstruction time it reports), alternately, best of N each, and the ratio of each pair. Both meshes are then measured the same way:
closed and manifold (Open3D's own checks), and the RMS distance to the true spheres of the
vertices within `select_mm` of one (the selection of `sl-metrology`), next to the same figure of
the cloud itself. Since a watertight mesh must also close what the scanner never saw (the
lower back of each sphere), the RMS is given over all those vertices and split into the
vertices supported by data (within --support-mm of a point of the cloud) and the others.
"""
import argparse
import json
import os
import subprocess
import tempfile
import time

import numpy as np
import open3d as o3d


def sphere_errors(points, truth):
    """Signed distance of each point to the nearest true sphere, and the selection mask."""
    spheres = [f for f in truth["features"] if f["type"] == "sphere"]
    best = np.full(len(points), np.inf)
    sel = np.zeros(len(points), dtype=bool)
    for s in spheres:
        d = np.linalg.norm(points - np.asarray(s["centre_mm"]), axis=1) - s["radius_mm"]
        closer = np.abs(d) < np.abs(best)
        best = np.where(closer, d, best)
        sel |= np.abs(d) <= s.get("select_mm", 2.0)
    return best, sel


def describe(name, points, truth):
    err, sel = sphere_errors(points, truth)
    e = err[sel]
    rms = float(np.sqrt(np.mean(e**2))) if len(e) else float("nan")
    print(f"{name:10s} {sel.sum():8d} of {len(points):8d} points within select of a sphere: "
          f"RMS {rms:.4f} mm, mean {e.mean():+.4f} mm, largest {np.abs(e).max():.4f} mm")
    return rms


def describe_split(name, points, truth, cloud, support_mm):
    """The RMS of `describe`, split by the distance of each vertex to the nearest cloud point."""
    err, sel = sphere_errors(points, truth)
    pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    near = np.asarray(pc.compute_point_cloud_distance(cloud)) <= support_mm
    for label, mask in (("supported", sel & near), ("unsupported", sel & ~near)):
        e = err[mask]
        rms = float(np.sqrt(np.mean(e**2))) if len(e) else float("nan")
        print(f"{name:10s}   {label:11s} (within {support_mm} mm of the cloud: "
              f"{'yes' if label == 'supported' else 'no'}): {mask.sum():8d} vertices, RMS {rms:.4f} mm")


def mesh_checks(name, mesh, self_intersection):
    """Closed (every edge of exactly two triangles: Open3D's `is_edge_manifold` without boundary
    edges) and vertex-manifold; Open3D's `is_watertight` adds a self-intersection test that takes
    minutes on a million triangles, run only with --self-intersection."""
    closed = mesh.is_edge_manifold(allow_boundary_edges=False)
    em = mesh.is_edge_manifold()
    vm = mesh.is_vertex_manifold()
    extra = ""
    if self_intersection:
        extra = f", self-intersecting {mesh.is_self_intersecting()}"
    print(f"{name:10s} {len(mesh.vertices)} vertices, {len(mesh.triangles)} triangles; "
          f"closed {closed}, edge-manifold {em}, vertex-manifold {vm}{extra}")
    return closed


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("ply")
    ap.add_argument("--truth", required=True)
    ap.add_argument("--depth", type=int, default=9)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--support-mm", type=float, default=1.0,
                    help="a vertex within this distance of a cloud point counts as supported by data")
    ap.add_argument("--self-intersection", action="store_true",
                    help="also run Open3D's self-intersection test (slow: minutes per mesh)")
    ap.add_argument("--slscan", help="path of the slscan binary (release) to run beside Open3D")
    ap.add_argument("--out", default=os.path.join(tempfile.gettempdir(), "poisson-peers"))
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)
    truth = json.load(open(args.truth))

    cloud = o3d.io.read_point_cloud(args.ply)
    assert cloud.has_normals(), "the cloud needs normals (merged.ply has them)"
    print(f"Open3D {o3d.__version__}, {len(cloud.points)} points from {args.ply}, "
          f"{os.cpu_count()} CPUs, depth {args.depth}")
    describe("cloud", np.asarray(cloud.points), truth)

    # Open3D and ours alternate, so that a machine whose speed drifts (this one's varies by
    # ±20 % from minute to minute) slows both alike; each pair's ratio is printed too.
    out = os.path.join(args.out, "ours")
    best, best_wall = float("inf"), float("inf")
    mesh, report = None, None
    for k in range(args.repeat):
        t = time.perf_counter()
        mesh, _dens = o3d.geometry.TriangleMesh.create_from_point_cloud_poisson(
            cloud, depth=args.depth)
        theirs = time.perf_counter() - t
        best = min(best, theirs)
        if args.slscan:
            t = time.perf_counter()
            subprocess.run([args.slscan, "mesh", args.ply, "--out", out, "--depth",
                            str(args.depth)], check=True, stdout=subprocess.DEVNULL)
            wall = time.perf_counter() - t
            r = json.load(open(os.path.join(out, "report.json")))
            if wall < best_wall:
                best_wall, report = wall, r
            print(f"pair {k + 1}: Open3D {theirs:.3f} s, slscan mesh {wall:.3f} s "
                  f"({wall / theirs:.2f}×)")
    print(f"Open3D     create_from_point_cloud_poisson: best of {args.repeat}: {best:.3f} s")
    mesh_checks("Open3D", mesh, args.self_intersection)
    describe("Open3D", np.asarray(mesh.vertices), truth)
    describe_split("Open3D", np.asarray(mesh.vertices), truth, cloud, args.support_mm)
    o3d.io.write_triangle_mesh(os.path.join(args.out, "open3d.ply"), mesh)

    if args.slscan:
        t = {s["name"]: s["ms"] for s in report["stages"]}
        print(f"ours       slscan mesh: best of {args.repeat}: {best_wall:.3f} s wall "
              f"(reconstruction {t['reconstruct'] / 1e3:.3f} s); best against best "
              f"{best_wall / best:.2f}×")
        ours = o3d.io.read_triangle_mesh(os.path.join(out, "mesh.ply"))
        mesh_checks("ours", ours, args.self_intersection)
        f = report["figures"]
        print(f"ours       report.json: watertight {f['watertight']}, manifold {f['manifold']}")
        describe("ours", np.asarray(ours.vertices), truth)
        describe_split("ours", np.asarray(ours.vertices), truth, cloud, args.support_mm)


if __name__ == "__main__":
    main()
