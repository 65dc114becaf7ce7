"""The along-beam integrals of the plane A-function, all separations at once.

:func:`cwproc.physics.afunctions.a_plane` needs, per separation ``(s_par, s_perp)``, the
outer integral of :func:`cwproc.physics.afunction_quadrature.structure_integral` with its own
smooth factor ``2 C(k1; s_perp) H_par`` and lag ``s_par``. Called once per separation
(about 800 separations per table of plane curves) its Python overhead and the many
small cosine-weight matrices cost about 3 s per probe. :func:`structure_integrals` is
the same rule for a column of smooth factors per lag: the same panels, the same pruning
of negligible panels per column, the same head and tail corrections, in matrix form
(equal to the loop within rounding, 1e-12 relative, tested).
"""

from __future__ import annotations

import math

import numpy as np

from cwproc.physics import afunction_quadrature as quadrature

#: separations per block (bounds the (separations, nodes) weight matrices to ~10 MB)
BLOCK = 256


def structure_integrals(
    p: quadrature.Panels, smooth: np.ndarray, length: float, rho: np.ndarray
) -> np.ndarray:
    """``int smooth_i(kappa) sinc^2(pi length kappa) [1 - cos(2 pi rho_i kappa)] dkappa``.

    Parameters
    ----------
    p : quadrature.Panels
        Panels and nodes of the integral.
    smooth : numpy.ndarray
        ``(nodes, n)``: the smooth factor of each integral at the panel nodes.
    length : float
        Length of the ``sinc^2`` factor (m), ``0`` for none.
    rho : numpy.ndarray
        ``(n,)`` lags (m), one per column of ``smooth``.

    Returns
    -------
    numpy.ndarray
        ``(n,)``: :func:`cwproc.physics.afunction_quadrature.structure_integral` of each column
        with its lag (tail power estimated from the last two nodes).
    """
    rho = np.asarray(rho, dtype=float)
    out = np.empty(rho.size)
    for i in range(0, rho.size, BLOCK):
        out[i : i + BLOCK] = _block(p, smooth[:, i : i + BLOCK], length, rho[i : i + BLOCK])
    return out


def _block(p: quadrature.Panels, smooth: np.ndarray, length: float, rho: np.ndarray) -> np.ndarray:
    """:func:`structure_integrals` of one block of columns."""
    w0, kappa, n = p.gl, p.kappa, p.kappa.size
    order = quadrature.ORDER
    if length > 0:
        direct = p.left * length < 1.0
        f = smooth * quadrature.sinc2(length * kappa)[:, None]
    else:
        direct = np.ones(n, bool)
        f = smooth
    # per column: drop whole panels beyond the last one whose integrand matters (1e-17)
    contrib = w0[:, None] * np.abs(f)
    significant = contrib > 1e-17 * contrib.sum(axis=0)
    last = n - 1 - np.argmax(significant[::-1], axis=0)
    cut = np.where(significant.any(axis=0), np.minimum(n, (last // order + 1) * order), n)
    pruned = cut < n
    inside = np.arange(n)[:, None] < cut[None, :]  # (nodes, n)
    # the cosine weights only on the nodes inside some column's cut (the rest weigh 0)
    used = np.arange(n) < cut.max()
    wr = np.zeros((rho.size, n))
    wr[:, used] = quadrature.cos_weights(p, rho, used)  # (n, nodes)
    fd = np.where(direct[:, None] & inside, f, 0.0)
    out = np.einsum("ik,ki->i", w0[None, :] - wr, fd)
    trig = ~direct
    g_all = None
    if trig.any():
        kt = kappa[trig]
        g_all = smooth[trig] / (2.0 * np.pi**2 * length**2 * kt**2)[:, None]  # (nt, n)
        kern = np.zeros((rho.size, kt.size))
        live = used[trig]
        if live.any():
            sub = trig & used
            wl = quadrature.cos_weights(p, np.array([length]), sub)
            wm = quadrature.cos_weights(p, np.abs(rho - length), sub)
            wp = quadrature.cos_weights(p, rho + length, sub)
            kern[:, live] = w0[None, sub] - wl - wr[:, sub] + 0.5 * wm + 0.5 * wp
        g = np.where(inside[trig], g_all, 0.0)
        out = out + np.einsum("ik,ki->i", kern, g)
    # head: f ~ f0 (k/k0)^(-s) below the first node, 1 - cos ~ 2 pi^2 rho^2 k^2
    k0, k1 = kappa[0], kappa[1]
    f0, f1 = f[0], f[1]
    head = (f0 > 0) & (f1 > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.minimum(-np.log(f1 / f0) / math.log(k1 / k0), 2.9)
        added = f0 * k0**s * 2 * np.pi**2 * rho**2 * p.lo ** (3 - s) / (3 - s)
    out = out + np.where(head, added, 0.0)
    # tail: envelope ~ e_n (k/k_n)^(-t) beyond the last node (non-oscillating part)
    env = g_all if (g_all is not None and trig[-1]) else f
    kn = kappa[-1]
    en, e2 = env[-1], env[-2]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -np.log(en / e2) / math.log(kn / kappa[-2])
        added = en * kn**t * p.hi ** (1 - t) / (t - 1)
    tail = (en > 0) & ~pruned & (t > 1.05)
    return out + np.where(tail, added, 0.0)
