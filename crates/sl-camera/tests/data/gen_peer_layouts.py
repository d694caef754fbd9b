#!/usr/bin/env python3
"""Regenerate the calibration files of other systems in tests/data/layouts/, written as those
systems write them: by cv2.FileStorage, with the keys, matrix shapes and element types their
save functions use (read from their public source; see docs/formats.md for file and line).

This is the documented switch to regenerate these golden files; it is not a dependency of the
crate or of CI. It needs OpenCV's Python bindings, e.g. the peers venv on the dev machine:

    /work/peers/bin/python crates/sl-camera/tests/data/gen_peer_layouts.py

One rig is written in every layout: a 1280x1024 camera and a 1024x768 projector whose centre
sits at CENTRE_MM in camera coordinates. `truth.json` holds the rig and, for a few points in
camera coordinates, the projector pixels cv2.projectPoints gives with the file's R, T (the way
the peers use them), so the tests check our reading of each convention against OpenCV's.

Files:
* scan3d_capture/calibration.yml: CalibrationData::save_calibration_yml (cam_K cam_kc proj_K
  proj_kc R T cam_error proj_error stereo_error; distortion 1x5 as cv::calibrateCamera returns).
* slmaster/caliInfo.yml: CaliPacker::writeCaliInfo after a projector calibration (M1 D1 S, then
  M4 D4 Rlp Tlp K1; S is a 2x1 double [width; height]).
* opencv_stereo/intrinsics.yml + extrinsics.yml: stereo_calib.cpp (M1 D1 M2 D2 with the
  rational model's 1x8 distortion; R T R1 R2 P1 P2 Q from cv2.stereoRectify).
"""
import json
import os

import cv2
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.path.join(HERE, "layouts")

CAM_SIZE = (1280, 1024)
PROJ_SIZE = (1024, 768)
K_CAM = np.array([[1402.5, 0.0, 651.25], [0.0, 1398.75, 509.5], [0.0, 0.0, 1.0]])
K_PROJ = np.array([[2021.0, 0.0, 511.5], [0.0, 2019.5, 797.25], [0.0, 0.0, 1.0]])
D_CAM5 = np.array([[-0.081, 0.125, 0.0007, -0.0004, -0.032]])
D_PROJ5 = np.array([[0.012, -0.045, 0.0002, 0.0011, 0.06]])
D_CAM8 = np.array([[-0.081, 0.125, 0.0007, -0.0004, -0.032, 0.004, -0.002, 0.001]])
D_PROJ8 = np.array([[0.012, -0.045, 0.0002, 0.0011, 0.06, -0.003, 0.001, 0.0005]])
# The projector's pose: p_proj = R p_cam + T, with the projector centre at CENTRE_MM.
RVEC = np.array([[0.02], [-0.35], [0.01]])
CENTRE_MM = np.array([[182.4], [-12.6], [31.2]])
R, _ = cv2.Rodrigues(RVEC)
T = -R @ CENTRE_MM
POINTS_CAM = np.array([[20.0, -30.0, 600.0], [-80.0, 45.0, 550.0], [60.0, 70.0, 700.0]])
ERRORS = {"cam_error": 0.183, "proj_error": 0.241, "stereo_error": 0.297}


def write(path, items):
    os.makedirs(os.path.dirname(path), exist_ok=True)
    fs = cv2.FileStorage(path, cv2.FILE_STORAGE_WRITE)
    for key, value in items:
        fs.write(key, value)
    fs.release()
    # The peers were built on OpenCV 2-4, whose FileStorage writes the `%YAML:1.0` header;
    # OpenCV 5 writes `%YAML 1.2`. The rest of the text is the same.
    with open(path) as f:
        text = f.read()
    if text.startswith("%YAML 1.2"):
        text = "%YAML:1.0" + text[len("%YAML 1.2"):]
    with open(path, "w") as f:
        f.write(text)


def main():
    write(os.path.join(OUT, "scan3d_capture", "calibration.yml"), [
        ("cam_K", K_CAM), ("cam_kc", D_CAM5), ("proj_K", K_PROJ), ("proj_kc", D_PROJ5),
        ("R", R), ("T", T),
        ("cam_error", ERRORS["cam_error"]), ("proj_error", ERRORS["proj_error"]),
        ("stereo_error", ERRORS["stereo_error"]),
    ])
    rlp, tlp = R.copy(), T.copy()
    write(os.path.join(OUT, "slmaster", "caliInfo.yml"), [
        ("M1", K_CAM), ("D1", D_CAM5),
        ("S", np.array([[float(CAM_SIZE[0])], [float(CAM_SIZE[1])]])),
        ("M4", K_PROJ), ("D4", D_PROJ5), ("Rlp", rlp), ("Tlp", tlp),
        ("K1", np.linspace(0.1, 0.8, 8).reshape(8, 1)),
    ])
    write(os.path.join(OUT, "opencv_stereo", "intrinsics.yml"), [
        ("M1", K_CAM), ("D1", D_CAM8), ("M2", K_PROJ), ("D2", D_PROJ8),
    ])
    r1, r2, p1, p2, q, _, _ = cv2.stereoRectify(
        K_CAM, D_CAM8, K_PROJ, D_PROJ8, CAM_SIZE, R, T, flags=cv2.CALIB_ZERO_DISPARITY, alpha=1)
    write(os.path.join(OUT, "opencv_stereo", "extrinsics.yml"), [
        ("R", R), ("T", T), ("R1", r1), ("R2", r2), ("P1", p1), ("P2", p2), ("Q", q),
    ])
    truth = {
        "generator": "gen_peer_layouts.py with OpenCV " + cv2.__version__,
        "camera_size": CAM_SIZE, "projector_size": PROJ_SIZE,
        "camera_K": K_CAM.tolist(), "projector_K": K_PROJ.tolist(),
        "camera_d5": D_CAM5.ravel().tolist(), "projector_d5": D_PROJ5.ravel().tolist(),
        "camera_d8": D_CAM8.ravel().tolist(), "projector_d8": D_PROJ8.ravel().tolist(),
        "projector_centre_mm": CENTRE_MM.ravel().tolist(),
        "errors": ERRORS,
        "points_cam_mm": POINTS_CAM.tolist(),
        # cv2.projectPoints with the file's R, T: what the peers compute.
        "projector_px_d5": cv2.projectPoints(POINTS_CAM, RVEC, T, K_PROJ, D_PROJ5)[0]
        .reshape(-1, 2).tolist(),
        "projector_px_d8": cv2.projectPoints(POINTS_CAM, RVEC, T, K_PROJ, D_PROJ8)[0]
        .reshape(-1, 2).tolist(),
    }
    with open(os.path.join(OUT, "truth.json"), "w") as f:
        json.dump(truth, f, indent=1)
        f.write("\n")


if __name__ == "__main__":
    main()
