"""Cached tables of the A-functions of one instrument configuration.

The A-functions of Smalikho (2020), eqs. 15-17 are expensive double integrals, but for a
given instrument (probe volume, elevation ``phi``, azimuth step ``dtheta``, spectrum
model) they depend only on the height ``h`` (which fixes ``dy = dtheta h / tan(phi)`` and,
for a cw lidar, the focus distance ``R = h / sin(phi)`` and so ``Z_R``), the lag number
``l``, ``mu = U / V_s`` and, for the finite-outer-scale models, ``L_V``. :func:`get_a_table`
computes them once on a grid over these variables and caches the result on disk;
:meth:`ATable.evaluate` interpolates.

Grid and interpolation. Heights: geometric, ratio 1.2; ``mu``: step 0.05 up to 2, 0.1 up
to 4, 0.25 beyond; outer scale: geometric, ratio 1.3. ``log A`` is interpolated with
4-point Lagrange (cubic) weights along each axis (``log h``, ``mu``, ``log L_V``); lags
are the integers ``1..n_lags``. The interpolation error is below 1e-4 relative (tested
against direct evaluation at points between the nodes). Outside the grid ``evaluate``
returns NaN.

Cache. Files ``atable-<sha256>.npz`` in ``platformdirs.user_cache_dir("cwproc")`` (or
``cache_dir``), keyed by a hash of every parameter and of :data:`TABLE_VERSION`; written
atomically (temporary file, then rename). A cache file that cannot be read, has the wrong
key or shapes, or holds non-finite values is rebuilt, never trusted. An unwritable cache
directory only costs the rebuild next time. With the default cache, a table missing
there is looked up next among the prebuilt tables shipped in the package
(``cwproc/atables/``, made at release by ``tools/build_atables.py`` for the shipped
presets and samples), so that a new user never waits; a table that must be built
announces itself on stderr when that is a terminal.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import platformdirs
from numpy.typing import ArrayLike

from cwproc.physics import afunctions
from cwproc.physics.spectra import MODELS, Model
from cwproc.physics.transfer import CWProbe, Probe, PulsedProbe

#: bump when the numerics or the grid change: old cache files are then ignored
TABLE_VERSION = 4
#: geometric ratio of the height nodes
HEIGHT_RATIO = 1.2
#: geometric ratio of the outer-scale nodes
OUTER_SCALE_RATIO = 1.3


def default_mu_grid(mu_max: float = 10.0) -> np.ndarray:
    """Nodes of ``mu``: step 0.05 to 2, 0.1 to 4, 0.25 beyond, up to ``mu_max``."""
    grid = np.concatenate(
        [np.arange(0.0, 2.0, 0.05), np.arange(2.0, 4.0, 0.1), np.arange(4.0, mu_max + 1e-9, 0.25)]
    )
    grid = grid[grid <= mu_max + 1e-9]
    if grid[-1] < mu_max:
        grid = np.append(grid, mu_max)
    return np.round(grid, 10)


def _geometric(lo: float, hi: float, ratio: float) -> np.ndarray:
    n = max(4, math.ceil(math.log(hi / lo) / math.log(ratio)) + 1)
    return np.geomspace(lo, hi, n)


def _lagrange4(nodes: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Indices ``(q, 4)``, weights ``(q, 4)`` of cubic Lagrange interpolation, and validity.

    Near the ends the 4-point stencil is shifted inwards; points outside ``[nodes[0],
    nodes[-1]]`` are flagged invalid.
    """
    x = np.asarray(x, dtype=float).ravel()
    n = nodes.size
    valid = (x >= nodes[0] - 1e-12 * abs(nodes[0])) & (x <= nodes[-1] + 1e-12 * abs(nodes[-1]))
    valid &= np.isfinite(x)
    xc = np.clip(np.where(np.isfinite(x), x, nodes[0]), nodes[0], nodes[-1])
    if n < 4:
        raise ValueError("an interpolation axis needs at least 4 nodes")
    i = np.clip(np.searchsorted(nodes, xc, side="right") - 2, 0, n - 4)
    idx = i[:, None] + np.arange(4)[None, :]
    xn = nodes[idx]  # (q, 4)
    w = np.ones((x.size, 4))
    for j in range(4):
        for k in range(4):
            if j != k:
                w[:, j] *= (xc - xn[:, k]) / (xn[:, j] - xn[:, k])
    return idx, w, valid


@dataclass(frozen=True)
class ATable:
    """Tabulated ``A_1 = A_perp(l dy)`` and ``A_2(l dy; mu)`` of one configuration.

    Attributes
    ----------
    heights_m : (nh,) heights (m) of the nodes.
    mu : (nm,) nodes of ``mu = U / V_s``.
    outer_scales_m : (nL,) nodes of ``L_V`` (m); ``(1,)`` NaN for the inertial model.
    log_a1 : (nL, nh, n_lags) ``ln A_1`` (A in m^(2/3)).
    log_a2 : (nL, nh, n_lags, nm) ``ln A_2``.
    params : the parameters the table was built for (also its cache key).
    """

    heights_m: np.ndarray
    mu: np.ndarray
    outer_scales_m: np.ndarray
    log_a1: np.ndarray
    log_a2: np.ndarray
    params: dict = field(default_factory=dict)

    @property
    def n_lags(self) -> int:
        """Number of lags ``l = 1..n_lags`` in the table."""
        return self.log_a1.shape[-1]

    @property
    def model(self) -> str:
        """Spectrum model of the table."""
        return str(self.params["model"])

    def dy(self, height_m: ArrayLike) -> np.ndarray:
        """Nominal transverse sampling ``dy = dtheta h / tan(phi)`` (m) at ``height_m`` (m).

        A cw probe with a known beam radius samples a circle of a smaller radius
        (:meth:`cwproc.physics.transfer.CWProbe.centre_range`); the table's lags use it.
        """
        phi = math.radians(self.params["phi_deg"])
        return math.radians(self.params["delta_theta_deg"]) * np.asarray(height_m) / math.tan(phi)

    def evaluate(
        self,
        lags: ArrayLike,
        height_m: ArrayLike,
        mu: ArrayLike,
        outer_scale_m: ArrayLike | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """``(A_1, A_2)`` (m^(2/3)) at lag numbers, heights, ``mu`` and outer scales.

        Parameters
        ----------
        lags : array_like of int
            Lag numbers ``l`` in ``1..n_lags``.
        height_m : array_like
            Heights (m) above the lidar.
        mu : array_like
            ``U / V_s`` (1).
        outer_scale_m : array_like, optional
            ``L_V`` (m); required for finite-outer-scale tables, ignored otherwise.

        All inputs broadcast. Points outside the tabulated ranges give NaN.
        """
        finite_l = self.model != "inertial"
        if finite_l and outer_scale_m is None:
            raise ValueError(f"a {self.model!r} table needs outer_scale_m")
        lval = outer_scale_m if finite_l else np.nan
        lags_b, h_b, mu_b, l_b = np.broadcast_arrays(
            np.asarray(lags), np.asarray(height_m, float), np.asarray(mu, float), np.asarray(lval)
        )
        shape = lags_b.shape
        lag = np.asarray(lags_b, dtype=float).ravel()
        lag_ok = (lag >= 1) & (lag <= self.n_lags) & (lag == np.round(lag))
        li = np.clip(np.where(np.isfinite(lag), lag, 1), 1, self.n_lags).astype(int) - 1
        with np.errstate(divide="ignore", invalid="ignore"):
            im, wm, vm = _lagrange4(self.mu, mu_b.ravel())
            if finite_l:
                il, wl, vl = _lagrange4(
                    np.log(self.outer_scales_m), np.log(l_b.astype(float).ravel())
                )
            else:
                il = np.zeros((lag.size, 1), int)
                wl = np.ones((lag.size, 1))
                vl = np.ones(lag.size, bool)
        # Interpolate in height first, once per distinct height (a day of blocks shares a
        # few hundred heights), then gather only the 4 x 4 (L_V, mu) neighbours per point.
        h_flat = h_b.ravel()
        h_unique, h_inverse = np.unique(h_flat, return_inverse=True)
        h_inverse = h_inverse.ravel()
        with np.errstate(divide="ignore", invalid="ignore"):
            ihu, whu, vhu = _lagrange4(np.log(self.heights_m), np.log(h_unique))
        vh = vhu[h_inverse]
        # (nL, n_unique, n_lag) and (nL, n_unique, n_lag, nm)
        a1_h = np.einsum("lukj,uk->luj", self.log_a1[:, ihu, :], whu)
        a2_h = np.einsum("lukjm,uk->lujm", self.log_a2[:, ihu, :, :], whu)
        n_u, n_lag, n_m = h_unique.size, self.n_lags, self.mu.size
        base = (il * n_u + h_inverse[:, None]) * n_lag + li[:, None]  # (q, a)
        log1 = np.einsum("qa,qa->q", wl, a1_h.ravel().take(base))
        vals2 = a2_h.ravel().take(base[:, :, None] * n_m + im[:, None, :])  # (q, a, 4)
        log2 = np.einsum("qa,qac,qc->q", wl, vals2, wm, optimize=True)
        ok1 = lag_ok & vh & vl
        ok2 = ok1 & vm
        out1 = np.where(ok1, np.exp(log1), np.nan).reshape(shape)
        out2 = np.where(ok2, np.exp(log2), np.nan).reshape(shape)
        return out1, out2


def _probe_params(probe: Probe) -> dict:
    if isinstance(probe, PulsedProbe):
        return {
            "kind": "pulsed",
            "delta_p_m": float(probe.delta_p_m),
            "delta_r_m": float(probe.delta_r_m),
            "gaussian": probe.gaussian,
        }
    if isinstance(probe, CWProbe):
        z_d = probe.focal_parameter_m
        return {
            "kind": "cw",
            "z_r_coefficient_per_m": float(probe.coefficient),
            "focal_parameter_m": None if z_d is None else float(z_d),
            "transverse_averaging": bool(probe.transverse_averaging),
        }
    raise TypeError(f"unknown probe {probe!r}")


def table_parameters(
    probe: Probe,
    *,
    phi_deg: float,
    delta_theta_deg: float,
    n_lags: int,
    model: Model = "inertial",
    height_range_m: tuple[float, float] = (10.0, 3000.0),
    mu_max: float = 10.0,
    outer_scale_range_m: tuple[float, float] = (10.0, 3000.0),
) -> dict:
    """The validated parameter dictionary of a table (its cache key is a hash of it)."""
    if model not in MODELS:
        raise ValueError(f"unknown model {model!r}; choose one of {', '.join(MODELS)}")
    if not 0 < phi_deg < 90:
        raise ValueError(f"phi_deg must be in (0, 90), got {phi_deg!r}")
    if not 0 < delta_theta_deg <= 90:
        raise ValueError(f"delta_theta_deg must be in (0, 90], got {delta_theta_deg!r}")
    if int(n_lags) < 2:
        raise ValueError("n_lags must be >= 2")
    h0, h1 = (float(v) for v in height_range_m)
    if not 0 < h0 < h1:
        raise ValueError("height_range_m must be (low, high) with 0 < low < high")
    l0, l1 = (float(v) for v in outer_scale_range_m)
    if not 0 < l0 < l1:
        raise ValueError("outer_scale_range_m must be (low, high) with 0 < low < high")
    if not mu_max > 0:
        raise ValueError("mu_max must be > 0")
    return {
        "version": TABLE_VERSION,
        "probe": _probe_params(probe),
        "phi_deg": float(phi_deg),
        "delta_theta_deg": float(delta_theta_deg),
        "n_lags": int(n_lags),
        "model": model,
        "height_range_m": [h0, h1],
        "mu_max": float(mu_max),
        "outer_scale_range_m": [l0, l1] if model != "inertial" else None,
    }


def table_key(params: dict) -> str:
    """SHA-256 of the canonical JSON of the table parameters."""
    text = json.dumps(params, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


def build_a_table(probe: Probe, params: dict) -> ATable:
    """Compute a table (no cache): ``A_1`` and ``A_2`` on the grid of ``params``.

    For every height node (and outer scale) the curves ``A_perp``, ``A_par`` of the lag are
    computed once (:func:`cwproc.physics.afunctions.a_curve_splines`) and eq. 15 is
    averaged for all lags and ``mu`` at once.
    """
    phi = params["phi_deg"]
    n_lags = params["n_lags"]
    model = params["model"]
    heights = _geometric(*params["height_range_m"], HEIGHT_RATIO)
    mu = default_mu_grid(params["mu_max"])
    if model == "inertial":
        scales = np.array([np.nan])
    else:
        scales = _geometric(*params["outer_scale_range_m"], OUTER_SCALE_RATIO)
    dtheta = math.radians(params["delta_theta_deg"])
    lags = np.arange(1, n_lags + 1, dtype=float)
    log_a1 = np.empty((scales.size, heights.size, n_lags))
    log_a2 = np.empty((scales.size, heights.size, n_lags, mu.size))
    ranges = heights / math.sin(math.radians(phi))
    # the probe centre samples the circle of radius R_c cos(phi): R_c = R for a pulsed
    # gate, R/(1 + (R/z_d)^2) for a cw focus (Banakh et al. (1999), Q_s)
    dys = dtheta * np.asarray(probe.centre_range(ranges), float) * math.cos(math.radians(phi))
    rho_lo = 0.02 * dys
    rho_hi = n_lags * dys * (1.0 + params["mu_max"]) * 1.01
    for i, big_l in enumerate(scales):
        outer = None if model == "inertial" else float(big_l)
        # one spectrum matrix over the wavenumbers of all heights (the costliest part)
        limits = [
            afunctions.panel_limits(
                lo,
                hi,
                probe=probe,
                dy=float(probe.transverse_size(dy)),
                range_m=rng,
                model=model,
                outer_scale_m=outer,
            )
            for lo, hi, dy, rng in zip(rho_lo, rho_hi, dys, ranges, strict=True)
        ]
        plane = afunctions.PlaneMatrix(
            min(lim[0] for lim in limits), max(lim[1] for lim in limits), model, outer
        )
        for j in range(heights.size):
            dy = float(dys[j])
            curves = afunctions.a_curve_splines(
                float(rho_lo[j]),
                float(rho_hi[j]),
                probe=probe,
                dy=float(probe.transverse_size(dy)),
                range_m=float(ranges[j]),
                model=model,
                outer_scale_m=outer,
                plane=plane,
            )
            log_a1[i, j] = np.log(curves.perp(lags * dy))
            a2v = afunctions.a2_from_curves(curves, (lags * dy)[:, None], mu[None, :], phi)
            log_a2[i, j] = np.log(a2v)
    return ATable(heights, mu, scales, log_a1, log_a2, dict(params))


def _cache_path(cache_dir: str | os.PathLike | None, key: str) -> Path:
    base = Path(cache_dir) if cache_dir is not None else Path(platformdirs.user_cache_dir("cwproc"))
    return base / f"atable-{key}.npz"


def _load(path: Path, key: str, params: dict) -> ATable | None:
    """The cached table at ``path``, or ``None`` if it is missing, corrupt or not this one."""
    try:
        with np.load(path, allow_pickle=False) as data:
            if str(data["key"]) != key:
                return None
            table = ATable(
                np.array(data["heights_m"]),
                np.array(data["mu"]),
                np.array(data["outer_scales_m"]),
                np.array(data["log_a1"]),
                np.array(data["log_a2"]),
                dict(params),
            )
    except Exception:  # any unreadable/corrupt file is rebuilt, never trusted
        return None
    nl, nh, nm = table.outer_scales_m.size, table.heights_m.size, table.mu.size
    ok = (
        table.log_a1.shape == (nl, nh, params["n_lags"])
        and table.log_a2.shape == (nl, nh, params["n_lags"], nm)
        and np.isfinite(table.log_a1).all()
        and np.isfinite(table.log_a2).all()
        and nh >= 4
        and nm >= 4
    )
    return table if ok else None


def _save(table: ATable, path: Path, key: str) -> None:
    """Write atomically (temporary file in the same directory, then rename)."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=".atable-", suffix=".npz.part", dir=path.parent)
        try:
            with os.fdopen(fd, "wb") as fh:
                np.savez(
                    fh,
                    key=np.array(key),
                    heights_m=table.heights_m,
                    mu=table.mu,
                    outer_scales_m=table.outer_scales_m,
                    log_a1=table.log_a1,
                    log_a2=table.log_a2,
                )
            os.replace(tmp, path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
    except OSError:
        return  # an unwritable cache only costs a rebuild next time


def get_a_table(
    probe: Probe,
    *,
    phi_deg: float,
    delta_theta_deg: float,
    n_lags: int,
    model: Model = "inertial",
    cache_dir: str | os.PathLike | None = None,
    height_range_m: tuple[float, float] = (10.0, 3000.0),
    mu_max: float = 10.0,
    outer_scale_range_m: tuple[float, float] = (10.0, 3000.0),
) -> ATable:
    """The A-function table of one instrument configuration, from the cache or computed.

    Parameters
    ----------
    probe : PulsedProbe or CWProbe
        Probe volume (:func:`cwproc.physics.transfer.probe_from_config`).
    phi_deg : float
        Elevation of the scan cone (degrees).
    delta_theta_deg : float
        Azimuth step between rays (degrees); ``dy = dtheta h / tan(phi)``.
    n_lags : int
        Largest lag number ``l`` tabulated (lags ``1..n_lags``).
    model : {"inertial", "von_karman", "exponential"}
        Spectrum model; the finite-outer-scale models add the ``L_V`` axis.
    cache_dir : path, optional
        Cache directory; default ``platformdirs.user_cache_dir("cwproc")``.
    height_range_m : (float, float)
        Heights (m) covered.
    mu_max : float
        Largest ``mu = U / V_s`` covered.
    outer_scale_range_m : (float, float)
        ``L_V`` (m) covered by finite-outer-scale tables.

    Returns
    -------
    ATable
    """
    params = table_parameters(
        probe,
        phi_deg=phi_deg,
        delta_theta_deg=delta_theta_deg,
        n_lags=n_lags,
        model=model,
        height_range_m=height_range_m,
        mu_max=mu_max,
        outer_scale_range_m=outer_scale_range_m,
    )
    key = table_key(params)
    path = _cache_path(cache_dir, key)
    table = _load(path, key, params)
    if table is not None:
        return table
    if cache_dir is None:
        table = _load(shipped_path(key), key, params)
        if table is not None:
            return table
    started = time.monotonic()
    _progress(
        f"cwproc: building the A-function table of this configuration ({model}), once; "
        f"cached in {path.parent} ..."
    )
    table = build_a_table(probe, params)
    _progress(f" done in {time.monotonic() - started:.0f} s\n")
    _save(table, path, key)
    return table


#: package folder of the prebuilt tables shipped in the wheel (``tools/build_atables.py``)
SHIPPED_PACKAGE = "cwproc.atables"


def shipped_path(key: str) -> Path:
    """Where a prebuilt table of ``key`` ships inside the package (it may not exist)."""
    from importlib import resources

    return Path(str(resources.files(SHIPPED_PACKAGE).joinpath(f"atable-{key}.npz")))


def _progress(text: str) -> None:
    """A note on stderr when it is a terminal (a table build takes tens of seconds)."""
    if sys.stderr is not None and sys.stderr.isatty():
        sys.stderr.write(text)
        sys.stderr.flush()
