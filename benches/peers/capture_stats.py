"""The figures that tell a render from a real capture: edge spread, projected-edge spread, noise
against intensity, fringe contrast, saturation and black level.

```sh
# every real set found under $SL_DATA (OpenCV's chessboards, SLMaster) and $SL_DATA_EXTRA (kamino)
SL_DATA=/work/shared/data SL_DATA_EXTRA=/work/sl-data-extra \
    /work/peers/bin/python benches/peers/capture_stats.py --real --json real.json
# renders written by `slscan simulate` (board sessions and phase captures, found by their manifests)
/work/peers/bin/python benches/peers/capture_stats.py --sim OUT_DIR [--sim OTHER ...] --json sim.json
# any other capture set with an sl-capture manifest, or board images
... capture_stats.py --manifest path/manifest.json[=FRAMES_DIR] --boards 9x6=DIR_OR_GLOB
```

Every pixel value is read with OpenCV (`IMREAD_UNCHANGED`, colour to grey by `COLOR_BGR2GRAY`)
and expressed in 8-bit grey levels (16-bit values divided by 257), so renders at `--bits 16` and
8-bit captures compare directly. What each figure is and how it is measured (also written into
the JSON as `method`):

* **edge spread** (board images): corners by `findChessboardCorners` + `cornerSubPix(5x5)` (or
  `findChessboardCornersSB` when the first fails). Each edge between two neighbouring inner
  corners is sampled across, at 9 stations between 30 % and 70 % of the way from one corner to
  the other (away from the X-junctions), over +-0.3 of the corner spacing, every 0.25 px, by
  bilinear interpolation; the 9 profiles are averaged and fitted with `c + (h/2) erf((d - d0) /
  (sqrt(2) sigma))` (a Gaussian line-spread of standard deviation sigma, px). Fits with a
  contrast under 20 grey levels, a residual RMS over 8 % of the contrast, or sigma outside
  (0.05, window/3) are dropped. Reported: median, quartiles and count of sigma, over all edges,
  by the edge's distance from the image centre (inner: under half the half-diagonal; outer:
  the rest), and by the edge's direction.
* **projected-edge spread** (Gray-code pattern/inverse pairs): D = (P - I) / M, M the full
  modulation of the pixel (the median over the three coarsest bits of |P - I|: wide stripes, so
  nearly every pixel is fully lit or fully dark in them; the albedo cancels in D). Pixels with
  M >= 30 grey levels. Stripe width: the masked length of every 8th line across the stripes
  divided by the sign changes of D on it (camera px). On every 8th line each sign change of D
  gives an edge; the profile of D is sampled along the local gradient of D (Gaussian-smoothed,
  sigma 1.5), over +-min(10, 0.45 stripe width) px, every 0.25 px, every sample inside the mask,
  and fitted with the same erf model (amplitude between 1 and 3, residual under 15 %). Only
  bits whose stripes are >= 20 px wide are fitted (nearer edges bias the fit).
* **fringe contrast**: for phase shifts, per frequency, A (mean) and B (amplitude of the
  fundamental, least squares over the N steps) per pixel, over the pixels the projector lights
  (B >= 10 grey levels at that frequency, no clipped frame); quantiles of B, B/A and
  B/(A - floor), floor the set's dark floor below. The projector's departure from a sinusoid:
  the RMS residual of the per-pixel sinusoid fit (noise included), and the 2nd harmonic B2/B
  fitted per 32x32 tile. For Gray codes, per bit, |P - I| / M over the pixels with M >= 30: 1
  where the stripes are resolved, falling as they get finer than the projector + camera blur
  (and, for wide stripes, by the light the lit stripes scatter into the dark ones).
* **noise against intensity**, phase shifts (N steps, here 4): the per-pixel residual of the
  least-squares fit I_k = A + B cos(phi - delta_k); for N = 4 it is r = (I0 - I1 + I2 - I3) / 2,
  which is 0 for a sinusoid plus any offset; for independent frames with var I = a + b I,
  var r = (1/4) sum var I_k = a + b A. But harmonics of the fringe profile reach r (the m-th
  when m = 2 mod 4: r = 2 B2 cos(2 phi + psi) for m = 2), and so does any other departure of
  the projector from a sinusoid (on SLMaster's captures, a non-harmonic pattern some 5 grey
  levels RMS, 40 times the noise). All of them depend on the projected value only, which is
  the same for neighbouring pixels along a fringe; so the noise is measured on the second
  difference of r along the fringes, r[i-1] - 2 r[i] + r[i+1] (variance 6 var r for white
  noise), on the pixels where the phase changes by <= 0.05 rad/px and the amplitude by <= 5 %
  along it (judged on the fringe smoothed by a Gaussian of 2 px, so as not to select pixels
  by their own noise). Pixels lit and never clipped; binned by A (8 grey levels); per bin the
  variance is a 98 %-trimmed mean of the squared differences, corrected for the trimming
  (chi-squared); then var = a + b A by weighted least squares over the bins of >= 200 pixels.
  a includes the quantisation 1/12 of an 8-bit frame (read noise = sqrt(a - 1/12)); b is grey
  levels per photo-electron. `neighbour_correlation` is the correlation of the differences of
  neighbouring pixels across the fringes: 0 for white noise, positive when the camera
  correlates neighbours (demosaicing, denoising), which makes the figure low by about that
  fraction. `--selftest` checks the estimators on synthetic frames with known noise.
* **noise against intensity**, Gray codes with a white (and black) frame: per pair, the lit
  frame minus the white frame (and the dark frame minus the black frame), where the pixel is
  >= 4 px from a stripe edge (the same sign of P - I over 9x9): albedo and fixed pattern cancel,
  the stray light that changes with the pattern is smooth; its second difference along the
  stripes has variance 12 sigma^2 (two frames); binned by the mean of the two values and
  fitted as above.
* **saturation and black level**: share of pixels at 0 and at full scale over all frames;
  quantiles 0.1 %, 1 %, 5 % and the median of all pixels; the median and 99th percentile of the
  black frame when the set has one; the dark floor = the 1 % quantile of all pixels.
"""

import argparse
import glob
import json
import math
import os
import sys
from pathlib import Path

import cv2
import numpy as np
from scipy import ndimage, optimize, special, stats

REPO = Path(__file__).resolve().parents[2]

# Thresholds named once (grey levels are 8-bit units).
MIN_EDGE_CONTRAST = 20.0  # board edges: black to white step at least this
MAX_EDGE_RESIDUAL = 0.08  # board edges: fit residual RMS / contrast
MIN_MODULATION = 30.0  # Gray codes: full modulation M of a pixel used
MIN_FRINGE_B = 10.0  # phase: amplitude of a pixel counted as lit (10 x the noise of ~1 level)
MIN_STRIPE_PX = 20.0  # projected edges: narrower stripes are not fitted (the neighbouring edges bias the fit)
NOISE_BIN = 8.0  # grey levels per intensity bin
MIN_BIN_PIXELS = 200
TILE = 32  # px, harmonic correction tiles
QUANTISATION = 1.0 / 12.0  # variance of rounding to integers
MAX_ALONG_PHASE = 0.05  # rad per px: phase change allowed along the noise difference
MAX_ALONG_CHANGE = 0.05  # relative change of the fringe amplitude allowed along it
TRIM = 0.98  # share of each bin's noise samples kept (drops edges and other outliers)


# ----------------------------------------------------------------------------- image files


def read(path):
    """(image as float64 in 8-bit grey levels, full-scale value of the file)."""
    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if img is None:
        raise SystemExit(f"capture_stats: cannot read {path}")
    if img.ndim == 3:
        img = cv2.cvtColor(img[:, :, :3], cv2.COLOR_BGR2GRAY)
    if img.dtype == np.uint8:
        return img.astype(np.float64), 255
    if img.dtype == np.uint16:
        return img.astype(np.float64) / 257.0, 65535
    raise SystemExit(f"capture_stats: {path}: unsupported pixel type {img.dtype}")


def quantiles(values, qs=(5, 25, 50, 75, 95)):
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return {"n": 0}
    out = {"n": int(v.size)}
    for q in qs:
        out[f"p{q}"] = float(np.percentile(v, q))
    return out


# ----------------------------------------------------------------------------- erf fits


def erf_model(d, c, h, d0, s):
    return c + 0.5 * h * special.erf((d - d0) / (math.sqrt(2.0) * s))


def fit_erf(d, y, s0=1.0):
    """(c, h, d0, sigma, residual RMS) of an erf edge fitted to profile y(d), or None."""
    y = np.asarray(y, dtype=np.float64)
    n = y.size
    k = max(2, n // 5)
    lo, hi = y[:k].mean(), y[-k:].mean()
    p0 = [0.5 * (lo + hi), hi - lo, 0.0, s0]
    try:
        p, _ = optimize.curve_fit(erf_model, d, y, p0=p0, maxfev=2000)
    except (RuntimeError, optimize.OptimizeWarning, ValueError):
        return None
    res = y - erf_model(d, *p)
    return p[0], p[1], p[2], abs(p[3]), float(np.sqrt((res**2).mean()))


# ----------------------------------------------------------------------------- board edges


def find_corners(img8, cols, rows):
    ok, c = cv2.findChessboardCorners(img8, (cols, rows))
    if ok:
        crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 30, 0.001)
        return cv2.cornerSubPix(img8, c, (5, 5), (-1, -1), crit).reshape(-1, 2)
    ok, c = cv2.findChessboardCornersSB(img8, (cols, rows), flags=cv2.CALIB_CB_ACCURACY)
    return c.reshape(-1, 2) if ok else None


def edge_spread(files, cols, rows):
    """Line-spread sigma of the board's black/white edges, over the given images."""
    edges = []  # (sigma, radius fraction, 'h' or 'v' normal, contrast)
    found = 0
    for f in files:
        img, _ = read(f)
        img8 = np.clip(np.rint(img), 0, 255).astype(np.uint8)
        corners = find_corners(img8, cols, rows)
        if corners is None:
            print(f"capture_stats: no {cols}x{rows} board in {f}", file=sys.stderr)
            continue
        found += 1
        g = corners.reshape(rows, cols, 2).astype(np.float64)
        hgt, wid = img.shape
        centre = np.array([(wid - 1) / 2, (hgt - 1) / 2])
        half_diag = math.hypot(wid, hgt) / 2
        pairs = []
        for j in range(rows):
            for i in range(cols - 1):
                pairs.append((g[j, i], g[j, i + 1]))
        for j in range(rows - 1):
            for i in range(cols):
                pairs.append((g[j, i], g[j + 1, i]))
        for a, b in pairs:
            v = b - a
            length = np.linalg.norm(v)
            if length < 8:
                continue
            t = v / length
            n = np.array([-t[1], t[0]])
            half = 0.3 * length
            d = np.arange(-half, half + 1e-9, 0.25)
            stations = np.linspace(0.3, 0.7, 9)
            pts = a[None, None, :] + stations[:, None, None] * v[None, None, :] + d[None, :, None] * n
            prof = ndimage.map_coordinates(img, [pts[..., 1].ravel(), pts[..., 0].ravel()], order=1)
            prof = prof.reshape(len(stations), len(d)).mean(axis=0)
            fit = fit_erf(d, prof)
            if fit is None:
                continue
            _, h, d0, s, res = fit
            if abs(h) < MIN_EDGE_CONTRAST or res > MAX_EDGE_RESIDUAL * abs(h):
                continue
            if not (0.05 < s < half / 3) or abs(d0) > half / 2:
                continue
            mid = 0.5 * (a + b)
            r = np.linalg.norm(mid - centre) / half_diag
            edges.append((s, r, "x" if abs(n[0]) > abs(n[1]) else "y", abs(h)))
    s = np.array([e[0] for e in edges])
    r = np.array([e[1] for e in edges])
    dirn = np.array([e[2] for e in edges])
    return {
        "method": "erf fit of the mean of 9 profiles across each board edge between 30 and 70 % "
        "of the way between neighbouring corners (OpenCV corners), +-0.3 corner spacing; sigma "
        "of the Gaussian line spread in px",
        "images": len(files),
        "boards_found": found,
        "sigma_px": quantiles(s),
        "sigma_inner_px": quantiles(s[r < 0.5]) if s.size else {"n": 0},
        "sigma_outer_px": quantiles(s[r >= 0.5]) if s.size else {"n": 0},
        "sigma_across_x_px": quantiles(s[dirn == "x"]) if s.size else {"n": 0},
        "sigma_across_y_px": quantiles(s[dirn == "y"]) if s.size else {"n": 0},
        "contrast": quantiles([e[3] for e in edges]),
    }


# ----------------------------------------------------------------------------- phase shifts


def phase_stats(frames, steps, shift_sign, floor, label):
    """Fringe contrast and noise of one frequency of an N-step phase shift."""
    n = steps
    stack = np.stack(frames)  # n x H x W
    delta = shift_sign * 2 * math.pi * np.arange(n) / n
    # I_k = A + C cos(delta_k) + S sin(delta_k); B cos(phi - delta) = B cos phi cos delta + ...
    cos_d, sin_d = np.cos(delta), np.sin(delta)
    a = stack.mean(axis=0)
    c = (2.0 / n) * np.tensordot(cos_d, stack, axes=1)
    s = (2.0 / n) * np.tensordot(sin_d, stack, axes=1)
    b = np.hypot(c, s)
    phi = np.arctan2(s, c)
    fitted = a[None] + c[None] * cos_d[:, None, None] + s[None] * sin_d[:, None, None]
    resid = stack - fitted  # in the (n - 3)-dimensional residual space of each pixel
    clipped = ((stack <= 0) | (stack >= 255)).any(axis=0)
    lit = (b >= MIN_FRINGE_B) & ~clipped
    out = {
        "steps": n,
        "lit_pixels": int(lit.sum()),
        "B": quantiles(b[lit]),
        "B_over_A": quantiles((b / np.maximum(a, 1e-9))[lit]),
        "B_over_A_minus_floor": quantiles((b / np.maximum(a - floor, 1e-9))[lit]),
        "A": quantiles(a[lit]),
    }
    # Residual of the sinusoid fit: noise plus the projector's departures from a sinusoid
    # (harmonics, dithering); for N = 4 every pixel's residual is r (I0 - I1 + I2 - I3) / 2.
    sysv = (resid**2).sum(axis=0) / max(n - 3, 1)
    out["fit_residual_rms"] = float(np.sqrt(sysv[lit].mean())) if n > 3 else None
    if n < 4:
        return out
    # Harmonic 2 per tile: residual ~ B (alpha cos 2(phi - delta) + beta sin 2(...)),
    # projected onto the residual space; |(alpha, beta)| = B2 / B.
    F = np.stack([np.ones(n), cos_d, sin_d], axis=1)
    P = np.eye(n) - F @ np.linalg.pinv(F)
    harmonic = []
    H, W = a.shape
    for y0 in range(0, H, TILE):
        for x0 in range(0, W, TILE):
            m = lit[y0 : y0 + TILE, x0 : x0 + TILE]
            if m.sum() < TILE * TILE // 3:
                continue
            bt = b[y0 : y0 + TILE, x0 : x0 + TILE][m]
            pt = phi[y0 : y0 + TILE, x0 : x0 + TILE][m]
            et = resid[:, y0 : y0 + TILE, x0 : x0 + TILE][:, m]
            X = np.stack([P @ (bt[None] * f(2 * (pt[None] - delta[:, None]))) for f in (np.cos, np.sin)], -1)
            coef, *_ = np.linalg.lstsq(X.reshape(-1, 2), et.ravel(), rcond=1e-9)
            harmonic.append(math.hypot(*coef))
    out["harmonic2_over_B"] = quantiles(harmonic)
    # Noise: the second difference of the residual along the fringes (3 neighbouring pixels
    # on one fringe see the same projector value, so the projector's systematic errors cancel
    # with the offset and the whole fringe profile).
    along = 0 if fringe_axis(phi, lit) == "vertical" else 1
    d2 = second_difference(resid, along)  # n x H x W, NaN where not defined
    # ... as long as the phase and the amplitude are nearly the same on the three pixels:
    # where a surface turns the fringes across the difference direction, or an albedo edge
    # crosses it, the fringe's departures from a sinusoid would leak in. Both are taken from
    # the fringe smoothed by a Gaussian of 2 px: a test on the pixel's own noisy values would
    # select pixels by their noise (measured: 6 % low).
    zs = ndimage.gaussian_filter(c, 2.0) + 1j * ndimage.gaussian_filter(s, 2.0)
    w = zs / np.maximum(np.abs(zs), 1e-9)
    bs = np.abs(zs)
    steady = np.zeros_like(lit)
    if along == 0:
        dphi = np.abs(np.angle(w[1:] * np.conj(w[:-1])))
        db = np.abs(bs[1:] - bs[:-1]) / np.maximum(bs[1:], 1e-9)
        ok_step = (dphi <= MAX_ALONG_PHASE) & (db <= MAX_ALONG_CHANGE)
        steady[1:-1] = ok_step[:-1] & ok_step[1:]
    else:
        dphi = np.abs(np.angle(w[:, 1:] * np.conj(w[:, :-1])))
        db = np.abs(bs[:, 1:] - bs[:, :-1]) / np.maximum(bs[:, 1:], 1e-9)
        ok_step = (dphi <= MAX_ALONG_PHASE) & (db <= MAX_ALONG_CHANGE)
        steady[:, 1:-1] = ok_step[:, :-1] & ok_step[:, 1:]
    ok = lit & shift_and(lit, along) & steady & np.isfinite(d2).all(axis=0)
    out["noise_pixels"] = int(ok.sum())
    q = (d2**2).sum(axis=0) / (6.0 * (n - 3))
    out["noise"] = noise_fit(a[ok], q[ok], n - 3)
    out["noise"]["direction"] = "along y" if along == 0 else "along x"
    out["noise"]["neighbour_correlation"] = neighbour_correlation(d2[0], ok, 1 - along)
    print(f"  {label}: {n} steps, {int(lit.sum())} lit px", file=sys.stderr)
    return out


def fringe_axis(phi, lit):
    """'vertical' when the phase changes mostly along x (fringes run along y)."""
    w = np.exp(1j * phi)
    gx = np.abs(np.angle(w[:, 1:] * np.conj(w[:, :-1])))[lit[:, 1:] & lit[:, :-1]]
    gy = np.abs(np.angle(w[1:] * np.conj(w[:-1])))[lit[1:] & lit[:-1]]
    return "vertical" if np.median(gx) >= np.median(gy) else "horizontal"


def second_difference(x, axis):
    """x[i-1] - 2 x[i] + x[i+1] along the image axis (0: y, 1: x) of a (..., H, W) array,
    NaN on the border."""
    out = np.full(x.shape, np.nan)
    if axis == 0:
        out[..., 1:-1, :] = x[..., :-2, :] - 2 * x[..., 1:-1, :] + x[..., 2:, :]
    else:
        out[..., :, 1:-1] = x[..., :, :-2] - 2 * x[..., :, 1:-1] + x[..., :, 2:]
    return out


def shift_and(mask, axis):
    """True where the pixel and both its neighbours along axis are True."""
    out = np.zeros_like(mask)
    if axis == 0:
        out[1:-1] = mask[:-2] & mask[1:-1] & mask[2:]
    else:
        out[:, 1:-1] = mask[:, :-2] & mask[:, 1:-1] & mask[:, 2:]
    return out


def neighbour_correlation(d2, ok, axis):
    """Correlation of the noise estimate between neighbours across the difference direction:
    0 for white noise; positive when the camera correlates neighbouring pixels (demosaicing,
    compression, denoising), which makes the estimate low by about that fraction."""
    if axis == 1:
        p, q, m = d2[:, :-1], d2[:, 1:], ok[:, :-1] & ok[:, 1:]
    else:
        p, q, m = d2[:-1], d2[1:], ok[:-1] & ok[1:]
    if m.sum() < 100:
        return None
    return float(np.corrcoef(p[m], q[m])[0, 1])


def noise_fit(level, q, nu):
    """Per bin of level: the noise variance, robustly, as the mean of q below the bin's
    98th percentile divided by what that trimming leaves of a chi2_nu / nu (exact for Gaussian
    noise; blind to the few pixels on edges, and unlike a median it works on the integer
    steps of 8-bit data); then a weighted least-squares fit var = a + b level over the bins."""
    cut = stats.chi2.ppf(TRIM, nu)
    scale = stats.chi2.cdf(cut, nu + 2) / TRIM  # E[X; X < cut] / (nu P(X < cut))
    bins = np.floor(level / NOISE_BIN).astype(int)
    rows = []
    for k in np.unique(bins):
        sel = bins == k
        if sel.sum() < MIN_BIN_PIXELS:
            continue
        qk = q[sel]
        v = float(qk[qk <= np.percentile(qk, 100 * TRIM)].mean() / scale)
        rows.append((float(level[sel].mean()), v, int(sel.sum())))
    out = {
        "method": "trimmed (98 %) variance of the second difference along the "
        "stripes, in bins of 8 grey levels; var = a + b level fitted by weighted least squares",
        "bins": [{"level": r[0], "var": r[1], "pixels": r[2]} for r in rows],
        "a": None,
        "b": None,
    }
    if len(rows) < 2:
        return out
    lv = np.array([r[0] for r in rows])
    vv = np.array([r[1] for r in rows])
    cnt = np.array([r[2] for r in rows])
    # sd of a variance estimate ~ var * sqrt(2 / (nu n)) (x1.36 for the median; a constant)
    w = np.sqrt(cnt * nu / 2.0) / np.maximum(vv, 1e-6)
    M = np.stack([np.ones_like(lv), lv], axis=1)
    coef, *_ = np.linalg.lstsq(M * w[:, None], vv * w, rcond=None)
    pred = M @ coef
    out.update(
        a=float(coef[0]),
        b=float(coef[1]),
        read_noise_sigma=float(math.sqrt(max(coef[0] - QUANTISATION, 0.0))),
        fit_rel_rms=float(np.sqrt((((vv - pred) / np.maximum(vv, 1e-6)) ** 2).mean())),
        range=[float(lv.min()), float(lv.max())],
    )
    return out


# ----------------------------------------------------------------------------- Gray codes


def stripe_width(dn, mask, axis):
    """Mean stripe width (px) along axis (1: rows, 0: columns): the masked length of every 8th
    line divided by the sign changes of D (smoothed by a Gaussian of 1 px against noise) on it."""
    sm = ndimage.gaussian_filter(dn, 1.0)
    s = np.sign(sm) if axis == 1 else np.sign(sm).T
    m = mask if axis == 1 else mask.T
    s, m = s[::8], m[::8]
    both = m[:, 1:] & m[:, :-1]
    changes = int(((s[:, 1:] != s[:, :-1]) & both).sum())
    return float(both.sum() / changes) if changes else float("inf")


def projected_edges(dn, mask, axis, width, rng):
    """Erf fits across the stripe edges of one Gray bit; sigma values (px)."""
    sm = ndimage.gaussian_filter(dn, 1.5)
    gy, gx = np.gradient(sm)
    half = min(10.0, 0.45 * width)
    d = np.arange(-half, half + 1e-9, 0.25)
    sig = []
    lines = range(4, dn.shape[0 if axis == 1 else 1] - 4, 8)
    cands = []
    for L in lines:
        row = dn[L] if axis == 1 else dn[:, L]
        mr = mask[L] if axis == 1 else mask[:, L]
        idx = np.flatnonzero((np.sign(row[1:]) != np.sign(row[:-1])) & mr[1:] & mr[:-1])
        for i in idx:
            # sub-pixel zero crossing between i and i+1
            f = row[i] / (row[i] - row[i + 1])
            cands.append((i + f, L) if axis == 1 else (L, i + f))
    if len(cands) > 600:
        pick = rng.choice(len(cands), 600, replace=False)
        cands = [cands[k] for k in pick]
    for x, y in cands:
        gxv = ndimage.map_coordinates(gx, [[y], [x]], order=1)[0]
        gyv = ndimage.map_coordinates(gy, [[y], [x]], order=1)[0]
        gn = math.hypot(gxv, gyv)
        if gn == 0:
            continue
        n = np.array([gxv, gyv]) / gn
        px, py = x + d * n[0], y + d * n[1]
        inside = ndimage.map_coordinates(mask.astype(np.float64), [py, px], order=0, cval=0.0)
        if not inside.all():
            continue
        prof = ndimage.map_coordinates(dn, [py, px], order=1)
        fit = fit_erf(d, prof)
        if fit is None:
            continue
        _, h, d0, s, res = fit
        if not (1.0 <= abs(h) <= 3.0) or res > 0.15 * abs(h):
            continue
        if not (0.05 < s < half / 3) or abs(d0) > half / 2:
            continue
        sig.append(s)
    return sig


def gray_stats(pairs, white, black, label, seed=0):
    """Per bit (MSB first) of one axis: stripe width, contrast, projected-edge spread."""
    axis = pairs["axis"]
    frames = [(read(p)[0], read(i)[0]) for p, i in pairs["frames"]]
    diffs = [p - i for p, i in frames]
    M = np.median(np.abs(np.stack(diffs[:3])), axis=0)
    mask = M >= MIN_MODULATION
    rng = np.random.default_rng(seed)
    bits = []
    for k, dif in enumerate(diffs):
        dn = np.where(mask, dif / np.maximum(M, 1e-9), 0.0)
        ratio = np.abs(dn[mask])
        width = stripe_width(dn, mask, 1 if axis == "column" else 0)
        entry = {
            "bit": k,
            "stripe_width_px": width,
            "contrast": quantiles(ratio, (10, 50, 90)),
        }
        if np.isfinite(width) and width >= MIN_STRIPE_PX:
            entry["edge_sigma_px"] = quantiles(
                projected_edges(dn, mask, 1 if axis == "column" else 0, width, rng)
            )
        bits.append(entry)
    print(f"  {label}: {axis} bits, {int(mask.sum())} px with M >= {MIN_MODULATION}", file=sys.stderr)
    return {"axis": axis, "modulated_pixels": int(mask.sum()), "bits": bits,
            "psf_from_contrast": psf_from_contrast(bits)}, frames


def model_contrast(width, core, share, tail):
    """Median over a period of |square wave of stripes `width` px wide, blurred by the PSF
    (1 - share) Gauss(core) + share Gauss(tail)|, the wave of +-1."""
    step = min(0.05, width / 40.0)
    half = int(math.ceil(4 * max(core, tail) / step)) + 1
    k = np.arange(-half, half + 1) * step
    psf = (1 - share) * np.exp(-0.5 * (k / core) ** 2) / core + share * np.exp(-0.5 * (k / tail) ** 2) / tail
    psf /= psf.sum()
    period = 2 * width
    n_per = max(1, int(round(period / step)))
    reps = 2 * int(math.ceil(half / n_per)) + 3
    x = (np.arange(reps * n_per) + 0.5) * (period / n_per)
    wave = np.where((x % period) < width, 1.0, -1.0)
    blurred = np.convolve(wave, psf, mode="same")
    mid = blurred[(reps // 2) * n_per : (reps // 2 + 1) * n_per]
    return float(np.median(np.abs(mid)))


def psf_from_contrast(bits):
    """Fit a two-Gaussian PSF (core sigma, tail share, tail sigma; camera px) to the median
    contrast of the Gray bits against their stripe width, each normalised like the data by
    the three coarsest bits."""
    ws = np.array([b["stripe_width_px"] for b in bits])
    cs = np.array([b["contrast"].get("p50", np.nan) for b in bits])
    ref = ws[:3][np.isfinite(ws[:3])]
    use = np.isfinite(ws) & np.isfinite(cs) & (ws >= 1.5) & (ws <= 300)
    if use.sum() < 4 or ref.size == 0:
        return None
    w_ref = float(np.median(ref))

    def model(p):
        core, share, tail = p
        r = model_contrast(w_ref, core, share, tail)
        return np.array([model_contrast(w, core, share, tail) / r for w in ws[use]])

    fit = optimize.least_squares(
        lambda p: model(p) - cs[use], x0=[1.0, 0.1, 20.0],
        bounds=([0.2, 0.0, 3.0], [5.0, 0.6, 200.0]),
    )
    core, share, tail = fit.x
    return {
        "method": "least squares of the model median |P - I| / M of a square wave blurred by "
        "(1 - share) Gauss(core) + share Gauss(tail) against the measured median contrast of "
        "the bits with stripes 1.5-300 px wide",
        "core_sigma_px": float(core),
        "tail_share": float(share),
        "tail_sigma_px": float(tail),
        "rms_misfit": float(np.sqrt((fit.fun**2).mean())),
        "bits_used": int(use.sum()),
    }


def gray_noise(blocks, white, black):
    """Noise from the Gray pairs against the white and black frames: per pair, the lit frame
    minus the white frame (and the dark frame minus the black frame) where the pixel is >= 4 px
    from a stripe edge (same sign of P - I over 9x9); the albedo and the fixed pattern cancel
    in the difference, a pattern-dependent stray light is smooth; the second difference of it
    along the stripes leaves noise of variance 2 x 6 sigma^2 (two frames)."""
    levels_, qs = [], []
    corr = []
    for axis, frames in blocks:
        along = 0 if axis == "column" else 1  # column bits: vertical stripes, run along y
        for p, i in frames:
            sign = np.sign(p - i)
            same = (ndimage.minimum_filter(sign, 9) == ndimage.maximum_filter(sign, 9)) & (sign != 0)
            for ref, v in ((white, np.maximum(p, i)), (black, np.minimum(p, i))):
                if ref is None:
                    continue
                good = same & (v > 0) & (v < 255) & (ref > 0) & (ref < 255)
                d2 = second_difference(v - ref, along)
                ok = shift_and(good, along) & np.isfinite(d2)
                levels_.append(((v + ref) / 2)[ok])
                qs.append((d2**2 / 12.0)[ok])
                c = neighbour_correlation(d2, ok, 1 - along)
                if c is not None:
                    corr.append(c)
    if not qs:
        return {"note": "no white frame: no Gray-code noise figure"}
    out = noise_fit(np.concatenate(levels_), np.concatenate(qs), 1)
    out["neighbour_correlation"] = float(np.median(corr)) if corr else None
    return out


# ----------------------------------------------------------------------------- levels


def levels(files, black=None):
    tot = zero = full = 0
    samples = []
    rng = np.random.default_rng(1)
    for f in files:
        img, fs = read(f)
        raw = img * (257.0 if fs == 65535 else 1.0)
        tot += img.size
        zero += int((raw <= 0).sum())
        full += int((raw >= fs).sum())
        samples.append(rng.choice(img.ravel(), min(img.size, 100000), replace=False))
    s = np.concatenate(samples)
    out = {
        "frames": len(files),
        "share_at_0": zero / tot,
        "share_at_full_scale": full / tot,
        "p0_1": float(np.percentile(s, 0.1)),
        "p1": float(np.percentile(s, 1)),
        "p5": float(np.percentile(s, 5)),
        "median": float(np.median(s)),
        "dark_floor": float(np.percentile(s, 1)),
    }
    if black is not None:
        b, _ = read(black)
        out["black_frame_median"] = float(np.median(b))
        out["black_frame_p99"] = float(np.percentile(b, 99))
    return out


# ----------------------------------------------------------------------------- sets


def manifest_set(manifest_path, frames_dir=None, white=None, black=None):
    """Figures of one capture set described by an sl-capture manifest."""
    man = json.loads(Path(manifest_path).read_text())
    base = Path(frames_dir) if frames_dir else Path(manifest_path).parent / man.get("frames_dir", ".")
    files = []
    for b in man["blocks"]:
        files += [base / f for f in b["frames"]]
    white = white or next((p for p in [base / "white.png"] if p.exists()), None)
    lev = levels(sorted(set(files)) + ([white] if white else []), black)
    out = {"kind": "capture set", "manifest": str(manifest_path), "levels": lev}
    floor = lev["dark_floor"]
    gray_frames = []
    for b in man["blocks"]:
        fr = [base / f for f in b["frames"]]
        if b["codec"] in ("phase", "hybrid"):
            n = b["steps"]
            periods = b["periods"] if isinstance(b["periods"], list) else [b["periods"]]
            sign = b.get("shift_sign", 1)
            for k, per in enumerate(periods):
                imgs = [read(f)[0] for f in fr[k * n : (k + 1) * n]]
                out.setdefault("phase", []).append(
                    {"axis": b["axis"], "periods": per,
                     **phase_stats(imgs, n, sign, floor, f"{Path(manifest_path).parent.name} {per} periods")}
                )
            if b["codec"] == "hybrid":
                g = b.get("gray", {})
                ref = g.get("reference", "inverse")
                rest = fr[n * len(periods):]
                if ref == "inverse":
                    pairs = {"axis": b["axis"], "frames": list(zip(rest[0::2], rest[1::2]))}
                    st, frames = gray_stats(pairs, None, None, "hybrid gray")
                    out.setdefault("gray", []).append(st)
                    gray_frames.append((b["axis"], frames))
        elif b["codec"] == "gray" and b.get("reference", "inverse") == "inverse":
            pairs = {"axis": b["axis"], "frames": list(zip(fr[0::2], fr[1::2]))}
            st, frames = gray_stats(pairs, None, None, Path(manifest_path).parent.name)
            out.setdefault("gray", []).append(st)
            gray_frames.append((b["axis"], frames))
    if gray_frames:
        w = read(white)[0] if white else None
        k = read(black)[0] if black else None
        out["gray_noise"] = gray_noise(gray_frames, w, k)
    return out


def kamino_sets(root):
    """procam_kamino: per capture, the Gray code (10 column bits, 10 row bits, pattern/inverse,
    MSB first), white 40, black 41; the board (9x7) in the white frames."""
    caps = sorted(Path(root).glob("capture_*"))
    out = {}
    whites = [c / "graycode_40.png" for c in caps]
    out["kamino white frames"] = {"kind": "board", "board": "9x7",
                                  "edge_spread": edge_spread(whites, 9, 7),
                                  "levels": levels(whites)}
    for c in caps:
        f = lambda k: f"graycode_{k:02d}.png"  # noqa: E731
        man = {
            "projector": {"width": 1024, "height": 768},
            "blocks": [
                {"codec": "gray", "axis": "column", "bits": 10, "reference": "inverse",
                 "frames": [f(k) for k in range(20)]},
                {"codec": "gray", "axis": "row", "bits": 10, "reference": "inverse",
                 "frames": [f(k) for k in range(20, 40)]},
            ],
        }
        tmp = Path(os.environ.get("TMPDIR", "/tmp")) / f"capture_stats_kamino_{c.name}.json"
        tmp.write_text(json.dumps(man))
        out[f"kamino {c.name} Gray code"] = manifest_set(
            tmp, frames_dir=c, white=c / "graycode_40.png", black=c / "graycode_41.png"
        )
    return out


def real_sets():
    out = {}
    data = os.environ.get("SL_DATA")
    if data:
        cb = Path(data) / "chessboard"
        for side in ("left", "right"):
            files = sorted(cb.glob(f"{side}*.jpg"))
            out[f"OpenCV {side} (9x6)"] = {"kind": "board", "board": "9x6",
                                            "edge_spread": edge_spread(files, 9, 6),
                                            "levels": levels(files)}
        for name in ("three_frequency_heterodyne", "shift_graycode"):
            man = REPO / "crates/sl-codec/tests/data/slmaster" / f"{name}.json"
            out[f"SLMaster {name}"] = manifest_set(man, frames_dir=Path(data) / "slmaster" / name)
    else:
        print("SL_DATA not set: skipping OpenCV's chessboards and SLMaster", file=sys.stderr)
    extra = os.environ.get("SL_DATA_EXTRA")
    if extra:
        out.update(kamino_sets(Path(extra) / "procam_kamino"))
    else:
        print("SL_DATA_EXTRA not set: skipping procam_kamino", file=sys.stderr)
    return out


def sim_sets(root):
    """Every capture set under an `slscan simulate` output folder (found by its manifest.json);
    board poses (board.json beside it) also give the edge spread of their white.png."""
    out = {}
    root = Path(root)
    whites_by_board = {}
    for man in sorted(root.rglob("manifest.json")):
        folder = man.parent
        name = f"sim {root.name}/{folder.relative_to(root)}"
        out[name] = manifest_set(man)
        bj = folder / "board.json"
        if bj.exists() and (folder / "white.png").exists():
            b = json.loads(bj.read_text())["board"]
            whites_by_board.setdefault((b["inner_cols"], b["inner_rows"]), []).append(folder / "white.png")
    for (c, r), files in whites_by_board.items():
        out[f"sim {root.name} white frames ({c}x{r})"] = {
            "kind": "board", "board": f"{c}x{r}",
            "edge_spread": edge_spread(files, c, r), "levels": levels(files)}
    return out


# ----------------------------------------------------------------------------- report


def fmt(q, key="p50"):
    return f"{q[key]:.2f}" if q.get("n", 0) and key in q else "–"


def iqr(q):
    return f"{q['p25']:.2f}–{q['p75']:.2f}" if q.get("n", 0) else "–"


def print_tables(res, per_bit=False):
    print("\n## Edge spread of board edges (sigma of the line spread, px)\n")
    print("| set | boards | edges | median | quartiles | inner | outer | across x | across y |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name, r in res.items():
        e = r.get("edge_spread")
        if not e:
            continue
        s = e["sigma_px"]
        print(f"| {name} | {e['boards_found']}/{e['images']} | {s['n']} | {fmt(s)} | {iqr(s)} | "
              f"{fmt(e['sigma_inner_px'])} | {fmt(e['sigma_outer_px'])} | "
              f"{fmt(e['sigma_across_x_px'])} | {fmt(e['sigma_across_y_px'])} |")
    print("\n## Gray codes: projected-edge spread, contrast of the fine bits, and the PSF fitted "
          "to the contrast (camera px)\n")
    print("| set | axis | projected-edge sigma (median over bits >= 20 px) | stripe width -> median "
          "contrast, bits under 60 px | PSF core sigma / tail share / tail sigma (misfit) |")
    print("|---|---|---|---|---|")
    for name, r in res.items():
        for g in r.get("gray", []):
            sig = [b["edge_sigma_px"]["p50"] for b in g["bits"] if b.get("edge_sigma_px", {}).get("n")]
            fine = ", ".join(f"{b['stripe_width_px']:.1f} -> {b['contrast']['p50']:.2f}"
                             for b in g["bits"] if b["stripe_width_px"] < 60 and b["contrast"].get("n"))
            p = g.get("psf_from_contrast")
            psf = (f"{p['core_sigma_px']:.2f} / {p['tail_share']:.3f} / {p['tail_sigma_px']:.1f} "
                   f"({p['rms_misfit']:.3f})" if p else "–")
            print(f"| {name} | {g['axis']} | {np.median(sig) if sig else float('nan'):.2f} "
                  f"({len(sig)} bits) | {fine} | {psf} |")
    if per_bit:
        print("\n## Gray codes per bit: stripe width (camera px), contrast |P-I|/M (p10/p50/p90), "
              "projected-edge sigma (px, median [quartiles] n)\n")
        print("| set | axis | bit | stripe px | contrast p10 / p50 / p90 | edge sigma |")
        print("|---|---|---|---|---|---|")
        for name, r in res.items():
            for g in r.get("gray", []):
                for b in g["bits"]:
                    c = b["contrast"]
                    es = b.get("edge_sigma_px")
                    edge = f"{fmt(es)} [{iqr(es)}] n={es['n']}" if es and es.get("n") else "–"
                    print(f"| {name} | {g['axis']} | {b['bit']} | {b['stripe_width_px']:.1f} | "
                          f"{fmt(c, 'p10')} / {fmt(c)} / {fmt(c, 'p90')} | {edge} |")
    f = lambda v, k=3: "–" if v is None else f"{v:.{k}f}"  # noqa: E731
    print("\n## Phase shifts: fringe contrast, the projector's departure from a sinusoid, "
          "noise (sigma^2 = a + b A, grey levels^2)\n")
    print("| set | periods | lit px | B p5/p50/p95 | B/A p50 | B/(A-floor) p50 | B2/B p50 | "
          "fit residual RMS | a | b | noise levels | neighbour corr |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for name, r in res.items():
        for p in r.get("phase", []):
            n = p.get("noise", {})
            rng = n.get("range")
            print(f"| {name} | {p['periods']:g} | {p['lit_pixels']} | "
                  f"{fmt(p['B'], 'p5')}/{fmt(p['B'])}/{fmt(p['B'], 'p95')} | {fmt(p['B_over_A'])} | "
                  f"{fmt(p['B_over_A_minus_floor'])} | {fmt(p.get('harmonic2_over_B', {}))} | "
                  f"{f(p.get('fit_residual_rms'), 2)} | {f(n.get('a'))} | {f(n.get('b'), 4)} | "
                  f"{'–' if not rng else f'{rng[0]:.0f}–{rng[1]:.0f}'} | {f(n.get('neighbour_correlation'), 2)} |")
    print("\n## Gray codes: noise against the white/black frames (sigma^2 = a + b I)\n")
    print("| set | a | b | read sigma | levels | neighbour corr |")
    print("|---|---|---|---|---|---|")
    for name, r in res.items():
        g = r.get("gray_noise")
        if not g or g.get("a") is None:
            continue
        print(f"| {name} | {g['a']:.3f} | {g['b']:.4f} | {g['read_noise_sigma']:.3f} | "
              f"{g['range'][0]:.0f}–{g['range'][1]:.0f} | {f(g.get('neighbour_correlation'), 2)} |")
    print("\n## Noise variance by level (grey levels^2), per set\n")
    for name, r in res.items():
        fits = [(f"{p['periods']:g} periods", p["noise"]) for p in r.get("phase", []) if "noise" in p]
        if r.get("gray_noise", {}).get("bins"):
            fits.append(("Gray vs white/black", r["gray_noise"]))
        for what, n in fits:
            cells = ", ".join(f"{b['level']:.0f}: {b['var']:.3f}" for b in n["bins"])
            print(f"- {name}, {what}: {cells}")
    print("\n## Saturation and black level (grey levels)\n")
    print("| set | frames | at 0 | at full scale | p0.1 | p1 (floor) | p5 | median | black frame p50 / p99 |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name, r in res.items():
        lv = r["levels"]
        bf = (f"{lv['black_frame_median']:.1f} / {lv['black_frame_p99']:.1f}"
              if "black_frame_median" in lv else "–")
        print(f"| {name} | {lv['frames']} | {100 * lv['share_at_0']:.3f} % | "
              f"{100 * lv['share_at_full_scale']:.3f} % | {lv['p0_1']:.1f} | {lv['p1']:.1f} | "
              f"{lv['p5']:.1f} | {lv['median']:.1f} | {bf} |")


def selftest():
    """The estimators on synthetic frames with known truth: a 4-step phase shift through a
    linear and a gamma-2.2 projector (harmonics) on a surface with albedo steps and turning
    fringes, noise var = 0.5 + 0.05 I, rounded to 8 bits; a Gray-code pair set with a white and
    a black frame, the same noise and a stray light that changes with the pattern; board edges
    blurred by a Gaussian of sigma 1.3 px (1.33 px with the pixel's own width)."""
    rng = np.random.default_rng(7)
    H, W = 512, 640
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float64)
    # a reflectance that grows down the image (so the levels span 30-120) times squares
    albedo = (0.1 + 0.85 * yy / H) * (0.6 + 0.4 * ((xx // 40 + yy // 40) % 2))
    a_true, b_true = 0.5, 0.05

    def expose(light):
        v = light + rng.normal(size=light.shape) * np.sqrt(a_true + b_true * light)
        return np.clip(np.rint(v), 0, 255)

    # fringes of 23 px, turning slowly across the rows (a curved surface)
    phi = 2 * math.pi * xx / 23.0 + 0.002 * yy**1.5
    for gamma in (1.0, 2.2):
        frames = [expose(20 + 200 * albedo * (0.5 + 0.5 * np.cos(phi - k * math.pi / 2)) ** gamma)
                  for k in range(4)]
        ph = phase_stats(frames, 4, 1, 0.0, "selftest phase")
        n = ph["noise"]
        print(f"phase, projector gamma {gamma}: a {n['a']:.3f} (true {a_true} + 1/12 = "
              f"{a_true + QUANTISATION:.3f}), b {n['b']:.4f} (true {b_true}); B2/B "
              f"{ph['harmonic2_over_B']['p50']:.3f}; the raw residual RMS {ph['fit_residual_rms']:.2f}")
    pairs = []
    for k in range(6):
        stripes = ((xx // (64 >> k)) % 2).astype(bool)
        stray = 3 + 4 * k * yy / H
        lit = 10 + 180 * albedo
        pairs.append((expose(np.where(stripes, lit, 10) + stray), expose(np.where(stripes, 10, lit) + stray)))
    white, black = expose(10 + 180 * albedo), expose(np.full((H, W), 10.0))
    g = gray_noise([("column", pairs)], white, black)
    print(f"gray:  a {g['a']:.3f} (true {a_true + QUANTISATION:.3f}), b {g['b']:.4f} (true {b_true})")
    yy, xx = yy[:256, :320], xx[:256, :320]
    sq = 40.0
    sharp = ((np.floor((xx - 20.5) / sq) + np.floor((yy - 20.5) / sq)) % 2 == 0)
    board = np.where((xx > 20) & (xx < 300) & (yy > 20) & (yy < 236) & sharp, 230.0, 30.0)
    board = ndimage.gaussian_filter(board, 1.3)
    tmp = Path(os.environ.get("TMPDIR", "/tmp")) / "capture_stats_selftest.png"
    cv2.imwrite(str(tmp), np.clip(np.rint(board + rng.normal(size=board.shape)), 0, 255).astype(np.uint8))
    e = edge_spread([tmp], 6, 4)
    print(f"edges: sigma {e['sigma_px']['p50']:.3f} px (true 1.33), {e['sigma_px']['n']} edges")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--real", action="store_true", help="all real sets under SL_DATA / SL_DATA_EXTRA")
    ap.add_argument("--sim", action="append", default=[], help="an `slscan simulate` output folder")
    ap.add_argument("--manifest", action="append", default=[],
                    help="MANIFEST.json[=FRAMES_DIR]: any sl-capture set")
    ap.add_argument("--boards", action="append", default=[],
                    help="COLSxROWS=DIR_OR_GLOB: board images (edge spread and levels)")
    ap.add_argument("--json", help="write every figure (with its method) here")
    ap.add_argument("--selftest", action="store_true", help="the estimators on synthetic truth")
    ap.add_argument("--per-bit", action="store_true", help="also print every Gray bit's figures")
    args = ap.parse_args()
    if args.selftest:
        selftest()
        return
    res = {}
    if args.real:
        res.update(real_sets())
    for s in args.sim:
        res.update(sim_sets(s))
    for m in args.manifest:
        path, _, frames = m.partition("=")
        res[f"manifest {path}"] = manifest_set(Path(path), frames_dir=frames or None)
    for b in args.boards:
        size, _, where = b.partition("=")
        cols, rows = (int(v) for v in size.lower().split("x"))
        files = sorted(Path(where).glob("*")) if Path(where).is_dir() else sorted(map(Path, glob.glob(where)))
        files = [f for f in files if f.suffix.lower() in (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".pgm")]
        res[f"boards {where}"] = {"kind": "board", "board": size, "edge_spread": edge_spread(files, cols, rows),
                                  "levels": levels(files)}
    if not res:
        ap.error("nothing to measure: give --real, --sim, --manifest or --boards")
    print_tables(res, args.per_bit)
    if args.json:
        Path(args.json).write_text(json.dumps(res, indent=1))
        print(f"\nwritten {args.json}", file=sys.stderr)


if __name__ == "__main__":
    main()
