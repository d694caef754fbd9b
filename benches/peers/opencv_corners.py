"""OpenCV's chessboard corners on the corner harness's rendered images, against their truth.

Run by `cargo run --release -p sl-calib --example corner_harness -- --python PEERS_PYTHON`
(or by hand: `PEERS_PYTHON benches/peers/opencv_corners.py DIR/manifest.json`). For each image
of the manifest: `cv2.findChessboardCorners` (default flags: adaptive threshold, normalised
image) then `cv2.cornerSubPix` with the usual 11x11 half-window (23x23 px), zero zone off,
30 iterations or 0.001 px — the call of OpenCV's calibration tutorial and of the capture
programs measured in issue 15. Each corner is matched to its nearest true corner. Writes
`opencv.json` beside the manifest and prints a table.

`PEERS_PYTHON benches/peers/opencv_corners.py --chessboard $SL_DATA/chessboard`: OpenCV's
camera RMS on the real sample images (left and right, 9x6), with cornerSubPix 11x11 and 7x7,
for comparison with ours (`SL_DATA=... cargo test -p sl-calib --test it real_chessboard --
--nocapture`).
"""

import json
import math
import sys
import time
from pathlib import Path

import cv2
import numpy as np


def chessboard(folder: Path) -> None:
    """Camera RMS of cv2.calibrateCamera on OpenCV's corners of the 13 sample images a side."""
    names = ["01", "02", "03", "04", "05", "06", "07", "08", "09", "11", "12", "13", "14"]
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 30, 0.001)
    obj = np.array([[i, j, 0] for j in range(6) for i in range(9)], np.float32)
    for side in ["left", "right"]:
        for half in [11, 7]:
            imgp = []
            for n in names:
                img = cv2.imread(str(folder / f"{side}{n}.jpg"), cv2.IMREAD_GRAYSCALE)
                ok, c = cv2.findChessboardCorners(img, (9, 6))
                if not ok:
                    print(f"opencv: no board in {side}{n}.jpg", file=sys.stderr)
                    continue
                imgp.append(cv2.cornerSubPix(img, c, (half, half), (-1, -1), criteria))
            rms, *_ = cv2.calibrateCamera([obj] * len(imgp), imgp, (640, 480), None, None)
            print(f"{side}: cornerSubPix {half}x{half}: {len(imgp)} images, camera RMS {rms:.4f} px")


def main() -> None:
    if sys.argv[1] == "--chessboard":
        chessboard(Path(sys.argv[2]))
        return
    manifest_path = Path(sys.argv[1])
    manifest = json.loads(manifest_path.read_text())
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 30, 0.001)
    per_condition: dict[str, dict] = {}
    for item in manifest["images"]:
        cond = per_condition.setdefault(
            item["condition"], {"errors": [], "found": 0, "tried": 0, "seconds": 0.0}
        )
        img = cv2.imread(str(manifest_path.parent / item["file"]), cv2.IMREAD_GRAYSCALE)
        truth = np.asarray(item["truth"], dtype=np.float64)
        start = time.perf_counter()
        ok, corners = cv2.findChessboardCorners(img, (item["cols"], item["rows"]))
        if ok:
            corners = cv2.cornerSubPix(img, corners, (11, 11), (-1, -1), criteria)
        cond["seconds"] += time.perf_counter() - start
        cond["tried"] += 1
        if not ok:
            print(f"opencv: no board in {item['file']}", file=sys.stderr)
            continue
        cond["found"] += 1
        found = corners.reshape(-1, 2).astype(np.float64)
        d = np.linalg.norm(found[:, None, :] - truth[None, :, :], axis=2).min(axis=1)
        cond["errors"].extend(d.tolist())
    out = {"conditions": {}}
    print("| condition | OpenCV RMS (px) | max | found | ms/image |")
    print("|---|---|---|---|---|")
    for name, c in per_condition.items():
        e = np.asarray(c["errors"])
        rms = float(math.sqrt((e**2).mean())) if e.size else None
        mx = float(e.max()) if e.size else None
        out["conditions"][name] = {
            "mean": float(e.mean()) if e.size else None,
            # Nearest rank, as the harness's p95.
            "p95": float(np.percentile(e, 95, method="inverted_cdf")) if e.size else None,
            "rms": rms,
            "max": mx,
            "found": c["found"],
            "tried": c["tried"],
            "ms_per_image": 1e3 * c["seconds"] / max(c["tried"], 1),
        }
        print(
            f"| {name} | {rms if rms is not None else float('nan'):.4f} | "
            f"{mx if mx is not None else float('nan'):.3f} | {c['found']}/{c['tried']} | "
            f"{1e3 * c['seconds'] / max(c['tried'], 1):.1f} |"
        )
    (manifest_path.parent / "opencv.json").write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
