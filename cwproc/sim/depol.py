"""Co- and cross-polarised stare rays: simulated pairs in the real layout.

No public Stream Line co/cross file pair was found (``real_data/hpl/PROVENANCE.md``), so
the depolarisation chain is tested on pairs made here. A Stream Line with a polariser
measures the two channels as separate rays with the same detector (Vakkari et al. (2021),
section 2): each channel writes its own ``.hpl`` intensity ``I = P / B_m`` (the received
power over the background ``B_m`` measured for that channel at the start of the hour)
and its own ``Background_*.txt`` holding that ``B_m``. The cross channel's signal is
``delta`` times the co channel's *true* SNR, and its noise and background are its own.

Two generators:

* :func:`cross_polarised` -- for canonical (background-corrected) synthetic stares whose
  true SNR is known (``snr_signal``, as :func:`aerosol_layer` sets it): the cross ray is
  ``delta x snr_signal`` plus independent noise.
* :func:`polarised_pair` -- for a real ``.hpl`` file and its background: both channels
  are re-measured from a true SNR profile taken from the real file, each with its own
  noise, its own background file (the real file's smooth background shape times
  gate-to-gate noise of the real file's level) and a noise floor offset like the real
  one (the background drifts between its measurement and the ray), so that
  :func:`cwproc.stages.snr_correction.correct_snr` has to do on both what it does on a real
  instrument's files, and the truth of every gate is known exactly.

Written with :func:`cwproc.io.halo.write_hpl` and :func:`write_background`, a pair is two
``.hpl`` files of the instrument's layout with the same file name in two folders, as
Cloudnet sites upload them (tags ``co`` and ``cross``), each with its background file.

An earlier version scaled the cross SNR from the co file's *uncorrected* SNR with no
background of its own, and then corrected both with the co background: the cross file then
carried the co channel's correction pattern (``B_m / (B_f F) - 1``, -0.001 on the Eriswil
signal gates) with weight 1 instead of ``delta``, its clipped co noise as a floor of its
own, and the co noise in both channels (``SNR_x - delta SNR_co`` -4 and -12 standard
errors at delta 0.1 and 0.3 on the Eriswil signal gates). With this construction a
method bias remained, and is fixed in the L1 stage
(:func:`cwproc.stages.doppler_lidar.refit_cross_floor`).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import xarray as xr

from cwproc.physics.snr_background import MIN_FIT_RANGE_M, fit_background_shape

#: half-width of the Stream Line's velocity search band (m s-1), where a noise gate's
#: velocity lies
SEARCH_BAND_M_S = 19.0


def cross_polarised(
    co: xr.Dataset,
    delta: float | np.ndarray,
    noise_std: float | np.ndarray,
    *,
    signal: np.ndarray | None = None,
    lag_s: float = 0.5,
    seed: int = 0,
) -> xr.Dataset:
    """The cross-polarised rays of ``co`` (a canonical, background-corrected stare).

    Parameters
    ----------
    co : xarray.Dataset
        Co-polarised stare rays (``snr``, ``radial_velocity``, ``time``, pointing).
    delta : float or numpy.ndarray
        True depolarisation ratio (broadcast to ``snr``).
    noise_std : float or numpy.ndarray
        Standard deviation of the cross channel's noise SNR (per ray or scalar).
    signal : numpy.ndarray, optional
        True (noise-free) SNR of the co channel, (rays, range); default ``co["snr_signal"]``
        (set by :func:`aerosol_layer`). The co channel's measured SNR is not used: its
        noise is the co channel's, not the cross channel's.
    lag_s : float
        Time of the cross ray after its co ray (s).
    seed : int
        Random seed of the noise.

    Returns
    -------
    xarray.Dataset
        The same layout as ``co``: ``snr`` = ``delta`` x ``signal`` + independent noise,
        ``snr_signal`` its truth, the velocity of the co ray where the cross signal is
        above 3 noise sd and uniform over the search band elsewhere, ``beta`` scaled like
        ``snr``.

    Raises
    ------
    ValueError
        Without ``signal`` and without ``co["snr_signal"]``.
    """
    if signal is None:
        if "snr_signal" not in co:
            raise ValueError("cross_polarised needs the co channel's true SNR (signal)")
        signal = co["snr_signal"].values
    rng = np.random.default_rng(seed)
    snr = np.asarray(co["snr"].values, dtype=float)
    truth = np.asarray(signal, dtype=float) * np.broadcast_to(delta, snr.shape)
    sd = np.broadcast_to(np.asarray(noise_std, dtype=float).reshape(-1, 1), snr.shape)
    snr_x = truth + rng.normal(0.0, 1.0, snr.shape) * sd
    out = co.copy(deep=True)
    out["snr"].values[...] = snr_x
    out["snr_signal"] = (co["snr"].dims, truth)
    out["radial_velocity"].values[...] = _cross_velocity(co, truth, sd, rng)
    if "beta" in out:
        with np.errstate(divide="ignore", invalid="ignore"):
            scale = np.where(snr != 0, snr_x / snr, 0.0)
        out["beta"].values[...] = np.asarray(co["beta"].values) * scale
    for name in ("snr_uncorrected", "noise_floor"):  # background_time: corrected as co
        if name in out:
            out = out.drop_vars(name)
    return _later(out, co, lag_s)


def _cross_velocity(
    co: xr.Dataset, truth: np.ndarray, sd: np.ndarray, rng: np.random.Generator
) -> np.ndarray:
    """The co ray's velocity where the cross signal is above 3 noise sd, else uniform
    over the search band (a noise gate's velocity)."""
    v = np.asarray(co["radial_velocity"].values, dtype=float)
    noisy = truth < 3 * sd
    return np.where(noisy, rng.uniform(-SEARCH_BAND_M_S, SEARCH_BAND_M_S, v.shape), v)


def _later(out: xr.Dataset, co: xr.Dataset, lag_s: float) -> xr.Dataset:
    t = np.asarray(co["time"].values, dtype="datetime64[ns]")
    out = out.assign_coords(time=("ray", t + np.timedelta64(int(lag_s * 1e9), "ns")))
    out.attrs = dict(co.attrs)
    return out


def background_stripes(
    background: np.ndarray, range_m: np.ndarray, *, min_range_m: float = MIN_FIT_RANGE_M
) -> tuple[np.ndarray, float]:
    """Smooth shape B_f of a measured background and its gate-to-gate noise level.

    Returns ``B_f`` (:func:`cwproc.physics.snr_background.fit_background_shape`, Vakkari et
    al. (2019)) and the robust standard deviation of ``B_m / B_f - 1`` beyond
    ``min_range_m`` (1.4826 MAD).
    """
    bm = np.asarray(background, dtype=float)
    r = np.asarray(range_m, dtype=float)
    fitted, _ = fit_background_shape(bm, r, min_range_m=min_range_m)
    rel = (bm / fitted - 1.0)[r > min_range_m]
    return fitted, float(1.4826 * np.median(np.abs(rel - np.median(rel))))


def measured_channel(
    truth: np.ndarray,
    reference: np.ndarray,
    range_m: np.ndarray,
    *,
    noise_std: float,
    stripe_std: float,
    floor_offset: float,
    rng: np.random.Generator,
    min_range_m: float = MIN_FIT_RANGE_M,
) -> tuple[np.ndarray, np.ndarray]:
    """One channel's written SNR and its background file, as a Stream Line makes them.

    The background of the hour at the time of the rays is ``B = B_ref (1 + floor_offset)``
    (``B_ref`` the smooth reference background, ``floor_offset`` its drift since it was
    measured); the background file holds ``B_m = B_ref (1 + stripe_std z)`` beyond
    ``min_range_m`` (z standard normal per gate: the gate-to-gate noise of one
    measurement; nearer gates ``B_ref`` itself); the received power is ``B (1 + S + n)``
    with ``n`` the noise (sd ``noise_std``) and the instrument writes
    ``I - 1 = B (1 + S + n) / B_m - 1`` (Manninen et al. (2016), eq. 1).

    Parameters
    ----------
    truth : numpy.ndarray
        True SNR S of the channel, (rays, range).
    reference : numpy.ndarray
        B_ref, (range,) detector counts.
    range_m : numpy.ndarray
        Gate distances (m).

    Returns
    -------
    snr : numpy.ndarray
        (rays, range) SNR as written in the ``.hpl`` file.
    background : numpy.ndarray
        (range,) the channel's background file values.
    """
    s = np.asarray(truth, dtype=float)
    far = np.asarray(range_m, dtype=float) > min_range_m
    stripes = np.where(far, stripe_std * rng.standard_normal(far.shape), 0.0)
    measured = np.asarray(reference, dtype=float) * (1.0 + stripes)
    power = (1.0 + floor_offset) * (1.0 + s + noise_std * rng.standard_normal(s.shape))
    return power / (1.0 + stripes) - 1.0, measured


def polarised_pair(
    co: xr.Dataset,
    background: np.ndarray,
    signal: np.ndarray,
    delta: float | np.ndarray,
    *,
    noise_std: float,
    floor_offset: tuple[float, float] = (0.0006, 0.0006),
    lag_s: float = 0.5,
    seed: int = 0,
    min_range_m: float = MIN_FIT_RANGE_M,
) -> tuple[xr.Dataset, xr.Dataset, np.ndarray, np.ndarray]:
    """A co/cross pair re-measured in the layout of a real stare (``co``, as read).

    Both channels see the true SNR ``signal`` (co) and ``delta x signal`` (cross) and
    each gets its own noise and its own background file (:func:`measured_channel`): the
    smooth shape of the real ``background`` (cut to the rays' gates) with gate-to-gate
    noise of the real file's level (:func:`background_stripes`); gates within
    ``min_range_m`` keep the real background. The co rays keep the real velocities (the
    real file's noise gates have noise velocities); the cross rays take them where their
    signal is above 3 noise sd, else a noise velocity. The cross rays come ``lag_s``
    after the co rays.

    Parameters
    ----------
    co : xarray.Dataset
        The real stare (uncorrected SNR, as :func:`cwproc.io.halo.read_hpl` gives it).
    background : numpy.ndarray
        The real background file's values (at least as many gates as ``co``).
    signal : numpy.ndarray
        True co SNR, (rays, range), e.g. the real file's corrected SNR on its signal gates.
    delta : float or numpy.ndarray
        True depolarisation ratio.
    noise_std : float
        Noise sd of each channel's SNR (the real file's corrected noise, ~0.002).
    floor_offset : (float, float)
        Drift of the background of each channel since its background file (the real
        Eriswil floors are 1.0005-1.0008).

    Returns
    -------
    co_sim, cross_sim : xarray.Dataset
        The two channels, ``snr`` as the instrument writes it, ``snr_signal`` the truth.
    background_co, background_cross : numpy.ndarray
        Their background files' values.
    """
    rng = np.random.default_rng(seed)
    r = np.asarray(co["range"].values, dtype=float)
    bm = np.asarray(background, dtype=float)[: r.size]
    fitted, stripe_std = background_stripes(bm, r, min_range_m=min_range_m)
    reference = np.where(r > min_range_m, fitted, bm)
    s_co = np.clip(np.asarray(signal, dtype=float), 0.0, None)
    s_x = s_co * np.broadcast_to(delta, s_co.shape)
    pairs = []
    for truth, offset in ((s_co, floor_offset[0]), (s_x, floor_offset[1])):
        snr, bg = measured_channel(
            truth,
            reference,
            r,
            noise_std=noise_std,
            stripe_std=stripe_std,
            floor_offset=offset,
            rng=rng,
            min_range_m=min_range_m,
        )
        ds = co.copy(deep=True)
        ds["snr"].values[...] = snr
        ds["snr_signal"] = (co["snr"].dims, truth)
        if "beta" in ds:
            with np.errstate(divide="ignore", invalid="ignore"):
                scale = np.where(co["snr"].values != 0, snr / co["snr"].values, 0.0)
            ds["beta"].values[...] = np.asarray(co["beta"].values) * scale
        pairs.append((ds, bg))
    (co_sim, bg_co), (x_sim, bg_x) = pairs
    x_sim["radial_velocity"].values[...] = _cross_velocity(
        co, s_x, np.full(s_x.shape, noise_std), rng
    )
    return co_sim, _later(x_sim, co, lag_s), bg_co, bg_x


def background_text(values: np.ndarray) -> str:
    """A Stream Line background file's text: one value per line, six decimals, CRLF."""
    return "".join(f"{v:.6f}\r\n" for v in np.asarray(values, dtype=float))


def write_background(values: np.ndarray, path: str | os.PathLike) -> Path:
    """Write a background file (name ``Background_DDMMYY-HHMMSS.txt``, the time of the
    measurement, as the instrument names it)."""
    out = Path(path)
    out.write_bytes(background_text(values).encode("ascii"))
    return out


def aerosol_layer(
    stare: xr.Dataset,
    *,
    top_m: float,
    snr: float,
    noise_std: float,
    scale_m: float = 40.0,
    seed: int = 0,
) -> xr.Dataset:
    """A stare's SNR as an aerosol layer over noise, its velocities noise above it.

    The SNR is ``snr`` up to ``top_m`` and falls as ``exp(-(r - top)/scale_m)`` above,
    plus Gaussian noise of ``noise_std`` (the Stream Line's noise after the background
    correction, Manninen et al. (2016)); where the signal is below three noise standard
    deviations the velocity is uniform over the +-19 m s-1 search band, as a noise
    gate's is. The simulator's stares have one SNR everywhere, so this gives the
    screening something to screen. ``snr_signal`` holds the true SNR (the profile).
    """
    rng = np.random.default_rng(seed)
    r = np.asarray(stare["range"].values, dtype=float)
    profile = snr * np.exp(-np.clip(r - top_m, 0.0, None) / scale_m)
    shape = stare["snr"].shape
    out = stare.copy(deep=True)
    out["snr"].values[...] = profile[None, :] + rng.normal(0.0, noise_std, shape)
    out["snr_signal"] = (stare["snr"].dims, np.broadcast_to(profile, shape).copy())
    noise_gate = np.broadcast_to(profile < 3 * noise_std, shape)
    v = np.asarray(out["radial_velocity"].values)
    out["radial_velocity"].values[...] = np.where(
        noise_gate, rng.uniform(-SEARCH_BAND_M_S, SEARCH_BAND_M_S, shape), v
    )
    if "beta" in out:
        out["beta"].values[...] = np.asarray(out["snr"].values) * 3e-5
    return out
