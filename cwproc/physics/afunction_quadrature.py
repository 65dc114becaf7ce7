"""Panel quadrature of the A-functions: Gauss-Legendre panels and Filon-type weights.

The numerics of :mod:`cwproc.physics.afunctions` (Smalikho (2020), eqs. 16-17), shared
with :mod:`cwproc.physics.plane_integral` and :mod:`cwproc.physics.curve_kernel`:
geometric wavenumber panels on a fixed lattice (:class:`Panels`, :func:`panels`), the
2-D spectrum on their nodes (:class:`PlaneMatrix`), the exact integrals of a degree-7
Legendre interpolant times ``cos(2 pi w kappa)`` on each panel (:func:`cos_weights`,
from the moments ``int P_m(x) exp(i a x) dx = 2 i^m j_m(a)``, :func:`spherical_j`), the
outer oscillatory integral of eqs. 16-17 (:func:`structure_integral`) and its head and
tail corrections (:func:`add_end_corrections`). See the module docstring of
:mod:`cwproc.physics.afunctions` for the method and its accuracy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.polynomial import legendre

from cwproc.physics import spectra

#: Gauss-Legendre order per panel
ORDER = 8
#: geometric ratio of the panel ends
PANEL_RATIO = 1.5


@dataclass(frozen=True)
class Panels:
    """Gauss-Legendre nodes of geometric panels on the wavenumber axis (cycles m-1).

    Panel ends lie on the fixed lattice ``PANEL_RATIO**j`` (``j`` integer), so that the
    nodes of two panel sets coincide where they overlap (:class:`PlaneMatrix` reuses the
    spectrum matrix between calls).
    """

    kappa: np.ndarray  # nodes (n,)
    gl: np.ndarray  # plain quadrature weights (n,)
    centre: np.ndarray  # centre of each node's panel (n,)
    half: np.ndarray  # half width of each node's panel (n,)
    left: np.ndarray  # left end of each node's panel (n,)
    pmx: np.ndarray  # (2m+1) P_m(x_k) w_k, shape (n, order)
    lo: float
    hi: float
    first: int  # lattice index j of the first panel's left end


def lattice_range(k_lo: float, k_hi: float) -> tuple[int, int]:
    """Lattice indices ``(j0, j1)`` with ``R^j0 <= k_lo`` and ``R^j1 >= k_hi``."""
    step = math.log(PANEL_RATIO)
    j0 = math.floor(math.log(k_lo) / step)
    j1 = max(j0 + 1, math.ceil(math.log(k_hi) / step))
    return j0, j1


def panels(k_lo: float, k_hi: float) -> Panels:
    j0, j1 = lattice_range(k_lo, k_hi)
    edges = PANEL_RATIO ** np.arange(j0, j1 + 1, dtype=float)
    n_pan = edges.size - 1
    x, w = legendre.leggauss(ORDER)
    c = 0.5 * (edges[1:] + edges[:-1])
    d = 0.5 * (edges[1:] - edges[:-1])
    kappa = (c[:, None] + d[:, None] * x[None, :]).ravel()
    gl = (d[:, None] * w[None, :]).ravel()
    m = np.arange(ORDER)
    pm = legendre.legvander(x, ORDER - 1) * (2 * m + 1)[None, :] * w[:, None]  # (order, order)
    return Panels(
        kappa=kappa,
        gl=gl,
        centre=np.repeat(c, ORDER),
        half=np.repeat(d, ORDER),
        left=np.repeat(edges[:-1], ORDER),
        pmx=np.tile(pm, (n_pan, 1)),
        lo=float(edges[0]),
        hi=float(edges[-1]),
        first=j0,
    )


class PlaneMatrix:
    """The 2-D spectrum on the nodes of a wide panel set, shared by many A-function calls.

    ``Phi(kappa_i, kappa_j)`` (Smalikho (2020), eq. 18 or a finite-outer-scale spectrum)
    is the costliest part of :func:`a_curves` and depends only on the model and the
    nodes. Built once over the union of the wavenumber ranges of a table (see
    :func:`panel_limits`), it hands out the sub-block of any panel set inside that range.
    """

    def __init__(
        self,
        k_lo: float,
        k_hi: float,
        model: spectra.Model = "inertial",
        outer_scale_m: float | None = None,
        constant: float | None = None,
    ) -> None:
        self.panels = panels(k_lo, k_hi)
        self.model = model
        self.outer_scale_m = outer_scale_m
        self.constant = constant
        k = self.panels.kappa
        self.matrix = spectra.plane_spectrum(
            k[:, None], k[None, :], model, outer_scale_m, constant=constant
        )

    def block(self, p: Panels) -> np.ndarray | None:
        """``Phi`` on the nodes of ``p``, or ``None`` when ``p`` is not inside this set."""
        start = (p.first - self.panels.first) * ORDER
        stop = start + p.kappa.size
        if start < 0 or stop > self.panels.kappa.size:
            return None
        return self.matrix[start:stop, start:stop]


def spherical_j(x: np.ndarray, order: int) -> np.ndarray:
    """Spherical Bessel functions ``j_0 .. j_(order-1)`` at ``x >= 0``, shape ``(order, *x.shape)``.

    Upward recurrence where ``x >= 16`` (stable there), Miller's downward recurrence
    from index 48 (28 when all ``x < 4``) normalised by ``j_0`` (or ``j_1`` near the zeros
    of ``j_0``) for ``0.5 <= x < 16``, the power series (10 terms) below; accuracy 1e-13
    relative to the largest of the ``j_m`` (checked against
    :func:`scipy.special.spherical_jn`, which is 20x slower).
    """
    x = np.asarray(x, dtype=float)
    out = np.empty((order, *x.shape))
    big = x >= 16.0
    xb = x[big]
    if xb.size:
        sin_b, cos_b = np.sin(xb), np.cos(xb)
        j_prev = sin_b / xb
        j_cur = (sin_b / xb - cos_b) / xb
        out[0][big] = j_prev
        if order > 1:
            out[1][big] = j_cur
        for m in range(1, order - 1):
            j_prev, j_cur = j_cur, (2 * m + 1) / xb * j_cur - j_prev
            out[m + 1][big] = j_cur
    mid = (x >= 0.5) & ~big
    xm = x[mid]
    if xm.size:
        inv = 1.0 / xm
        j_next = np.zeros_like(xm)
        j_cur = np.full_like(xm, 1e-200)
        vals = [j_cur] * order
        top = 48 if xm.max() >= 4.0 else 28  # start index of the downward recurrence
        for m in range(top, 0, -1):
            j_next, j_cur = j_cur, (2 * m + 1) * inv * j_cur - j_next
            if m - 1 < order:
                vals[m - 1] = j_cur
        # normalise by j_0 = sin(x)/x or, near its zeros, by j_1 = sin(x)/x^2 - cos(x)/x
        j0 = np.sinc(xm / np.pi)
        j1 = (np.sin(xm) * inv - np.cos(xm)) * inv
        norm = np.where(np.abs(j0) >= np.abs(j1), j0 / vals[0], j1 / vals[1])
        for m in range(order):
            out[m][mid] = vals[m] * norm
    small = x < 0.5
    xs = x[small]
    if xs.size:
        h = -0.5 * xs**2
        dfact = 1.0
        for m in range(order):
            dfact *= 2 * m + 1  # (2m+1)!!
            term = np.ones_like(xs)
            total = np.ones_like(xs)
            for k in range(1, 10):
                term = term * h / (k * (2 * m + 2 * k + 1))
                total = total + term
            out[m][small] = xs**m / dfact * total
    return out


def cos_weights(p: Panels, freq: np.ndarray, nodes: np.ndarray | None = None) -> np.ndarray:
    """Weights ``W[f, k]`` with ``sum_k W[f, k] s(kappa_k) = int s(kappa) cos(2 pi f kappa)``.

    Exact for ``s`` a polynomial of degree < 8 on each panel (Filon-type quadrature with
    Legendre moments). ``nodes`` (boolean mask) restricts the columns computed.
    """
    freq = np.atleast_1d(np.asarray(freq, dtype=float))
    sel = slice(None) if nodes is None else nodes
    centre, half, pmx = p.centre[sel], p.half[sel], p.pmx[sel]
    om = 2.0 * np.pi * freq[:, None]  # (F, 1)
    arg_c = om * centre[None, :]  # (F, n)
    jn = spherical_j(om * half[None, :], ORDER)
    cos_c = np.cos(arg_c)
    sin_c = np.sin(arg_c)
    # cos(a + m pi/2) = cos a, -sin a, -cos a, sin a, ...
    even = jn[0] * pmx[None, :, 0] - jn[2] * pmx[None, :, 2] + jn[4] * pmx[None, :, 4]
    even = even - jn[6] * pmx[None, :, 6]
    odd = -jn[1] * pmx[None, :, 1] + jn[3] * pmx[None, :, 3] - jn[5] * pmx[None, :, 5]
    odd = odd + jn[7] * pmx[None, :, 7]
    return (cos_c * even + sin_c * odd) * half[None, :]


def sinc2(x: np.ndarray) -> np.ndarray:
    return np.sinc(x) ** 2  # numpy sinc(x) = sin(pi x)/(pi x)


def integral_weights(p: Panels, length: float, factor: np.ndarray) -> np.ndarray:
    """Weights for ``int s(kappa) factor(kappa) sinc^2(pi length kappa) dkappa`` (s smooth)."""
    if length <= 0:
        return p.gl * factor
    trig = p.left * length >= 1.0
    w = p.gl * factor * sinc2(length * p.kappa)
    if trig.any():
        kt = p.kappa[trig]
        w0 = p.gl[trig]
        wl = cos_weights(p, np.array([length]), trig)[0]
        w[trig] = (w0 - wl) * factor[trig] / (2.0 * np.pi**2 * length**2 * kt**2)
    return w


def structure_integral(
    p: Panels,
    smooth: np.ndarray,
    length: float,
    rho: np.ndarray,
    tail_power: float | None,
    wr: np.ndarray | None = None,
) -> np.ndarray:
    """``int_0^inf smooth(kappa) sinc^2(pi length kappa) [1 - cos(2 pi rho kappa)] dkappa``.

    ``smooth`` is given at the panel nodes; ``length = 0`` means no sinc^2 factor.
    ``tail_power``: power-law exponent of the integrand envelope beyond the last node (used
    for the tail correction when no filter makes it negligible), ``None`` to estimate it.
    ``wr``: the cosine weights ``cos_weights(p, rho)`` when already computed.
    """
    rho = np.asarray(rho, dtype=float)
    w0 = p.gl
    if wr is None:
        wr = cos_weights(p, rho)  # (R, n)
    if length > 0:
        direct = p.left * length < 1.0
        f = smooth * sinc2(length * p.kappa)
    else:
        direct = np.ones(p.kappa.size, bool)
        f = smooth
    # drop whole panels beyond the last one whose integrand matters at all (1e-17)
    contrib = w0 * np.abs(f)
    significant = np.flatnonzero(contrib > 1e-17 * contrib.sum())
    cut = p.kappa.size
    if significant.size:
        cut = min(cut, (significant[-1] // ORDER + 1) * ORDER)
    pruned = cut < p.kappa.size
    inside = np.arange(p.kappa.size) < cut
    trig = ~direct & inside
    direct = direct & inside
    out = (w0[None, direct] - wr[:, direct]) @ f[direct]
    if trig.any():
        kt = p.kappa[trig]
        g = smooth[trig] / (2.0 * np.pi**2 * length**2 * kt**2)
        wl = cos_weights(p, np.array([length]), trig)
        wm = cos_weights(p, np.abs(rho - length), trig)
        wp = cos_weights(p, rho + length, trig)
        kern = w0[None, trig] - wl - wr[:, trig] + 0.5 * wm + 0.5 * wp
        out = out + kern @ g
    return add_end_corrections(out, p, f, g if trig[-1] else f, rho, pruned, tail_power)


def add_end_corrections(
    out: np.ndarray,
    p: Panels,
    f: np.ndarray,
    env: np.ndarray,
    rho: np.ndarray,
    pruned: bool,
    tail_power: float | None,
) -> np.ndarray:
    """``out`` plus the integral below the first and beyond the last wavenumber node.

    Head: ``f ~ f0 (k/k0)^(-s)`` below the first node, ``1 - cos ~ 2 pi^2 rho^2 k^2``.
    Tail: the envelope ``env ~ e_n (k/k_n)^(-t)`` beyond the last node (its
    non-oscillating part; ``t`` from the last two nodes unless ``tail_power`` is given),
    left out when the panels were ``pruned``.
    """
    k0, k1 = p.kappa[0], p.kappa[1]
    f0, f1 = f[0], f[1]
    if f0 > 0 and f1 > 0:
        s = min(-math.log(f1 / f0) / math.log(k1 / k0), 2.9)
        out = out + f0 * k0**s * 2 * np.pi**2 * rho**2 * p.lo ** (3 - s) / (3 - s)
    kn, en = p.kappa[-1], env[-1]
    if en > 0 and not pruned:
        t = tail_power
        if t is None:
            t = -math.log(env[-1] / env[-2]) / math.log(kn / p.kappa[-2])
        if t > 1.05:
            out = out + en * kn**t * p.hi ** (1 - t) / (t - 1)
    return out
