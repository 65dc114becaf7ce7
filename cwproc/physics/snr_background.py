"""SNR correction of Halo Stream Line data with the instrument's background files.

The Stream Line reports the intensity I = SNR + 1 = P / B_m(r), the received power P of
a gate divided by the background B_m(r) it measured without a pulse (the hour's
``Background_*.txt``). B_m is noisy from gate to gate (vertical stripes in I) and its
level drifts, so I of signal-free gates is not 1 and a fixed SNR threshold keeps noise or
drops weak signal. The correction has two steps:

1. **background shape** (Vakkari et al. (2019), for firmware that writes
   background files; Manninen et al. (2016)): replace the measured B_m(r) by a
   smooth fit B_f(r), I_b = I B_m / B_f  (:func:`fit_background_shape`,
   :func:`reweight_intensity`);
2. **noise floor** (Manninen et al. (2016)): fit a straight
   line F(r) = a + b r to I_b of the signal-free gates of each ray and divide by it, so
   that signal-free gates have SNR = 0 on average: SNR_c = I_b / F - 1
   (:func:`signal_free_gates`, :func:`fit_noise_floor`).

All functions are pure numpy. Arrays are ``(ray, range)`` unless stated; ranges in m.
"""

from __future__ import annotations

import numpy as np

#: gates nearer than this (m) are left out of every fit: the outgoing pulse and the
#: telescope's near-field leak into them (3 pulse lengths, as in doppy)
MIN_FIT_RANGE_M = 90.0
#: scaled-MAD threshold of the iterative clipping of background peaks (detector artefacts)
PEAK_CLIP_MADS = 4.0
#: e-folding lengths (m) tried by the exponential-plus-line background model
_EFOLD_GRID_M = np.geomspace(30.0, 6000.0, 48)
#: the exponential model is chosen only when it lowers the residual sum of squares of the
#: straight line by at least this fraction (otherwise the line: fewer parameters)
EXP_MODEL_GAIN = 0.05
#: a gate is signal when its 5-gate running median exceeds the noise level by this many
#: standard errors of a 5-gate median (noise sd from the scaled MAD of the ray)
SIGNAL_SIGMAS = 3.0
#: signal gates are widened by this many gates each way (weak edges of aerosol layers)
SIGNAL_DILATION_GATES = 2
#: fewest signal-free gates for a noise-floor fit of a ray
MIN_NOISE_GATES = 10
#: largest |F - 1| of an accepted noise floor. The floors of the real files are within
#: 0.0009 of 1 (docs/streamline-background.md); a "floor" beyond 0.005 (below the 0.008
#: SNR screen) is signal that filled the ray (a short-range VAD inside the boundary
#: layer), and dividing by it would erase the signal, so such rays keep I_b - 1
MAX_FLOOR_OFFSET = 0.005


def _robust_sd(x: np.ndarray, axis: int | None = None) -> np.ndarray:
    """1.4826 x median absolute deviation (the sd of Gaussian noise)."""
    med = np.nanmedian(x, axis=axis, keepdims=True)
    return 1.4826 * np.nanmedian(np.abs(x - med), axis=axis)


def _line_design(range_m: np.ndarray) -> np.ndarray:
    return np.column_stack([np.ones_like(range_m), range_m])


def fit_background_shape(
    background: np.ndarray, range_m: np.ndarray, *, min_range_m: float = MIN_FIT_RANGE_M
) -> tuple[np.ndarray, str]:
    """Smooth fit B_f(r) of a measured background profile B_m(r).

    Vakkari et al. (2019): the background of newer Stream Line firmware is
    smooth in range apart from gate-to-gate noise, with (in some instruments) an
    exponential rise near the lidar. Two models are fitted by least squares to the gates
    beyond ``min_range_m`` after iterative clipping of peaks (> 4 scaled MADs):

    * line: B = c0 + c1 r;
    * exponential plus line: B = c0 + c1 r + c2 exp(-r / L), L on a log grid 30-6000 m
      (linear in c0..c2 for each L).

    The exponential model is used when it lowers the residual sum of squares by at least
    ``EXP_MODEL_GAIN`` (5 %).

    Parameters
    ----------
    background : numpy.ndarray
        Measured background per gate, shape ``(range,)`` (detector counts).
    range_m : numpy.ndarray
        Range of each gate centre (m), shape ``(range,)``.
    min_range_m : float
        Gates nearer than this are not fitted (the fit is still evaluated there).

    Returns
    -------
    fit : numpy.ndarray
        B_f(r), shape ``(range,)``, same units as ``background``.
    model : str
        ``"line"`` or ``"exponential+line"``.

    Raises
    ------
    ValueError
        Fewer than 4 gates to fit, or the fit is not positive everywhere.
    """
    b = np.asarray(background, dtype=float)
    r = np.asarray(range_m, dtype=float)
    scale = float(np.median(b[r > min_range_m])) if np.any(r > min_range_m) else 0.0
    use = (r > min_range_m) & np.isfinite(b)
    if use.sum() < 4 or not scale > 0:
        raise ValueError(f"background: {int(use.sum())} gates beyond {min_range_m:g} m to fit")
    y = b / scale
    design = _line_design(r / 1000.0)
    for _ in range(3):  # clip peaks about the line
        coef, *_ = np.linalg.lstsq(design[use], y[use], rcond=None)
        resid = y - design @ coef
        sd = float(_robust_sd(resid[use]))
        keep = use & (np.abs(resid) <= PEAK_CLIP_MADS * sd) if sd > 0 else use
        if keep.sum() < 4 or np.array_equal(keep, use):
            break
        use = keep
    line = design @ coef
    rss_line = float(np.sum((y - line)[use] ** 2))
    best, rss_best = line, rss_line
    for efold in _EFOLD_GRID_M:
        d3 = np.column_stack([design, np.exp(-r / efold)])
        c3, *_ = np.linalg.lstsq(d3[use], y[use], rcond=None)
        model = d3 @ c3
        rss = float(np.sum((y - model)[use] ** 2))
        if rss < rss_best:
            best, rss_best = model, rss
    chosen = "line"
    if rss_line > 0 and rss_best <= (1.0 - EXP_MODEL_GAIN) * rss_line:
        chosen = "exponential+line"
    else:
        best = line
    fit = best * scale
    if not np.all(fit > 0):
        raise ValueError("background: fitted background is not positive at every gate")
    return fit, chosen


def reweight_intensity(
    intensity: np.ndarray, measured: np.ndarray, fitted: np.ndarray
) -> np.ndarray:
    """I_b = I B_m / B_f: the intensity relative to the smooth background (step 1).

    Vakkari et al. (2019): I = P / B_m, so I B_m / B_f = P / B_f.
    ``measured`` and ``fitted`` broadcast against ``intensity`` (e.g. ``(ray, range)``).
    """
    return np.asarray(intensity, dtype=float) * (np.asarray(measured) / np.asarray(fitted))


def signal_free_gates(
    intensity: np.ndarray, range_m: np.ndarray, *, min_range_m: float = MIN_FIT_RANGE_M
) -> np.ndarray:
    """Gates holding only noise (True), per ray, from the intensity I_b.

    Manninen et al. (2016), fit the noise floor to the cloud- and aerosol-free
    gates. Here a gate is signal when the 5-gate running median along range of its ray
    exceeds the ray's median by ``SIGNAL_SIGMAS`` standard errors of a 5-gate median of
    Gaussian noise (noise sd: scaled MAD of the ray; standard error of a median of n:
    1.2533 sd / sqrt(n)), or when the gate alone exceeds it by 5 noise sd; signal gates
    are widened by ``SIGNAL_DILATION_GATES`` gates each way. Gates nearer than
    ``min_range_m`` and non-finite gates are never signal-free.

    Returns
    -------
    numpy.ndarray of bool, shape of ``intensity``.
    """
    from scipy import ndimage  # here: 0.1-0.2 s of imports only a corrected day needs

    i = np.atleast_2d(np.asarray(intensity, dtype=float))
    level = np.nanmedian(i, axis=1, keepdims=True)
    sd = _robust_sd(i, axis=1)[:, None]
    smooth = ndimage.median_filter(i, size=(1, 5), mode="nearest")
    signal = (smooth - level > SIGNAL_SIGMAS * 1.2533 * sd / np.sqrt(5.0)) | (i - level > 5.0 * sd)
    if SIGNAL_DILATION_GATES > 0:
        signal = ndimage.binary_dilation(
            signal, structure=np.ones((1, 2 * SIGNAL_DILATION_GATES + 1), bool)
        )
    near = np.asarray(range_m, dtype=float)[None, :] <= min_range_m
    return ~signal & ~near & np.isfinite(i)


def fit_noise_floor(
    intensity: np.ndarray, range_m: np.ndarray, noise: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Noise floor F(r) = a + b r of each ray from its signal-free gates (step 2).

    Manninen et al. (2016): the intensity of signal-free gates is fitted with a
    straight line in range, and the intensity divided by it. Least squares per ray
    (normal equations, vectorised over rays).

    Parameters
    ----------
    intensity : numpy.ndarray
        I_b, shape ``(ray, range)``.
    range_m : numpy.ndarray
        Gate ranges (m), shape ``(range,)``.
    noise : numpy.ndarray of bool
        Signal-free gates (:func:`signal_free_gates`), shape ``(ray, range)``.

    Returns
    -------
    floor : numpy.ndarray
        F, shape ``(ray, range)``; NaN for rays with fewer than ``MIN_NOISE_GATES``
        signal-free gates.
    coefficients : numpy.ndarray
        ``(ray, 2)``: a (dimensionless) and b (m-1).
    """
    i = np.atleast_2d(np.asarray(intensity, dtype=float))
    r = np.asarray(range_m, dtype=float)
    w = np.asarray(noise, dtype=bool) & np.isfinite(i)
    iz = np.where(w, i, 0.0)
    n = w.sum(axis=1).astype(float)
    sr = (w * r).sum(axis=1)
    srr = (w * r * r).sum(axis=1)
    si = iz.sum(axis=1)
    sri = (iz * r).sum(axis=1)
    det = n * srr - sr * sr
    ok = (n >= MIN_NOISE_GATES) & (det > 0)
    with np.errstate(invalid="ignore", divide="ignore"):
        b = np.where(ok, (n * sri - sr * si) / det, np.nan)
        a = np.where(ok, (si - b * sr) / n, np.nan)
    floor = a[:, None] + b[:, None] * r[None, :]
    return floor, np.column_stack([a, b])


def plausible_floor(floor: np.ndarray, noise: np.ndarray) -> np.ndarray:
    """Rays whose fitted floor stays within ``MAX_FLOOR_OFFSET`` of 1 over their
    signal-free gates (bool, shape ``(ray,)``); see :data:`MAX_FLOOR_OFFSET`."""
    off = np.where(noise, np.abs(floor - 1.0), 0.0)
    return np.isfinite(floor).all(axis=1) & (off.max(axis=1) <= MAX_FLOOR_OFFSET)


def corrected_snr(
    intensity: np.ndarray,
    range_m: np.ndarray,
    measured: np.ndarray,
    fitted: np.ndarray,
    *,
    min_range_m: float = MIN_FIT_RANGE_M,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """SNR after both steps: SNR_c = (I B_m / B_f) / F - 1.

    Manninen et al. (2016); Vakkari et al. (2019).

    Parameters
    ----------
    intensity : numpy.ndarray
        I = SNR + 1 as the instrument gave it, ``(ray, range)``.
    range_m : numpy.ndarray
        ``(range,)`` (m).
    measured, fitted : numpy.ndarray
        B_m and B_f of each ray, ``(ray, range)`` or ``(range,)``.
    min_range_m : float
        Gates nearer than this are not used in the noise-floor fit.

    Returns
    -------
    snr : numpy.ndarray
        Corrected SNR ``(ray, range)``; rays whose noise floor cannot be fitted (fewer
        than ``MIN_NOISE_GATES`` signal-free gates, or a floor farther than
        ``MAX_FLOOR_OFFSET`` from 1) keep the background-reweighted SNR I_b - 1; gates
        nearer than ``min_range_m`` keep the instrument's I - 1 (the fits leave them
        out: the background there, e.g. 0.04 of the far value at 24 m in the Eriswil
        file, is not the extrapolated fit).
    floor : numpy.ndarray
        F ``(ray, range)`` (NaN where not fitted).
    noise : numpy.ndarray of bool
        The signal-free gates used.
    """
    ib = np.atleast_2d(reweight_intensity(intensity, measured, fitted))
    noise = signal_free_gates(ib, range_m, min_range_m=min_range_m)
    floor, _ = fit_noise_floor(ib, range_m, noise)
    floor[~plausible_floor(floor, noise)] = np.nan
    snr = np.where(np.isfinite(floor), ib / floor - 1.0, ib - 1.0)
    near = np.asarray(range_m, dtype=float) <= min_range_m
    snr[:, near] = np.atleast_2d(intensity)[:, near] - 1.0  # outside the fits: not corrected
    return snr, floor, noise
