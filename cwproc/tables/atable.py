"""The A-function tables of the table store: cache, shipped tables, build.

:func:`get_a_table` gives the table of one instrument configuration
(:func:`cwproc.physics.atable.build_a_table`, Smalikho (2020), eqs. 15-17): from the
cache, files ``atable-<sha256>.npz`` in :func:`cwproc.tables.store.default_cache_dir`
(or ``cache_dir``), keyed by a hash of every parameter and of the code of the physics
modules the build uses (:func:`code_version`, so that a change of the code is never
served an old table); written atomically (temporary file, then rename). A cache file
that cannot be read, has the wrong key or shapes, or holds non-finite values is
rebuilt, never trusted. An unwritable cache directory only costs the rebuild next
time. With the default cache, a table missing there is looked up next among the
prebuilt tables shipped in the package (:mod:`cwproc.atables`, made at release by
``tools/build_atables.py`` for the shipped presets and samples), so that a new user
never waits; a table that must be built shows a :mod:`cwproc.progress` bar (only when
the command line turned progress on).
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np

from cwproc import progress
from cwproc.physics import atable as physics_atable
from cwproc.physics.atable import build_a_table, probe_from_params, table_key
from cwproc.physics.atable_interp import N_BINS, ATable
from cwproc.physics.spectra import Model
from cwproc.physics.transfer import Probe
from cwproc.tables.store import cache_path, code_digest, load_arrays, save_arrays

__all__ = [
    "CODE_ROOT",
    "SHIPPED_PACKAGE",
    "build_a_table",
    "code_version",
    "get_a_table",
    "probe_from_params",
    "save_table",
    "shipped_path",
    "table_key",
    "table_parameters",
    "terminal_bar",
]

#: the module whose code a table depends on: its source and that of the physics modules
#: it imports are hashed into the key (:func:`cwproc.tables.store.code_digest`)
CODE_ROOT = "cwproc.physics.atable"
#: package folder of the prebuilt tables shipped in the wheel (``tools/build_atables.py``)
SHIPPED_PACKAGE = "cwproc.atables"


def code_version() -> str:
    """Hash of the code the tables depend on (the ``"code"`` entry of their parameters).

    :func:`cwproc.tables.store.code_digest` of :data:`CODE_ROOT` and the physics
    modules it uses: any change of them gives every table a new key, so that a cached
    or shipped table never outlives the code that computed it.
    """
    return code_digest(CODE_ROOT)


def table_parameters(probe: Probe, **options) -> dict:
    """:func:`cwproc.physics.atable.table_parameters` with the key of the current code.

    ``options``: the keywords of :func:`cwproc.physics.atable.table_parameters` but
    ``code``, which is :func:`code_version`.
    """
    return physics_atable.table_parameters(probe, code=code_version(), **options)


@contextlib.contextmanager
def terminal_bar(description: str, total: int) -> Iterator[Callable[[int], None]]:
    """A :data:`cwproc.physics.atable.Bar` on the terminal (:func:`cwproc.progress.bar`:
    drawn only when the command line turned progress on)."""
    with progress.bar(desc=description, total=total) as shown:
        yield shown.update


def _load(path: Path, key: str, params: dict) -> ATable | None:
    """The stored table at ``path``, or ``None`` if it is missing, corrupt or not this one."""
    data = load_arrays(path, key)
    if data is None:
        return None
    try:
        table = ATable(
            data["heights_m"],
            data["mu"],
            data["outer_scales_m"],
            data["log_a1"],
            data["log_a2"],
            dict(params),
            data["bins_a2"] if params["model"] == "inertial" else None,
            data["scale_bins"] if data["scale_bins"].size else None,
        )
    except Exception:  # an array missing or unusable: rebuilt, never trusted
        return None
    nl, nh, nm = table.outer_scales_m.size, table.heights_m.size, table.mu.size
    n_lags = params["n_lags"]
    ok = (
        table.log_a1.shape == (nl, nh, n_lags)
        and table.log_a2.shape == (nl, nh, n_lags, nm)
        and np.isfinite(table.log_a1).all()
        and np.isfinite(table.log_a2).all()
        and (
            table.bins_a2 is None
            or (
                table.bins_a2.shape == (nl, nh, n_lags, nm, N_BINS)
                and np.isfinite(table.bins_a2).all()
            )
        )
        and (
            table.scale_bins is None
            or (
                table.scale_bins.shape == (nl, n_lags, nm, N_BINS)
                and np.isfinite(table.scale_bins).all()
            )
        )
        and nh >= 4
        and nm >= 4
    )
    return table if ok else None


def save_table(table: ATable, path: Path, key: str) -> None:
    """Write ``table`` under ``key`` atomically (:func:`cwproc.tables.store.save_arrays`)."""
    save_arrays(
        path,
        {
            "key": np.array(key),
            "heights_m": table.heights_m,
            "mu": table.mu,
            "outer_scales_m": table.outer_scales_m,
            "log_a1": table.log_a1,
            "log_a2": table.log_a2,
            "bins_a2": np.zeros(0) if table.bins_a2 is None else table.bins_a2,
            "scale_bins": np.zeros(0) if table.scale_bins is None else table.scale_bins,
        },
    )


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
    swept: bool = True,
    geometry: str | None = None,
    dwell: float = 0.0,
) -> ATable:
    """The A-function table of one instrument configuration, stored or computed.

    Parameters
    ----------
    probe : PulsedProbe or CWProbe
        Probe volume (:func:`cwproc.pipeline.probe_from_config`).
    phi_deg : float
        Elevation of the scan cone (degrees).
    delta_theta_deg : float
        Azimuth step between rays (degrees); ``dy = dtheta h / tan(phi)``.
    n_lags : int
        Largest lag number ``l`` tabulated (lags ``1..n_lags``).
    model : {"inertial", "von_karman", "exponential"}
        Spectrum model; the finite-outer-scale models add the ``L_V`` axis.
    cache_dir : path, optional
        Cache directory; default :func:`cwproc.tables.store.default_cache_dir` (then
        the shipped tables).
    height_range_m : (float, float)
        Heights (m) covered.
    mu_max : float
        Largest ``mu = U / V_s`` covered.
    outer_scale_range_m : (float, float)
        ``L_V`` (m) covered by finite-outer-scale tables.
    swept, geometry, dwell
        See :func:`cwproc.physics.atable.table_parameters`.

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
        swept=swept,
        geometry=geometry,
        dwell=dwell,
    )
    key = table_key(params)
    path = cache_path(cache_dir, "atable", key)
    table = _load(path, key, params)
    if table is not None:
        return table
    if cache_dir is None:
        table = _load(shipped_path(key), key, params)
        if table is not None:
            return table
    table = build_a_table(probe, params, terminal_bar)
    save_table(table, path, key)
    return table


def shipped_path(key: str) -> Path:
    """Where a prebuilt table of ``key`` ships inside the package (it may not exist)."""
    from importlib import resources

    return Path(str(resources.files(SHIPPED_PACKAGE).joinpath(f"atable-{key}.npz")))
