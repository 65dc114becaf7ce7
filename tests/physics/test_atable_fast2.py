"""The fast plane A-function and plane curves (issue 30): equal to the direct evaluation.

- :func:`cwproc.physics.afunctions.a_plane` integrates along the beam for all
  separations at once (:mod:`cwproc.physics.plane_integral`); the former loop, one
  :func:`cwproc.physics.afunction_quadrature.structure_integral` per separation, is rebuilt here
  as the reference: equal within 1e-12 relative.
- :class:`cwproc.physics.atable_swept.PlaneCurves` evaluates its spline per cell in numpy
  (:class:`cwproc.physics.atable_swept.BicubicPieces`): equal to
  ``RectBivariateSpline.ev`` of the same data within 1e-12 on ``log A``.
"""

from __future__ import annotations

import numpy as np
import pytest

from cwproc.physics import afunction_quadrature as quadrature
from cwproc.physics import afunctions
from cwproc.physics.transfer import CWProbe, PulsedProbe


def _a_plane_loop(s_par, s_perp, *, probe, range_m, model="inertial", outer_scale_m=None):
    """The plane A-function by the former per-separation loop (reference)."""
    s1, st = np.abs(np.ravel(s_par)), np.abs(np.ravel(s_perp))
    lengths = np.concatenate([s1[s1 > 0], st[st > 0]])
    k_lo, k_hi, _ = afunctions.panel_limits(
        lengths.min(),
        lengths.max(),
        probe=probe,
        dy=0.0,
        range_m=range_m,
        model=model,
        outer_scale_m=outer_scale_m,
    )
    shared = quadrature.PlaneMatrix(k_lo, k_hi, model, outer_scale_m)
    p, phi = shared.panels, shared.matrix
    fac_par, len_par = afunctions.longitudinal_factor(probe, p, range_m)
    perps, which = np.unique(st, return_inverse=True)
    options = dict(probe=probe, dy=0.0, range_m=range_m, model=model, outer_scale_m=outer_scale_m)
    chunks = [perps[i : i + 64] for i in range(0, perps.size, 64)]  # as a_plane
    a_perp_v = np.concatenate([afunctions.a_curves(c, plane=shared, **options)[0] for c in chunks])
    cross = np.concatenate([phi @ quadrature.cos_weights(p, c).T for c in chunks], axis=1)
    cross = cross + phi[:, [0]] * p.lo
    out = np.zeros(s1.size)
    for j in range(perps.size):
        sel = np.flatnonzero((which == j) & (s1 > 0))
        if sel.size == 0:
            continue
        if perps[j] == 0:
            out[sel] = afunctions.a_curves(s1[sel], plane=shared, **options)[1]
            continue
        smooth = 2.0 * cross[:, j] * fac_par
        out[sel] = quadrature.structure_integral(p, smooth, len_par, s1[sel], None)
    return out + a_perp_v[which]


@pytest.mark.parametrize(
    ("probe", "range_m", "model", "outer"),
    [
        (PulsedProbe(15.3, 30.0), 100.0, "inertial", None),
        (PulsedProbe(15.3, 18.0), 300.0, "von_karman", 80.0),
        (CWProbe(0.0013), 120.0, "inertial", None),
    ],
)
def test_a_plane_equals_the_per_separation_loop(probe, range_m, model, outer):
    rng = np.random.default_rng(3)
    s = np.geomspace(0.02, 400.0, 300)
    beta = rng.uniform(0.0, 0.5 * np.pi, s.size)
    s_par, s_perp = s * np.sin(beta), s * np.cos(beta)
    s_perp[:5] = 0.0  # along the beam
    s_par[5:10] = 0.0  # across the beam
    s_par[10], s_perp[10] = 0.0, 0.0
    s_perp[20:30] = s_perp[20]  # shared transverse lengths
    options = dict(probe=probe, range_m=range_m, model=model, outer_scale_m=outer)
    fast = afunctions.a_plane(s_par, s_perp, **options)
    direct = _a_plane_loop(s_par, s_perp, **options)
    assert fast[10] == 0.0 and direct[10] == 0.0
    np.testing.assert_allclose(fast, direct, rtol=1e-12, atol=0)


def test_plane_curves_pieces_equal_the_fitpack_spline():
    from scipy import interpolate

    from cwproc.physics import atable_swept

    curves = atable_swept.plane_curves(PulsedProbe(15.3, 30.0), 120.0, 0.02, 150.0)
    spline = interpolate.RectBivariateSpline(curves.log_s, curves.angle, curves.log_a)
    rng = np.random.default_rng(5)
    x = rng.uniform(curves.log_s[0], curves.log_s[-1], 20000)
    y = rng.uniform(0.0, 1.0, x.size)
    x[:4] = curves.log_s[[0, -1, 2, 7]]  # the ends and knots
    y[:4] = curves.angle[[0, -1, 3, 16]]
    np.testing.assert_allclose(curves.pieces()(x, y), spline.ev(x, y), rtol=0, atol=1e-12)
    # the power law below the grid, as the former evaluation by ev
    s_par, s_perp = np.array([1e-3, 5e-3, 0.0]), np.array([2e-3, 0.0, 4e-3])
    ls, beta = (
        np.log(np.hypot(s_par, s_perp)),
        atable_swept._angle_coordinate(np.arctan2(s_par, s_perp)),
    )
    lo, l1 = curves.log_s[0], curves.log_s[1]
    first, second = spline.ev(np.full(3, lo), beta), spline.ev(np.full(3, l1), beta)
    expected = np.exp(first + (second - first) / (l1 - lo) * (ls - lo))
    np.testing.assert_allclose(curves(s_par, s_perp), expected, rtol=1e-12)
