"""Stage ``qc``: screen radial velocities by SNR and robust outlier tests, never drop.

``screen_radial_velocity`` adds ``qc_flag_radial(ray, range)`` (int8, bits combine):

* 0 good;
* 1 SNR below ``snr_min`` (or SNR not finite);
* 2 robust outlier: ``|r - median(r)| > outlier_threshold * 1.4826 MAD(r)``, where ``r``
  are the residuals of every SNR-good ray of one scan and gate about a VAD fit
  (Smalikho (2020), eq. 1; homodyne ``|V_r|`` model for cw data) computed without the
  rays flagged so far. The fit is repeated ``OUTLIER_PASSES`` times so that the first,
  outlier-contaminated fit does not decide; 1.4826 MAD is the standard deviation of
  Gaussian residuals. The scaled MAD is floored at
  ``max(MIN_SPREAD_M_S, velocity_resolution_m_s)`` so that noise-free or quantised data
  do not turn round-off into outliers. Only scan/gate groups with at least
  ``MIN_RAYS_FOR_OUTLIERS`` SNR-good rays are tested, those of fewer than ``FEW_RAYS``
  rays at ``FEW_RAYS_FACTOR`` times the threshold; rays outside conical scans
  (``scan < 0``) get no outlier test;
* 4 radial velocity not finite.

``radial_velocity`` and every other variable are left untouched.

Default thresholds (``cwproc.config.QCConfig``): ``snr_min = 0.008`` (-21 dB, linear
SNR = Halo intensity - 1), where the Stream Line's velocity estimates turn from
Gaussian scatter into uniformly distributed noise estimates: in the real vertical
stares of ``real_data/hpl`` (Eriswil, Warsaw, Hyytiala) the fraction of gates with
|V_r| > 3 m s-1 is 50 % at SNR 0.004-0.006, 6 % at 0.006-0.008 and 0 above 0.008.
``outlier_threshold = 4`` scaled MADs: 6e-5 of Gaussian residuals lie beyond 4 sigma,
but the MAD of 24 residuals scatters, so 0.2-0.4 % of good rays of a 24-ray scan are
flagged (``tests/stages/test_qc.py``), while noise estimates of +-6..20 m s-1 that pass
the SNR test are caught (> 97 % with a quarter of the rays contaminated).
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from cwproc.errors import CwprocError
from cwproc.io.scan_join import is_homodyne
from cwproc.metadata import described
from cwproc.physics.geometry import beam_unit_vector
from cwproc.physics.scan_layout import scan_layout
from cwproc.physics.vad_least_squares import (
    fit_least_absolute,
    fit_scans,
    group_linear_residuals,
    linear_start,
    ray_rows,
    row_residuals,
)
from cwproc.stages.scan_guard import require_distinct_scans
from cwproc.stages.vad import pointing, scan_chunks

FLAG_LOW_SNR = 1
FLAG_OUTLIER = 2
FLAG_NOT_FINITE = 4
#: scaled MAD of Gaussian data = 1.4826 MAD
MAD_TO_STD = 1.4826
#: fewest SNR-good rays of a scan/gate for the outlier test (3 unknowns + 3 dof)
MIN_RAYS_FOR_OUTLIERS = 6
#: groups of fewer rays than this (12-ray VADs; 24- and 36-ray scans are not affected)
#: take ``FEW_RAYS_FACTOR`` times the outlier threshold: the median and MAD of the
#: residuals of a 3-parameter VAD fit to so few rays scatter so much that at the
#: threshold 4 the test flagged 2.2-2.4 % of good 12-ray rays (exact Gaussian
#: statistics, mu 0 and 3; 24 rays: 0.3-0.4 %), the largest turbulent deviations, so
#: D_L and the variance of V'_L were 6 % low and the 12-ray eps 13-26 % low. At 6
#: (x1.5) 0.3-0.5 % of good rays are flagged and 87-89 % of noise estimates of
#: +-6-20 m s-1 in 3 % of the rays still caught (95-97 % at 4)
FEW_RAYS = 18
FEW_RAYS_FACTOR = 1.5
#: fit / flag passes of the outlier test
OUTLIER_PASSES = 3
#: floor of the scaled MAD (m s-1)
MIN_SPREAD_M_S = 0.01


def snr_flags(snr: np.ndarray, snr_min: float) -> np.ndarray:
    """``FLAG_LOW_SNR`` where ``snr < snr_min`` or the SNR is not finite (int8)."""
    with np.errstate(invalid="ignore"):
        low = ~(np.asarray(snr, dtype=float) >= snr_min)
    return np.where(low, np.int8(FLAG_LOW_SNR), np.int8(0))


def robust_outliers(
    residuals: np.ndarray, valid: np.ndarray, threshold: float, min_spread: float
) -> np.ndarray:
    """Outliers of residuals grouped along axis 1 by the median/MAD rule.

    Parameters
    ----------
    residuals : ndarray, shape (S, R, G)
        Residuals about a fit (m s-1).
    valid : ndarray of bool, shape (S, R, G)
        Entries that take part (others are never outliers).
    threshold : float
        Multiple of the scaled MAD beyond which an entry is an outlier.
    min_spread : float
        Floor of the scaled MAD (m s-1).

    Returns
    -------
    ndarray of bool, shape (S, R, G)
    """
    return _outliers(residuals, *tested_entries(valid), threshold, min_spread)


def tested_entries(valid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The entries the outlier test takes (``valid`` in groups of at least
    ``MIN_RAYS_FOR_OUTLIERS``) and their number per group: (S, R, G), (S, G)."""
    n = valid.sum(axis=1)
    enough = n >= MIN_RAYS_FOR_OUTLIERS
    return valid & enough[:, None, :], np.where(enough, n, 0)


def _outliers(
    residuals: np.ndarray,
    use: np.ndarray,
    n: np.ndarray,
    threshold: float,
    min_spread: float,
    axis: int = 1,
) -> np.ndarray:
    """:func:`robust_outliers` of the entries ``use`` (``n`` of them per group; the rays
    along ``axis``)."""
    centre = np.expand_dims(median_along_rays(residuals, use, n, axis), axis)
    deviation = np.abs(residuals - centre)
    mad = median_along_rays(deviation, use, n, axis)
    spread = np.maximum(MAD_TO_STD * mad, min_spread)
    limit = np.where(n < FEW_RAYS, FEW_RAYS_FACTOR * threshold, threshold) * spread
    return use & (deviation > np.expand_dims(limit, axis))


def median_along_rays(
    values: np.ndarray, use: np.ndarray, n: np.ndarray | None = None, axis: int = 1
) -> np.ndarray:
    """Median over ``axis`` of the entries where ``use`` is true (NaN for empty groups).

    Parameters
    ----------
    values : ndarray, shape (S, R, G)
        (or (S, G, R) with ``axis=-1``: rays contiguous, the faster sort)
    use : ndarray of bool, the shape of ``values``
    n : ndarray of int, shape (S, G), optional
        ``use.sum(axis=axis)`` when the caller holds it.
    axis : int, optional
        The axis of the rays.

    Returns
    -------
    ndarray, shape (S, G)
    """
    ordered = np.where(use, values, np.inf)
    ordered.sort(axis=axis)  # in place: no second (S, R, G) array
    n = use.sum(axis=axis) if n is None else n
    lo = np.take_along_axis(ordered, np.expand_dims(np.maximum((n - 1) // 2, 0), axis), axis)
    hi = np.take_along_axis(ordered, np.expand_dims(np.maximum(n // 2, 0), axis), axis)
    with np.errstate(invalid="ignore"):
        return np.where(n > 0, 0.5 * (lo + hi).squeeze(axis), np.nan)


@described(None)
def screen_radial_velocity(
    ds: xr.Dataset,
    *,
    snr_min: float = 0.008,
    outlier_threshold: float = 4.0,
    homodyne: bool | None = None,
) -> xr.Dataset:
    """Flag low-SNR, outlying and non-finite radial velocities (adds ``qc_flag_radial``).

    Parameters
    ----------
    ds : xarray.Dataset
        Scan dataset (``docs/DEVELOPING.md``). Without ``snr`` (e.g. cw data) the SNR
        test is skipped, and the attrs say so.
    snr_min : float, optional
        Minimum linear SNR (Halo intensity - 1).
    outlier_threshold : float, optional
        Outlier threshold in scaled MADs of the residuals of a robust VAD fit.
    homodyne : bool, optional
        The VAD model of the outlier test is ``|A beta|`` (homodyne detection). None:
        the ``homodyne`` attribute of ``ds`` (:func:`cwproc.io.scan_join.is_homodyne`).

    The defaults of the keyword arguments are those of the ``streamline`` preset
    (``[qc]`` of ``cwproc/configs/streamline.toml``).

    Returns
    -------
    xarray.Dataset
        ``ds`` with ``qc_flag_radial(ray, range)`` int8: 0 good, 1 low SNR, 2 outlier,
        4 not finite (bits combine). No value is changed or removed.

    Raises
    ------
    CwprocError
        No ``radial_velocity(ray, range)`` in the input.
    """
    require_distinct_scans(ds, stage="screen_radial_velocity")
    if "radial_velocity" not in ds or ds["radial_velocity"].dims != ("ray", "range"):
        raise CwprocError(
            "Screening needs a scan dataset with radial_velocity(ray, range); this input has none."
        )
    velocity = ds["radial_velocity"].values.astype(float, copy=False)  # not written to
    flag = np.where(np.isfinite(velocity), np.int8(0), np.int8(FLAG_NOT_FINITE))
    has_snr = "snr" in ds
    if has_snr:
        flag |= snr_flags(ds["snr"].values, snr_min)
    min_spread = max(MIN_SPREAD_M_S, float(ds.attrs.get("velocity_resolution_m_s", 0.0) or 0.0))
    homodyne = is_homodyne(ds) if homodyne is None else bool(homodyne)
    outlier = outlier_flags(
        ds,
        velocity,
        flag == 0,
        threshold=outlier_threshold,
        min_spread=min_spread,
        homodyne=homodyne,
    )
    np.bitwise_or(flag, np.int8(FLAG_OUTLIER), out=flag, where=outlier)
    out = ds.copy()
    out["qc_flag_radial"] = (
        ("ray", "range"),
        flag,
        {
            "method": (
                "SNR threshold; robust outliers |r - median(r)| > k * 1.4826 MAD(r) of the "
                f"residuals r about a VAD fit per scan and gate ({OUTLIER_PASSES} passes)"
                + ("; homodyne |V_r| model" if homodyne else "")
            ),
            "snr_min": float(snr_min) if has_snr else "not applied (no snr in the input)",
            "outlier_threshold": float(outlier_threshold),
            "min_spread_m_s": min_spread,
        },
    )
    return out


def outlier_flags(
    ds: xr.Dataset,
    velocity: np.ndarray,
    good: np.ndarray,
    *,
    threshold: float,
    min_spread: float,
    homodyne: bool,
) -> np.ndarray:
    """Robust outliers among the ``good`` (ray, range) entries of conical scans.

    Parameters
    ----------
    ds : xarray.Dataset
        Scan dataset (azimuth, elevation, scan).
    velocity : ndarray, shape (ray, range)
        Radial velocity (m s-1).
    good : ndarray of bool, shape (ray, range)
        Entries that passed the finiteness and SNR tests.
    threshold : float
        Multiple of the scaled MAD.
    min_spread : float
        Floor of the scaled MAD (m s-1).
    homodyne : bool
        Fit ``|A beta|`` to ``|V_r|`` (homodyne detection).

    Returns
    -------
    ndarray of bool, shape (ray, range)
    """
    outlier = np.zeros(velocity.shape, dtype=bool)
    if "scan" not in ds or "azimuth" not in ds or "elevation" not in ds:
        return outlier
    azimuth, elevation = pointing(ds)
    layout = scan_layout(ds["scan"].values, np.isfinite(azimuth) & np.isfinite(elevation))
    for rows in scan_chunks(layout, velocity.shape[1]):
        sub = layout.subset(rows)
        present = sub.present[:, :, None]
        base = sub.take(good) & present
        values = sub.take(velocity)
        design = beam_unit_vector(sub.take(azimuth), sub.take(elevation))
        use, n = tested_entries(base)  # the same in every pass
        if homodyne:
            _, residuals = fit_least_absolute(values, design, base, homodyne=True)
            flagged = _outliers(residuals, use, n, threshold, min_spread)
            flagged = _homodyne_passes(values, design, base, flagged, use, n, threshold, min_spread)
        else:
            ray_data = ray_rows(values, base)
            ok, beta, _ = linear_start(values, design, base, ray_data, residuals=False)
            # float32 rows of rays (contiguous): the iterations' data and the faster sorts
            ray_data = tuple(a.astype(np.float32) for a in ray_data)
            _, residuals = fit_least_absolute(
                values, design, base, homodyne=False, start=(ok, beta), rows=ray_data, as_rows=True
            )
            rays_last = use.transpose(0, 2, 1)
            flagged = _outliers(residuals, rays_last, n, threshold, min_spread, axis=-1)
            flagged = _linear_passes(
                values,
                design,
                base,
                flagged.transpose(0, 2, 1),
                use,
                n,
                threshold,
                min_spread,
                row_residuals(ray_data[0], design, beta),
            )
        index = sub.index[sub.present]
        outlier[index] = flagged[sub.present]
    return outlier


def _homodyne_passes(
    values: np.ndarray,
    design: np.ndarray,
    base: np.ndarray,
    flagged: np.ndarray,
    use: np.ndarray,
    n: np.ndarray,
    threshold: float,
    min_spread: float,
) -> np.ndarray:
    """The ``OUTLIER_PASSES`` fit / flag passes of homodyne data (``|A beta|`` refitted
    over every scan and gate: its Gauss-Newton iterations stop together)."""
    for _ in range(OUTLIER_PASSES):
        residuals = fit_scans(values, design, base & ~flagged, homodyne=True).residuals
        again = _outliers(residuals, use, n, threshold, min_spread)
        if np.array_equal(again, flagged):
            break  # the next pass would fit the same rays and flag the same again
        flagged = again
    return flagged


def _linear_passes(
    values: np.ndarray,
    design: np.ndarray,
    base: np.ndarray,
    flagged: np.ndarray,
    use: np.ndarray,
    n: np.ndarray,
    threshold: float,
    min_spread: float,
    residuals: np.ndarray,
) -> np.ndarray:
    """The ``OUTLIER_PASSES`` fit / flag passes of the linear VAD model; each refits only
    the (scan, gate) groups whose rays differ from those of their last fit.

    ``values``, ``base``, ``flagged`` and ``use`` are (S, R, G), ``n`` (S, G);
    ``residuals`` are those of the least-squares fit of every group on all its ``base``
    rays as rows of rays (S, G, R) (:func:`cwproc.physics.vad_least_squares.row_residuals`, float32
    or float64; overwritten), tested along their contiguous axis. The least-squares fit
    of a (scan, gate) group is its own (Smalikho (2020), eq. 1, per scan and gate), so a
    group with no flagged ray keeps these residuals in the first pass, and a group whose
    rays were flagged alike in the last two passes is fitted on the same rays again and
    is flagged as before. The first pass refits the groups with a ray flagged by the L1
    fit (about 75 of 2000 groups of a chunk of 20 scans) and tests every group; the
    later ones refit and test the groups whose flags the pass before changed (about 3).
    Each group is refitted alone (:func:`cwproc.physics.vad_least_squares.group_linear_residuals`):
    the flags are those of refitting and testing every group in every pass, up to the
    round-off of a sum taken in another order (and of float32 residuals).
    """
    todo = flagged.any(axis=1)  # groups fitted on other rays than their residuals'
    for number in range(OUTLIER_PASSES):
        scans, gates = np.nonzero(todo)
        if scans.size:
            residuals[scans, gates] = group_linear_residuals(
                values, design, base & ~flagged, scans, gates
            )
        if number == 0:
            rays_last = use.transpose(0, 2, 1)
            again = _outliers(residuals, rays_last, n, threshold, min_spread, axis=-1)
            again = again.transpose(0, 2, 1)
        else:
            again = flagged.copy()
            again[scans, :, gates] = _outliers(
                residuals[scans, gates],
                use[scans, :, gates],
                n[scans, gates],
                threshold,
                min_spread,
                axis=-1,
            )
        changed = np.any(again != flagged, axis=1)
        if not changed.any():
            break  # the next pass would fit the same rays and flag the same again
        flagged, todo = again, changed
    return flagged
