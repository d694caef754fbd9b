"""Our checkerboard corners against OpenCV's on real boards, through the same calibration.

```sh
cargo build --release -p sl-calib --example corners_json
SL_DATA=/work/shared/data SL_DATA_EXTRA=/work/sl-data-extra \
    /work/peers/bin/python benches/peers/real_corner_rms.py [--json out.json] \
    [--set NAME=COLSxROWS=GLOB ...]
```

Sets (each skipped with a message when its folder is not there):
* OpenCV's samples, `$SL_DATA/chessboard/left*.jpg` and `right*.jpg` (9x6, 640x480 JPEG);
* procam_kamino's white frames, `$SL_DATA_EXTRA/procam_kamino/capture_*/graycode_40.png` (9x7);
* procam_kamino's fringe means: per pose the mean of its 40 pattern frames (00-39: 20 Gray-code
  pairs, so every pixel is lit in exactly half of them and the mean is a white frame at half
  light with the noise of 40 frames averaged). Written as 16-bit PNG, value round(257 mean), to
  a temporary folder; every detector reads it at 8 bits, round(mean) (our detector takes 8-bit
  images; OpenCV's findChessboardCorners too), and one more row refines OpenCV's corners with
  cornerSubPix(11x11) on the float mean itself;
* any `--set NAME=COLSxROWS=GLOB` given.

Methods, each on the same 8-bit images:
* `ours saddle`: `sl_calib::detect_checkerboard` with the saddle points alone
  (`junction_fraction` 0), and `ours junction`: with `DetectorConfig::with_junction_fit()`
  (both by `crates/sl-calib/examples/corners_json.rs`; `ours default` too when the library's
  default differs from both);
* `OpenCV subpix 11x11 / 7x7 / 5x5`: `findChessboardCorners` (default flags) then
  `cornerSubPix` with that window, zero zone off, 30 iterations or 0.001 px;
* `OpenCV SB accuracy`: `findChessboardCornersSB` with `CALIB_CB_ACCURACY` (and
  `CALIB_CB_EXHAUSTIVE` when that finds nothing).

Figures, per set and method, on the images every method found (so all rows see the same views):
* `RMS 5` / `RMS 8`: the RMS reprojection error `cv2.calibrateCamera` returns (sqrt of the mean
  squared 2-D residual) with the 5-coefficient model (k1 k2 p1 p2 k3) and with the rational
  8-coefficient model (`CALIB_RATIONAL_MODEL`), object points (i, j, 0) in squares;
* `held-out 5` / `held-out 8`: leave one image out: calibrate on the others, fit the pose of
  the left-out image with the intrinsics held (`solvePnP`, iterative, from the camera's own
  start), and pool the reprojection residuals of all left-out images into one RMS. A refiner
  whose errors the calibration absorbs into its parameters gains nothing here;
* the intrinsics of the 5-coefficient calibration with their standard deviations
  (`calibrateCameraExtended`), to see whether the methods agree on the camera;
* per method, on how many left-out images its held-out RMS is lower than the saddle points'
  and the junction fit's, and the pooled held-out RMS minus the saddle points' with a 90 %
  bootstrap interval over the images (2000 resamplings, seed 0): real boards have no seeds,
  the sample of views is the draw;
* the RMS distance of each method's corners to every other's (matched by nearest corner).

The images are neither copied nor kept (the fringe means live in a temporary folder).
"""

import argparse
import glob
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[2]
EXAMPLE = Path(os.environ.get("CARGO_TARGET_DIR", REPO / "target")) / "release/examples/corners_json"
CRITERIA = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 30, 0.001)


def board_sets(extra_sets, tmp):
    """[(name, cols, rows, [image paths], {path: float image or None})]."""
    sets = []
    data = os.environ.get("SL_DATA")
    if data and (Path(data) / "chessboard").is_dir():
        for side in ("left", "right"):
            files = sorted((Path(data) / "chessboard").glob(f"{side}*.jpg"))
            sets.append((f"OpenCV {side}", 9, 6, files, {}))
    else:
        print("SL_DATA not set (or no chessboard/): skipping OpenCV's samples", file=sys.stderr)
    extra = os.environ.get("SL_DATA_EXTRA")
    kam = Path(extra) / "procam_kamino" if extra else None
    if kam and kam.is_dir():
        caps = sorted(kam.glob("capture_*"))
        sets.append(("kamino white", 9, 7, [c / "graycode_40.png" for c in caps], {}))
        means, floats = [], {}
        for c in caps:
            stack = [cv2.imread(str(c / f"graycode_{k:02d}.png"), cv2.IMREAD_GRAYSCALE) for k in range(40)]
            mean = np.mean(np.stack(stack).astype(np.float64), axis=0)
            out = Path(tmp) / f"kamino_mean_{c.name}.png"
            cv2.imwrite(str(out), np.clip(np.rint(mean * 257.0), 0, 65535).astype(np.uint16))
            means.append(out)
            floats[out] = mean.astype(np.float32)
        sets.append(("kamino fringe mean", 9, 7, means, floats))
    else:
        print("SL_DATA_EXTRA not set (or no procam_kamino/): skipping kamino", file=sys.stderr)
    for spec in extra_sets:
        name, size, pattern = spec.split("=", 2)
        cols, rows = (int(v) for v in size.lower().split("x"))
        files = sorted(Path(p) for p in glob.glob(pattern))
        if not files:
            raise SystemExit(f"--set {spec}: no file matches {pattern}")
        sets.append((name, cols, rows, files, {}))
    return sets


def grey8(path):
    """The 8-bit grey image every detector sees (16-bit scaled by round(v / 257), as ours)."""
    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if img is None:
        raise SystemExit(f"cannot read {path}")
    if img.ndim == 3:
        img = cv2.cvtColor(img[:, :, :3], cv2.COLOR_BGR2GRAY)
    if img.dtype == np.uint16:
        img = np.clip(np.floor(img.astype(np.float64) / 257.0 + 0.5), 0, 255).astype(np.uint8)
    return img


def ours(files, cols, rows, refiner):
    if not EXAMPLE.exists():
        raise SystemExit(f"{EXAMPLE} missing: cargo build --release -p sl-calib --example corners_json")
    with tempfile.NamedTemporaryFile(suffix=".json", delete=False) as f:
        out = f.name
    subprocess.run(
        [str(EXAMPLE), "--board", f"{cols}x{rows}", "--refiner", refiner, "--out", out, *map(str, files)],
        check=True,
        stderr=subprocess.DEVNULL,
    )
    doc = json.loads(Path(out).read_text())
    os.unlink(out)
    res = {}
    for entry in doc["images"]:
        c = entry.get("corners")
        res[Path(entry["file"])] = np.asarray(c, np.float64) if c else None
    return res, doc["config"]


def opencv_subpix(files, cols, rows, half, floats=None):
    res = {}
    for f in files:
        img = grey8(f)
        ok, c = cv2.findChessboardCorners(img, (cols, rows))
        if not ok:
            res[f] = None
            continue
        src = floats[f] if floats else img
        res[f] = cv2.cornerSubPix(src, c, (half, half), (-1, -1), CRITERIA).reshape(-1, 2).astype(np.float64)
    return res


def opencv_sb(files, cols, rows):
    res = {}
    for f in files:
        img = grey8(f)
        ok, c = cv2.findChessboardCornersSB(img, (cols, rows), flags=cv2.CALIB_CB_ACCURACY)
        if not ok:
            ok, c = cv2.findChessboardCornersSB(
                img, (cols, rows), flags=cv2.CALIB_CB_ACCURACY | cv2.CALIB_CB_EXHAUSTIVE
            )
        res[f] = c.reshape(-1, 2).astype(np.float64) if ok else None
    return res


def object_points(cols, rows):
    return np.array([[i, j, 0] for j in range(rows) for i in range(cols)], np.float32)


def calibrate(corners, cols, rows, size, flags):
    obj = [object_points(cols, rows)] * len(corners)
    img = [c.astype(np.float32).reshape(-1, 1, 2) for c in corners]
    rms, K, D, rv, tv, sd_int, _, _ = cv2.calibrateCameraExtended(obj, img, size, None, None, flags=flags)
    return rms, K, D, sd_int.ravel()


def held_out(corners, cols, rows, size, flags):
    """(RMS over all images of the residuals of image i with the intrinsics of the others,
    the RMS of each image)."""
    obj = object_points(cols, rows)
    res = []
    for i in range(len(corners)):
        rest = corners[:i] + corners[i + 1 :]
        _, K, D, _ = calibrate(rest, cols, rows, size, flags)
        ok, rv, tv = cv2.solvePnP(obj, corners[i].astype(np.float64), K, D, flags=cv2.SOLVEPNP_ITERATIVE)
        if not ok:
            return float("nan"), []
        proj, _ = cv2.projectPoints(obj, rv, tv, K, D)
        res.append(proj.reshape(-1, 2) - corners[i])
    r = np.concatenate(res)
    per_image = [float(np.sqrt((e**2).sum(axis=1).mean())) for e in res]
    return float(np.sqrt((r**2).sum(axis=1).mean())), per_image


def match_rms(a, b):
    d = np.linalg.norm(a[:, None, :] - b[None, :, :], axis=2).min(axis=1)
    return float(np.sqrt((d**2).mean()))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--set", action="append", default=[], help="NAME=COLSxROWS=GLOB: another board set")
    ap.add_argument("--json", help="write every figure here")
    args = ap.parse_args()
    results = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name, cols, rows, files, floats in board_sets(args.set, tmp):
            size = grey8(files[0]).shape[::-1]
            methods = {}
            methods["ours saddle"], cfg_s = ours(files, cols, rows, "saddle")
            methods["ours junction"], cfg_j = ours(files, cols, rows, "junction")
            dflt, cfg_d = ours(files, cols, rows, "default")
            if cfg_d not in (cfg_s, cfg_j):
                methods["ours default"] = dflt
            for half in (11, 7, 5):
                methods[f"OpenCV subpix {half}x{half}"] = opencv_subpix(files, cols, rows, half)
            if floats:
                methods["OpenCV subpix 11x11 on the float mean"] = opencv_subpix(files, cols, rows, 11, floats)
            methods["OpenCV SB accuracy"] = opencv_sb(files, cols, rows)
            found = {m: [f for f in files if r.get(f) is not None] for m, r in methods.items()}
            common = [f for f in files if all(r.get(f) is not None for r in methods.values())]
            print(f"{name}: {len(files)} images, {len(common)} found by every method", file=sys.stderr)
            set_res = {"board": [cols, rows], "images": len(files), "common": len(common), "methods": {}}
            for m, r in methods.items():
                cs = [r[f] for f in common]
                entry = {"found": len(found[m])}
                if len(cs) >= 3:
                    rms5, K, D, sd = calibrate(cs, cols, rows, size, 0)
                    rms8, *_ = calibrate(cs, cols, rows, size, cv2.CALIB_RATIONAL_MODEL)
                    entry.update(
                        rms5=rms5,
                        rms8=rms8,
                        held5=held_out(cs, cols, rows, size, 0)[0],
                        held5_per_image=held_out(cs, cols, rows, size, 0)[1],
                        held8=held_out(cs, cols, rows, size, cv2.CALIB_RATIONAL_MODEL)[0],
                        fx=K[0, 0], fy=K[1, 1], cx=K[0, 2], cy=K[1, 2],
                        dist=D.ravel().tolist(),
                        sd_fx=float(sd[0]), sd_fy=float(sd[1]), sd_cx=float(sd[2]), sd_cy=float(sd[3]),
                        sd_k1=float(sd[4]),
                    )
                    # all images this method found, not only the common ones
                    if len(found[m]) != len(common):
                        entry["rms5_all_found"] = calibrate([r[f] for f in found[m]], cols, rows, size, 0)[0]
                set_res["methods"][m] = entry
            # Paired: on how many held-out images each method beats ours saddle / junction.
            for m, e in set_res["methods"].items():
                for ref in ("ours saddle", "ours junction"):
                    r0 = set_res["methods"].get(ref, {}).get("held5_per_image")
                    if r0 and e.get("held5_per_image"):
                        e[f"held5_wins_vs_{ref.split()[1]}"] = int(
                            sum(a < b for a, b in zip(e["held5_per_image"], r0)))
            # Bootstrap over the views: the pooled held-out RMS minus the saddle points', 90 %
            # interval of 2000 resamplings of the images (every image has the same corner count).
            rng = np.random.default_rng(0)
            base = set_res["methods"].get("ours saddle", {}).get("held5_per_image")
            for m, e in set_res["methods"].items():
                per = e.get("held5_per_image")
                if not base or not per:
                    continue
                a, b = np.asarray(per) ** 2, np.asarray(base) ** 2
                draws = rng.integers(0, len(a), size=(2000, len(a)))
                d = np.sqrt(a[draws].mean(axis=1)) - np.sqrt(b[draws].mean(axis=1))
                e["held5_minus_saddle"] = float(np.sqrt(a.mean()) - np.sqrt(b.mean()))
                e["held5_minus_saddle_90"] = [float(np.percentile(d, 5)), float(np.percentile(d, 95))]
            names = list(methods)
            set_res["distance"] = {
                a: {b: float(np.mean([match_rms(methods[a][f], methods[b][f]) for f in common]))
                    for b in names}
                for a in names
            } if common else {}
            results[name] = set_res
    print_tables(results)
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1, default=float))


def print_tables(results):
    print("\n## Calibration RMS and held-out RMS (px), same cv2.calibrateCamera, images found by every method\n")
    print("| set | method | found | RMS 5 | held-out 5 | RMS 8 | held-out 8 | "
          "held-out images better than saddle / junction | held-out 5 minus saddle [90 %] |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name, s in results.items():
        for m, e in s["methods"].items():
            if "rms5" not in e:
                print(f"| {name} | {m} | {e['found']}/{s['images']} | – | – | – | – | – | – |")
                continue
            wins = f"{e.get('held5_wins_vs_saddle', '–')} / {e.get('held5_wins_vs_junction', '–')} of {s['common']}"
            iv = e.get("held5_minus_saddle_90")
            diff = (f"{e['held5_minus_saddle']:+.4f} [{iv[0]:+.4f}, {iv[1]:+.4f}]"
                    if iv and m != "ours saddle" else "–")
            print(f"| {name} ({s['common']} views) | {m} | {e['found']}/{s['images']} | {e['rms5']:.4f} | "
                  f"{e['held5']:.4f} | {e['rms8']:.4f} | {e['held8']:.4f} | {wins} | {diff} |")
    print("\n## Intrinsics (5-coefficient model) +- their standard deviations\n")
    print("| set | method | fx | fy | cx | cy | k1 | k2 |")
    print("|---|---|---|---|---|---|---|---|")
    for name, s in results.items():
        for m, e in s["methods"].items():
            if "fx" not in e:
                continue
            print(f"| {name} | {m} | {e['fx']:.2f} ± {e['sd_fx']:.2f} | {e['fy']:.2f} ± {e['sd_fy']:.2f} | "
                  f"{e['cx']:.2f} ± {e['sd_cx']:.2f} | {e['cy']:.2f} ± {e['sd_cy']:.2f} | "
                  f"{e['dist'][0]:.4f} ± {e['sd_k1']:.4f} | {e['dist'][1]:.4f} |")
    print("\n## Mean RMS distance between the methods' corners (px)\n")
    for name, s in results.items():
        if not s["distance"]:
            continue
        names = list(s["distance"])
        short = [n.replace("OpenCV ", "cv ").replace("ours ", "") for n in names]
        print(f"\n{name}:\n")
        print("| | " + " | ".join(short) + " |")
        print("|---" * (len(names) + 1) + "|")
        for a, sa in zip(names, short):
            print(f"| {sa} | " + " | ".join(f"{s['distance'][a][b]:.3f}" for b in names) + " |")


if __name__ == "__main__":
    main()
