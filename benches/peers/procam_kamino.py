"""The kamino410/procam-calibration sample set calibrated by its own `calibrate.py` (OpenCV 5.0)
and by `slscan calibrate all --layout`, side by side: RMS, intrinsics, distortion, R, T.

    cargo build --release --example slscan
    SL_DATA_EXTRA=/work/sl-data-extra /work/peers/bin/python benches/peers/procam_kamino.py \
        [--slscan target/release/examples/slscan] [--mirror /work/.mirror/kamino410+procam-calibration/repo]

The peer's script is not copied into this repository: it is taken from the git mirror of its
repository (`git show HEAD:calibrate.py`) into a temporary folder, with links to the five
`capture_*` folders beside it (it globs `./capture_*`), and run as its README says for the
sample data: `calibrate.py 768 1024 9 7 75 1 -black_thr 40 -white_thr 5` (projector 1024x768,
board 9x7 inner corners, 75-unit squares). Two adaptations, neither changing its arithmetic:
OpenCV 5's `findChessboardCorners` returns the corners as N x 2 where the script indexes
`corner[0][0]` (N x 1 x 2 in OpenCV 4), so the corners are reshaped to N x 1 x 2; and its
`calibrateCamera` / `stereoCalibrate` calls are wrapped to record their results.

Beware when reading the peer's figures: its stereo step calls `cv2.stereoCalibrate` with the
default flags, `CALIB_FIX_INTRINSIC`: both devices' intrinsics and distortion stay those of the
separate calibrations and only R, T are fitted. `slscan` refines everything jointly (as
`stereoCalibrate` with free intrinsics), so the script also re-runs the peer's own
`stereoCalibrate` inputs with `CALIB_USE_INTRINSIC_GUESS` (free intrinsics, started from its
separate calibrations): that is the like-for-like stereo figure. The script also passes the
projector and camera sizes as (height, width) to `calibrateCamera` (only the start of the
principal point depends on it).

The two calibrations are compared parameter by parameter, and the whole lens models (intrinsics
and distortion together) by the displacement between them over the image: each pixel of a
40-px grid is un-projected through the peer's model and projected through ours; the largest and
RMS distance is printed. The poses are five, so parameters such as k3 are barely determined (see
the standard deviations slscan reports): the models agree when their displacement is small even
where single coefficients differ.
"""

import argparse
import contextlib
import io
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import cv2
import numpy as np

PEER_ARGS = ["768", "1024", "9", "7", "75", "1", "-black_thr", "40", "-white_thr", "5"]
REPO = Path(__file__).resolve().parents[2]
LAYOUT = REPO / "tests" / "data" / "procam_kamino" / "layout.json"


def run_peer(mirror: Path, data: Path):
    """Runs calibrate.py in a temporary folder; returns the recorded OpenCV results."""
    work = Path(tempfile.mkdtemp(prefix="kamino-peer-"))
    script = subprocess.run(
        ["git", "--git-dir", str(mirror), "show", "HEAD:calibrate.py"],
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    (work / "calibrate.py").write_text(script)
    for d in sorted(data.glob("capture_*")):
        os.symlink(d, work / d.name)

    find = cv2.findChessboardCorners
    calibrate_camera = cv2.calibrateCamera
    stereo = cv2.stereoCalibrate
    rec = {"calibrate": [], "stereo": []}

    def find_corners(img, shape, *a, **k):
        ok, corners = find(img, shape, *a, **k)
        if ok and corners is not None:
            corners = corners.reshape(-1, 1, 2)
        return ok, corners

    def calib(*a, **k):
        r = calibrate_camera(*a, **k)
        rec["calibrate"].append({"size": a[2], "rms": r[0], "K": r[1], "dist": r[2].ravel()})
        return r

    def stereo_calib(*a, **k):
        r = stereo(*a, **k)
        rec["stereo"].append({"args": a, "rms": r[0], "R": r[5], "T": r[6].ravel()})
        return r

    cv2.findChessboardCorners = find_corners
    cv2.calibrateCamera = calib
    cv2.stereoCalibrate = stereo_calib
    cwd = os.getcwd()
    sys.path.insert(0, str(work))
    try:
        os.chdir(work)
        import calibrate as peer  # noqa: E402  (the peer's script, from the mirror)

        sys.argv = ["calibrate.py", *PEER_ARGS]
        with contextlib.redirect_stdout(io.StringIO()):
            peer.main()
    finally:
        os.chdir(cwd)
        sys.path.remove(str(work))
        cv2.findChessboardCorners = find
        cv2.calibrateCamera = calibrate_camera
        cv2.stereoCalibrate = stereo
    cam, proj = rec["calibrate"]
    st = rec["stereo"][0]
    # The same stereo inputs with the intrinsics free (started from the separate calibrations).
    objp, cam_pts, proj_pts, K1, d1, K2, d2, size = st["args"][:8]
    free = stereo(
        objp, cam_pts, proj_pts, K1.copy(), d1.copy(), K2.copy(), d2.copy(), size,
        flags=cv2.CALIB_USE_INTRINSIC_GUESS,
    )
    return {
        "camera": cam,
        "projector": proj,
        "stereo_fixed": {"rms": st["rms"], "R": st["R"], "T": st["T"]},
        "stereo_free": {
            "rms": free[0], "K_cam": free[1], "d_cam": free[2].ravel(),
            "K_proj": free[3], "d_proj": free[4].ravel(), "R": free[5], "T": free[6].ravel(),
        },
    }


def run_slscan(slscan: Path, data: Path, extra: list[str]):
    out = Path(tempfile.mkdtemp(prefix="kamino-slscan-"))
    cmd = [str(slscan), "calibrate", "all", str(data), "--layout", str(LAYOUT),
           "--board", "9x7", "--square", "75", "--out", str(out), *extra]
    subprocess.run(cmd, check=True, capture_output=True, text=True)
    calib = json.loads((out / "calibration.json").read_text())
    report = json.loads((out / "report.json").read_text())["figures"]
    return calib, report


def K_dist(dev):
    i, d = dev["intrinsics"], dev["distortion"]
    K = np.array([[i["fx"], 0, i["cx"]], [0, i["fy"], i["cy"]], [0, 0, 1]])
    return K, np.array([d["k1"], d["k2"], d["p1"], d["p2"], d["k3"]])


def rays(px, K, d):
    """Unit rays of the pixels `px` (N x 1 x 2) through the model (K, d), checked to converge."""
    n = cv2.undistortPoints(px, K, d,
                            criteria=(cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12))
    pts = np.concatenate([n.reshape(-1, 2), np.ones((len(px), 1))], 1)
    again, _ = cv2.projectPoints(pts, np.zeros(3), np.zeros(3), K, d)
    assert np.abs(again.reshape(-1, 2) - px.reshape(-1, 2)).max() < 1e-3, "undistortPoints did not converge"
    return pts / np.linalg.norm(pts, axis=1, keepdims=True)


def model_gap(K_a, d_a, K_b, d_b, w, h, step=40):
    """How far model b puts the rays model a puts on a 40-px grid of the image: (largest, RMS)
    distance in px as they are, then (largest, RMS, angle) after the rotation of the device's
    frame that best maps a's rays onto b's (a shift of the principal point is partly such a
    rotation, which the board poses absorb)."""
    xs, ys = np.meshgrid(np.arange(0, w, step, dtype=np.float64), np.arange(0, h, step, dtype=np.float64))
    px = np.stack([xs.ravel(), ys.ravel()], 1).reshape(-1, 1, 2)
    ra, rb = rays(px, K_a, d_a), rays(px, K_b, d_b)

    def gap(r):
        back, _ = cv2.projectPoints(r, np.zeros(3), np.zeros(3), K_b, d_b)
        g = np.linalg.norm(back.reshape(-1, 2) - px.reshape(-1, 2), axis=1)
        return g.max(), np.sqrt((g ** 2).mean())

    # Kabsch: the rotation R minimising sum |R ra - rb|^2.
    U, _, Vt = np.linalg.svd(rb.T @ ra)
    R = U @ np.diag([1, 1, np.linalg.det(U @ Vt)]) @ Vt
    return gap(ra), (*gap(ra @ R.T), rot_deg(R))


def rot_deg(R):
    return np.degrees(np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1)))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--slscan", default=str(REPO / "target" / "release" / "examples" / "slscan"))
    ap.add_argument("--mirror", default="/work/.mirror/kamino410+procam-calibration/repo")
    ap.add_argument("--slscan-arg", action="append", default=[],
                    help="extra argument for slscan calibrate all (repeat; write --slscan-arg=--corners --slscan-arg=junction)")
    args = ap.parse_args()
    extra = os.environ.get("SL_DATA_EXTRA")
    if not extra:
        print("SL_DATA_EXTRA not set: skipping the procam_kamino comparison")
        return
    data = Path(extra) / "procam_kamino"

    peer = run_peer(Path(args.mirror), data)
    calib, report = run_slscan(Path(args.slscan), data, args.slscan_arg)
    ours_cam, ours_proj = calib["camera"], calib["projector"]
    Kc, dc = K_dist(ours_cam)
    Kp, dp = K_dist(ours_proj)
    sd_c = report["camera"]["std_dev"]
    sd_p = report["projector"]["std_dev"]
    # Ours: T_cam_proj (projector into camera). The peer's R, T map camera into projector.
    Rcp = np.array(calib["T_cam_proj"]["rotation"])
    tcp = np.array(calib["T_cam_proj"]["translation_mm"])
    R_ours, T_ours = Rcp.T, -Rcp.T @ tcp

    print(f"procam_kamino: 5 poses, {' '.join(args.slscan_arg) or 'default corners'}")
    print()
    print("RMS (px)              slscan   peer (its run)   peer, stereo with free intrinsics")
    print(f"camera alone          {calib['rms']['camera']:.4f}   {peer['camera']['rms']:.4f}")
    print(f"projector alone       {calib['rms']['projector']:.4f}   {peer['projector']['rms']:.4f}")
    print(f"stereo                {calib['rms']['stereo']:.4f}   {peer['stereo_fixed']['rms']:.4f} (intrinsics fixed)   "
          f"{peer['stereo_free']['rms']:.4f}")
    print()
    # Our joint (stereo) models against the peer's final ones (its separate calibrations: the
    # stereo step keeps them), and against its free-intrinsics stereo run.
    sf = peer["stereo_free"]
    rows = [
        ("camera", Kc, dc, sd_c, peer["camera"]["K"], peer["camera"]["dist"], sf["K_cam"], sf["d_cam"], 1280, 1024),
        ("projector", Kp, dp, sd_p, peer["projector"]["K"], peer["projector"]["dist"], sf["K_proj"], sf["d_proj"], 1024, 768),
    ]
    for name, K, d, sd, Kpeer, dpeer, Kfree, dfree, w, h in rows:
        print(f"{name}: parameter, slscan (± its σ), peer, (ours − peer)/σ, peer with free intrinsics")
        vals = [("fx", K[0, 0], Kpeer[0, 0], Kfree[0, 0], sd["intrinsics"][0]),
                ("fy", K[1, 1], Kpeer[1, 1], Kfree[1, 1], sd["intrinsics"][1]),
                ("cx", K[0, 2], Kpeer[0, 2], Kfree[0, 2], sd["intrinsics"][2]),
                ("cy", K[1, 2], Kpeer[1, 2], Kfree[1, 2], sd["intrinsics"][3])]
        vals += [(k, d[i], dpeer[i], dfree[i], sd["distortion"][i])
                 for i, k in enumerate(["k1", "k2", "p1", "p2", "k3"])]
        for k, o, p, f, s in vals:
            print(f"  {k:3s} {o:12.5g} ± {s:<10.3g} {p:12.5g}   {(o - p) / s:+6.2f}σ   {f:12.5g}")
        for label, Ka, da in [("the peer's", Kpeer, dpeer), ("the peer's free-intrinsics stereo", Kfree, dfree)]:
            (mx, rms), (amx, arms, ang) = model_gap(Ka, da, K, d, w, h)
            print(f"  whole model against {label}: largest {mx:.2f} px, RMS {rms:.2f} px; after a "
                  f"{ang:.3f}° turn of the frame {amx:.2f} / {arms:.2f} px")
    print()
    for label, R, T in [("peer (intrinsics fixed)", peer["stereo_fixed"]["R"], peer["stereo_fixed"]["T"]),
                        ("peer (free intrinsics)", sf["R"], sf["T"])]:
        dR = rot_deg(R_ours.T @ R)
        print(f"T_proj_cam, slscan against {label}: rotation {rot_deg(R_ours):.4f}° vs {rot_deg(R):.4f}°, "
              f"apart {dR:.4f}°; T {np.round(T_ours, 2)} vs {np.round(T, 2)} "
              f"(|T| {np.linalg.norm(T_ours):.2f} vs {np.linalg.norm(T):.2f}), apart {np.linalg.norm(T_ours - T):.2f}")
    fx = peer["stereo_fixed"]
    print(f"T_proj_cam, the peer's two runs against each other: apart {rot_deg(fx['R'].T @ sf['R']):.4f}°, "
          f"{np.linalg.norm(fx['T'] - sf['T']):.2f}")
    print(f"σ of slscan's T_proj_cam (rotation vector rad, translation): {np.round(report['T_cam_proj']['T_proj_cam_std_dev'], 4)}")


if __name__ == "__main__":
    main()
