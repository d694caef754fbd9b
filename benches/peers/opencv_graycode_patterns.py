"""OpenCV's `structured_light.GrayCodePattern` for a small 40x24 projector, and OpenCV's own
decoding of it, for `crates/sl-codec/tests/it/opencv_graycode.rs`.

    /work/peers/bin/python benches/peers/opencv_graycode_patterns.py crates/sl-codec/tests/data/opencv_graycode

Writes `pattern_00.png` .. `pattern_21.png` (6 column bits then 5 row bits, each as pattern and
inverse, as `GrayCodePattern.generate` orders them) and `pattern_22.png` / `pattern_23.png`
(white, black: kamino410/procam-calibration appends them so), the `manifest.json` that
describes them in sl-codec's schema (`"centered": false`: OpenCV codes pixel x as gray(x), with
no centring of the 2^bits codes on the projector), and `opencv_decoded.json`: for every pixel,
`GrayCodePattern.getProjPixel` on the patterns themselves as the "captured" images (each pixel
sees its own projector pixel), i.e. OpenCV's reading of its own code. 40 and 24 are not powers
of two, so a centred code would be off by 12 columns and 4 rows.
"""

import json
import sys
from pathlib import Path

import cv2
import numpy as np

W, H = 40, 24


def main():
    out = Path(sys.argv[1])
    out.mkdir(parents=True, exist_ok=True)
    gc = cv2.structured_light_GrayCodePattern.create(W, H)
    ok, patterns = gc.generate()
    assert ok
    patterns = list(patterns) + [np.full((H, W), 255, np.uint8), np.zeros((H, W), np.uint8)]
    names = []
    for i, p in enumerate(patterns):
        name = f"pattern_{i:02d}.png"
        cv2.imwrite(str(out / name), p)
        names.append(name)
    cols = int(np.ceil(np.log2(W)))
    rows = int(np.ceil(np.log2(H)))
    assert gc.getNumberOfPatternImages() == 2 * (cols + rows)
    manifest = {
        "description": "OpenCV 5.0 structured_light GrayCodePattern 40x24 (benches/peers/opencv_graycode_patterns.py); pattern_22 white, pattern_23 black",
        "projector": {"width": W, "height": H},
        "blocks": [
            {"codec": "gray", "axis": "column", "bits": cols, "centered": False,
             "frames": names[: 2 * cols]},
            {"codec": "gray", "axis": "row", "bits": rows, "centered": False,
             "frames": names[2 * cols: 2 * (cols + rows)]},
        ],
    }
    (out / "manifest.json").write_text(json.dumps(manifest, indent=1) + "\n")
    captured = patterns[: 2 * (cols + rows)]
    decoded = []
    for y in range(H):
        row = []
        for x in range(W):
            err, pix = gc.getProjPixel(captured, x, y)
            row.append(None if err else [int(pix[0]), int(pix[1])])
        decoded.append(row)
    (out / "opencv_decoded.json").write_text(json.dumps(
        {"description": "GrayCodePattern.getProjPixel(patterns, x, y) -> [column, row] per pixel, rows of the image in order; null where OpenCV reports an error",
         "width": W, "height": H, "projector_pixel": decoded}) + "\n")
    print(f"{len(names)} images, manifest.json and opencv_decoded.json in {out}")


if __name__ == "__main__":
    main()
