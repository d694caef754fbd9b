"""Reference for tests/it/real_chessboard.rs: cv2.calibrateCamera (OpenCV 5, default flags) on
the corners our detector found in $SL_DATA/chessboard/left*.jpg (tests/data/left_corners.json,
written by the test with SL_CALIB_REGENERATE=1). Writes tests/data/opencv_left.json.
Run with any Python that has OpenCV and numpy; not a dependency of the project."""
import json, pathlib, time
import cv2
import numpy as np

here = pathlib.Path(__file__).parent
corners = json.loads((here / "left_corners.json").read_text())
obj = np.array([[i, j, 0] for j in range(6) for i in range(9)], np.float32)
objp = [obj] * len(corners)
# OpenCV takes float32 image points: they differ from ours by < 1e-5 px, far below the
# 1e-4 px tolerance of the test.
imgp = [np.array(c, np.float32).reshape(-1, 1, 2) for c in corners]
t = time.perf_counter()
rms, K, dist, rvecs, tvecs = cv2.calibrateCamera(objp, imgp, (640, 480), None, None)
ms = (time.perf_counter() - t) * 1e3
out = dict(rms=rms, fx=K[0, 0], fy=K[1, 1], cx=K[0, 2], cy=K[1, 2],
           dist=dist.ravel().tolist(), opencv=cv2.__version__, ms=ms)
(here / "opencv_left.json").write_text(json.dumps(out, indent=1) + "\n")
print(out)
