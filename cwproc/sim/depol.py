"""Cross-polarised stare rays for a co-polarised stare: simulated pairs in the real layout.

No public Stream Line co/cross file pair was found (``real_data/hpl/PROVENANCE.md``), so
the depolarisation chain is tested on pairs made here: each co-polarised ray gets a
cross-polarised ray measured ``lag_s`` later at the same pointing, whose SNR is
``delta`` times the co ray's signal plus independent Gaussian noise of the same
standard deviation as the co ray's noise (the cross channel has the same detector and
background, Vakkari et al. (2021), section 2). Written with
:func:`cwproc.io.halo.write_hpl`, the pair is two ``.hpl`` files of the instrument's
layout with the same file name in two folders, as Cloudnet sites upload them (tags
``co`` and ``cross``).
"""

from __future__ import annotations

import numpy as np
import xarray as xr


def cross_polarised(
    co: xr.Dataset,
    delta: float | np.ndarray,
    noise_std: float | np.ndarray,
    *,
    lag_s: float = 0.5,
    seed: int = 0,
) -> xr.Dataset:
    """The cross-polarised rays of ``co`` (a canonical scan dataset), one per co ray.

    Parameters
    ----------
    co : xarray.Dataset
        Co-polarised stare rays (``snr``, ``radial_velocity``, ``time``, pointing).
    delta : float or numpy.ndarray
        True depolarisation ratio (broadcast to ``snr``).
    noise_std : float or numpy.ndarray
        Standard deviation of the cross channel's noise SNR (per ray or scalar).
    lag_s : float
        Time of the cross ray after its co ray (s).
    seed : int
        Random seed of the noise.

    Returns
    -------
    xarray.Dataset
        The same layout as ``co``: ``snr`` = ``delta`` x ``max(snr_co, 0)`` + noise, the
        velocity of the co ray where the cross signal is above its noise and uniform
        over the search band elsewhere, ``beta`` scaled like ``snr``.
    """
    rng = np.random.default_rng(seed)
    snr = np.asarray(co["snr"].values, dtype=float)
    signal = np.clip(snr, 0.0, None) * np.broadcast_to(delta, snr.shape)
    sd = np.broadcast_to(np.asarray(noise_std, dtype=float).reshape(-1, 1), snr.shape)
    snr_x = signal + rng.normal(0.0, 1.0, snr.shape) * sd
    v = np.asarray(co["radial_velocity"].values, dtype=float)
    noisy = signal < 3 * sd
    v_x = np.where(noisy, rng.uniform(-19.0, 19.0, v.shape), v)
    out = co.copy(deep=True)
    out["snr"].values[...] = snr_x
    out["radial_velocity"].values[...] = v_x
    if "beta" in out:
        with np.errstate(divide="ignore", invalid="ignore"):
            scale = np.where(snr != 0, snr_x / snr, 0.0)
        out["beta"].values[...] = np.asarray(co["beta"].values) * scale
    for name in ("snr_uncorrected", "noise_floor"):  # background_time: corrected as co
        if name in out:
            out = out.drop_vars(name)
    t = np.asarray(co["time"].values, dtype="datetime64[ns]")
    out = out.assign_coords(time=("ray", t + np.timedelta64(int(lag_s * 1e9), "ns")))
    out.attrs = dict(co.attrs)
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
    screening something to screen.
    """
    rng = np.random.default_rng(seed)
    r = np.asarray(stare["range"].values, dtype=float)
    profile = snr * np.exp(-np.clip(r - top_m, 0.0, None) / scale_m)
    shape = stare["snr"].shape
    out = stare.copy(deep=True)
    out["snr"].values[...] = profile[None, :] + rng.normal(0.0, noise_std, shape)
    noise_gate = np.broadcast_to(profile < 3 * noise_std, shape)
    v = np.asarray(out["radial_velocity"].values)
    out["radial_velocity"].values[...] = np.where(noise_gate, rng.uniform(-19, 19, shape), v)
    if "beta" in out:
        out["beta"].values[...] = np.asarray(out["snr"].values) * 3e-5
    return out
