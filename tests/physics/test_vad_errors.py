"""VAD error theory (seed 002) against REFERENCE_VALUES.md section 2 and Monte Carlo.

Closed forms are compared with the reference tables to 1e-4 relative (the tables print
5-6 significant digits). Monte-Carlo checks use 20 000 seeded draws; the relative
standard error of an RMS estimated from n Gaussian draws is 1/sqrt(2n) = 0.5 %, so
they are held to 4 standard errors (2 %).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from cwproc.physics import vad_errors as ve

RTOL = 1e-4
ATOL = 2e-6  # half a unit of the last printed digit (6 decimals in section 2.3/2.4)
N_MC = 20_000
MC_RTOL = 4.0 / np.sqrt(2.0 * N_MC)


def reference_table(reference_dir: Path, heading: str) -> list[dict[str, float]]:
    """Rows of the first markdown table after the heading that starts with ``heading``."""
    lines = (reference_dir / "REFERENCE_VALUES.md").read_text(encoding="utf-8").splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith(heading))
    table = []
    for line in lines[start + 1 :]:
        if line.startswith("|"):
            table.append([c.strip() for c in line.strip().strip("|").split("|")])
        elif table:
            break
    header, rows = table[0], table[2:]
    return [{h: float(v) for h, v in zip(header, row, strict=True)} for row in rows]


def close(actual: float, expected: float) -> bool:
    return bool(np.isclose(actual, expected, rtol=RTOL, atol=ATOL))


# --------------------------------------------------------------------------------------
# 2.1 full circle
# --------------------------------------------------------------------------------------


def test_full_circle_matches_reference_table(reference_dir: Path) -> None:
    rows = reference_table(reference_dir, "### 2.1")
    assert len(rows) == 32
    for r in rows:
        n, phi = int(r["N"]), r["phi"]
        az = ve.uniform_azimuths_deg(n)
        closed = ve.max_error_full_circle(n, phi, 1.0)
        from_weights = ve.max_errors(ve.least_squares_weights(az, phi), 1.0)
        decoupled = ve.max_errors(ve.decoupled_weights(az, phi), 1.0)
        for got in (closed, from_weights, decoupled):
            assert close(got[0], r["max dVx"]), (n, phi, got)
            assert close(got[1], r["max dVy"]), (n, phi, got)
            assert close(got[2], r["max dVz"]), (n, phi, got)
        assert close(ve.max_error_full_circle_limit(phi, 1.0)[0], r["N->inf max dVx"])
        rms = ve.rms_error_full_circle(n, phi, 1.0)
        assert close(rms[0], r["rms dVx (closed)"])
        assert close(rms[2], r["rms dVz (closed)"])
        np.testing.assert_allclose(ve.rms_errors(ve.least_squares_weights(az, phi), 1.0), rms)


def test_vertical_maximum_error_independent_of_n() -> None:
    # seed 002, after eq. 6: the V_z bound depends only on Delta and phi
    values = [ve.max_error_full_circle(n, 35.3, 0.5)[2] for n in (4, 7, 24, 360)]
    np.testing.assert_allclose(values, 0.5 / np.sin(np.deg2rad(35.3)), rtol=1e-12)


@pytest.mark.parametrize(("n", "phi"), [(6, 15.0), (24, 60.0), (72, 35.3)])
def test_full_circle_rms_monte_carlo(n: int, phi: float) -> None:
    rng = np.random.default_rng(2002 + n)
    az = ve.uniform_azimuths_deg(n)
    a = ve.design_matrix(az, phi)
    noise = rng.standard_normal((N_MC, n))
    errors = np.linalg.lstsq(a, noise.T, rcond=None)[0].T
    rms = np.sqrt(np.mean(errors**2, axis=0))
    np.testing.assert_allclose(rms, ve.rms_error_full_circle(n, phi, 1.0), rtol=MC_RTOL)


@pytest.mark.parametrize(("n", "phi"), [(6, 60.0), (24, 35.3)])
def test_maximum_error_is_a_bound_and_attained(n: int, phi: float) -> None:
    rng = np.random.default_rng(7 + n)
    az = ve.uniform_azimuths_deg(n)
    a = ve.design_matrix(az, phi)
    w = ve.least_squares_weights(az, phi)
    bound = ve.max_errors(w, 1.0)
    uniform = rng.uniform(-1.0, 1.0, (N_MC, n))
    errors = np.abs(np.linalg.lstsq(a, uniform.T, rcond=None)[0].T)
    assert np.all(errors.max(axis=0) <= bound * (1 + 1e-12))
    adversarial = np.sign(w)  # d_i = Delta sign(W_ki), row k
    attained = np.abs(np.einsum("kn,kn->k", w, adversarial))
    np.testing.assert_allclose(attained, bound, rtol=1e-12)


# --------------------------------------------------------------------------------------
# 2.2 missing sector
# --------------------------------------------------------------------------------------


def test_missing_sector_matches_reference_table(reference_dir: Path) -> None:
    rows = reference_table(reference_dir, "### 2.2")
    assert len(rows) == 12
    phi = 35.3
    for r in rows:
        n, s = int(r["N"]), r["s (deg)"]
        az = ve.uniform_azimuths_deg(n, s)
        assert az.size == int(r["n kept"])
        paper = ve.max_errors(ve.decoupled_weights(az, phi), 1.0)
        ls_w = ve.least_squares_weights(az, phi)
        ls = ve.max_errors(ls_w, 1.0)
        ls_rms = ve.rms_errors(ls_w, 1.0)
        asym = ve.max_error_sector_asymptotic(phi, s, 1.0)
        lin = ve.max_error_sector_linearised(phi, s, 1.0)
        expected = {
            "paper max dVx": paper[0],
            "paper max dVy": paper[1],
            "paper max dVz": paper[2],
            "asym dVx (15)": asym[0],
            "lin dVx (16)": lin[0],
            "asym dVy": asym[1],
            "LS max dVx": ls[0],
            "LS max dVy": ls[1],
            "LS max dVz": ls[2],
            "LS rms dVx": ls_rms[0],
            "LS rms dVz": ls_rms[2],
        }
        for column, got in expected.items():
            assert close(got, r[column]), (n, s, column, got, r[column])
        full = ve.max_errors(ve.decoupled_weights(ve.uniform_azimuths_deg(n), phi), 1.0)
        assert close(paper[0] / full[0], r["ratio paper dVx / full"])


def test_eleven_percent_claim() -> None:
    # seed 002, end of section 5: ~11 % along the bisector for a 90 deg sector
    assert ve.sector_error_factor(90.0) == pytest.approx(1.1073, abs=1e-4)
    # the exact N -> infinity asymptote (eq. 15) gives 1.0941 (REFERENCE_VALUES 2.2)
    ratio = ve.max_error_sector_asymptotic(35.3, 90.0, 1.0) / ve.max_error_full_circle_limit(
        35.3, 1.0
    )
    assert ratio[0] == pytest.approx(1.0941, abs=1e-4)
    assert ratio[2] == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize("sector", [60.0, 120.0])
def test_missing_sector_least_squares_rms_monte_carlo(sector: float) -> None:
    rng = np.random.default_rng(int(sector))
    phi = 35.3
    az = ve.uniform_azimuths_deg(72, sector)
    a = ve.design_matrix(az, phi)
    errors = np.linalg.lstsq(a, rng.standard_normal((N_MC, az.size)).T, rcond=None)[0].T
    rms = np.sqrt(np.mean(errors**2, axis=0))
    expected = ve.rms_errors(ve.least_squares_weights(az, phi), 1.0)
    np.testing.assert_allclose(rms, expected, rtol=MC_RTOL)
    # the along-bisector component is the one that degrades
    full = ve.rms_error_full_circle(72, phi, 1.0)
    assert expected[0] / full[0] > expected[1] / full[1]


# --------------------------------------------------------------------------------------
# 2.3 linear horizontal gradient
# --------------------------------------------------------------------------------------


def test_gradient_matches_reference_table(reference_dir: Path) -> None:
    rows = reference_table(reference_dir, "### 2.3")
    assert len(rows) == 10
    a = b = 0.001
    for r in rows:
        n, phi, radius = int(r["N"]), r["phi"], r["R' (m)"]
        assert close(1000.0 * np.cos(np.deg2rad(phi)), radius)
        az = ve.uniform_azimuths_deg(n)
        bias = ve.shear_bias(az, phi, radius, a, b)
        bound = ve.shear_error_bound(az, phi, radius, a, b)
        limit = ve.shear_error_bound_limit(phi, radius, a, b)
        for got, column in zip(bias, ("actual dVx", "actual dVy", "actual dVz"), strict=True):
            assert np.isclose(got, r[column], rtol=1e-3, atol=2e-6), (n, phi, column)
        assert close(ve.shear_w_bias(phi, radius, a), r["a R'/(2 tan phi)"])
        for got, column in zip(
            bound, ("bound dVx (finite N)", "bound dVy", "bound dVz"), strict=True
        ):
            assert np.isclose(got, r[column], rtol=1e-3, atol=2e-6), (n, phi, column)
        assert close(limit[0], r["bound N->inf dVx"])
        assert close(limit[1], r["dVy"])
        assert close(limit[2], r["dVz"])


@pytest.mark.parametrize("n", [4, 8, 24])
def test_gradient_biases_only_w_simulated(n: int) -> None:
    """Simulate the sheared field at the scan-circle points and fit it (seed 002, eq. 18)."""
    rng = np.random.default_rng(n)
    phi, range_m = 60.0, 800.0
    radius = range_m * np.cos(np.deg2rad(phi))
    az = ve.uniform_azimuths_deg(n)
    theta = np.deg2rad(az)
    x = radius * np.cos(theta)
    for _ in range(20):
        vx0, vy0, vz0, a, b = rng.normal(0, [8, 8, 0.5, 0.005, 0.005])
        vx, vy = vx0 + a * x, vy0 + b * x
        vr = (
            vx * np.cos(np.deg2rad(phi)) * np.cos(theta)
            + vy * np.cos(np.deg2rad(phi)) * np.sin(theta)
            + vz0 * np.sin(np.deg2rad(phi))
        )
        fit = np.linalg.lstsq(ve.design_matrix(az, phi), vr, rcond=None)[0]
        bias = fit - [vx0, vy0, vz0]
        np.testing.assert_allclose(bias[:2], 0.0, atol=1e-10)
        assert bias[2] == pytest.approx(float(ve.shear_w_bias(phi, radius, a)), rel=1e-9)
        np.testing.assert_allclose(ve.shear_bias(az, phi, radius, a, b), bias, atol=1e-10)


# --------------------------------------------------------------------------------------
# 2.4 tilted cone axis
# --------------------------------------------------------------------------------------


def test_tilt_matches_reference_table(reference_dir: Path) -> None:
    rows = reference_table(reference_dir, "### 2.4")
    assert len(rows) == 8
    for r in rows:
        phi, gamma = r["phi"], r["gamma (deg)"]
        radius = 1000.0 * np.cos(np.deg2rad(phi))
        exact = ve.tilt_bias_exact(phi, gamma, [10.0, 0.0, 0.5], 0.02, 1000.0, 72)
        first = ve.tilt_bias_first_order(phi, gamma, 10.0, 0.5, 0.02, radius)
        assert close(exact[0], r["exact dVx"])
        assert close(exact[1], r["exact dVy"])
        assert close(exact[2], r["exact dVz"])
        assert close(first[0], r["1st-order dVx = -g Vz"])
        assert close(first[2], r["1st-order dVz = g Vx - g ax R'/(2 tan phi)"])
        height_only = -np.deg2rad(gamma) * ve.shear_w_bias(phi, radius, 0.02)
        assert close(height_only, r["height-only part of dVz"])


def test_tilt_first_order_is_the_small_angle_limit() -> None:
    # the error of the first-order form is O(gamma^2): (exact - first order)/gamma^2
    # converges as gamma -> 0 (to 2 % between 0.05 and 0.025 deg)
    args = ([10.0, 2.0, 0.5], 0.02, 1000.0, 36)
    radius = 1000.0 * np.cos(np.deg2rad(45.0))
    scaled = [
        (
            ve.tilt_bias_exact(45.0, g, *args)
            - ve.tilt_bias_first_order(45.0, g, 10.0, 0.5, 0.02, radius)
        )
        / np.deg2rad(g) ** 2
        for g in (0.05, 0.025)
    ]
    np.testing.assert_allclose(scaled[0][[0, 2]], scaled[1][[0, 2]], rtol=0.02)


def test_bad_arguments_raise() -> None:
    with pytest.raises(ValueError, match="n_azimuths"):
        ve.uniform_azimuths_deg(0)
    with pytest.raises(ValueError, match="sector_deg"):
        ve.max_error_sector_asymptotic(35.3, 200.0, 1.0)
    with pytest.raises(ValueError, match="estimator"):
        ve.shear_bias(ve.uniform_azimuths_deg(8), 35.3, 100.0, 0.01, 0.0, estimator="x")
