"""The predicted noise as a prior, calibrated on the day's data (stage ``epsilon``).

The noise term ``2 sigma_e^2`` of Smalikho (2020), eq. 4 is the intercept of the least
squares of ``D_L``; the SNR gives a prediction of it (Pearson et al. (2009), eq. 3,
:func:`cwproc.physics.noise.velocity_noise_std`) whose absolute level rests on assumed
settings (the signal's spectral width) and can be off by a factor. The data decide:

1. every cell is fitted with the prediction as a prior
   (:func:`cwproc.physics.structure_fit.fit_structure_function`): the intercept is kept
   where it is precise or where it contradicts the prediction (both uncertainties),
   the prediction is used elsewhere (flag 32);
2. the free intercepts of all cells of the instrument and day
   (:func:`cell_intercepts`) give the factor ``k`` that the SNR prediction is off by,
   with its standard error (:func:`cwproc.physics.noise.noise_calibration`);
3. where ``k`` differs from 1 by more than :data:`CALIBRATION_SIGNIFICANT` standard
   errors (statistical and, :data:`CALIBRATION_MODEL_REL`, of the model's structure
   function, in quadrature; and by more than :data:`CALIBRATION_RELEVANT`), explains the cells
   (:data:`CALIBRATION_MAX_DISPERSION`), the day holds at least
   :data:`CALIBRATION_MIN_BLOCKS` blocks, ``k`` is known to a relative standard error of
   :data:`CALIBRATION_MAX_REL_SE` and some cells took the prediction, the cells
   are fitted again with the prediction times ``k`` and the prior's relative error of
   ``2 sigma_e^2`` from that of ``k`` (:func:`calibrated_prior_rel_se`).

``noise_std_calibration`` of the product holds ``k`` and its standard error
(:func:`add_calibration`).
"""

from __future__ import annotations

import math

import numpy as np
import xarray as xr

from cwproc.physics.noise import noise_calibration
from cwproc.physics.structure_fit import (
    MIN_NOISE_LAGS,
    NOISE_PRIOR_REL_SE,
    free_intercept,
    pooled_covariance,
    weighted_intercept,
)
from cwproc.stages.epsilon.cells import Cells
from cwproc.stages.epsilon.flags import FLAG_NOISE_PREDICTED
from cwproc.stages.epsilon.records import FitSetup

__all__ = [
    "NOISE_PRIOR_REL_SE",
    "add_calibration",
    "calibrated_prior_rel_se",
    "calibration_applies",
    "cell_intercepts",
    "day_calibration",
]

#: the calibration is applied where it differs from 1 by more than this many standard errors
CALIBRATION_SIGNIFICANT = 2.0
#: ... and by more than this share (a smaller one moves eps by well under 1 %)
CALIBRATION_RELEVANT = 0.05
#: ... and only when learnt from at least this many blocks: the cells of one block share
#: its turbulence across heights, so a few blocks' median is not the instrument's (on the
#: two blocks of the shipped sample it read k = 0.46 +- 0.24 where the truth is 1.18)
CALIBRATION_MIN_BLOCKS = 10
#: ... and only when ``k`` is known to this relative standard error: where the free
#: intercepts are imprecise (24-ray step-stare scans, 15 deg between rays, mu 1: k read
#: 3.6 +- 0.7 where the truth is 1) their median carries the model's shape at the
#: first lags more than the noise
CALIBRATION_MAX_REL_SE = 0.1
#: ... and only where one factor explains the cells: the robust standard deviation of
#: their intercepts about ``k^2`` in units of their errors at most this (about 1 on
#: exact statistics, where the prediction is off by one factor; a day whose prediction
#: is off by a factor varying from cell to cell has no one calibration)
CALIBRATION_MAX_DISPERSION = 3.0
#: relative error of the model's structure function that the intercept of a cell carries
#: whatever the number of cells (systematic, not averaged away): the swept-ray tables'
#: ``D(l)`` were 1.2-1.6 % off the reference at mu 3 (72 rays,
#: benchmarks/bench_reference_72ray.py; 0.05 % off the exact generator since the outer
#: scale's difference takes the sweep kernel, issue 29) and the step-stare dwell tables
#: are up to 2.4 % off; at
#: mu 1 a 72-ray day with sigma_e = 0.05 m s-1 (``2 sigma_e^2`` 3 % of ``D(1)``) read
#: ``k`` = 1.24 from intercepts moved by 1.3 % of ``D(1)`` and applied it
CALIBRATION_MODEL_REL = 0.02
#: least relative standard error of a calibrated ``2 sigma_e^2`` of one block: the
#: block's SNR varies about the day's, and the calibration is one factor for all SNRs
CALIBRATED_PRIOR_FLOOR = 0.1


def cell_intercepts(
    cells: Cells,
    a2: np.ndarray,
    valid: np.ndarray,
    setup: FitSetup,
    predicted: np.ndarray,
    skip: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(intercept, standard error, predicted sigma_e, D at the first lag)`` of the cells.

    The cells that can calibrate the prediction; the fourth array, the cell's structure
    function at its first lag (m2 s-2), scales the model's systematic error of the
    intercept (:data:`CALIBRATION_MODEL_REL`, :func:`day_calibration`).

    The free intercept of Smalikho (2020), eq. 4 with the cell's ``A_2`` (m2 s-2) and the
    uncalibrated prediction ``predicted`` (m s-1); NaN where the fit has fewer than
    :data:`~cwproc.physics.structure_fit.MIN_NOISE_LAGS` lags, no covariance of D, or
    ``skip`` (flagged bad, exact cw cells). Where every lag is valid and the height has
    enough such blocks, the intercept of the generalised least squares with the
    covariance of D pooled over the height's blocks
    (:func:`cwproc.physics.structure_fit.weighted_intercept`,
    :func:`~cwproc.physics.structure_fit.pooled_covariance`); elsewhere that of equal
    weights (:func:`cwproc.physics.structure_fit.free_intercept`). The equal weights
    measured ``2 sigma_e^2`` to 0.8-1.25 of itself per block on exact 72-ray statistics
    (100 blocks, mu 0 and 1), so that a day of 100 cells read ``k`` to 6-7 % and, with the
    prediction x1.5 too high, 1.127 of the truth at mu 1; the pooled weights halve that
    scatter. Not the detectability of the fit's decision
    (the prediction, which may be off, against the smallest D): the calibration's own
    precision rule (:func:`cwproc.physics.noise.noise_calibration`) selects the cells.
    """
    d_cov = setup.d_cov
    b, se, n = free_intercept(cells.d, a2, valid, d_cov)
    if d_cov is not None and cells.d.ndim == 3:
        every = np.all(valid & np.isfinite(cells.d) & (cells.d > 0) & np.isfinite(a2), axis=-1)
        usable = every & ~skip & (n >= MIN_NOISE_LAGS)
        weight = pooled_covariance(cells.d, d_cov, usable)  # (height, lag, lag)
        b_w, se_w = weighted_intercept(cells.d, a2, weight[None], weight[None])
        use = usable & np.isfinite(b_w) & np.isfinite(se_w)
        b, se = np.where(use, b_w, b), np.where(use, se_w, se)
    keep = (n >= MIN_NOISE_LAGS) & ~skip
    nan = np.full(b.shape, np.nan)
    first = np.where(valid[..., 0] & np.isfinite(cells.d[..., 0]), cells.d[..., 0], np.nan)
    return (
        np.where(keep, b, nan),
        np.where(keep, se, nan),
        np.where(keep, predicted, nan),
        np.where(keep, first, nan),
    )


def day_calibration(intercepts: list[tuple]) -> tuple[float, float, int, float, float]:
    """``(k, SE(k), cells, dispersion, model SE(k))`` over all groups of blocks.

    :func:`cwproc.physics.noise.noise_calibration` of the cells of all groups, and the
    robust standard deviation (1.4826 times the median absolute value) of
    ``z = (b - k^2 2 sigma_pred^2) / s_b``: about 1 where one factor ``k`` explains every
    cell's intercept within its error, larger where the prediction's error varies from
    cell to cell (:func:`calibration_applies`). The model SE of ``k``: the systematic
    error :data:`CALIBRATION_MODEL_REL` times the median first-lag ``D`` of the cells
    (:func:`cell_intercepts`, all cells share it, so it does not average away) over the
    median intercept ``b``, as ``SE(k) = k SE(b) / (2 b)``.
    """
    if not intercepts:
        return math.nan, math.nan, 0, math.nan, math.nan
    b, se, pred = (np.concatenate([np.ravel(p[i]) for p in intercepts]) for i in range(3))
    k, se_k, n = noise_calibration(b, se, pred)
    with np.errstate(invalid="ignore", divide="ignore"):
        z = (b - k**2 * 2.0 * pred**2) / se
    z = z[np.isfinite(z)]
    dispersion = float(1.4826 * np.median(np.abs(z))) if z.size else math.nan
    model_se = 0.0  # cells given without their first-lag D: no model error known
    if all(len(p) > 3 for p in intercepts):
        first = np.concatenate([np.ravel(p[3]) for p in intercepts])
        ok = np.isfinite(first) & np.isfinite(b) & np.isfinite(se)
        b_mid = float(np.median(b[ok])) if ok.any() else math.nan
        if ok.any() and b_mid > 0:
            model_se = k * CALIBRATION_MODEL_REL * float(np.median(first[ok])) / (2.0 * b_mid)
    return k, se_k, n, dispersion, model_se


def calibration_applies(calibration: tuple, products: list[xr.Dataset]) -> bool:
    """Whether the cells are fitted again with the calibrated prediction (module doc, 3).

    Not with fewer than :data:`CALIBRATION_MIN_BLOCKS` blocks in ``products``: ``k`` is
    then reported, not applied; nor where ``k`` is within
    :data:`CALIBRATION_SIGNIFICANT` times its statistical and model errors (the fifth
    item of :func:`day_calibration`, in quadrature) of 1; nor where one factor does not
    explain the cells (``dispersion``, the fourth item of :func:`day_calibration`, above
    :data:`CALIBRATION_MAX_DISPERSION`).
    """
    k, se_k = calibration[0], calibration[1]
    if not (math.isfinite(k) and math.isfinite(se_k)):
        return False
    if len(calibration) > 3 and not calibration[3] <= CALIBRATION_MAX_DISPERSION:
        return False
    if sum(int(p.sizes.get("time", 0)) for p in products) < CALIBRATION_MIN_BLOCKS:
        return False
    if se_k > CALIBRATION_MAX_REL_SE * k:
        return False
    # significant against the statistical and the model's systematic error together
    model_se = calibration[4] if len(calibration) > 4 else 0.0
    total = math.hypot(se_k, model_se) if math.isfinite(model_se) else math.inf
    if abs(k - 1.0) <= max(CALIBRATION_SIGNIFICANT * total, CALIBRATION_RELEVANT):
        return False
    return any(
        bool(np.any((p["turbulence_flag"].values.astype(int) & FLAG_NOISE_PREDICTED) > 0))
        for p in products
    )


def calibrated_prior_rel_se(calibration: tuple) -> float:
    """Relative standard error of a calibrated ``2 sigma_e^2``: ``2 SE(k) / k``, at least
    :data:`CALIBRATED_PRIOR_FLOOR`."""
    k, se_k = calibration[0], calibration[1]
    return max(2.0 * se_k / k, CALIBRATED_PRIOR_FLOOR)


def add_calibration(out: xr.Dataset, calibration: tuple, applied: bool) -> None:
    """``noise_std_calibration`` in the product (in place), its standard error an attribute.

    One scalar: a separate standard-error variable would be one more variable without a
    CF standard name (the ACDD score of the turbulence product counts them).
    """
    k, se_k, n = calibration[:3]
    out["noise_std_calibration"] = ((), float(k))
    out["noise_std_calibration"].attrs.update(
        standard_error=float(se_k),
        model_standard_error=float(calibration[4]) if len(calibration) > 4 else float("nan"),
        cells=int(n),
        applied=int(applied),
        method="median over the cells of sigma_e^2 fitted / predicted "
        "(cwproc.physics.noise.noise_calibration); applied to the prediction where the "
        f"data do not determine sigma_e when it differs from 1 by more than "
        f"{CALIBRATION_SIGNIFICANT:g} standard errors and {CALIBRATION_RELEVANT:g}, "
        f"learnt from at least {CALIBRATION_MIN_BLOCKS} blocks to a relative standard "
        f"error of at most {CALIBRATION_MAX_REL_SE:g}",
    )
