"""Stage ``vad``: the wind vector per scan and height from conical (VAD) scans.

For every 360 deg rotation (``scan >= 0``) and range gate, the least-squares fit of

.. math:: V_r(\\theta) = w \\sin\\phi + \\cos\\phi (u \\sin\\theta + v \\cos\\theta),

with ``theta`` the azimuth clockwise from north and ``phi`` the elevation of each ray
(Smalikho (2020), eq. 1 and eq. 8; Banakh et al. (1999), after eq. 23; the forward model
is :func:`cwproc.physics.geometry.radial_velocity`). Rays are grouped by scan
(:class:`ScanLayout`) and all scans and gates are solved at once by the batched fits of
:mod:`cwproc.physics.vad_least_squares`. Standard errors come from the residual variance and
``(A^T A)^-1``; their behaviour with the number of rays, a missing azimuth sector,
shear and tilt is the error theory of the VAD accuracy paper (Theoretical accuracy of
wind-vector reconstruction from lidar VAD scanning, sections 2-4;
:mod:`cwproc.physics.vad_errors`).

Homodyne cw lidars (ZephIR) measure only ``|V_r|``: the model becomes ``|A beta|``
(:func:`cwproc.physics.vad_least_squares.fit_homodyne`). ``beta`` and ``-beta`` fit equally well:
the 180 deg ambiguity is resolved by a reference direction (argument, a
``reference_direction`` variable of the scan dataset, or the ``reference_direction_deg``
attribute, in this order).
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import xarray as xr
from numpy.typing import NDArray

from cwproc.errors import CwprocError
from cwproc.io.scan_join import is_homodyne
from cwproc.metadata import described
from cwproc.physics.geometry import (
    beam_unit_vector,
    height_from_range,
    normalise_pointing,
    speed_and_direction,
)
from cwproc.physics.scan_layout import (
    ELEVATION_TOLERANCE_DEG,
    ScanLayout,
    scan_layout,
    select_conical_scans,
)
from cwproc.physics.vad_least_squares import fit_scans
from cwproc.references import VAD_WIND
from cwproc.stages.scan_guard import require_distinct_scans

#: budget of (scan x ray x gate) elements per chunk; bounds memory on long days
CHUNK_ELEMENTS = 4_000_000

#: the papers of the VAD fit (the ``vad_references`` attribute of the wind product)
REFERENCES = VAD_WIND

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


# --------------------------------------------------------------------------------------
# layout: rays -> (scan, ray in scan)
# --------------------------------------------------------------------------------------


def scan_chunks(layout: ScanLayout, n_gates: int) -> Iterator[slice]:
    """Contiguous blocks of scans whose padded arrays hold at most ``CHUNK_ELEMENTS``."""
    n_scan, max_rays = layout.index.shape
    per_scan = max(1, max_rays * max(n_gates, 1))
    step = max(1, CHUNK_ELEMENTS // per_scan)
    for start in range(0, n_scan, step):
        yield slice(start, min(start + step, n_scan))


# --------------------------------------------------------------------------------------
# derived quantities
# --------------------------------------------------------------------------------------


def speed_direction_errors(
    u: FloatArray, v: FloatArray, covariance: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Standard errors of speed and direction by first-order propagation.

    ``var(S) = (u^2 C_uu + v^2 C_vv + 2 u v C_uv) / S^2`` and
    ``var(D) = (v^2 C_uu + u^2 C_vv - 2 u v C_uv) / S^4`` (rad^2), S = hypot(u, v).

    Parameters
    ----------
    u, v : ndarray
        Wind components (m s-1).
    covariance : ndarray, shape (..., 3, 3)
        Covariance of (u, v, w) (m2 s-2).

    Returns
    -------
    (speed_error, direction_error) : (m s-1, deg)
    """
    cuu, cvv, cuv = covariance[..., 0, 0], covariance[..., 1, 1], covariance[..., 0, 1]
    s2 = u**2 + v**2
    with np.errstate(invalid="ignore", divide="ignore"):
        var_s = (u**2 * cuu + v**2 * cvv + 2 * u * v * cuv) / s2
        var_d = (v**2 * cuu + u**2 * cvv - 2 * u * v * cuv) / s2**2
    return np.sqrt(np.maximum(var_s, 0.0)), np.rad2deg(np.sqrt(np.maximum(var_d, 0.0)))


def azimuth_gap(azimuth_deg: FloatArray, valid: BoolArray) -> FloatArray:
    """Largest azimuth gap (deg) between the valid rays of each (scan, gate), wrapping 360.

    The gates whose every ray is valid (most of them) take the gap of their scan's
    rays, found once per scan; the others are sorted one by one (the same values).

    Parameters
    ----------
    azimuth_deg : ndarray, shape (S, R)
        Azimuths in [0, 360) (deg).
    valid : ndarray of bool, shape (S, R, G)

    Returns
    -------
    ndarray, shape (S, G)
        360 where fewer than two rays are valid.
    """
    full = valid.all(axis=1)
    out = np.empty(full.shape)
    out[...] = _sorted_gap(azimuth_deg, np.ones((*azimuth_deg.shape, 1), dtype=bool))
    scan, gate = np.nonzero(~full)
    if scan.size:
        out[scan, gate] = _sorted_gap(azimuth_deg[scan], valid[scan, :, gate][..., None])[:, 0]
    return out


def _sorted_gap(azimuth_deg: FloatArray, valid: BoolArray) -> FloatArray:
    """:func:`azimuth_gap` of every (scan, gate) by sorting its valid azimuths."""
    az = np.where(valid, azimuth_deg[:, :, None], np.nan)
    az = np.sort(az, axis=1)  # NaN last
    n = valid.sum(axis=1)
    inner = np.diff(az, axis=1)
    inner = np.where(np.isnan(inner), -np.inf, inner).max(axis=1, initial=-np.inf)
    first = az[:, 0, :]
    last = np.take_along_axis(az, np.maximum(n - 1, 0)[:, None, :], axis=1)[:, 0, :]
    gap = np.maximum(inner, first + 360.0 - last)
    return np.where(n >= 2, gap, 360.0)


def _circular_difference(a: FloatArray, b: FloatArray) -> FloatArray:
    """Smallest absolute angle between directions a and b (deg)."""
    return np.abs((np.asarray(a) - np.asarray(b) + 180.0) % 360.0 - 180.0)


def resolve_homodyne_ambiguity(beta: FloatArray, reference_deg: FloatArray) -> FloatArray:
    """Choose between ``beta`` and ``-beta``: the from-direction nearest the reference.

    Parameters
    ----------
    beta : ndarray, shape (S, G, 3)
        Fitted (u, v, w) with arbitrary overall sign.
    reference_deg : ndarray, shape (S,) or scalar
        Reference wind-from direction (deg from north).

    Returns
    -------
    ndarray, shape (S, G, 3)
    """
    _, direction = speed_and_direction(beta[..., 0], beta[..., 1])
    reference = np.broadcast_to(np.asarray(reference_deg, dtype=float), beta.shape[:1])
    flip = _circular_difference(direction, reference[:, None]) > 90.0
    return np.where(flip[..., None], -beta, beta)


# --------------------------------------------------------------------------------------
# the stage
# --------------------------------------------------------------------------------------


def pointing(ds: xr.Dataset) -> tuple[FloatArray, FloatArray]:
    """Azimuth in [0, 360) and elevation in [-90, 90] of every ray (deg)."""
    return normalise_pointing(ds["azimuth"].values, ds["elevation"].values)


def usable_mask(ds: xr.Dataset) -> BoolArray:
    """(ray, range) entries a fit may use: finite and, when screened, flag 0."""
    valid = np.isfinite(ds["radial_velocity"].values)
    if "qc_flag_radial" in ds:
        valid &= ds["qc_flag_radial"].values == 0
    return valid


def _require(ds: xr.Dataset, names: tuple[str, ...]) -> None:
    missing = [n for n in names if n not in ds.variables]
    if missing:
        raise CwprocError(
            "The VAD fit needs a scan dataset with "
            + ", ".join(names)
            + f"; this one lacks {', '.join(missing)}."
        )


def _reference_directions(
    ds: xr.Dataset, layout: ScanLayout, reference_direction_deg: float | None
) -> tuple[FloatArray, str]:
    """Per-scan reference wind-from direction for homodyne data, and how it was obtained."""
    n_scan = layout.scan_ids.size
    if reference_direction_deg is not None:
        return (
            np.full(n_scan, float(reference_direction_deg)),
            f"configured reference direction {float(reference_direction_deg):g} deg",
        )
    if "reference_direction" in ds and ds["reference_direction"].dims == ("ray",):
        rad = np.deg2rad(layout.take(ds["reference_direction"].values.astype(float)))
        mean = np.rad2deg(np.arctan2(np.nanmean(np.sin(rad), 1), np.nanmean(np.cos(rad), 1)))
        if np.all(np.isfinite(mean)):
            return mean % 360.0, "measured reference direction (variable reference_direction)"
    attr = ds.attrs.get("reference_direction_deg")
    if attr is not None and np.isfinite(float(attr)):
        return (
            np.full(n_scan, float(attr)),
            f"reference direction {float(attr):g} deg from the input attribute "
            "reference_direction_deg",
        )
    raise CwprocError(
        "Homodyne lidar data measure only |V_r|, so the wind direction is ambiguous by 180 "
        "degrees; set vad.reference_direction_deg in the configuration or provide a "
        "measured reference_direction (deg) in the input."
    )


def _mean_times(ds: xr.Dataset, layout: ScanLayout) -> np.ndarray:
    """Mean ray time of each scan, averaged from the scan's own earliest ray.

    Offsets from the scan's own origin keep the float sums small (exact to the
    nanosecond) and make the result independent of what else the dataset holds.
    """
    times = layout.take(ds["time"].values.astype("datetime64[ns]").astype(np.int64))
    good = layout.present & (times != np.iinfo(np.int64).min)
    t0 = np.where(good, times, np.iinfo(np.int64).max).min(axis=1)
    t0 = np.where(good.any(axis=1), t0, 0)
    offsets = np.where(good, times - t0[:, None], 0).astype(float)
    offsets[~good] = np.nan
    mean = np.nanmean(offsets, axis=1)
    return (t0 + np.round(mean).astype(np.int64)).astype("datetime64[ns]")


@described("wind")
def fit_vad(
    ds: xr.Dataset,
    *,
    min_rays: int = 6,
    max_gap_deg: float = 120.0,
    reference_direction_deg: float | None = None,
    max_residual_std: float = 3.0,
    homodyne: bool | None = None,
) -> xr.Dataset:
    """Wind vector per conical scan and height (Smalikho (2020), eq. 1).

    Parameters
    ----------
    ds : xarray.Dataset
        Scan dataset (``docs/DEVELOPING.md``), optionally screened by
        :func:`cwproc.stages.qc.screen_radial_velocity`; only entries with
        ``qc_flag_radial == 0`` (or, unscreened, finite ones) are used.
    min_rays : int, optional
        Fewest rays for a good fit (fewer: flag bit 1; fewer than 3: no fit).
    max_gap_deg : float, optional
        Largest azimuth gap between used rays (deg) before flag bit 2.
    reference_direction_deg : float, optional
        Homodyne data only: wind-from direction (deg from north) that resolves the
        180 deg ambiguity. When None, a ``reference_direction(ray)`` variable or the
        ``reference_direction_deg`` attribute of ``ds`` is used.
    max_residual_std : float, optional
        Residual standard deviation (m s-1) above which a fit is flagged bad (bit 4):
        3 m s-1 is far above the noise of good gates (< 0.5 m s-1) plus the turbulent
        scatter of a scan (~1 m s-1), and typical of noise gates or folded velocities.
    homodyne : bool, optional
        Fit ``|V_r| = |A beta|`` (homodyne detection). None: the ``homodyne`` attribute
        of ``ds`` (:func:`cwproc.io.scan_join.is_homodyne`).

    The defaults of the keyword arguments are those of the ``streamline`` preset
    (``[vad]`` of ``cwproc/configs/streamline.toml``).

    Returns
    -------
    xarray.Dataset
        The wind product: dims ``(time, height)``; ``qc_flag`` bits: 1 fewer than
        ``min_rays`` rays, 2 azimuth gap > ``max_gap_deg``, 4 bad fit (not determined:
        < 3 rays or ``cond(A^T A) > 1e8``; no residual degree of freedom, so no
        error estimate; residual std > ``max_residual_std``; homodyne iterations not
        converged).

    Raises
    ------
    CwprocError
        Missing variables, no conical scan, or homodyne data without any reference
        direction.
    """
    _check_scan_dataset(ds)
    azimuth, elevation = pointing(ds)
    layout, phi, scan_elevation, n_other = select_conical_scans(
        scan_layout(ds["scan"].values, np.isfinite(azimuth) & np.isfinite(elevation)),
        elevation,
    )
    homodyne = is_homodyne(ds) if homodyne is None else bool(homodyne)
    joined = _fit_scan_chunks(ds, layout, (azimuth, elevation), homodyne)
    beta = joined["beta"]
    attrs_resolution = "not applicable (heterodyne: signed radial velocities)"
    if homodyne:
        reference, attrs_resolution = _reference_directions(ds, layout, reference_direction_deg)
        beta = resolve_homodyne_ambiguity(beta, reference)
    return _wind_dataset(
        ds,
        layout,
        beta=beta,
        covariance=joined["cov"],
        n_rays=joined["n"],
        residual_std=joined["res"],
        fit_ok=joined["ok"],
        gap=joined["gap"],
        phi=phi,
        scan_elevation=scan_elevation,
        n_other=n_other,
        homodyne=homodyne,
        resolution=attrs_resolution,
        params={
            "min_rays": min_rays,
            "max_gap_deg": max_gap_deg,
            "max_residual_std": max_residual_std,
        },
    )


def _check_scan_dataset(ds: xr.Dataset) -> None:
    """Refuse a dataset the VAD fit cannot take (scan numbers that collide across files,
    missing variables, radial velocities not on ``(ray, range)``)."""
    require_distinct_scans(ds, stage="fit_vad")
    _require(ds, ("radial_velocity", "azimuth", "elevation", "scan", "time", "range"))
    if ds["radial_velocity"].dims != ("ray", "range"):
        raise CwprocError(
            "The VAD fit needs radial_velocity with dimensions (ray, range); this input has "
            f"{ds['radial_velocity'].dims}."
        )


def _fit_scan_chunks(
    ds: xr.Dataset,
    layout: ScanLayout,
    pointing_deg: tuple[FloatArray, FloatArray],
    homodyne: bool,
) -> dict[str, np.ndarray]:
    """The batched fits of the scans of ``layout`` (:func:`scan_chunks` at a time):
    ``beta`` (u, v, w), ``cov`` its covariance, ``n`` rays used, ``res`` residual std,
    ``ok`` determined and converged, ``gap`` the largest azimuth gap (deg), per scan and
    gate; ``pointing_deg``: the azimuth and elevation of every ray."""
    azimuth, elevation = pointing_deg
    velocity = ds["radial_velocity"].values.astype(float, copy=False)  # not written to
    valid_all = usable_mask(ds)
    parts: list[dict[str, np.ndarray]] = []
    for rows in scan_chunks(layout, velocity.shape[1]):
        sub = layout.subset(rows)
        present = sub.present[:, :, None]
        valid = sub.take(valid_all) & present
        design = beam_unit_vector(sub.take(azimuth), sub.take(elevation))
        fit = fit_scans(sub.take(velocity), design, valid, homodyne=homodyne)
        parts.append(
            {
                "beta": fit.beta,
                "cov": fit.covariance,
                "n": fit.n_rays,
                "res": fit.residual_std,
                "ok": fit.determined & fit.converged,
                "gap": azimuth_gap(sub.take(azimuth), valid),
            }
        )
    return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}


def _wind_dataset(
    ds: xr.Dataset,
    layout: ScanLayout,
    *,
    beta: FloatArray,
    covariance: FloatArray,
    n_rays: np.ndarray,
    residual_std: FloatArray,
    fit_ok: BoolArray,
    gap: FloatArray,
    phi: float,
    scan_elevation: FloatArray,
    n_other: int,
    homodyne: bool,
    resolution: str,
    params: dict[str, float],
) -> xr.Dataset:
    u, v, w = beta[..., 0], beta[..., 1], beta[..., 2]
    speed_error, direction_error = speed_direction_errors(u, v, covariance)
    bad = ~fit_ok | ~np.isfinite(residual_std) | (residual_std > params["max_residual_std"])
    flag = (
        np.where(n_rays < params["min_rays"], 1, 0)
        | np.where(gap > params["max_gap_deg"], 2, 0)
        | np.where(bad, 4, 0)
    ).astype(np.int8)
    dims = ("time", "height")
    method = (
        "homodyne least squares |V_r| = |w sin(phi) + cos(phi)(u sin(theta) + v cos(theta))| "
        "(global minimum over the arc sign patterns, then Gauss-Newton by sign assignment)"
        if homodyne
        else "least squares V_r = w sin(phi) + cos(phi)(u sin(theta) + v cos(theta))"
    )
    fit_attrs = {"method": method}
    error_attrs = {"method": "square root of the diagonal of s^2 (A^T A)^-1, s^2 = SSR/(n - 3)"}
    range_m = ds["range"].values.astype(float)
    height = height_from_range(range_m, phi)
    wind_speed, wind_direction = speed_and_direction(u, v)
    out = xr.Dataset(
        {
            "u": (dims, u, fit_attrs),
            "v": (dims, v, fit_attrs),
            "w": (dims, w, fit_attrs),
            "wind_speed": (dims, wind_speed, fit_attrs),
            "wind_direction": (dims, wind_direction, fit_attrs),
            "u_error": (dims, np.sqrt(covariance[..., 0, 0]), error_attrs),
            "v_error": (dims, np.sqrt(covariance[..., 1, 1]), error_attrs),
            "w_error": (dims, np.sqrt(covariance[..., 2, 2]), error_attrs),
            "wind_speed_error": (dims, speed_error, {"method": "first-order propagation"}),
            "wind_direction_error": (
                dims,
                direction_error,
                {"method": "first-order propagation"},
            ),
            "residual_std": (dims, residual_std),
            "n_rays": (dims, n_rays.astype(np.int32)),
            "max_azimuth_gap": (dims, gap),
            "qc_flag": (
                dims,
                flag,
                {
                    "bad_fit_definition": (
                        "fewer than 3 rays or cond(A^T A) > 1e8; no residual degree of "
                        "freedom (n = 3); residual std > "
                        f"{params['max_residual_std']:g} m s-1; homodyne fit not converged"
                    ),
                },
            ),
        },
        coords={
            "time": ("time", _mean_times(ds, layout)),
            "height": ("height", height),
            "range": ("height", range_m),
            "scan": ("time", layout.scan_ids),
            "elevation": ("time", scan_elevation),
        },
    )
    out.attrs = {k: v for k, v in ds.attrs.items()}
    out.attrs.update(
        {
            "vad_method": method,
            "vad_references": REFERENCES,
            "vad_min_rays": int(params["min_rays"]),
            "vad_max_gap_deg": float(params["max_gap_deg"]),
            "vad_max_residual_std_m_s": float(params["max_residual_std"]),
            "vad_elevation_deg": phi,
            "vad_elevation_selection": (
                f"scans at the most common conical elevation {phi:g} deg "
                f"(+-{ELEVATION_TOLERANCE_DEG:g} deg) are fitted; {n_other} conical scan(s) "
                "at other elevations were left out"
            ),
            "vad_scans_other_elevation": n_other,
            "vad_homodyne_ambiguity": resolution,
        }
    )
    return out
