"""Tables of the A-functions of one instrument configuration.

The A-functions of Smalikho (2020), eqs. 15-17 are expensive double integrals, but for a
given instrument (probe volume, elevation ``phi``, azimuth step ``dtheta``, spectrum
model) they depend only on the height ``h`` (which fixes ``dy = dtheta h / tan(phi)`` and,
for a cw lidar, the focus distance ``R = h / sin(phi)`` and so ``Z_R``), the lag number
``l``, ``mu = U / V_s`` and, for the finite-outer-scale models, ``L_V``. :func:`build_a_table`
computes them once on a grid over these variables (the table store
:mod:`cwproc.tables.atable` keeps them on disk);
:meth:`cwproc.physics.atable_interp.ATable.evaluate` interpolates.

Grid and interpolation. Heights: geometric, ratio 1.2; ``mu``: step 0.05 up to 2, 0.1 up
to 4, 0.25 beyond; outer scale: geometric, ratio 1.3. ``log A`` is interpolated with
4-point Lagrange (cubic) weights along each axis (``log h``, ``mu``, ``log L_V``); lags
are the integers ``1..n_lags``. The interpolation error is below 1e-4 relative (tested
against direct evaluation at points between the nodes). Outside the grid ``evaluate``
returns NaN.

Parameters and key. :func:`table_parameters` validates a configuration into the
dictionary whose hash (:func:`table_key`) names the table; its ``"code"`` entry is the
hash of the physics code the build uses, given by the table store
(:func:`cwproc.tables.atable.code_version`), so that a stored table never outlives the
code that computed it. The build reports its progress only through the ``bar``
callback it is given (:data:`Bar`): this module reads no file, no environment and
writes nothing.

Speed. The spectrum-independent quadrature weights of each height
(:class:`cwproc.physics.curve_kernel.CurveKernel`) serve every ``L_V`` node; the
inertial swept pairs of a geometry serve its finite-outer-scale table; the pairs are
computed at every :data:`PAIRS_STRIDE`-th height node and interpolated in ``log R``
between them (:func:`cwproc.physics.atable_swept.by_height`, within 2e-4 of direct
evaluation, tested).
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager

import numpy as np
from scipy import sparse

from cwproc.physics import afunctions, atable_swept, spectra
from cwproc.physics.atable_geometry import (
    azimuth_to_nodes,
    circle_halves,
    eq15_points,
    full_circle,
    pair_geometry_terms,
    per_theta_half_a2,
)
from cwproc.physics.atable_interp import N_BINS, ATable
from cwproc.physics.canonical_key import parameter_key
from cwproc.physics.curve_kernel import CurveKernel, CurveStack, shared_plane
from cwproc.physics.spectra import MODELS, Model
from cwproc.physics.transfer import CWProbe, Probe, PulsedProbe

#: a progress report of a build step: ``bar(description, total)`` is a context manager
#: giving ``advance(n)``, called as ``n`` of the ``total`` items are done
#: (:func:`cwproc.tables.atable.get_a_table` draws it on the terminal)
Bar = Callable[[str, int], AbstractContextManager[Callable[[int], None]]]


@contextlib.contextmanager
def no_bar(description: str, total: int) -> Iterator[Callable[[int], None]]:
    """The :data:`Bar` that reports nothing (the default of :func:`build_a_table`)."""
    yield lambda n: None


#: geometry models of a table
GEOMETRIES = ("two_beam", "small_angle")
#: geometric ratio of the height nodes
HEIGHT_RATIO = 1.2
#: geometric ratio of the outer-scale nodes
OUTER_SCALE_RATIO = 1.3
#: the swept pairs are computed at every PAIRS_STRIDE-th height node and interpolated
#: in between (:func:`cwproc.physics.atable_swept.by_height`)
PAIRS_STRIDE = 2
#: ... except where the probe's range offsets ``sqrt(3) sigma_v / R`` exceed this (1)
PAIRS_DIRECT_OFFSET = 0.25
#: step of the dwell fraction of step-stare tables (:func:`table_dwell_step`): a dwell
#: 0.025 off changes D(1) by under 0.3 % at mu = 3 (the largest effect, 15 deg steps)
DWELL_STEP = 0.05


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


def probe_from_params(probe: dict) -> Probe:
    """The probe of a table's ``params["probe"]`` (:func:`table_parameters`)."""
    if probe["kind"] == "pulsed":
        return PulsedProbe(probe["delta_p_m"], probe["delta_r_m"], probe["gaussian"])
    averaging = bool(probe["transverse_averaging"])
    z_d = probe["focal_parameter_m"]
    if z_d is None:
        return CWProbe(probe["z_r_coefficient_per_m"], transverse_averaging=averaging)
    # a beam radius of 1 m and the wavelength of z_d = 2 pi a0^2 / lambda, to the last bit
    wavelength = 2.0 * math.pi / z_d
    for _ in range(64):
        made = CWProbe(wavelength_m=wavelength, beam_radius_m=1.0, transverse_averaging=averaging)
        if made.focal_parameter_m == z_d:
            break
        wavelength = math.nextafter(wavelength, 0.0 if made.focal_parameter_m < z_d else math.inf)
    return made


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
    swept: bool = True,
    geometry: str | None = None,
    dwell: float = 0.0,
    code: str = "",
) -> dict:
    """The validated parameter dictionary of a table (its key is a hash of it).

    ``swept``: each ray is accumulated while the beam sweeps its azimuth step (continuous
    scan: the rays seen at their own times, :mod:`cwproc.physics.atable_swept`; with
    ``geometry="small_angle"`` ``H_perp`` of Smalikho (2020), eq. 20), ``False`` for
    step-stare rays.
    ``dwell``: step-stare rays only, the dwell fraction ``d = T_d / tau`` (ray dwell over
    ray period, in ``[0, 1]``): each ray averages the field the wind carries past during
    ``T_d`` (:func:`cwproc.physics.atable_swept.dwell_kernel`); 0 for instantaneous rays.
    Rounded to :data:`DWELL_STEP` (the tables of nearby dwells are the same within the
    interpolation error); swept rays ignore it (their rays last the whole ray period).
    ``geometry``: ``"two_beam"`` (exact pair geometry, :func:`geometry_correction`) or
    ``"small_angle"`` (Smalikho (2020), eq. 15 alone); ``None``: ``"two_beam"`` for a
    pulsed probe, ``"small_angle"`` for a cw probe (whose Lorentzian, longer than the
    separations, lets the beam spacing vary along the probe, which the point-probe
    correction does not describe; cw cells with finite outer scales use the exact model
    of :class:`cwproc.physics.exact_lag.ExactLagModel`).
    ``code``: the hash of the code that builds the table (the ``"code"`` entry, so that
    a stored table is never served to other code;
    :func:`cwproc.tables.atable.code_version`); empty for a table built and used in
    memory.
    """
    if geometry is None:
        geometry = "small_angle" if isinstance(probe, CWProbe) else "two_beam"
    if model not in MODELS:
        raise ValueError(f"unknown model {model!r}; choose one of {', '.join(MODELS)}")
    if not 0 < phi_deg < 90:
        raise ValueError(f"phi_deg must be in (0, 90), got {phi_deg!r}")
    if not 0 < delta_theta_deg <= 120:
        raise ValueError(f"delta_theta_deg must be in (0, 120], got {delta_theta_deg!r}")
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
    if geometry not in GEOMETRIES:
        raise ValueError(f"geometry must be one of {', '.join(GEOMETRIES)}, got {geometry!r}")
    if not 0.0 <= float(dwell) <= 1.0:
        raise ValueError(f"dwell must be a fraction of the ray period in [0, 1], got {dwell!r}")
    extra = {}
    if not swept and geometry == "two_beam" and isinstance(probe, PulsedProbe):
        extra["dwell"] = table_dwell_step(dwell)
    return {
        "swept": bool(swept),
        **extra,
        "geometry": geometry,
        "code": str(code),
        "probe": _probe_params(probe),
        "phi_deg": float(phi_deg),
        "delta_theta_deg": float(delta_theta_deg),
        "n_lags": int(n_lags),
        "model": model,
        "height_range_m": [h0, h1],
        "mu_max": float(mu_max),
        "outer_scale_range_m": [l0, l1] if model != "inertial" else None,
    }


def table_dwell_step(dwell: float) -> float:
    """The dwell fraction of a table: ``dwell`` rounded to :data:`DWELL_STEP`, in [0, 1]."""
    return float(min(1.0, max(0.0, round(float(dwell) / DWELL_STEP) * DWELL_STEP)))


def table_key(params: dict) -> str:
    """SHA-256 of the canonical JSON of the table parameters."""
    return parameter_key(params)


#: the swept pairs of the last tables built (:func:`_memo_swept_pairs`)
_PAIRS_MEMO: dict[str, list[np.ndarray]] = {}


def _table_nodes(params: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The height (m), ``mu`` and outer-scale (m; NaN for an inertial table) nodes of a
    table (ratios :data:`HEIGHT_RATIO`, :data:`OUTER_SCALE_RATIO`)."""
    heights = _geometric(*params["height_range_m"], HEIGHT_RATIO)
    mu = default_mu_grid(params["mu_max"])
    if params["model"] == "inertial":
        return heights, mu, np.array([np.nan])
    return heights, mu, _geometric(*params["outer_scale_range_m"], OUTER_SCALE_RATIO)


def _height_probes(
    probe: Probe, params: dict, heights: np.ndarray, swept: bool
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(range, dy, transverse probe size)`` (m) at the height nodes: the probe centre
    samples the circle of radius R_c cos(phi), R_c = R for a pulsed gate, R/(1 +
    (R/z_d)^2) for a cw focus (Banakh et al. (1999), Q_s); ``dy = dtheta R_c cos(phi)``;
    no transverse size for step-stare rays."""
    phi = params["phi_deg"]
    ranges = heights / math.sin(math.radians(phi))
    radius = np.asarray(probe.centre_range(ranges), float) * math.cos(math.radians(phi))
    dys = math.radians(params["delta_theta_deg"]) * radius
    perp_size = np.asarray(probe.transverse_size(dys), float) if swept else np.zeros_like(dys)
    return ranges, dys, perp_size


def _curve_kernels(
    probe: Probe,
    params: dict,
    per_height: tuple[np.ndarray, np.ndarray, np.ndarray],
    largest: float | None,
    reach: float = 0.0,
) -> list[CurveKernel]:
    """The A-curve kernel of each height node over the lags of the table
    (:class:`cwproc.physics.curve_kernel.CurveKernel`, from ``0.02 dy`` to ``(L + reach)
    dy (1 + mu_max)``); ``per_height``: :func:`_height_probes`; ``largest``: the largest
    outer scale (m; None for an inertial table); ``reach``: fractional lags beyond the
    last (1 for the nodes of :func:`cwproc.physics.atable_swept.difference_kernel`)."""
    ranges, dys, perp_size = per_height
    rho_lo = 0.02 * dys
    rho_hi = (params["n_lags"] + reach) * dys * (1.0 + params["mu_max"]) * 1.01
    return [
        CurveKernel(
            float(rho_lo[j]),
            float(rho_hi[j]),
            probe=probe,
            dy=float(perp_size[j]),
            range_m=float(ranges[j]),
            outer_scale_m=largest,
        )
        for j in range(ranges.size)
    ]


def _memo_swept_pairs(
    probe: Probe,
    params: dict,
    ranges: np.ndarray,
    dys: np.ndarray,
    mu: np.ndarray,
    same: np.ndarray,
    bar: Bar = no_bar,
) -> list[np.ndarray]:
    """:func:`_swept_pairs`, kept in memory for the next table of the same geometry.

    The inertial pairs do not depend on the spectrum model, and a retrieval asks for the
    inertial table and then the finite-outer-scale one of the same geometry: the second
    reuses the pairs of the first (the last two geometries are kept).
    """
    key = parameter_key(
        {k: v for k, v in params.items() if k not in ("model", "outer_scale_range_m")}
        | {"ranges": ranges.tolist(), "mu": mu.tolist()}
    )
    if key not in _PAIRS_MEMO:
        while len(_PAIRS_MEMO) >= 2:
            _PAIRS_MEMO.pop(next(iter(_PAIRS_MEMO)))
        _PAIRS_MEMO[key] = _swept_pairs(probe, params, ranges, dys, mu, same, bar)
    return _PAIRS_MEMO[key]


def _swept_pairs(
    probe: Probe,
    params: dict,
    ranges: np.ndarray,
    dys: np.ndarray,
    mu: np.ndarray,
    same: np.ndarray,
    bar: Bar = no_bar,
) -> list[np.ndarray]:
    """Per height the inertial A_2 integrand of the pairs of rays (plane A-function).

    :func:`cwproc.physics.atable_swept.swept_a2` on :func:`full_circle`,
    ``(lags, mu, theta)``; ``same`` is twice the same-beam term per height. Swept rays
    of continuous scans (``params["swept"]``) take the sweep kernel over fractional lags
    (:func:`cwproc.physics.atable_swept.sweep_kernel`); step-stare rays the pairs at the
    lags averaged over the rays' dwell ``params["dwell"]``
    (:func:`cwproc.physics.atable_swept.dwell_kernel`; the lags themselves,
    :func:`cwproc.physics.atable_swept.stare_kernel`, for instantaneous rays). A pulsed probe
    weights the same lengths at every range, so one plane A-function serves all
    heights; other probes get one per height.
    """
    phi, step = params["phi_deg"], params["delta_theta_deg"]
    lags = np.arange(1, params["n_lags"] + 1, dtype=float)
    theta = full_circle()
    if params.get("swept", True):
        kernel = atable_swept.sweep_kernel(lags)
    else:
        kernel = atable_swept.dwell_kernel(lags, float(params.get("dwell", 0.0)))
    top = (lags[-1] + 1.0) * (2.0 + float(np.max(mu))) * 1.05
    span = (1e-3 * float(np.min(dys)), top * float(np.max(dys)))
    plane = None
    if isinstance(probe, PulsedProbe):
        plane = atable_swept.plane_curves(probe, float(ranges[0]), *span)

    def pairs_at(j: int) -> np.ndarray:
        offsets = atable_swept.offset_rule(probe, float(ranges[j]))
        x_scan, x_wind, _ = atable_swept.kernel_nodes(kernel)
        ratio = atable_swept.geometry_ratio(phi, step, x_scan, mu, theta, offsets, x_wind)
        here = plane or atable_swept.plane_curves(
            probe, float(ranges[j]), 1e-3 * dys[j], top * dys[j]
        )
        return atable_swept.swept_a2(
            here,
            ratio,
            kernel,
            phi_deg=phi,
            delta_theta_deg=step,
            dy=float(dys[j]),
            offsets=offsets,
            same=float(same[j]),
            mu=mu,
            theta=theta,
        )

    with bar("A-table (swept pairs)", ranges.size) as advance:
        offset = [atable_swept.offset_rule(probe, float(r))[0][-1] for r in ranges]
        direct = np.asarray(offset) > PAIRS_DIRECT_OFFSET
        return atable_swept.by_height(pairs_at, ranges, PAIRS_STRIDE, direct, advance)


def _height_cell(
    curves: afunctions.ACurves | CurveStack | None,
    swept: tuple[afunctions.ACurves | None, np.ndarray | None],
    geometry: tuple[float, np.ndarray, np.ndarray],
    lag_m: np.ndarray,
    mu: np.ndarray,
    phi: float,
    sweep: tuple[np.ndarray, ...] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """``A_1`` ``(lags,)`` and the ``A_2`` integrand ``(lags, mu, theta)`` of one height.

    Without pairs (``swept = (None, None)``: cw probes, small-angle geometry): eq. 15 of
    ``curves`` with the point-probe ratios ``g1``, ``g2`` on the cross term, ``(A + 2S) g -
    2S`` (``geometry = (2S, g1, g2)``). Pulsed rays (swept or step-stare): the inertial
    integrand of :func:`_swept_pairs`, ``A_1`` its value at ``mu = 0`` (azimuth
    mean); a finite outer scale adds eq. 15's difference of the model's and the
    inertial curves of the same probe (``swept[0]``) times the point-probe ratio, as the
    step-stare table of eq. 15 would: the outer scale acts on the large separations,
    where the probe's shape and the sweep matter little. (Eq. 15's ratio as a factor
    instead was up to 1.4 % high at lag 3, ``mu`` 3, 15 deg step-stare, and 3.9 % at lag
    4 with 8 deg swept rays, growing with the lag; the difference: within 0.4 % and 1.5 %,
    flat in the lag; h = 100 m, phi 35 deg, ``L_V`` = 200 m, against
    :func:`cwproc.physics.two_beam.two_beam_structure_function`.)

    ``sweep``: swept rays, ``(x dy, K)`` of
    :func:`cwproc.physics.atable_swept.difference_kernel` (m, and ``(lags, nodes)``)
    with ``curves`` and ``swept[0]`` of rays at rest (no ``H_perp``): the difference
    is eq. 15's of sub-beams at the fractional lags ``x``, through the sweep kernel as
    the pairs are, so the ray's own averaging along the path the wind stretches it to,
    ``|e_scan - mu e_wind| dy``, acts on it too. (``H_perp`` at the whole lags averages
    across the scan over ``dy`` only, with no own term: at ``mu`` 3, 5 deg, 165-225 m,
    ``L_V`` 150 m it was 0.9-1.5 % low against the exact two-beam model and the
    reference of issue 29, 0.1 % after.) The eq.-15 ratio of the fallback is that of
    the whole lags. Step-stare rays with a dwell: ``sweep`` is ``(x_scan dy, x_wind dy,
    K)`` of :func:`cwproc.physics.atable_swept.dwell_difference_kernel`, the difference
    through the dwell kernel (:func:`_dwell_difference`).
    """
    s2, g1, g2 = geometry
    inert, pairs = swept
    # per L_V node (curves.one(k)): arrays of one node stay in the cache (2x faster than
    # the whole stack at once); the half circle's eq. 15 broadcast over both halves
    if pairs is None:
        a1 = (curves.perp(lag_m) + s2) * g1 - s2
        out = np.empty((curves.n_curves, *g2.shape))
        points = eq15_points(lag_m, mu, phi)
        for k in range(curves.n_curves):
            half = per_theta_half_a2(curves.one(k), lag_m, mu, phi, points)[0]
            circle_halves(out[k])[...] = (half[..., None, :] + s2) * circle_halves(g2) - s2
        return a1, out
    a1 = pairs[:, 0, :].mean(axis=-1)
    if inert is None:
        return a1, pairs
    points = eq15_points(lag_m, mu, phi)
    inert15 = per_theta_half_a2(inert, lag_m, mu, phi, points)
    a1_diff = curves.perp(lag_m) - inert.perp(lag_m)
    if sweep is not None and len(sweep) == 2:
        a1_diff = (curves.perp(sweep[0]) - inert.perp(sweep[0])) @ sweep[1].T
        swept_diff = _swept_difference(curves, inert, sweep, mu, phi)
    elif sweep is not None:  # (at mu = 0 the dwell moves nothing: a1_diff as it is)
        swept_diff = _dwell_difference(curves, inert, sweep, mu, phi)
    a1_out = _outer_scale_blend(a1, a1_diff, g1, curves.perp(lag_m) / inert.perp(lag_m))
    out = np.empty((curves.n_curves, *pairs.shape))
    for k in range(curves.n_curves):
        model15 = per_theta_half_a2(curves.one(k), lag_m, mu, phi, points)[0]
        diff = model15 - inert15 if sweep is None else swept_diff(k)
        circle_halves(out[k])[...] = _outer_scale_blend(
            circle_halves(pairs),
            diff[..., None, :],
            circle_halves(g2),
            (model15 / inert15)[..., None, :],
        )
    return a1_out, out


#: log-spaced separations (per lag-1 ``dy``) of :func:`_swept_difference`'s curves
SWEPT_DIFFERENCE_GRID = 400


def _swept_difference(
    curves: CurveStack,
    inert: afunctions.ACurves,
    sweep: tuple[np.ndarray, np.ndarray],
    mu: np.ndarray,
    phi: float,
) -> Callable[[int], np.ndarray]:
    """Eq. 15's difference of ``curves`` and ``inert`` through the sweep kernel, per node.

    A function of the outer-scale node ``k`` giving ``(lags, mu, theta half)``. Eq. 15
    at the fractional lag ``x`` is ``w_perp A_perp(x rho) + w_par A_par(x rho)`` with
    ``rho = dy sqrt(g)`` and the weights of ``(mu, theta)`` alone
    (:func:`cwproc.physics.afunctions.transport_weights`), so the kernel's sums ``sum_x
    K(l, x) dA(x rho)`` are functions of ``rho`` only: they are formed on
    :data:`SWEPT_DIFFERENCE_GRID` log-spaced ``sqrt(g)`` from 1e-4 (below, the
    difference is negligible) and interpolated linearly in ``log sqrt(g)``: within 1e-4
    of ``D`` of the sums at every point (72-ray reference bench), at the cost of eq. 15
    at the whole lags (the sums at every point doubled the finite table's build).
    ``sweep``: ``(x dy, K)``
    (:func:`cwproc.physics.atable_swept.difference_kernel`).
    """
    x_m, weights = sweep
    sg, wp, wl = afunctions.transport_weights(mu, phi)
    top = max(float(sg.max()), 1.0) * 1.0001
    grid = np.geomspace(1e-4, top, SWEPT_DIFFERENCE_GRID)
    rho = x_m[:, None] * grid[None, :]  # (nodes, grid), m
    sums = [
        np.einsum("lx,kxg->klg", weights, stacked(rho) - single(rho))
        for stacked, single in ((curves.perp, inert.perp), (curves.par, inert.par))
    ]
    step = math.log(grid[1] / grid[0])
    at = (np.log(np.maximum(sg, grid[0])) - math.log(grid[0])) / step
    i = np.clip(np.floor(at).astype(np.intp), 0, grid.size - 2)
    f = np.clip(at - i, 0.0, 1.0)
    # value + f * slope per grid cell, gathered once per node of L_V (cache-sized)
    cells = [(s[..., :-1], np.diff(s, axis=-1)) for s in sums]

    def at_node(k: int) -> np.ndarray:
        (p0, dp), (q0, dq) = ((v[k], d[k]) for v, d in cells)
        return wp * (p0[:, i] + f * dp[:, i]) + wl * (q0[:, i] + f * dq[:, i])

    return at_node


def _dwell_difference(
    curves: CurveStack,
    inert: afunctions.ACurves,
    kernel: tuple[np.ndarray, np.ndarray, np.ndarray],
    mu: np.ndarray,
    phi: float,
) -> Callable[[int], np.ndarray]:
    """Eq. 15's difference of ``curves`` and ``inert`` through the dwell kernel, per node.

    A function of the outer-scale node ``k`` giving ``(lags, mu, theta half)``: ``sum_x
    K(l, x) dA(x)`` over the nodes ``x = (x_scan, x_wind)`` of
    :func:`cwproc.physics.atable_swept.dwell_difference_kernel` (``kernel``: ``(x_scan
    dy, x_wind dy, K)``, m and ``(lags, nodes)``), eq. 15 (Smalikho (2020)) of the
    separation ``x_scan dy e_scan - x_wind dy mu e_wind`` of beams at rest: ``g = (x_scan
    - x_wind mu sin th)^2 + (x_wind mu cos th)^2`` in place of
    :func:`cwproc.physics.afunctions.transport_weights`' ``x_scan = x_wind``. So the
    ray's own averaging over the path the wind carries the field during its dwell acts on
    the outer scale's part too. (At the whole lags, ``mu`` 3, 24 rays, 3 s dwell in a 4 s
    ray, h 100 m, ``L_V`` 200 m, ``D(1-3)`` was 0.7-1.2 % below the exact generator;
    0.9996-1.0020 of it now, ``benchmarks/diag_dwell_outer_scale.py``.)
    The differences ``dA_perp``, ``dA_par`` of all nodes are formed on
    :data:`SWEPT_DIFFERENCE_GRID` log-spaced separations and interpolated linearly in
    ``log rho`` by one sparse matrix of the kernel, the weights and the interpolation
    (as :func:`_swept_difference`: below the grid the difference is negligible).
    """
    xs, xw, weights = kernel
    th = afunctions._theta()
    wind = xw[:, None, None] * np.asarray(mu, float)[None, :, None]
    a = xs[:, None, None] - wind * np.sin(th)
    b = wind * np.cos(th)
    g = a**2 + b**2  # (nodes, mu, theta half), m^2
    moved = g > 0.0
    s2, c2 = math.sin(math.radians(phi)) ** 2, math.cos(math.radians(phi)) ** 2
    safe = np.where(moved, g, 1.0)
    wp = np.where(moved, s2 + c2 * a**2 / safe, 0.0)  # (no separation: no difference)
    wl = np.where(moved, c2 * b**2 / safe, 0.0)
    top = float(np.sqrt(g.max())) * 1.0001
    grid = np.geomspace(1e-4 * top, top, SWEPT_DIFFERENCE_GRID)
    at = np.log(np.maximum(np.sqrt(safe), grid[0]) / grid[0]) / math.log(grid[1] / grid[0])
    i = np.clip(np.floor(at).astype(np.intp), 0, grid.size - 2)
    f = np.clip(at - i, 0.0, 1.0)
    # rows (lag, mu, theta), columns dA_perp then dA_par on the grid
    lag, node = np.nonzero(weights)
    shape = (weights.shape[0], *g.shape[1:])
    rows = np.ravel_multi_index(
        (lag[:, None, None], *np.indices(g.shape[1:])[:, None]), shape
    )  # (pairs, mu, theta)
    rows = np.broadcast_to(rows, (lag.size, *g.shape[1:]))
    kw = weights[lag, node][:, None, None]
    vals, cols = [], []
    for part, offset in ((wp, 0), (wl, grid.size)):
        w = kw * part[node]
        vals += [w * (1.0 - f[node]), w * f[node]]
        cols += [i[node] + offset, i[node] + offset + 1]
    matrix = sparse.csr_matrix(
        (
            np.concatenate([v.ravel() for v in vals]),
            (np.tile(rows.ravel(), 4), np.concatenate([c.ravel() for c in cols])),
        ),
        shape=(int(np.prod(shape)), 2 * grid.size),
    )
    d_curves = np.concatenate(
        [curves.perp(grid) - inert.perp(grid), curves.par(grid) - inert.par(grid)], axis=1
    )  # (n_curves, 2 grid)
    out = np.ascontiguousarray((matrix @ d_curves.T).T).reshape(curves.n_curves, *shape)

    def at_node(k: int) -> np.ndarray:
        return out[k]

    return at_node


def _outer_scale_blend(
    inertial: np.ndarray, difference: np.ndarray, ratio: np.ndarray, factor: np.ndarray
) -> np.ndarray:
    """The inertial pair A with an outer scale: eq. 15's difference, or its ratio where large.

    ``inertial + difference * ratio`` (``ratio`` the point-probe ratio) where that is at
    least 0.8 of ``inertial * factor`` (eq. 15's ratio of the model to the inertial
    curves), ``inertial * factor`` below 0.5 of it (separations far beyond ``L_V``, where
    the difference would exceed the pair's own A), linear in between: positive and
    continuous.
    """
    added = inertial + difference * ratio
    scaled = inertial * factor
    with np.errstate(invalid="ignore", divide="ignore"):
        share = np.clip((added / scaled - 0.5) / 0.3, 0.0, 1.0)
    return scaled + share * (added - scaled)


def build_a_table(probe: Probe, params: dict, bar: Bar = no_bar) -> ATable:
    """Compute a table: ``A_1`` and ``A_2`` on the grid of ``params``.

    For every height node (and outer scale) the curves ``A_perp``, ``A_par`` of the lag are
    computed once (:func:`cwproc.physics.afunctions.a_curve_splines`) and eq. 15 is
    evaluated for all lags, ``mu`` and azimuths at once. With ``geometry="two_beam"`` it is
    multiplied by the point-probe ratio of :func:`geometry_correction` and, for
    finite outer scales, ``sigma_V^2 |S_a - S_b|^2`` (:func:`uniform_mode`) are added.
    Pulsed probes (and swept rays of any probe with a transverse size) take the pairs
    of :mod:`cwproc.physics.atable_swept` with the plane A-function instead
    (:func:`_swept_pairs`): swept rays of continuous scans the sweep kernel over
    step-stare pairs at fractional lags, step-stare rays the pairs at the lags. ``A_2``
    is stored as its azimuth average (``log_a2``) and, for inertial tables, its means
    over azimuth bins relative to that average (``bins_a2``), so that sectors and gaps
    can be averaged over the azimuths of the pairs present. ``bar``: the progress
    report of the two long steps (:data:`Bar`; none by default).
    """
    phi, n_lags, model = params["phi_deg"], params["n_lags"], params["model"]
    swept = bool(params.get("swept", True))
    heights, mu, scales = _table_nodes(params)
    lags = np.arange(1, n_lags + 1, dtype=float)
    to_nodes = azimuth_to_nodes(full_circle())
    log_a1 = np.empty((scales.size, heights.size, n_lags))
    log_a2 = np.empty((scales.size, heights.size, n_lags, mu.size))
    bins_a2 = np.empty((scales.size, heights.size, n_lags, mu.size, N_BINS))
    ranges, dys, perp_size = _height_probes(probe, params, heights, swept)
    # pulsed step-stare rays take the plane A-function too (Stream Line gate: eq. 15's
    # mix was 1.9 % low on the circle at lag 1, mu = 1, and down to 0.82 per azimuth)
    plane_pairs = np.any(perp_size > 0) or isinstance(probe, PulsedProbe)
    plane_pairs = plane_pairs and params.get("geometry", "two_beam") == "two_beam"
    # an inertial table of pairs is the pairs alone: no eq.-15 curves, no point ratios
    pairs_only = plane_pairs and model == "inertial"
    same, g1, g2, unif = pair_geometry_terms(probe, params, ranges, mu, swept, not pairs_only)
    swept_pairs: list = [None] * heights.size
    inertial: list = [None] * heights.size
    largest = None if model == "inertial" else float(scales.max())
    # swept pairs with an outer scale: eq. 15's difference of rays at rest at the nodes
    # of the sweep kernel (_height_cell), so curves without H_perp, one lag further
    # (step-stare rays with a dwell: through the dwell kernel, _dwell_difference)
    sweep: tuple[np.ndarray, ...] | None = None
    if plane_pairs and swept and model != "inertial":
        sweep = atable_swept.difference_kernel(lags)
        perp_size = np.zeros_like(perp_size)
    elif plane_pairs and model != "inertial" and float(params.get("dwell", 0.0)) > 0.0:
        sweep = atable_swept.dwell_difference_kernel(lags, float(params["dwell"]))
    per_height = (ranges, dys, perp_size)
    reach = 0.0 if sweep is None else 1.0
    kernels = [] if pairs_only else _curve_kernels(probe, params, per_height, largest, reach)
    if plane_pairs:
        swept_pairs = _memo_swept_pairs(probe, params, ranges, dys, mu, same, bar)
        if model != "inertial":
            flat = shared_plane(kernels, "inertial", None)
            inertial = [kernel.curves(flat) for kernel in kernels]
    # the curves of every L_V node and height: one spectrum matrix per L_V, shared
    per_scale = []
    with bar(f"A-table ({model})", scales.size + heights.size) as advance:
        for big_l in scales if kernels else []:
            outer = None if model == "inertial" else float(big_l)
            plane = shared_plane(kernels, model, outer)
            per_scale.append([kernel.curves(plane) for kernel in kernels])
            advance(1)
        sigma2 = np.array(
            [0.0 if model == "inertial" else spectra.variance_per_eps23(model, s) for s in scales]
        )
        j_ref = heights.size // 2
        for j in range(heights.size):
            a1, per_theta = _height_cell(
                CurveStack.of([curves[j] for curves in per_scale]) if kernels else None,
                (inertial[j], swept_pairs[j]),
                (same[j], g1, g2),
                lags * float(dys[j]),
                mu,
                phi,
                None if sweep is None else (*(x * float(dys[j]) for x in sweep[:-1]), sweep[-1]),
            )
            a1 = a1 + sigma2[:, None] * unif
            if model == "inertial":  # (the pairs themselves: kept for the next table)
                per_theta = per_theta + sigma2[:, None, None, None] * unif[:, None, None]
            else:  # a new array of _height_cell
                per_theta += sigma2[:, None, None, None] * unif[:, None, None]
            c0 = per_theta.mean(axis=-1)
            log_a1[:, j] = np.log(a1)
            log_a2[:, j] = np.log(c0)
            if model == "inertial" or j == j_ref:  # finite tables keep one height's bins
                bins_a2[:, j] = (per_theta @ to_nodes) / c0[..., None]
            advance(1)
    keep = bins_a2 if model == "inertial" else None
    scale_bins = None
    if model != "inertial" and swept_pairs[0] is not None:
        # per-node ratio over the inertial one at the middle height (ATable.scale_ratio)
        pairs = swept_pairs[j_ref]
        inert = (pairs @ to_nodes) / pairs.mean(axis=-1)[..., None]
        scale_bins = bins_a2[:, j_ref] / inert[None]
    return ATable(heights, mu, scales, log_a1, log_a2, dict(params), keep, scale_bins)
