"""Writes the small image files of crates/sl-codec/tests/data/opencv_images/ with OpenCV's
own encoders (cv2.imwrite), so that sl-codec's reader is tested on files it did not write.

Pixel values are those of crates/sl-codec/tests/it/image_formats.rs (grey8_at, grey16_at,
rgb8_at, rgb16_at, jpeg blocks); keep both in step. Regenerate with

    /work/peers/bin/python benches/peers/opencv_image_files.py crates/sl-codec/tests/data/opencv_images

The expected grey of the colour files is recomputed by the test from the same formulas; this
script also writes `expected_grey.txt`, OpenCV's own cvtColor(COLOR_BGR2GRAY) of each colour
file as OpenCV decodes it, which the test compares with ours exactly.
"""
import os
import sys

import cv2
import numpy as np

W, H = 16, 8


def grey8_at(x, y):
    if (x, y) == (0, 0):
        return 0
    if (x, y) == (1, 0):
        return 255
    return (x * 13 + y * 29 + 7) % 256


def grey16_at(x, y):
    if (x, y) == (0, 0):
        return 0
    if (x, y) == (1, 0):
        return 65535
    return (x * 4111 + y * 977 + 301) % 65536


def rgb8_at(x, y):
    fixed = {(0, 0): (255, 0, 0), (1, 0): (0, 255, 0), (2, 0): (0, 0, 255), (3, 0): (255, 255, 255)}
    if (x, y) in fixed:
        return fixed[(x, y)]
    return ((x * 16) % 256, (y * 32 + 5) % 256, 255 - x * 9)


def rgb16_at(x, y):
    fixed = {(0, 0): (65535, 0, 0), (1, 0): (0, 65535, 0), (2, 0): (0, 0, 65535),
             (3, 0): (65535, 65535, 65535)}
    if (x, y) in fixed:
        return fixed[(x, y)]
    return (x * 4000, y * 8000 + 33, 65535 - x * 3001)


def jpeg_block(x, y):
    """Flat 8x8 blocks: one DCT block each, only its DC term."""
    return 40 + 100 * (x // 8) + 30 * (y // 8)


def main(out):
    os.makedirs(out, exist_ok=True)
    g8 = np.array([[grey8_at(x, y) for x in range(W)] for y in range(H)], np.uint8)
    g16 = np.array([[grey16_at(x, y) for x in range(W)] for y in range(H)], np.uint16)
    # OpenCV holds colour as BGR.
    c8 = np.array([[rgb8_at(x, y)[::-1] for x in range(W)] for y in range(H)], np.uint8)
    c16 = np.array([[rgb16_at(x, y)[::-1] for x in range(W)] for y in range(H)], np.uint16)
    jb = np.array([[jpeg_block(x, y) for x in range(W)] for y in range(H)], np.uint8)
    files = {
        "grey8.bmp": g8, "colour8.bmp": c8,
        "grey8.pgm": g8, "grey16.pgm": g16, "colour8.ppm": c8,
        "grey8.png": g8, "grey16.png": g16, "colour8.png": c8, "colour16.png": c16,
        "grey8.tif": g8, "grey16.tif": g16, "colour8.tif": c8, "colour16.tif": c16,
    }
    for name, img in files.items():
        assert cv2.imwrite(os.path.join(out, name), img), name
    assert cv2.imwrite(os.path.join(out, "blocks.jpg"), jb, [cv2.IMWRITE_JPEG_QUALITY, 100])
    lines = []
    for name in sorted(n for n in files if n.startswith("colour")):
        back = cv2.imread(os.path.join(out, name), cv2.IMREAD_UNCHANGED)
        grey = cv2.cvtColor(back, cv2.COLOR_BGR2GRAY)
        lines.append(name + " " + " ".join(str(int(v)) for v in grey.ravel()))
    with open(os.path.join(out, "expected_grey.txt"), "w") as f:
        f.write("# OpenCV %s cvtColor(COLOR_BGR2GRAY), row-major %dx%d, by %s\n"
                % (cv2.__version__, W, H, os.path.basename(__file__)))
        f.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "crates/sl-codec/tests/data/opencv_images")
