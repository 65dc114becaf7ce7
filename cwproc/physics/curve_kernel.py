"""``A_perp`` and ``A_par`` of one probe and lag range for many spectra at once.

:func:`cwproc.physics.afunctions.a_curves` computes the double integrals of Smalikho
(2020), eqs. 16-17 as an inner integral of the 2-D spectrum ``Phi`` (eq. 18 or a
finite-outer-scale spectrum) against one transfer function and an outer Filon-type
integral against the other and ``1 - cos(2 pi rho kappa)``. Everything but ``Phi`` depends
only on the panels, the probe, ``dy`` and the lags: the quadrature weights of the inner
integrals and the cosine weights of the outer ones (spherical Bessel moments, the
costliest part after ``Phi``). A table with an outer-scale axis (``L_V``) needs the same
curves for every ``L_V`` node at each height, so :class:`CurveKernel` prepares these
weights once per height and :meth:`CurveKernel.curves` applies them to the spectrum
matrix of each ``L_V`` (a :class:`~cwproc.physics.afunction_quadrature.PlaneMatrix` whose panels
cover the kernel's): two matrix products per curve instead of a full
:func:`~cwproc.physics.afunctions.a_curves` call. The arithmetic is that of
:func:`~cwproc.physics.afunctions.a_curves` (same panels, heads, tails and pruning of
negligible panels), so the results agree to rounding (1e-12 relative, tested).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cwproc.physics import afunction_quadrature as quadrature
from cwproc.physics import spectra
from cwproc.physics.afunction_quadrature import PlaneMatrix
from cwproc.physics.afunctions import ACurves, longitudinal_factor, panel_limits
from cwproc.physics.transfer import Probe

try:  # optional C extension (setup.py): the splines' sums, the same numbers bit for bit
    from cwproc.physics import _pieces
except ImportError:  # pragma: no cover - depends on the build
    _pieces = None

#: whether :class:`CurveStack` uses the C extension when it is built (tests compare both)
_use_extension = True


@dataclass(frozen=True)
class _Outer:
    """Weights of the outer integral ``int smooth sinc^2(pi L k) [1 - cos(2 pi rho k)] dk``.

    ``direct`` ``(R, n)`` acts on ``f = smooth sinc^2`` at the nodes of panels below
    ``1/L``, ``trig`` ``(R, n)`` on ``g = smooth / (2 pi^2 L^2 k^2)`` beyond (zero
    columns elsewhere): the split of
    :func:`cwproc.physics.afunction_quadrature.structure_integral`.
    """

    direct: np.ndarray
    trig: np.ndarray
    is_trig: np.ndarray
    sinc2: np.ndarray
    inv: np.ndarray
    rho: np.ndarray


def _outer(p: quadrature.Panels, length: float, rho: np.ndarray, wr: np.ndarray) -> _Outer:
    """:class:`_Outer` of the panels ``p``, the probe length ``length`` (m) and lags ``rho``."""
    w0 = p.gl
    n = p.kappa.size
    if length > 0:
        is_trig = p.left * length >= 1.0
        sinc2 = quadrature.sinc2(length * p.kappa)
    else:
        is_trig = np.zeros(n, bool)
        sinc2 = np.ones(n)
    direct = np.where(~is_trig[None, :], w0[None, :] - wr, 0.0)
    trig = np.zeros_like(direct)
    inv = np.zeros(n)
    if is_trig.any():
        kt = p.kappa[is_trig]
        wl = quadrature.cos_weights(p, np.array([length]), is_trig)
        wm = quadrature.cos_weights(p, np.abs(rho - length), is_trig)
        wp = quadrature.cos_weights(p, rho + length, is_trig)
        trig[:, is_trig] = w0[None, is_trig] - wl - wr[:, is_trig] + 0.5 * wm + 0.5 * wp
        inv[is_trig] = 1.0 / (2.0 * np.pi**2 * length**2 * kt**2)
    return _Outer(direct, trig, is_trig, sinc2, inv, rho)


def _apply_outer(
    p: quadrature.Panels, o: _Outer, smooth: np.ndarray, tail_power: float | None
) -> np.ndarray:
    """:func:`~cwproc.physics.afunction_quadrature.structure_integral` with the
    prepared weights ``o`` (one ``smooth``)."""
    f = smooth * o.sinc2
    contrib = p.gl * np.abs(f)
    significant = np.flatnonzero(contrib > 1e-17 * contrib.sum())
    cut = p.kappa.size
    if significant.size:
        cut = min(cut, (significant[-1] // quadrature.ORDER + 1) * quadrature.ORDER)
    pruned = cut < p.kappa.size
    g = smooth * o.inv
    # einsum, not BLAS: matrix-vector products this small lose to the threads of a
    # multi-threaded BLAS on a busy machine (6x slower under load average 9)
    out = np.einsum("rk,k->r", o.direct[:, :cut], f[:cut])
    out = out + np.einsum("rk,k->r", o.trig[:, :cut], g[:cut])
    return quadrature.add_end_corrections(
        out, p, f, g if o.is_trig[-1] else f, o.rho, pruned, tail_power
    )


class CurveKernel:
    """The spectrum-independent part of :func:`cwproc.physics.afunctions.a_curve_splines`.

    Parameters
    ----------
    rho_min, rho_max : float
        Lag range (m) of the splines (at least 61 and 14 per decade geometric lags, as
        :func:`~cwproc.physics.afunctions.a_curve_splines`).
    probe : PulsedProbe or CWProbe or None
        Longitudinal weighting (Smalikho (2020), eq. 19, or the cw Lorentzian).
    dy : float
        Transverse size (m) of ``H_perp`` (Smalikho (2020), eq. 20), 0 for none.
    range_m : float, optional
        Focus distance (m) of a cw probe.
    outer_scale_m : float, optional
        Largest ``L_V`` (m) the kernel serves: the panels start below ``1e-5 / L_V``.
    """

    def __init__(
        self,
        rho_min: float,
        rho_max: float,
        *,
        probe: Probe | None,
        dy: float,
        range_m: float | None = None,
        outer_scale_m: float | None = None,
        n: int = 61,
    ) -> None:
        n = max(n, math.ceil(14 * math.log10(rho_max / rho_min)) + 1)
        self.rho = np.geomspace(rho_min, rho_max, n)
        model = "inertial" if outer_scale_m is None else "von_karman"
        k_lo, k_hi, self.has_par = panel_limits(
            rho_min,
            rho_max,
            probe=probe,
            dy=dy,
            range_m=range_m,
            model=model,
            outer_scale_m=outer_scale_m,
        )
        self.panels = p = quadrature.panels(k_lo, k_hi)
        self.dy = dy
        self.fac_par, self.len_par = longitudinal_factor(probe, p, range_m)
        self.u_par = quadrature.integral_weights(p, self.len_par, self.fac_par)
        self.u_perp = quadrature.integral_weights(p, dy, np.ones_like(p.kappa))
        wr = quadrature.cos_weights(p, self.rho)
        self.perp_outer = _outer(p, dy, self.rho, wr)
        self.par_outer = _outer(p, self.len_par, self.rho, wr)

    def limits(self) -> tuple[float, float]:
        """Wavenumber range (cycles m-1) a :class:`PlaneMatrix` must cover for this kernel."""
        return self.panels.lo, self.panels.hi

    def curves(self, plane: PlaneMatrix) -> ACurves:
        """:class:`~cwproc.physics.afunctions.ACurves` of the spectrum of ``plane``.

        Equals ``a_curve_splines(rho_min, rho_max, probe=..., dy=..., model=...,
        outer_scale_m=..., plane=plane)`` on the kernel's panels.
        """
        p = self.panels
        phi = plane.block(p)
        if phi is None:
            raise ValueError("the plane matrix does not cover the kernel's wavenumbers")
        g_perp = np.einsum("k,km->m", self.u_par, phi) + phi[0, :] * self.fac_par[0] * p.lo
        g_par = np.einsum("km,m->k", phi, self.u_perp) + phi[:, 0] * p.lo
        if not self.has_par:
            g_perp = g_perp + phi[-1, :] * p.kappa[-1] ** (8 / 3) * p.hi ** (-5 / 3) * 0.6
        if self.dy == 0:
            g_par = g_par + phi[:, -1] * p.kappa[-1] ** (8 / 3) * p.hi ** (-5 / 3) * 0.6
        tail = 5.0 / 3.0 if (not self.has_par and self.dy == 0) else None
        perp = _apply_outer(p, self.perp_outer, 2.0 * g_perp, tail)
        par = _apply_outer(p, self.par_outer, 2.0 * g_par * self.fac_par, tail)
        return ACurves(np.log(self.rho), np.log(perp), np.log(par))


def shared_plane(
    kernels: list[CurveKernel], model: spectra.Model, outer_scale_m: float | None
) -> PlaneMatrix:
    """One :class:`PlaneMatrix` of ``model`` covering the panels of all ``kernels``."""
    lo = min(k.limits()[0] for k in kernels)
    hi = max(k.limits()[1] for k in kernels)
    return PlaneMatrix(lo * (1 + 1e-12), hi * (1 - 1e-12), model, outer_scale_m)


@dataclass(frozen=True)
class CurveStack:
    """``A_perp`` and ``A_par`` of several spectra (one per ``L_V``) on the same lags.

    The stacked form of :class:`~cwproc.physics.afunctions.ACurves` (the same cubic
    log-log spline, :class:`scipy.interpolate.CubicSpline`, and power-law continuation):
    ``perp(rho)`` and ``par(rho)`` return ``(n_curves, *rho.shape)``. The splines are
    kept as polynomials per cell of the uniform ``log rho`` grid and summed by Horner's
    rule, the cell found by arithmetic on the grid step, in the optional C extension
    ``cwproc.physics._pieces`` when it is built (the same operations in the same order:
    the same numbers, bit for bit, tested), else in numpy (:meth:`numpy_log`). Equal to
    ``CubicSpline.__call__`` within rounding (2e-15 relative, tested).
    """

    log_rho: np.ndarray
    log_perp: np.ndarray  # (n_curves, n)
    log_par: np.ndarray  # (n_curves, n)

    @classmethod
    def of(cls, curves: list[ACurves]) -> CurveStack:
        """The stack of ``curves`` (all on the same lags)."""
        return cls(
            curves[0].log_rho,
            np.stack([c.log_perp for c in curves]),
            np.stack([c.log_par for c in curves]),
        )

    @property
    def n_curves(self) -> int:
        """Number of curves (``L_V`` nodes) in the stack."""
        return self.log_perp.shape[0]

    def one(self, k: int) -> CurveStack:
        """The stack of curve ``k`` alone (its spline pieces: those of this stack)."""
        single = CurveStack(self.log_rho, self.log_perp[k : k + 1], self.log_par[k : k + 1])
        for name in ("perp", "par"):
            coef, ends = self._pieces(name)
            object.__setattr__(single, f"_{name}", (coef[k : k + 1], ends[k : k + 1]))
        return single

    def _pieces(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """``(coef (n_curves, cells, 4), ends (n_curves, 4))`` of ``log_perp`` or ``log_par``.

        ``coef``: powers 3, 2, 1, 0 of the offset from the cell's left knot; ``ends``:
        value and slope of the straight lines below the first and beyond the last knot.
        """
        cached = self.__dict__.get(f"_{name}")
        if cached is None:
            from scipy import interpolate  # here: with scipy.optimize, 0.1 s of imports

            x = self.log_rho
            if x.size < 3 or not np.allclose(np.diff(x), x[1] - x[0], rtol=1e-9, atol=0):
                raise ValueError("CurveStack needs at least three uniform log-lags")
            logv = getattr(self, f"log_{name}")
            spline = interpolate.CubicSpline(x, logv.T)
            coef = np.ascontiguousarray(np.transpose(spline.c, (2, 1, 0)))
            s_lo = (logv[:, 1] - logv[:, 0]) / (x[1] - x[0])
            s_hi = (logv[:, -1] - logv[:, -2]) / (x[-1] - x[-2])
            ends = np.ascontiguousarray(np.stack([logv[:, 0], s_lo, logv[:, -1], s_hi], axis=1))
            cached = (coef, ends)
            object.__setattr__(self, f"_{name}", cached)
        return cached

    def numpy_log(self, name: str, log_rho: np.ndarray) -> np.ndarray:
        """``log A`` of every curve at ``log_rho`` in numpy (the reference of the C kernel)."""
        coef, ends = self._pieces(name)
        x = self.log_rho
        first, last = x[0], x[-1]
        cell = np.floor((log_rho - first) * ((x.size - 1) / (last - first)))
        cell = np.clip(cell, 0, x.size - 2).astype(np.intp)
        d = log_rho - x.take(cell)
        c = [coef[:, :, p].take(cell, axis=1) for p in range(4)]  # (n_curves, *shape)
        val = ((c[0] * d + c[1]) * d + c[2]) * d + c[3]
        extra = (slice(None),) + (None,) * log_rho.ndim
        e = [ends[:, p][extra] for p in range(4)]
        val = np.where(log_rho < first, e[0] + e[1] * (log_rho - first), val)
        return np.where(log_rho > last, e[2] + e[3] * (log_rho - last), val)

    def _eval(self, name: str, rho: np.ndarray, log_rho: np.ndarray | None) -> np.ndarray:
        rho = np.asarray(rho, dtype=float)
        lr = np.log(np.maximum(rho, 1e-300)) if log_rho is None else log_rho
        if _pieces is None or not _use_extension:
            val = self.numpy_log(name, lr)
        else:
            coef, ends = self._pieces(name)
            x = self.log_rho
            scale = (x.size - 1) / (x[-1] - x[0])
            val = np.empty((coef.shape[0], *lr.shape))
            lr_c = np.ascontiguousarray(lr)
            _pieces.cubic_stack(coef, x, float(scale), coef.shape[0], ends, lr_c, val)
        out = np.exp(val)
        if np.any(rho <= 0):
            out = np.where(rho > 0, out, 0.0)
        return out

    def perp(self, rho: np.ndarray, log_rho: np.ndarray | None = None) -> np.ndarray:
        """``A_perp(rho)`` (m^(2/3)) of every curve, ``(n_curves, *rho.shape)``.

        ``log_rho``: ``log(max(rho, 1e-300))`` when already computed.
        """
        return self._eval("perp", rho, log_rho)

    def par(self, rho: np.ndarray, log_rho: np.ndarray | None = None) -> np.ndarray:
        """``A_par(rho)`` (m^(2/3)) of every curve, ``(n_curves, *rho.shape)``."""
        return self._eval("par", rho, log_rho)
