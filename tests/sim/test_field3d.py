"""Frozen isotropic turbulence field: spectrum normalisation, tensor, synthesis statistics."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.fft
from scipy import integrate

from cwproc.physics import spectra
from cwproc.sim.field3d import (
    energy_spectrum_rad,
    field_variance,
    grid_variance,
    von_karman_field,
)

EPS = 0.01  # m2 s-3
SCALE = 20.0  # m


@pytest.mark.parametrize("model", ["von_karman", "exponential"])
def test_energy_spectrum_integrates_to_three_halves_of_the_variance(model):
    # int_0^inf E(k) dk = (3/2) sigma_V^2, sigma_V^2 = (eps L_V / c)^(2/3) (Banakh (1999) eq. 19)
    total, _ = integrate.quad(
        lambda k: energy_spectrum_rad(k, EPS, SCALE, model), 0, np.inf, limit=500
    )
    assert total == pytest.approx(1.5 * field_variance(EPS, SCALE, model), rel=1e-4)


def test_inertial_range_spectrum_has_the_kolmogorov_constant():
    # E(k) -> alpha eps^(2/3) k^(-5/3), alpha = 1.5208 for C_K = 2 (Smalikho (2020) eq. 12)
    k = 50.0 / SCALE * 100
    alpha = energy_spectrum_rad(k, EPS, SCALE) / (EPS ** (2 / 3) * k ** (-5 / 3))
    assert alpha == pytest.approx(1.5208, rel=1e-3)


def _spectral(field):
    return scipy.fft.fftn(field.velocity, axes=(1, 2, 3))


def test_field_is_divergence_free():
    f = von_karman_field((32, 32, 32), 1.0, epsilon=EPS, integral_scale_m=SCALE, seed=3)
    ks = [2 * np.pi * scipy.fft.fftfreq(32, 1.0)] * 3
    kx, ky, kz = np.meshgrid(*ks, indexing="ij")
    spec = _spectral(f)
    div = kx * spec[0] + ky * spec[1] + kz * spec[2]
    scale = np.sqrt(kx**2 + ky**2 + kz**2) * np.abs(spec).max(axis=0)
    assert np.max(np.abs(div)) <= 1e-10 * np.max(scale)
    assert np.abs(f.velocity.mean(axis=(1, 2, 3))).max() < 1e-12


def test_ensemble_variance_and_structure_functions_match_the_tensor():
    """20 seeded fields: variance and D(r) equal the sums of the isotropic tensor.

    Expected: sigma_i^2 = sum Phi_ii dk^3 (grid_variance) and
    D_ii(r e_x) = 2 sum Phi_ii(k) (1 - cos(k_x r)) dk^3 (Banakh (1999) eq. 16 in spectral
    form); 20 x 32^3 samples, tolerance 6 % (statistical, large scales dominate).
    """
    shape, dx = (32, 32, 32), 1.0
    var = np.zeros(3)
    lags = np.array([2, 4, 8])
    dl = np.zeros(lags.size)
    dn = np.zeros(lags.size)
    n = 20
    for seed in range(n):
        u = von_karman_field(shape, dx, epsilon=EPS, integral_scale_m=8.0, seed=seed).velocity
        var += u.var(axis=(1, 2, 3)) / n
        dl += np.array([np.mean((np.roll(u[0], -r, 0) - u[0]) ** 2) for r in lags]) / n
        dn += np.array([np.mean((np.roll(u[1], -r, 0) - u[1]) ** 2) for r in lags]) / n
    np.testing.assert_allclose(var, grid_variance(shape, dx, EPS, 8.0), rtol=0.06)
    ks = [2 * np.pi * scipy.fft.fftfreq(m, dx) for m in shape]
    kx, ky, kz = np.meshgrid(*ks, indexing="ij")
    k2 = kx**2 + ky**2 + kz**2
    safe = np.where(k2 > 0, k2, 1.0)
    nyquist = np.pi / dx  # Nyquist planes carry no energy (no -k partner)
    keep = (k2 > 0) & (np.abs(kx) < nyquist) & (np.abs(ky) < nyquist) & (np.abs(kz) < nyquist)
    dens = np.where(keep, energy_spectrum_rad(np.sqrt(safe), EPS, 8.0) / (4 * np.pi * safe), 0)
    dk3 = (2 * np.pi / (32 * dx)) ** 3
    exp_l = [2 * np.sum(dens * (1 - kx**2 / safe) * (1 - np.cos(kx * r * dx))) * dk3 for r in lags]
    exp_n = [2 * np.sum(dens * (1 - ky**2 / safe) * (1 - np.cos(kx * r * dx))) * dk3 for r in lags]
    np.testing.assert_allclose(dl, exp_l, rtol=0.06)
    np.testing.assert_allclose(dn, exp_n, rtol=0.06)


def test_grid_approaches_the_continuous_field_as_it_grows():
    # the periodic grid misses the wavenumbers below 2 pi/extent and above pi/dx
    small = grid_variance((32, 32, 32), 1.0, EPS, SCALE)[0]
    large = grid_variance((128, 128, 128), 1.0, EPS, SCALE)[0]
    full = field_variance(EPS, SCALE)
    assert small < large < full
    assert large / full > 0.85


def test_inertial_range_structure_function_follows_the_two_thirds_law():
    """Mid-range lags of a large grid: D_par(r2) - D_par(r1) within 15 % of von Karman.

    Differences remove the constant deficit from the unresolved wavenumbers above the grid's
    Nyquist wavenumber (Smalikho (2020), eq. 12; spectra.longitudinal_structure_function).
    """
    f = von_karman_field((128, 64, 64), 1.0, epsilon=EPS, integral_scale_m=SCALE, seed=11)
    u = f.velocity[0]
    d = [np.mean((np.roll(u, -r, 0) - u) ** 2) for r in (6, 12)]
    th = EPS ** (2 / 3) * spectra.longitudinal_structure_function(
        np.array([6.0, 12.0]), "von_karman", SCALE
    )
    assert (d[1] - d[0]) / (th[1] - th[0]) == pytest.approx(1.0, rel=0.15)


def test_interpolation_is_exact_at_nodes_and_periodic():
    f = von_karman_field((16, 16, 8), 2.0, epsilon=EPS, integral_scale_m=SCALE, seed=1)
    i, j, k = np.array([0, 3, 15]), np.array([1, 7, 15]), np.array([0, 5, 7])
    at_nodes = f.interpolate(i * 2.0, j * 2.0, k * 2.0)
    np.testing.assert_allclose(at_nodes, f.velocity[:, i, j, k], atol=1e-12)
    ex, ey, ez = f.extent_m
    x, y, z = np.array([1.3, 7.7]), np.array([2.1, 30.0]), np.array([0.4, 9.9])
    np.testing.assert_allclose(
        f.interpolate(x + ex, y - 2 * ey, z + ez), f.interpolate(x, y, z), atol=1e-12
    )


def test_same_seed_same_field_and_bad_arguments_rejected():
    a = von_karman_field((8, 8, 8), 1.0, epsilon=EPS, integral_scale_m=SCALE, seed=5)
    b = von_karman_field((8, 8, 8), 1.0, epsilon=EPS, integral_scale_m=SCALE, seed=5)
    np.testing.assert_array_equal(a.velocity, b.velocity)
    with pytest.raises(ValueError):
        von_karman_field((8, 8), 1.0, epsilon=EPS, integral_scale_m=SCALE, seed=5)
    with pytest.raises(ValueError):
        von_karman_field((8, 8, 8), 1.0, epsilon=-1.0, integral_scale_m=SCALE, seed=5)


def test_two_level_field_holds_the_large_scales():
    """A coarse grid 4 times larger carries the wavenumbers below the split.

    The variance of the two-level field is the sum of both grids' tensor sums and is much
    closer to the continuous sigma_V^2 (Banakh et al. (1999), eq. 19) than one grid.
    """
    shape, dx, scale = (64, 64, 64), 1.0, 16.0
    one = grid_variance(shape, dx, EPS, scale)[0]
    two = grid_variance(shape, dx, EPS, scale, coarse_factor=4)[0]
    full = field_variance(EPS, scale)
    assert one < two < full
    assert one / full < 0.8 < 0.85 < two / full  # the rest is above the Nyquist wavenumber
    var = np.zeros(3)
    for seed in range(8):
        f = von_karman_field(
            shape, dx, epsilon=EPS, integral_scale_m=scale, seed=seed, coarse_factor=4
        )
        assert f.extent_m == (256.0, 256.0, 256.0)
        x = np.arange(0.0, 256.0, 1.0)  # fine nodes: only the coarse level is interpolated
        grid = np.meshgrid(x, x[::8], x[::8], indexing="ij")
        var += f.interpolate(*grid).reshape(3, -1).var(axis=1) / 8
    np.testing.assert_allclose(var, two, rtol=0.1)
    with pytest.raises(ValueError, match="coarse_factor"):
        von_karman_field(shape, dx, epsilon=EPS, integral_scale_m=scale, seed=0, coarse_factor=16)


def test_interpolation_is_the_periodic_trilinear_of_scipy():
    # map_coordinates(order=1, mode="grid-wrap") is the reference; points far outside
    # the box (a day of advection) wrap
    from scipy import ndimage

    from cwproc.sim.field3d import trilinear_wrap_numpy

    f = von_karman_field((12, 10, 8), 2.0, epsilon=EPS, integral_scale_m=SCALE, seed=1)
    xyz = np.random.default_rng(2).uniform(-5e5, 5e5, (3000, 3))
    want = np.stack(
        [
            ndimage.map_coordinates(
                f.velocity[c], (xyz / 2.0).T, order=1, mode="grid-wrap", prefilter=False
            )
            for c in range(3)
        ],
        axis=-1,
    )
    np.testing.assert_allclose(f.interpolate_points(xyz), want, rtol=0, atol=1e-9)
    table, shape, dx = f.levels[0]
    np.testing.assert_allclose(
        trilinear_wrap_numpy(table, shape, xyz / dx), want, rtol=0, atol=1e-9
    )
