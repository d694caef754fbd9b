"""The plain rectify-and-match peer of `sl_tri::Binocular` on the same decoded maps.

On `binocular_sdk` (SL_DATA_EXTRA): writes the capture's manifests (the same as
`crates/sl-scan/tests/it/binocular_sdk.rs`), runs `slscan decode --format npy` on both cameras
and `slscan reconstruct L --right R --calib cali/intrinsic.yml` (ours, timed by the command's
own report), then, on our decoded column maps, the plain method a numpy/OpenCV user writes:

  * `cv2.stereoRectify` + `cv2.initUndistortRectifyMap` (once per calibration, not timed),
    `cv2.remap` of both column maps (bilinear);
  * per rectified row, each left code looked up among the right row's codes sorted
    (`np.searchsorted`), the right position interpolated between the two neighbouring codes when
    they are adjacent pixels; no left-right check, no depth-jump filter;
  * `cv2.reprojectImageTo3D` of the disparity.

Prints, for both: points (coverage), the disparity's roughness (the median of
|d(x-1) - 2 d(x) + d(x+1)| along rectified rows where three neighbours matched, as our report
defines it) and the time.

    cargo build --release --example slscan
    SL_DATA_EXTRA=/work/sl-data-extra /work/peers/bin/python \
        benches/peers/binocular_rectify_match.py --slscan target/release/examples/slscan --runs 3
"""
import argparse
import json
import os
import subprocess
import tempfile
import time

import cv2
import numpy as np

MANIFEST = """{{"format": "sl-capture", "version": 1,
  "description": "binocular_sdk phaseGray (peer)",
  "projector": {{"width": 1920, "height": 1080}}, "bit_depth": 8,
  "frames_dir": "{frames}",
  "blocks": [{{"codec": "hybrid", "axis": "column", "steps": 4, "periods": 32,
    "phase_offset": 3.141592653589793, "shift_sign": -1,
    "gray": {{"bits": 6, "reference": "phase_mean", "binary": false, "stripe_width": 30,
      "origin": -0.5}},
    "frames": [{names}]}}]}}"""


def read_mat(fs, key):
    m = fs.getNode(key).mat()
    if m is None:
        raise SystemExit("%s: no matrix %s" % (fs, key))
    return m


def roughness(disp):
    """Median |d(x-1) - 2 d(x) + d(x+1)| along rows where the three are finite (px)."""
    second = disp[:, :-2] - 2.0 * disp[:, 1:-1] + disp[:, 2:]
    second = np.abs(second[np.isfinite(second)])
    return float(np.median(second)) if second.size else float("nan")


def match_rows(left, right):
    """Disparity of each left pixel: its code among the right row's (plain lookup)."""
    h, w = left.shape
    disp = np.full((h, w), np.nan, dtype=np.float32)
    xs = np.arange(w, dtype=np.float64)
    for y in range(h):
        rc = right[y]
        ok = np.isfinite(rc)
        if ok.sum() < 2:
            continue
        rx = xs[ok]
        rv = rc[ok].astype(np.float64)
        order = np.argsort(rv, kind="stable")
        rv, rx = rv[order], rx[order]
        lc = left[y]
        lx = np.nonzero(np.isfinite(lc))[0]
        if lx.size == 0:
            continue
        c = lc[lx].astype(np.float64)
        k = np.searchsorted(rv, c)
        inside = (k > 0) & (k < rv.size)
        k, c, lx = k[inside], c[inside], lx[inside]
        x0, x1 = rx[k - 1], rx[k]
        v0, v1 = rv[k - 1], rv[k]
        adjacent = (np.abs(x1 - x0) == 1.0) & (v1 > v0)
        t = (c[adjacent] - v0[adjacent]) / (v1[adjacent] - v0[adjacent])
        xr = x0[adjacent] + t * (x1[adjacent] - x0[adjacent])
        disp[y, lx[adjacent]] = (lx[adjacent] - xr).astype(np.float32)
    return disp


def peer(lcol, rcol, intrinsic, extrinsic):
    fi = cv2.FileStorage(intrinsic, cv2.FILE_STORAGE_READ)
    fe = cv2.FileStorage(extrinsic, cv2.FILE_STORAGE_READ)
    m1, d1, m2, d2 = (read_mat(fi, k) for k in ("M1", "D1", "M2", "D2"))
    r, t = read_mat(fe, "R"), read_mat(fe, "T")
    h, w = lcol.shape
    r1, r2, p1, p2, q, _, _ = cv2.stereoRectify(m1, d1, m2, d2, (w, h), r, t)
    maps = [
        cv2.initUndistortRectifyMap(m, d, rr, p, (w, h), cv2.CV_32FC1)
        for m, d, rr, p in ((m1, d1, r1, p1), (m2, d2, r2, p2))
    ]
    start = time.perf_counter()
    lr = cv2.remap(lcol, maps[0][0], maps[0][1], cv2.INTER_LINEAR, borderValue=np.nan)
    rr = cv2.remap(rcol, maps[1][0], maps[1][1], cv2.INTER_LINEAR, borderValue=np.nan)
    disp = match_rows(lr, rr)
    disp[~(disp > 0)] = np.nan
    xyz = cv2.reprojectImageTo3D(np.nan_to_num(disp, nan=-1.0), q)
    elapsed = time.perf_counter() - start
    points = xyz[np.isfinite(disp)]
    return {
        "points": int(points.shape[0]),
        "roughness_px": roughness(disp),
        "seconds": elapsed,
        "depth_mm": [float(np.percentile(points[:, 2], 1)), float(np.percentile(points[:, 2], 99))]
        if points.size
        else None,
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--slscan", required=True, help="path of the slscan binary (release)")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--work", help="working folder (default: a temporary one)")
    args = ap.parse_args()
    extra = os.environ.get("SL_DATA_EXTRA")
    if not extra:
        raise SystemExit("SL_DATA_EXTRA not set (binocular_sdk is extracted there)")
    data = os.path.join(extra, "binocular_sdk")
    work = args.work or tempfile.mkdtemp(prefix="binocular-peer-")
    names = ", ".join('"%d.bmp"' % k for k in range(10))
    for side in ("L", "R"):
        d = os.path.join(work, side)
        os.makedirs(d, exist_ok=True)
        with open(os.path.join(d, "manifest.json"), "w") as f:
            f.write(MANIFEST.format(frames=os.path.join(data, "phaseGray", side), names=names))
        subprocess.run(
            [args.slscan, "decode", d, "--format", "npy", "--force", "--out", d + "-decoded"],
            check=True,
            stdout=subprocess.DEVNULL,
        )
    calib = os.path.join(data, "cali", "intrinsic.yml")
    ours = []
    for run in range(args.runs):
        out = os.path.join(work, "ours")
        start = time.perf_counter()
        subprocess.run(
            [args.slscan, "reconstruct", os.path.join(work, "L"), "--right",
             os.path.join(work, "R"), "--calib", calib, "--force", "--out", out],
            check=True,
            stdout=subprocess.DEVNULL,
        )
        wall = time.perf_counter() - start
        with open(os.path.join(out, "report.json")) as f:
            rep = json.load(f)
        fig = rep["figures"]
        stages = {s["name"]: s["ms"] for s in rep.get("stages", [])}
        ours.append((fig, stages, wall))
    lcol = np.load(os.path.join(work, "L-decoded", "col.npy")).astype(np.float32)
    rcol = np.load(os.path.join(work, "R-decoded", "col.npy")).astype(np.float32)
    theirs = [peer(lcol, rcol, calib, os.path.join(data, "cali", "extrinsic.yml"))
              for _ in range(args.runs)]
    fig, stages, _ = ours[-1]
    match_ms = sorted(s.get("match and triangulate", float("nan")) for _, s, _ in ours)
    print("binocular_sdk, %dx%d, the same decoded column maps" % (lcol.shape[1], lcol.shape[0]))
    print("%-34s %10s %14s %24s" % ("", "points", "roughness px", "time"))
    print("%-34s %10d %14.3f %24s" % (
        "ours (sl_tri::Binocular)", fig["points"], fig["disparity_roughness_px"],
        "match+tri %.0f ms (median of %d)" % (match_ms[len(match_ms) // 2], len(match_ms))))
    t = sorted(r["seconds"] for r in theirs)
    print("%-34s %10d %14.3f %24s" % (
        "OpenCV rectify + numpy match", theirs[0]["points"], theirs[0]["roughness_px"],
        "remap+match+3D %.0f ms (median of %d)" % (1000 * t[len(t) // 2], len(t))))
    print("peer depth range (1st-99th percentile): %s mm" % theirs[0]["depth_mm"])


if __name__ == "__main__":
    main()
