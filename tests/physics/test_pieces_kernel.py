"""The C kernels of the A-table splines (``cwproc.physics._pieces``, issue 30): the same
numbers as their numpy paths, bit for bit, so that a table does not depend on whether
the optional extension was built (the shipped tables equal a rebuild either way).

- :class:`cwproc.physics.atable_swept.BicubicPieces` and the ``log A`` of
  :class:`cwproc.physics.atable_swept.PlaneCurves` (the power law below the grid, the
  angle coordinate): equal to :meth:`~cwproc.physics.atable_swept.BicubicPieces.numpy_at`;
- :class:`cwproc.physics.curve_kernel.CurveStack`: equal to its numpy Horner sums, and
  to :class:`scipy.interpolate.CubicSpline` (the former evaluation) within 4e-15
  relative on ``A``.
"""

from __future__ import annotations

from functools import partial

import numpy as np
import pytest

from cwproc.physics import atable_swept, curve_kernel
from cwproc.physics.curve_kernel import CurveKernel, CurveStack, shared_plane
from cwproc.physics.transfer import PulsedProbe

pytest.importorskip("cwproc.physics._pieces", reason="the C extension is not built")


@pytest.fixture(scope="module")
def plane() -> atable_swept.PlaneCurves:
    return atable_swept.plane_curves(PulsedProbe(15.3, 30.0), 120.0, 0.02, 150.0)


def _both(monkeypatch, module, call):
    monkeypatch.setattr(module, "_use_extension", True)
    compiled = call()
    monkeypatch.setattr(module, "_use_extension", False)
    return compiled, call()


def test_bicubic_kernel_is_the_numpy_path_bit_for_bit(plane, monkeypatch):
    pieces = plane.pieces()
    rng = np.random.default_rng(11)
    x = rng.uniform(plane.log_s[0] - 0.5, plane.log_s[-1] + 0.5, 50000)  # ends: clipped cells
    y = rng.uniform(-0.1, 1.1, x.size)
    x[:6] = plane.log_s[[0, -1, 1, 2, 7, 30]]  # on the nodes, where rounding picks the cell
    y[:6] = plane.angle[[0, -1, 1, 3, 8, 16]]
    compiled, numpy = _both(monkeypatch, atable_swept, lambda: pieces(x, y))
    np.testing.assert_array_equal(compiled, numpy)
    assert np.isfinite(compiled).all()
    # 2-D input keeps its shape
    compiled, numpy = _both(monkeypatch, atable_swept, lambda: pieces(x.reshape(100, -1), y[0]))
    assert compiled.shape == (100, 500)
    np.testing.assert_array_equal(compiled, numpy)


def test_plane_curves_kernel_is_the_numpy_path_bit_for_bit(plane, monkeypatch):
    rng = np.random.default_rng(12)
    s = np.exp(rng.uniform(np.log(1e-4), np.log(400.0), (40, 300)))  # below and above the grid
    beta = rng.uniform(0.0, 0.5 * np.pi, s.shape)
    s_par, s_perp = s * np.sin(beta), s * np.cos(beta)
    s_par[0, :10], s_perp[1, :10] = 0.0, 0.0  # across and along the beam exactly
    s_par[2, 0] = s_perp[2, 0] = 0.0  # no separation: A = 0
    compiled, numpy = _both(monkeypatch, atable_swept, lambda: plane(s_par, -s_perp))
    np.testing.assert_array_equal(compiled, numpy)
    positive = np.ones(s.shape, bool)
    positive[2, 0] = False
    assert compiled[2, 0] == 0.0 and (compiled[positive] > 0).all()
    assert (np.hypot(s_par, s_perp) < 0.02).sum() > 1000  # the power law was exercised


def test_curve_stack_kernel_is_the_numpy_path_and_the_cubic_spline(monkeypatch):
    from scipy import interpolate

    probe = PulsedProbe(15.3, 30.0)
    kernel = CurveKernel(0.05, 90.0, probe=probe, dy=0.0, range_m=150.0, outer_scale_m=900.0)
    curves = [kernel.curves(shared_plane([kernel], "von_karman", L)) for L in (30.0, 300.0)]
    curves.append(kernel.curves(shared_plane([kernel], "inertial", None)))
    stack = CurveStack.of(curves)
    rng = np.random.default_rng(13)
    rho = np.exp(rng.uniform(np.log(1e-3), np.log(1e4), (7, 3000)))  # below, in and above
    rho[0, :4] = np.exp(stack.log_rho[[0, -1, 5, 33]])  # on the knots
    rho[1, 0] = 0.0
    for name in ("perp", "par"):
        compiled, numpy = _both(monkeypatch, curve_kernel, partial(getattr(stack, name), rho))
        np.testing.assert_array_equal(compiled, numpy)
        assert compiled.shape == (3, *rho.shape)
        assert (compiled[:, 1, 0] == 0.0).all()
        # the former evaluation: scipy's spline inside, power laws through the end nodes
        logv = getattr(stack, f"log_{name}")
        x = stack.log_rho
        lr = np.log(rho[rho > 0])
        inside = interpolate.CubicSpline(x, logv.T)(np.clip(lr, x[0], x[-1])).T
        below = logv[:, :1] + (logv[:, 1:2] - logv[:, :1]) / (x[1] - x[0]) * (lr - x[0])
        above = logv[:, -1:] + (logv[:, -1:] - logv[:, -2:-1]) / (x[-1] - x[-2]) * (lr - x[-1])
        expected = np.exp(np.where(lr < x[0], below, np.where(lr > x[-1], above, inside)))
        np.testing.assert_allclose(compiled[:, rho > 0], expected, rtol=4e-15, atol=0)


def test_curve_stack_refuses_lags_off_a_uniform_log_grid():
    stack = CurveStack(np.log([1.0, 2.0, 5.0, 9.0]), np.zeros((1, 4)), np.zeros((1, 4)))
    with pytest.raises(ValueError, match="uniform"):
        stack.perp(np.array([3.0]))


def test_tables_do_not_depend_on_the_build(monkeypatch):
    """A swept pulsed table and its von Karman table, built with the C kernels and with
    numpy alone: the same arrays, bit for bit."""
    from cwproc.physics import atable

    probe = PulsedProbe(15.3, 30.0)
    options = dict(phi_deg=30.0, delta_theta_deg=4.0, n_lags=3, height_range_m=(80.0, 200.0))
    finite = dict(model="von_karman", outer_scale_range_m=(50.0, 200.0))
    tables = []
    for flag in (True, False):
        monkeypatch.setattr(atable_swept, "_use_extension", flag)
        monkeypatch.setattr(curve_kernel, "_use_extension", flag)
        atable._PAIRS_MEMO.clear()
        inertial = atable.build_a_table(probe, atable.table_parameters(probe, **options))
        outer = atable.build_a_table(probe, atable.table_parameters(probe, **options, **finite))
        tables.append((inertial, outer))
    for compiled, numpy in zip(*tables, strict=True):
        for name in ("log_a1", "log_a2", "bins_a2", "scale_bins"):
            a, b = getattr(compiled, name), getattr(numpy, name)
            assert (a is None) == (b is None), name
            if a is not None:
                np.testing.assert_array_equal(a, b, err_msg=name)
