"""Virtual sonic anemometer: 10.7 Hz wind series with a prescribed structure-function type.

Each wind component is a stationary Gaussian process whose structure function is
prescribed in the form of Gladkikh et al. (2014), eq. 7: D(r) = C 10^{y(lg r)}, with
y of type 1 (line, eq. 4), type 2 (parabola, eq. 5) or type 3 (parabola up to r_S,
then a line, eq. 6 and eq. 10), for r up to an outer lag r_out beyond which D stays
constant (the process is stationary with variance D(r_out)/2). Time lags follow from
Taylor's hypothesis, r = V_h tau.

The covariance B(tau) = [D(r_out) - D(V_h tau)]/2 (zero beyond r_out) is sampled by
circulant embedding (exact Gaussian process when the embedding is non-negative,
Davies & Harte; small negative eigenvalues, which occur at the kink of type 3, are set
to zero and their share is reported). Series are made in one-hour chunks, each chunk
independent, so a month streams in bounded memory; chunks are aligned with the 10-min
analysis windows.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import scipy.fft
import xarray as xr

from cwproc.io.meteo2 import write_meteo2
from cwproc.sim.output import write_truth

#: Meteo-2 sample rate f_d (Hz), Gladkikh et al. (2014), section 1
METEO2_RATE_HZ = 10.7


@dataclass(frozen=True)
class SFModel:
    """Prescribed normalised structure function lg D_n(x), x = lg(r / 1 m).

    Parameters
    ----------
    sf_type : int
        1, 2 or 3 (Gladkikh et al. (2014), eqs. 4-6).
    slope : float
        Type 1: mu; type 3: gamma of the linear part.
    a1, a2 : float
        Types 2 and 3: linear and quadratic coefficients of the parabola (a1, a2 or
        d1, d2).
    r_s_m : float
        Type 3: lag of the change from parabola to line (m).
    r_out_m : float
        Outer lag (m) beyond which D is constant.
    c_m2s2 : float
        C = D(1 m) (m2 s-2).
    """

    sf_type: int = 1
    slope: float = 2.0 / 3.0
    a1: float = 0.79
    a2: float = -0.2
    r_s_m: float = 3.0
    r_out_m: float = 40.0
    c_m2s2: float = 0.05

    def lg_dn(self, x: np.ndarray) -> np.ndarray:
        """lg D(r)/D(1 m) for x = lg r (r in m), before the outer lag."""
        x = np.asarray(x, dtype=float)
        if self.sf_type == 1:
            return self.slope * x
        para = self.a1 * x + self.a2 * x * x
        if self.sf_type == 2:
            return para
        xs = np.log10(self.r_s_m)
        at_s = self.a1 * xs + self.a2 * xs * xs
        return np.where(x <= xs, para, at_s + self.slope * (x - xs))

    def structure_function(self, r: np.ndarray) -> np.ndarray:
        """D(r) (m2 s-2): C 10^{y(lg r)} up to r_out, constant beyond (eq. 7)."""
        r = np.asarray(r, dtype=float)
        rr = np.clip(r, 1e-12, self.r_out_m)
        d = self.c_m2s2 * 10.0 ** self.lg_dn(np.log10(rr))
        return np.where(r > 0, d, 0.0)


def default_models(sf_type: int) -> tuple[SFModel, SFModel, SFModel]:
    """Models of the longitudinal, transverse and vertical components for a type.

    Type 1 uses mu = 2/3 (Kolmogorov); types 2 and 3 the all-site means of
    Gladkikh et al. (2014), Tables 4 and 5 (rounded), with a clearer break for type 3.
    """
    if sf_type == 1:
        base = SFModel(1, slope=2.0 / 3.0, r_out_m=20.0)
    elif sf_type == 2:
        base = SFModel(2, a1=0.79, a2=-0.20, r_out_m=60.0)
    elif sf_type == 3:
        base = SFModel(3, a1=0.78, a2=-0.45, slope=0.75, r_s_m=3.0, r_out_m=60.0)
    else:
        raise ValueError(f"sf_type must be 1, 2 or 3, got {sf_type}")
    return (
        base,
        SFModel(**{**asdict(base), "c_m2s2": base.c_m2s2 * 1.3}),
        SFModel(**{**asdict(base), "c_m2s2": base.c_m2s2 * 0.6}),
    )


def circulant_sqrt_spectrum(cov: np.ndarray, size: int) -> tuple[np.ndarray, float]:
    """sqrt of the eigenvalues of the circulant embedding of a covariance.

    Parameters
    ----------
    cov : ndarray
        B(k) for lags k = 0..L (L < size/2), zero beyond.
    size : int
        Circulant size M.

    Returns
    -------
    sqrt_eig : ndarray, shape (M,)
        sqrt(max(lambda, 0) / M).
    negative_share : float
        Sum of |negative eigenvalues| / sum |eigenvalues| (0 for an exact embedding).
    """
    row = np.zeros(size)
    row[: cov.size] = cov
    row[size - cov.size + 1 :] = cov[1:][::-1]
    eig = scipy.fft.fft(row).real
    neg = float(-eig[eig < 0].sum() / max(np.abs(eig).sum(), 1e-300))
    return np.sqrt(np.clip(eig, 0.0, None) / size), neg


def gaussian_series(sqrt_eig: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """One realisation (first ``n`` samples) of the circulant Gaussian process."""
    m = sqrt_eig.size
    z = rng.standard_normal(m) + 1j * rng.standard_normal(m)
    return scipy.fft.fft(sqrt_eig * z).real[:n]


@dataclass
class SonicTruth:
    """What the simulator prescribed (written next to the data as JSON)."""

    sf_type: int
    models: list[dict] = field(default_factory=list)
    mean_speed_m_s: float = 0.0
    direction_deg: float = 0.0
    sampling_rate_hz: float = METEO2_RATE_HZ
    start: str = ""
    hours: float = 0.0
    seed: int = 0
    negative_eigenvalue_share: float = 0.0


def component_covariances(
    models: tuple[SFModel, SFModel, SFModel], speed: float, rate: float
) -> list[np.ndarray]:
    """B(k) = [D(r_out) - D(V_h k / f)]/2 for k = 0..L of each component (m2 s-2)."""
    out = []
    for m in models:
        n_lag = int(np.ceil(m.r_out_m / speed * rate)) + 1
        r = np.arange(n_lag + 1) * speed / rate
        d_out = m.structure_function(np.array([m.r_out_m]))[0]
        out.append(0.5 * (d_out - m.structure_function(r)))
    return out


def iter_sonic_chunks(
    *,
    hours: float,
    sf_type: int = 1,
    seed: int = 0,
    speed: float = 6.0,
    direction_deg: float = 30.0,
    rate_hz: float = METEO2_RATE_HZ,
    start: str = "2014-06-01T00:00:00",
    chunk_s: float = 3600.0,
    models: tuple[SFModel, SFModel, SFModel] | None = None,
) -> Iterator[xr.Dataset]:
    """Yield consecutive sonic datasets (one per chunk) of a synthetic record.

    Parameters
    ----------
    hours : float
        Record length (h).
    sf_type : int
        Type of the prescribed structure functions (when ``models`` is None).
    seed : int
        Seed of the random generator.
    speed : float
        Mean horizontal wind V_h (m s-1).
    direction_deg : float
        Angle of the mean wind vector from the instrument +u axis toward +v (degree).
    rate_hz : float
        Sampling rate f_d (Hz).
    start : str
        ISO start time (UTC); chunks start at multiples of ``chunk_s`` from it.
    chunk_s : float
        Chunk length (s); keep a multiple of the analysis window.
    models : tuple of SFModel, optional
        Longitudinal, transverse, vertical models.

    Yields
    ------
    xarray.Dataset
        Canonical sonic dataset (``u``, ``v``, ``w``, ``temperature``, ``diagnostic``,
        attrs ``sampling_rate_hz`` etc.).
    """
    models = models or default_models(sf_type)
    rng = np.random.default_rng(seed)
    covs = component_covariances(models, speed, rate_hz)
    n_total = int(np.floor(hours * 3600.0 * rate_hz + 1e-9))
    n_chunk = int(np.floor(chunk_s * rate_hz + 1e-9))
    size = scipy.fft.next_fast_len(n_chunk + max(c.size for c in covs) + 1)
    spectra = [circulant_sqrt_spectrum(c, size) for c in covs]
    phi = np.deg2rad(direction_deg)
    t0 = np.datetime64(start, "ns")
    k0 = 0
    while k0 < n_total:
        n = min(n_chunk, n_total - k0)
        k = np.arange(k0, k0 + n)
        offsets = np.rint(k * (1e9 / rate_hz)).astype(np.int64)
        time = t0 + offsets.astype("timedelta64[ns]")
        v1, v2, v3 = (gaussian_series(s, n, rng) for s, _ in spectra)
        u = speed * np.cos(phi) + v1 * np.cos(phi) - v2 * np.sin(phi)
        v = speed * np.sin(phi) + v1 * np.sin(phi) + v2 * np.cos(phi)
        temperature = 15.0 + 0.2 * rng.standard_normal(n)
        ds = xr.Dataset(
            {
                "u": (("time",), u),
                "v": (("time",), v),
                "w": (("time",), v3),
                "temperature": (("time",), temperature),
                "diagnostic": (("time",), np.zeros(n, dtype=np.int64)),
            },
            coords={"time": (("time",), time)},
            attrs={
                "instrument": "cwproc virtual sonic (Meteo-2 layout)",
                "frame": "instrument x, y, z axes",
                "orientation_deg": 0.0,
                "sampling_rate_hz": rate_hz,
            },
        )
        yield ds
        k0 += n


def simulate_sonic_dataset(**kwargs) -> xr.Dataset:
    """The whole synthetic record as one dataset (arguments of :func:`iter_sonic_chunks`)."""
    return xr.concat(list(iter_sonic_chunks(**kwargs)), dim="time")


def sonic_truth(
    *,
    hours: float,
    sf_type: int = 1,
    seed: int = 0,
    speed: float = 6.0,
    direction_deg: float = 30.0,
    rate_hz: float = METEO2_RATE_HZ,
    start: str = "2014-06-01T00:00:00",
    models: tuple[SFModel, SFModel, SFModel] | None = None,
) -> SonicTruth:
    """The prescribed truth of a simulation (same arguments as the generator)."""
    models = models or default_models(sf_type)
    covs = component_covariances(models, speed, rate_hz)
    n_chunk = int(np.floor(3600.0 * rate_hz + 1e-9))
    size = scipy.fft.next_fast_len(n_chunk + max(c.size for c in covs) + 1)
    neg = max(circulant_sqrt_spectrum(c, size)[1] for c in covs)
    return SonicTruth(
        sf_type=models[0].sf_type,
        models=[asdict(m) for m in models],
        mean_speed_m_s=speed,
        direction_deg=direction_deg,
        sampling_rate_hz=rate_hz,
        start=start,
        hours=hours,
        seed=seed,
        negative_eigenvalue_share=neg,
    )


def write_simulation(
    outdir: str | os.PathLike,
    *,
    hours: float = 1.0,
    sf_type: int = 1,
    seed: int = 0,
    speed: float = 6.0,
    direction_deg: float = 30.0,
    start: str = "2014-06-01T00:00:00",
) -> tuple[list[Path], Path]:
    """Write a synthetic record as Meteo-2 files (one per UTC day) plus ``truth.json``.

    Returns
    -------
    files : list of Path
        The Meteo-2 files.
    truth : Path
        The JSON truth file.
    """

    outdir = Path(outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    args = dict(
        hours=hours,
        sf_type=sf_type,
        seed=seed,
        speed=speed,
        direction_deg=direction_deg,
        start=start,
    )
    by_day: dict[str, list[xr.Dataset]] = {}
    for chunk in iter_sonic_chunks(**args):
        day = np.datetime_as_string(chunk["time"].values[0], unit="D").replace("-", "")
        by_day.setdefault(day, []).append(chunk)
    files = []
    for day, chunks in sorted(by_day.items()):
        path = outdir / f"meteo2_sim_type{sf_type}_{day}.txt"
        write_meteo2(xr.concat(chunks, dim="time"), path, station="cwproc simulator")
        files.append(path)
    truth = write_truth(
        outdir / f"meteo2_sim_type{sf_type}_truth.json",
        asdict(sonic_truth(**args)),
        sort_keys=False,
    )
    return files, truth
