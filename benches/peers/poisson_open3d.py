"""Open3D's screened Poisson reconstruction beside ours, on the same merged cloud, same run.

    cargo run --release --example slscan -- scan --out out/scan
    cargo build --release --example slscan
    /work/peers/bin/python benches/peers/poisson_open3d.py out/scan/merged.ply \
        --truth out/scan/truth.json --slscan target/release/examples/slscan [--repeat 3]

Times `create_from_point_cloud_poisson(depth=9)` (Open3D's defaults otherwise: width 0,
scale 1.1, linear_fit False, all cores) and, with --slscan, `slscan mesh CLOUD --out DIR
--depth 9` (wall time of the whole command, reading and writing files included, and the
reconstruction time it reports), best of N each. Both meshes are then measured the same way:
watertight and manifold (Open3D's own checks), and the RMS distance to the true spheres of the
vertices within `select_mm` of one (the selection of `sl-metrology`), next to the same figure of
the cloud itself.
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


def mesh_checks(name, mesh):
    wt = mesh.is_watertight()
    em = mesh.is_edge_manifold()
    vm = mesh.is_vertex_manifold()
    print(f"{name:10s} {len(mesh.vertices)} vertices, {len(mesh.triangles)} triangles; "
          f"watertight {wt}, edge-manifold {em}, vertex-manifold {vm}")
    return wt


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("ply")
    ap.add_argument("--truth", required=True)
    ap.add_argument("--depth", type=int, default=9)
    ap.add_argument("--repeat", type=int, default=3)
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

    best = float("inf")
    mesh = None
    for _ in range(args.repeat):
        t = time.perf_counter()
        mesh, _dens = o3d.geometry.TriangleMesh.create_from_point_cloud_poisson(
            cloud, depth=args.depth)
        best = min(best, time.perf_counter() - t)
    print(f"Open3D     create_from_point_cloud_poisson: best of {args.repeat}: {best:.3f} s")
    mesh_checks("Open3D", mesh)
    describe("Open3D", np.asarray(mesh.vertices), truth)
    o3d.io.write_triangle_mesh(os.path.join(args.out, "open3d.ply"), mesh)

    if args.slscan:
        out = os.path.join(args.out, "ours")
        best_wall = float("inf")
        report = None
        for _ in range(args.repeat):
            t = time.perf_counter()
            subprocess.run([args.slscan, "mesh", args.ply, "--out", out, "--depth",
                            str(args.depth)], check=True, stdout=subprocess.DEVNULL)
            wall = time.perf_counter() - t
            r = json.load(open(os.path.join(out, "report.json")))
            if wall < best_wall:
                best_wall, report = wall, r
        t = {s["name"]: s["ms"] for s in report["stages"]}
        print(f"ours       slscan mesh: best of {args.repeat}: {best_wall:.3f} s wall "
              f"(reconstruction {t['reconstruct'] / 1e3:.3f} s)")
        ours = o3d.io.read_triangle_mesh(os.path.join(out, "mesh.ply"))
        mesh_checks("ours", ours)
        f = report["figures"]
        print(f"ours       report.json: watertight {f['watertight']}, manifold {f['manifold']}")
        describe("ours", np.asarray(ours.vertices), truth)


if __name__ == "__main__":
    main()
