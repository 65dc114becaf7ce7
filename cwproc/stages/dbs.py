"""Stage ``dbs``: 10-min wind and turbulence intensity from WindCube ``.rtd`` beams.

:func:`dbs_statistics` turns the lines of sight of a WindCube (:mod:`cwproc.io.windcube_rtd`)
into interval statistics: per complete beam cycle (0, 90, 180, 270 deg and, v2/v2.1,
the vertical beam) the DBS wind ``u, v, w`` (:mod:`cwproc.physics.dbs`); per interval
the mean wind, the variances of ``u``, ``v``, ``w`` and of the along-wind component, and
the turbulence intensity ``TI = sigma_along / |U|``, measured and corrected.

The corrections, each with its assumption (module :mod:`cwproc.physics.dbs`):

1. **noise** (subtracted): ``sum_k a_k^2 sigma_e,k^2`` with ``sigma_e`` of each beam
   from its mean CNR by Pearson et al. (2009), eq. 3, with the accumulation settings
   ``points_per_gate`` and ``pulses_per_los`` (WF 2.x files write them ``NA``; the
   defaults are those of cwproc's virtual WindCube, not Leosphere figures). Holds above
   the detection threshold: flag bit 2 where the median CNR of the interval is below
   ``min_cnr_db`` + 3 dB.
2. **volume averaging** (divided out): the ratio of the pulsed probe's radial-velocity
   variance to the point variance, isotropic von Karman turbulence of integral scale
   ``L_V`` (default ``2 Lambda_1``, ``Lambda_1 = 0.7 min(h, 60 m)``: the longitudinal
   integral scale ``L_u/4`` of the IEC 61400-1 Kaimal spectrum, ``L_u = 8.1 Lambda_1``;
   an assumption, set ``integral_scale_m`` when it is known).
3. **cross-contamination** (divided out): the DBS estimate's variance over the true
   component variance for the beams' separation (``2 h tan theta``) and timing in the
   same isotropic model (Sathe et al. (2011)); in the atmospheric surface layer, where
   ``sigma_w < sigma_u``, isotropy overstates the contamination by ``sigma_w^2``.

Flag bits (``dbs_flag``, they combine; 0 good): 1 fewer than ``min_cycles_percent`` of
the possible complete cycles; 2 low CNR (noise law not valid); 4 inhomogeneous flow
across the cone (the four inclined beams' mean, ``w`` from them, differs from the
vertical beam's by more than ``max_w_mismatch`` m/s: complex terrain or a local
disturbance, where DBS itself does not hold).
"""

from __future__ import annotations

import functools

import numpy as np
import xarray as xr

from cwproc.errors import CwprocError
from cwproc.metadata import described
from cwproc.physics import dbs
from cwproc.physics.geometry import speed_and_direction
from cwproc.physics.noise import velocity_noise_std

#: the DBS estimates whose variances are reported: along-wind (TI), u (east), v (north), w
COMPONENTS = ("along", "u", "v", "w")

#: flag bits of the DBS statistics
FLAG_FEW_CYCLES = 1
FLAG_LOW_CNR = 2
FLAG_INHOMOGENEOUS = 4

#: defaults of the virtual WindCube (cwproc.sim.windcube): range weighting and accumulation
DEFAULT_DELTA_P_M = 15.0
DEFAULT_DELTA_R_M = 20.0
DEFAULT_POINTS_PER_GATE = 10
DEFAULT_PULSES_PER_LOS = 10000


def default_integral_scale(height_m: float) -> float:
    """``2 Lambda_1`` (m), ``Lambda_1 = 0.7 min(h, 60 m)`` (IEC 61400-1 Kaimal: L_u/4)."""
    return 2.0 * 0.7 * min(float(height_m), 60.0)


def beam_cycles(beams: np.ndarray) -> np.ndarray:
    """Start indices of the complete cycles ``0, 90, 180, 270[, V]`` in a beam sequence."""
    vertical = bool(np.any(beams == "V"))
    order = [*dbs.INCLINED, "V"] if vertical else list(dbs.INCLINED)
    n = beams.size - len(order) + 1
    if n <= 0:
        return np.zeros(0, dtype=int)
    ok = np.ones(n, dtype=bool)
    for j, label in enumerate(order):
        ok &= beams[j : j + n] == label
    return np.flatnonzero(ok)


@functools.lru_cache(maxsize=4096)
def _ratios(
    height: float,
    scan_angle: float,
    times: tuple[tuple[str, float], ...],
    wind: tuple[float, float],
    scale: float,
    delta_p: float,
    delta_r: float,
    vertical: bool,
) -> dict[str, float]:
    """Volume, cross and combined ratios of the along-wind and w estimates (cached)."""
    nodes = dbs.range_nodes(delta_p, delta_r, max(min(delta_p, delta_r) / 6.0, 0.5))
    beam_time = dict(times)
    mean_wind = np.array([wind[0], wind[1], 0.0])
    along = dbs.along_wind_coefficients(wind[0], wind[1], scan_angle)
    w = dbs.estimator_coefficients("w", scan_angle, vertical)
    common = {
        "height_m": height,
        "scan_angle_deg": scan_angle,
        "beam_time_s": beam_time,
        "mean_wind": mean_wind,
        "integral_scale_m": scale,
    }
    # one beam with itself: the same for every beam direction in isotropic turbulence
    volume = dbs.estimator_variance_ratio({"0": 1.0}, range_nodes=nodes, **common)
    out = {"volume": volume}
    u = dbs.estimator_coefficients("u", scan_angle, vertical)
    v = dbs.estimator_coefficients("v", scan_angle, vertical)
    for name, coef in (("along", along), ("u", u), ("v", v), ("w", w)):
        out[f"cross_{name}"] = dbs.estimator_variance_ratio(coef, **common)
        out[f"full_{name}"] = dbs.estimator_variance_ratio(coef, range_nodes=nodes, **common)
    return out


@described("dbs")
def dbs_statistics(
    rtd: xr.Dataset,
    *,
    window_s: float = 600.0,
    min_cnr_db: float = -23.0,
    delta_p_m: float = DEFAULT_DELTA_P_M,
    delta_r_m: float = DEFAULT_DELTA_R_M,
    points_per_gate: float = DEFAULT_POINTS_PER_GATE,
    pulses_per_los: float = DEFAULT_PULSES_PER_LOS,
    integral_scale_m: float | None = None,
    min_cycles_percent: float = 80.0,
    max_w_mismatch: float = 0.3,
) -> xr.Dataset:
    """Interval statistics of the DBS wind of a WindCube ``.rtd`` record.

    Parameters
    ----------
    rtd : xarray.Dataset
        :func:`cwproc.io.windcube_rtd.read_windcube_rtd` output.
    window_s : float
        Interval (s); intervals start at whole multiples of it (UTC), stamped at their end.
    min_cnr_db : float
        Lines of sight with a lower CNR (dB) are missing (the WindCube's own threshold,
        ``CNRThreshold=-23`` in the real header).
    delta_p_m, delta_r_m : float
        The pulsed range weighting (m) of the volume-averaging model.
    points_per_gate, pulses_per_los : float
        Accumulation behind one line of sight, for the noise law.
    integral_scale_m : float, optional
        L_V of the isotropic model (m); default :func:`default_integral_scale`.
    min_cycles_percent : float
        Fewer complete cycles than this share of the possible ones sets flag bit 1.
    max_w_mismatch : float
        Largest difference (m s-1) of ``w`` from the inclined and the vertical beams.

    Returns
    -------
    xarray.Dataset
        dims ``(time, height)``, time = end of interval: ``wind_speed``,
        ``wind_direction``, ``w``, ``u_mean``, ``v_mean``, ``n_cycles``, ``volume_ratio``;
        for each of ``along`` (the along-wind component), ``u`` (east), ``v`` (north)
        and ``w``: ``<c>_variance_measured``, ``<c>_noise_variance``,
        ``<c>_cross_ratio``, ``<c>_full_ratio`` and ``<c>_variance`` (all corrections,
        m2 s-2); ``wind_speed_std`` (measured along-wind),
        ``turbulence_intensity`` (measured), ``turbulence_intensity_noise``,
        ``turbulence_intensity_volume``, ``turbulence_intensity_cross`` (one correction
        each), ``turbulence_intensity_corrected`` (all three), ``w_std``,
        ``w_std_corrected``, ``cnr``, ``data_availability``, ``dbs_flag``.
    """
    for name in ("radial_velocity", "beam", "cnr"):
        if name not in rtd:
            raise CwprocError(f"no {name!r}: not the lines of sight of a WindCube .rtd file")
    angle = float(rtd.attrs["scan_angle_deg"])
    beams = rtd["beam"].values.astype(str)
    starts = beam_cycles(beams)
    if starts.size == 0:
        raise CwprocError("no complete DBS cycle (0, 90, 180, 270 deg) in the lines of sight")
    vertical = bool(np.any(beams == "V"))
    order = [*dbs.INCLINED, "V"] if vertical else list(dbs.INCLINED)
    vr = np.where(rtd["cnr"].values >= min_cnr_db, rtd["radial_velocity"].values, np.nan)
    cnr = rtd["cnr"].values
    times = rtd["time"].values
    beam_vr = {b: vr[starts + j] for j, b in enumerate(order)}
    beam_cnr = {b: cnr[starts + j] for j, b in enumerate(order)}
    seconds = (times - times[0]).astype(float) / 1e9
    beam_time = tuple(
        (b, float(np.median(seconds[starts + j] - seconds[starts]))) for j, b in enumerate(order)
    )
    cycle_s = float(np.median(np.diff(seconds[starts]))) if starts.size > 1 else len(order)
    comp = {
        c: sum(a * beam_vr[b] for b, a in dbs.estimator_coefficients(c, angle, vertical).items())
        for c in ("u", "v", "w")
    }
    w_inclined = sum(beam_vr[b] for b in dbs.INCLINED) / (4.0 * np.cos(np.deg2rad(angle)))
    epoch = times[starts].astype("datetime64[ns]").astype(np.int64)
    step = int(window_s * 1e9)
    window = epoch // step
    keys = np.unique(window)
    heights = rtd["height"].values
    nh = heights.size
    names = (
        "wind_speed wind_direction w u_mean v_mean n_cycles volume_ratio cnr "
        "data_availability w_mismatch"
    ).split()
    for c in COMPONENTS:
        names += [f"{c}_variance_measured", f"{c}_noise_variance"]
        names += [f"{c}_cross_ratio", f"{c}_full_ratio"]
    out = {n: np.full((keys.size, nh), np.nan) for n in names}
    for i, key in enumerate(keys):
        rows = window == key
        _interval(
            out, i, rows, comp, w_inclined, beam_cnr, heights,
            angle=angle, vertical=vertical, beam_time=beam_time,
            cycle_s=cycle_s, window_s=window_s,
            settings=(delta_p_m, delta_r_m, points_per_gate, pulses_per_los, integral_scale_m),
        )  # fmt: skip
    return _assemble(rtd, out, keys, step, heights, min_cnr_db, min_cycles_percent, max_w_mismatch)


def _interval(
    out: dict[str, np.ndarray],
    i: int,
    rows: np.ndarray,
    comp: dict[str, np.ndarray],
    w_inclined: np.ndarray,
    beam_cnr: dict[str, np.ndarray],
    heights: np.ndarray,
    *,
    angle: float,
    vertical: bool,
    beam_time: tuple[tuple[str, float], ...],
    cycle_s: float,
    window_s: float,
    settings: tuple,
) -> None:
    """Fill row ``i`` of ``out`` with the statistics of the cycles ``rows``."""
    delta_p, delta_r, points, pulses, scale = settings
    u, v, w = comp["u"][rows], comp["v"][rows], comp["w"][rows]
    good = np.isfinite(u) & np.isfinite(v)
    with np.errstate(invalid="ignore", divide="ignore"):
        for k, h in enumerate(heights):
            ok = good[:, k]
            out["n_cycles"][i, k] = ok.sum()
            out["data_availability"][i, k] = min(100.0, 100.0 * ok.sum() * cycle_s / window_s)
            cnr_all = np.concatenate([beam_cnr[b][rows, k] for b in beam_cnr])
            out["cnr"][i, k] = np.nanmedian(cnr_all)
            if ok.sum() < 3:
                continue
            um, vm = u[ok, k].mean(), v[ok, k].mean()
            out["u_mean"][i, k], out["v_mean"][i, k] = um, vm
            speed, direction = speed_and_direction(um, vm)
            out["wind_speed"][i, k], out["wind_direction"][i, k] = speed, direction
            along = (u[ok, k] * um + v[ok, k] * vm) / speed
            out["along_variance_measured"][i, k] = along.var(ddof=1)
            out["u_variance_measured"][i, k] = u[ok, k].var(ddof=1)
            out["v_variance_measured"][i, k] = v[ok, k].var(ddof=1)
            wk = w[:, k][np.isfinite(w[:, k])]
            out["w"][i, k] = wk.mean() if wk.size else np.nan
            out["w_variance_measured"][i, k] = wk.var(ddof=1) if wk.size > 2 else np.nan
            if vertical:
                out["w_mismatch"][i, k] = np.nanmean(w_inclined[rows, k]) - out["w"][i, k]
            sigma2 = {
                b: np.nanmean(velocity_noise_std(10.0 ** (beam_cnr[b][rows, k] / 10.0), points,
                                                 pulses) ** 2)
                for b in beam_cnr
            }  # fmt: skip
            coefficients = {
                "along": dbs.along_wind_coefficients(um, vm, angle),
                **{c: dbs.estimator_coefficients(c, angle, vertical) for c in ("u", "v", "w")},
            }
            for c, coef in coefficients.items():
                out[f"{c}_noise_variance"][i, k] = dbs.noise_variance(coef, sigma2)
            wind = (round(float(um) * 2) / 2, round(float(vm) * 2) / 2)
            ratios = _ratios(
                float(h), angle, beam_time, wind,
                float(scale if scale is not None else default_integral_scale(h)),
                float(delta_p), float(delta_r), vertical,
            )  # fmt: skip
            out["volume_ratio"][i, k] = ratios["volume"]
            for name in COMPONENTS:
                out[f"{name}_cross_ratio"][i, k] = ratios[f"cross_{name}"]
                out[f"{name}_full_ratio"][i, k] = ratios[f"full_{name}"]


def _assemble(
    rtd: xr.Dataset,
    out: dict[str, np.ndarray],
    keys: np.ndarray,
    step: int,
    heights: np.ndarray,
    min_cnr_db: float,
    min_cycles_percent: float,
    max_w_mismatch: float,
) -> xr.Dataset:
    """The statistics as a dataset: TI measured, with each correction, with all of them."""
    dims = ("time", "height")
    end = ((keys + 1) * step).astype("datetime64[ns]")
    ds = xr.Dataset({n: (dims, v) for n, v in out.items()}, coords={"time": end, "height": heights})
    speed = ds["wind_speed"]
    measured = ds["along_variance_measured"]
    noise = ds["along_noise_variance"]
    with np.errstate(invalid="ignore"):
        ti = {
            "turbulence_intensity": measured,
            "turbulence_intensity_noise": measured - noise,
            "turbulence_intensity_volume": measured / ds["volume_ratio"],
            "turbulence_intensity_cross": measured / ds["along_cross_ratio"],
            "turbulence_intensity_corrected": (measured - noise) / ds["along_full_ratio"],
        }
        for name, variance in ti.items():
            ds[name] = np.sqrt(variance.where(variance > 0)) / speed
        ds["wind_speed_std"] = np.sqrt(measured)
        ds["w_std"] = np.sqrt(ds["w_variance_measured"])
        for c in COMPONENTS:
            corrected = (ds[f"{c}_variance_measured"] - ds[f"{c}_noise_variance"]) / ds[
                f"{c}_full_ratio"
            ]
            ds[f"{c}_variance"] = corrected.where(corrected > 0)
            ds[f"{c}_variance"].attrs["method"] = (
                "(measured - noise variance) / combined DBS and probe ratio"
            )
        ds["w_std_corrected"] = np.sqrt(ds["w_variance"])
    flag = xr.where(ds["data_availability"] < min_cycles_percent, dbs_flag_bit(1), 0)
    flag = flag | xr.where(ds["cnr"] < min_cnr_db + 3.0, FLAG_LOW_CNR, 0)
    flag = flag | xr.where(np.abs(ds["w_mismatch"]) > max_w_mismatch, FLAG_INHOMOGENEOUS, 0)
    ds["dbs_flag"] = flag.astype(np.int8)
    methods = {
        "turbulence_intensity": "sqrt(var of the DBS along-wind component) / mean speed",
        "turbulence_intensity_noise": "noise variance from CNR subtracted (Pearson et al. "
        "(2009), eq. 3)",
        "turbulence_intensity_volume": "divided by the pulsed probe's variance ratio "
        "(isotropic von Karman)",
        "turbulence_intensity_cross": "divided by the DBS cross-contamination ratio of point "
        f"probes (isotropic von Karman; {dbs.SATHE_2011})",
        "turbulence_intensity_corrected": "(measured - noise) / combined DBS and probe ratio",
    }
    for name, text in methods.items():
        ds[name].attrs["method"] = text
    ds.attrs = {
        k: rtd.attrs[k]
        for k in ("instrument", "instrument_kind", "system_id", "scan_angle_deg", "source_files")
        if k in rtd.attrs
    }
    ds.attrs.update(
        averaging_interval_s=float(step / 1e9),
        time_stamp_position="end",
        dbs_references=f"{dbs.SATHE_2011}; {dbs.SATHE_MANN_2013}",
        dbs_flag_meanings="1 few complete cycles; 2 low CNR (noise law not valid); "
        "4 inhomogeneous flow across the cone (complex terrain)",
    )
    return ds


def dbs_flag_bit(bit: int) -> int:
    """The flag value of bit ``bit`` (1, 2 or 4), named for the reader of the code."""
    return {1: FLAG_FEW_CYCLES, 2: FLAG_LOW_CNR, 4: FLAG_INHOMOGENEOUS}[bit]
