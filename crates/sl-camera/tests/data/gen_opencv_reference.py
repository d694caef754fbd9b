#!/usr/bin/env python3
"""Regenerate the OpenCV reference fixtures of the sl-camera tests.

This script is the documented switch to regenerate the golden files in this folder; it is
not a dependency of the crate or of CI (the tests only read the files it wrote). It needs
numpy, scipy and OpenCV's Python bindings (any 4.x/5.x), e.g. the peers venv on the dev machine:

    /tmp/peers/bin/python crates/sl-camera/tests/data/gen_opencv_reference.py

It writes, next to itself:

* ``opencv_project_points.json``: for several lenses (the strong reference design, a mild
  webcam, a 4-coefficient lens, a projector-like lens with an off-centre principal point, an
  8-coefficient rational wide-angle lens, and no distortion), a pose (rvec/tvec), 3-D object
  points, the pixels ``cv2.projectPoints`` gives for them and its Jacobian
  (columns: rvec(3), tvec(3), fx, fy, cx, cy, distortion coefficients).
  The points are drawn so that their pixels cover the whole image (a margin of 2 % outside
  included; the 4 corners, 4 edge midpoints and the centre are always there) and stay inside
  the region where the radial distortion is monotonic.
  ``cv2.projectPoints`` ignores the skew entry K[0,1], so every lens here has zero skew; the
  skew is tested against its closed form instead.
* ``opencv_calibration_sample.yml`` / ``.xml``: files in the shape OpenCV's calibration
  sample (``samples/cpp/calibration.cpp``) writes, written by ``cv2.FileStorage``.
* ``slstudio_calibration.yml`` / ``.xml``: files in the shape SLStudio's
  ``CalibrationData::saveXML`` writes (``Kc kc Kp kp Rp Tp`` in single precision, errors,
  frame and screen sizes), written by ``cv2.FileStorage``.
"""
import json
import os

import cv2
import numpy as np
from scipy.optimize import least_squares

HERE = os.path.dirname(os.path.abspath(__file__))
RNG = np.random.default_rng(20240611)

# name, width, height, fx, fy, cx, cy, distortion coefficients in OpenCV order
LENSES = [
    ("reference_strong", 1280, 720, 1440.4, 1437.1, 667.8, 354.2,
     [0.5466, -20.20, -0.02203, 0.008259, 211.1]),
    ("webcam_mild", 1280, 720, 905.3, 903.9, 641.2, 362.7,
     [-0.283, 0.0912, 0.00081, -0.00043, -0.0121]),
    ("four_coefficients", 640, 480, 532.8, 531.6, 318.4, 241.9,
     [-0.121, 0.0315, -0.0012, 0.0007]),
    ("projector_offset", 1920, 1080, 2210.0, 2208.5, 955.0, 1102.0,
     [0.041, -0.162, 0.0006, -0.0011, 0.21]),
    ("rational_wide", 1280, 960, 602.1, 601.4, 644.6, 478.3,
     [2.31, 0.87, 0.00061, -0.00032, 0.029, 2.68, 1.47, 0.19]),
    ("no_distortion", 800, 600, 700.0, 690.0, 399.5, 299.5, []),
]

POINTS_PER_LENS = 80
MARGIN = 0.02  # fraction of the image size allowed outside the image


def radial_is_monotonic_up_to(dist, r):
    """True if r * f(r^2) is strictly increasing on [0, r] (dense numeric check)."""
    k = list(dist) + [0.0] * (8 - len(dist))
    k1, k2, _, _, k3, k4, k5, k6 = k
    rr = np.linspace(0.0, r, 4000)
    s = rr * rr
    f = (1 + k1 * s + k2 * s**2 + k3 * s**3) / (1 + k4 * s + k5 * s**2 + k6 * s**3)
    den = 1 + k4 * s + k5 * s**2 + k6 * s**3
    return bool(np.all(np.diff(rr * f) > 0) and np.all(den > 0))


def lens_case(name, w, h, fx, fy, cx, cy, dist, pose_kind):
    K = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
    d = np.array(dist, dtype=np.float64)
    # Candidate undistorted normalised points: a multiple of the pinhole extent of the image
    # (wide lenses compress the periphery, so they need a larger box to reach the corners).
    spread = 3.0 if len(dist) == 8 else 1.6
    xs = spread * (np.array([-0.5, w - 0.5]) - cx) / fx
    ys = spread * (np.array([-0.5, h - 0.5]) - cy) / fy
    pts = []
    while len(pts) < POINTS_PER_LENS:
        x = RNG.uniform(xs[0], xs[1])
        y = RNG.uniform(ys[0], ys[1])
        if len(d) and not radial_is_monotonic_up_to(d, 1.05 * np.hypot(x, y)):
            continue
        z = RNG.uniform(300.0, 2000.0)
        p = np.array([[x * z, y * z, z]])
        px, _ = cv2.projectPoints(p, np.zeros(3), np.zeros(3), K, d if len(d) else None)
        u, v = px.reshape(2)
        if -MARGIN * w <= u <= (1 + MARGIN) * w and -MARGIN * h <= v <= (1 + MARGIN) * h:
            pts.append(p[0])
    # Plus the exact corners, edge midpoints and centre of the image (pixel-centre convention:
    # the image spans -0.5 .. w-0.5), found by least squares on cv2.projectPoints itself.
    for tu in (-0.5, (w - 1) / 2, w - 0.5):
        for tv in (-0.5, (h - 1) / 2, h - 0.5):
            def residual(xy):
                px, _ = cv2.projectPoints(np.array([[xy[0], xy[1], 1.0]]), np.zeros(3),
                                          np.zeros(3), K, d if len(d) else None)
                return px.reshape(2) - [tu, tv]
            sol = least_squares(residual, [(tu - cx) / fx, (tv - cy) / fy], xtol=1e-15,
                                ftol=1e-15, gtol=1e-15)
            assert np.max(np.abs(sol.fun)) < 1e-6, (name, tu, tv, sol.fun)
            assert not len(d) or radial_is_monotonic_up_to(d, 1.05 * np.hypot(*sol.x))
            z = RNG.uniform(300.0, 2000.0)
            pts.append(np.array([sol.x[0] * z, sol.x[1] * z, z]))
    p_cam = np.array(pts)
    if pose_kind == "identity":
        rvec = np.zeros(3)
        tvec = np.zeros(3)
    elif pose_kind == "near_pi":
        axis = RNG.normal(size=3)
        axis /= np.linalg.norm(axis)
        rvec = axis * (np.pi - 1e-3)
        tvec = RNG.uniform(-200, 200, size=3)
    else:
        rvec = RNG.uniform(-1.2, 1.2, size=3)
        tvec = RNG.uniform(-200, 200, size=3)
    R, _ = cv2.Rodrigues(rvec)
    # p_cam = R p_world + t  =>  p_world = R^T (p_cam - t)
    p_world = (R.T @ (p_cam - tvec).T).T
    img, jac = cv2.projectPoints(p_world, rvec, tvec, K, d if len(d) else None)
    img = img.reshape(-1, 2)
    return {
        "name": name,
        "width": w,
        "height": h,
        "camera_matrix": K.reshape(-1).tolist(),
        "distortion": d.tolist(),
        "rvec": rvec.tolist(),
        "tvec": tvec.tolist(),
        "object_points": p_world.tolist(),
        "image_points": img.tolist(),
        "jacobian": jac.tolist(),
    }


def write_reference_vectors():
    kinds = ["random", "identity", "random", "near_pi", "random", "random"]
    cases = [lens_case(*lens, kind) for lens, kind in zip(LENSES, kinds)]
    out = {
        "generator": "tests/data/gen_opencv_reference.py",
        "opencv_version": cv2.__version__,
        "note": "cv2.projectPoints of object_points with rvec/tvec; jacobian columns: "
                "rvec(3), tvec(3), fx, fy, cx, cy, distortion coefficients in OpenCV order. "
                "Skew is zero: cv2.projectPoints ignores K[0,1].",
        "cases": cases,
    }
    # One case per block and one point per line: compact, yet diffs stay readable.
    # Python's json writes the shortest repr that round-trips every float exactly.
    lines = ["{"]
    for key in ("generator", "opencv_version", "note"):
        lines.append(f" {json.dumps(key)}: {json.dumps(out[key])},")
    lines.append(' "cases": [')
    for i, case in enumerate(cases):
        lines.append("  {")
        items = list(case.items())
        for j, (key, value) in enumerate(items):
            end = "," if j + 1 < len(items) else ""
            if key in ("object_points", "image_points", "jacobian"):
                rows = ",\n    ".join(json.dumps(row) for row in value)
                lines.append(f"   {json.dumps(key)}: [\n    {rows}\n   ]{end}")
            else:
                lines.append(f"   {json.dumps(key)}: {json.dumps(value)}{end}")
        lines.append("  }" + ("," if i + 1 < len(cases) else ""))
    lines.append(" ]")
    lines.append("}")
    with open(os.path.join(HERE, "opencv_project_points.json"), "w") as f:
        f.write("\n".join(lines) + "\n")


def write_calibration_sample(ext):
    """Keys and layout of OpenCV's samples/cpp/calibration.cpp saveCameraParams."""
    fs = cv2.FileStorage(os.path.join(HERE, "opencv_calibration_sample." + ext),
                         cv2.FILE_STORAGE_WRITE)
    K = np.array([[905.3, 0.0, 641.2], [0.0, 903.9, 362.7], [0.0, 0.0, 1.0]])
    d = np.array([[-0.283], [0.0912], [0.00081], [-0.00043], [-0.0121]])
    fs.write("calibration_time", "Tue Jun 11 10:21:07 2024")
    fs.write("nr_of_frames", 14)
    fs.write("image_width", 1280)
    fs.write("image_height", 720)
    fs.write("board_width", 9)
    fs.write("board_height", 6)
    fs.write("square_size", 25.0)
    fs.write("flags", 0)
    fs.write("fisheye_model", 0)
    fs.write("camera_matrix", K)
    fs.write("distortion_coefficients", d)
    fs.write("avg_reprojection_error", 0.3187)
    fs.writeComment("a comment as the sample would not write, to test the reader")
    fs.write("per_view_reprojection_errors", RNG.uniform(0.2, 0.4, size=(14, 1)).astype(np.float32))
    fs.write("extrinsic_parameters", RNG.uniform(-1, 1, size=(14, 6)))
    fs.write("image_points", RNG.uniform(0, 600, size=(14, 54, 2)).astype(np.float32)[:2])
    fs.release()


def write_slstudio(ext):
    """Keys and types of SLStudio's CalibrationData::saveXML (Matx33f, Vec<float,5>, ...)."""
    fs = cv2.FileStorage(os.path.join(HERE, "slstudio_calibration." + ext),
                         cv2.FILE_STORAGE_WRITE)
    Kc = np.array([[1440.4, 0.0, 667.8], [0.0, 1437.1, 354.2], [0.0, 0.0, 1.0]], np.float32)
    kc = np.array([[0.5466], [-20.20], [-0.02203], [0.008259], [211.1]], np.float32)
    Kp = np.array([[2210.0, 0.0, 955.0], [0.0, 2208.5, 1102.0], [0.0, 0.0, 1.0]], np.float32)
    kp = np.array([[0.041], [-0.162], [0.0006], [-0.0011], [0.21]], np.float32)
    rvec = np.array([0.02, -0.31, 0.015])
    Rp, _ = cv2.Rodrigues(rvec)
    Tp = np.array([[152.3], [-12.7], [38.9]])
    fs.write("Kc", Kc)
    fs.write("kc", kc)
    fs.write("Kp", Kp)
    fs.write("kp", kp)
    fs.write("Rp", Rp.astype(np.float32))
    fs.write("Tp", Tp.astype(np.float32))
    fs.write("cam_error", 0.1873)
    fs.write("proj_error", 0.2411)
    fs.write("stereo_error", 0.2702)
    fs.write("frameWidth", 1280)
    fs.write("frameHeight", 720)
    fs.write("screenResX", 1920)
    fs.write("screenResY", 1080)
    fs.release()


if __name__ == "__main__":
    write_reference_vectors()
    for ext in ("yml", "xml"):
        write_calibration_sample(ext)
        write_slstudio(ext)
    print("wrote fixtures to", HERE)
