"""Frozen 3-D homogeneous isotropic turbulent velocity field (FFT synthesis).

The field is synthesised on a periodic grid from the isotropic spectral tensor of an
incompressible velocity field,

.. math::

    \\Phi_{ij}(\\mathbf k) = \\frac{E(k)}{4\\pi k^2}
        \\left(\\delta_{ij} - \\frac{k_i k_j}{k^2}\\right),

the spectral form of the isotropic correlation tensor of Banakh et al. (1999), eq. 16,
with the von Kármán energy spectrum (or the spectrum of the correlation model of
Banakh et al. (1999), eq. 17) of :mod:`cwproc.physics.spectra`, e.g.

.. math::

    E(k) = \\alpha\\,\\varepsilon^{2/3} \\ell^{5/3} \\frac{(k\\ell)^4}{[1 + (k\\ell)^2]^{17/6}},

which tends to the Kolmogorov law :math:`\\alpha\\varepsilon^{2/3}k^{-5/3}` for
:math:`k\\ell \\gg 1`. The spectral constant :math:`\\alpha` is chosen so that the
longitudinal structure function in the inertial range is
:math:`D_\\parallel = C_K \\varepsilon^{2/3} r^{2/3}` with :math:`C_K = 2`, the constant
used by Smalikho (2020), eq. 12 and Banakh et al. (1999), eq. 18. The length
:math:`\\ell` is set from the longitudinal integral scale
:math:`L_V = \\int_0^\\infty B_V(r)\\,dr/\\sigma_V^2` (Banakh et al. (1999), after eq. 17):
:math:`L_V = \\ell\\sqrt{\\pi}\\,\\Gamma(5/6)/\\Gamma(1/3)`.

Coordinates are geographic: ``x`` east, ``y`` north, ``z`` up (metres); velocity
components ``(u, v, w)`` along them (m s-1). Wavenumbers ``k`` are in rad m-1.

A periodic grid of extent ``n * spacing`` holds only wavenumbers between
``2 pi/(n spacing)`` and the Nyquist wavenumber ``pi/spacing``: the variance of the
synthetic field is smaller than :func:`field_variance` by what lies outside, which
:func:`grid_variance` computes exactly.
"""

from __future__ import annotations

import functools
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Literal

import numpy as np
import scipy.fft

from cwproc.physics.spectra import energy_spectrum, variance_from

try:  # the compiled interpolation (setup.py); numpy does the same without it
    from cwproc.sim import _trilinear
except ImportError:  # pragma: no cover - depends on the build
    _trilinear = None

#: points above which the compiled interpolation runs in two threads
_SPLIT = 200_000

Model = Literal["von_karman", "exponential"]


def energy_spectrum_rad(
    k: np.ndarray, epsilon: float, integral_scale_m: float, model: Model = "von_karman"
) -> np.ndarray:
    """3-D energy spectrum E(k) (m3 s-2) with k in rad m-1.

    The spectrum of :func:`cwproc.physics.spectra.energy_spectrum` (cycles m-1, per
    eps^(2/3)) converted to angular wavenumbers: ``E_rad(k) = E_cyc(k/2pi)/(2pi)``.
    Its integral over k is (3/2) sigma_V^2.
    """
    k = np.asarray(k, dtype=float)
    kappa = k / (2 * np.pi)
    return epsilon ** (2 / 3) * energy_spectrum(kappa, model, integral_scale_m) / (2 * np.pi)


def field_variance(epsilon: float, integral_scale_m: float, model: Model = "von_karman") -> float:
    """Variance sigma_V^2 of one velocity component of the infinite field (m2 s-2).

    ``sigma_V^2 = (eps L_V / c)^(2/3)``, Banakh et al. (1999), eq. 19.
    """
    return float(variance_from(epsilon, integral_scale_m, model))


@dataclass(frozen=True)
class FrozenField:
    """A frozen velocity field on a periodic grid.

    Attributes
    ----------
    velocity : numpy.ndarray
        ``(3, nx, ny, nz)`` components ``u, v, w`` (m s-1) at the grid nodes
        ``(i dx, j dx, k dx)``.
    spacing_m : float
        Grid spacing (m), the same along x, y, z.
    epsilon : float
        Dissipation rate of the spectrum (m2 s-3).
    integral_scale_m : float
        Longitudinal integral scale L_V of the spectrum (m).
    seed : int
        Seed of the random generator that made it.
    coarse_velocity : numpy.ndarray, optional
        ``(3, mx, my, mz)`` large-scale part on a coarser grid (same shape, spacing
        ``coarse_spacing_m``), added to the fine part; ``None`` for a one-level field.
    coarse_spacing_m : float, optional
        Spacing (m) of the coarse grid, an integer multiple of ``spacing_m``.
    """

    velocity: np.ndarray
    spacing_m: float
    epsilon: float
    integral_scale_m: float
    seed: int
    coarse_velocity: np.ndarray | None = None
    coarse_spacing_m: float | None = None

    @property
    def extent_m(self) -> tuple[float, float, float]:
        """Periodic extent (m) along x, y, z (of the coarse grid when there is one)."""
        grid = self.velocity if self.coarse_velocity is None else self.coarse_velocity
        dx = self.spacing_m if self.coarse_spacing_m is None else self.coarse_spacing_m
        return tuple(float(n * dx) for n in grid.shape[1:])  # type: ignore[return-value]

    def interpolate(self, x: np.ndarray, y: np.ndarray, z: np.ndarray) -> np.ndarray:
        """Velocity at arbitrary points (periodic trilinear interpolation).

        Parameters
        ----------
        x, y, z : numpy.ndarray
            Coordinates (m), broadcastable to one shape ``S``.

        Returns
        -------
        numpy.ndarray
            ``(3, *S)`` velocity components u, v, w (m s-1).
        """
        x, y, z = np.broadcast_arrays(x, y, z)
        return np.moveaxis(self.interpolate_points(np.stack([x, y, z], axis=-1)), -1, 0)

    def interpolate_points(self, xyz: np.ndarray) -> np.ndarray:
        """Velocity at points ``xyz`` of shape ``(..., 3)`` (m): ``(..., 3)`` u, v, w (m s-1).

        Periodic trilinear interpolation of every level (:func:`trilinear_wrap`), the
        three components of a node gathered together.
        """
        xyz = np.asarray(xyz, dtype=float)
        points = xyz.reshape(-1, 3)
        out = np.zeros_like(points)
        for table, shape, dx in self.levels:
            out += trilinear_wrap(table, shape, points / dx)
        return out.reshape(xyz.shape)

    @functools.cached_property
    def levels(self) -> tuple[tuple[np.ndarray, tuple[int, int, int], float], ...]:
        """``(table, shape, spacing)`` of each level: the grid as ``(nx ny nz, 3)``
        node-major (a node's u, v, w side by side), its shape and spacing (m)."""
        grids = [(self.velocity, self.spacing_m)]
        if self.coarse_velocity is not None and self.coarse_spacing_m is not None:
            grids.append((self.coarse_velocity, self.coarse_spacing_m))
        return tuple(
            (np.ascontiguousarray(g.reshape(3, -1).T), tuple(g.shape[1:]), float(dx))
            for g, dx in grids
        )


def trilinear_wrap(table: np.ndarray, shape: tuple[int, ...], coords: np.ndarray) -> np.ndarray:
    """Periodic trilinear interpolation of a node-major grid at points in grid units.

    The scheme of :func:`scipy.ndimage.map_coordinates` with ``order=1,
    mode="grid-wrap"``. Done by the compiled ``cwproc.sim._trilinear`` (built by
    ``setup.py``; about 10x faster, without the GIL, in two threads for large point
    sets) when it is there, else by :func:`trilinear_wrap_numpy`.

    Parameters
    ----------
    table : numpy.ndarray
        ``(nx ny nz, C)`` values, node ``(i, j, k)`` at row ``(i ny + j) nz + k``.
    shape : tuple of int
        ``(nx, ny, nz)``.
    coords : numpy.ndarray
        ``(P, 3)`` point coordinates in units of the grid spacing.

    Returns
    -------
    numpy.ndarray
        ``(P, C)`` interpolated values.
    """
    if _trilinear is None:
        return trilinear_wrap_numpy(table, shape, coords)
    table = np.ascontiguousarray(table, dtype=np.float64)
    coords = np.ascontiguousarray(coords, dtype=np.float64)
    out = np.empty((coords.shape[0], table.shape[1]))
    nx, ny, nz = (int(n) for n in shape)
    parts = np.array_split(np.arange(coords.shape[0]), 2 if coords.shape[0] > _SPLIT else 1)

    def run(index: np.ndarray) -> None:
        if index.size:
            sl = slice(index[0], index[-1] + 1)
            _trilinear.wrap(table, nx, ny, nz, table.shape[1], coords[sl], out[sl])

    if len(parts) == 1:
        run(parts[0])
    else:
        with ThreadPoolExecutor(len(parts)) as pool:
            list(pool.map(run, parts))
    return out


def trilinear_wrap_numpy(
    table: np.ndarray, shape: tuple[int, ...], coords: np.ndarray
) -> np.ndarray:
    """:func:`trilinear_wrap` in numpy: eight gathers of a node's components per point."""
    base = np.floor(coords)
    frac = coords - base
    lo = base.astype(np.int64) % np.asarray(shape)
    hi = (lo + 1) % np.asarray(shape)
    stride = (shape[1] * shape[2], shape[2], 1)
    index = [(lo[:, a] * stride[a], hi[:, a] * stride[a]) for a in range(3)]
    weight = [(1.0 - frac[:, a], frac[:, a]) for a in range(3)]
    out = np.zeros((coords.shape[0], table.shape[1]))
    for i in (0, 1):
        for j in (0, 1):
            ij = index[0][i] + index[1][j]
            wij = weight[0][i] * weight[1][j]
            for k in (0, 1):
                out += (wij * weight[2][k])[:, None] * np.take(table, ij + index[2][k], axis=0)
    return out


def _wavenumbers(shape: tuple[int, int, int], spacing_m: float) -> list[np.ndarray]:
    return [
        2
        * np.pi
        * scipy.fft.fftfreq(n, d=spacing_m).reshape([-1 if a == i else 1 for a in range(3)])
        for i, n in enumerate(shape)
    ]


def _tensor_amplitude(
    shape: tuple[int, int, int],
    spacing_m: float,
    epsilon: float,
    integral_scale_m: float,
    model: Model,
    band: tuple[float, float] = (0.0, np.inf),
) -> tuple[list[np.ndarray], np.ndarray, np.ndarray]:
    """Wavenumbers, k^2 and sqrt(E(k)/(4 pi k^2) dk^3) on the FFT grid (0 at k = 0)."""
    ks = _wavenumbers(shape, spacing_m)
    k2 = ks[0] ** 2 + ks[1] ** 2 + ks[2] ** 2
    dk3 = np.prod([2 * np.pi / (n * spacing_m) for n in shape])
    k = np.sqrt(k2)
    with np.errstate(divide="ignore", invalid="ignore"):
        e = energy_spectrum_rad(np.where(k2 > 0, k, 1.0), epsilon, integral_scale_m, model)
        density = e / (4 * np.pi * k2)
    density = np.where((k2 > 0) & (k >= band[0]) & (k < band[1]), density, 0.0)
    # Nyquist planes (even sizes) have no distinct -k partner: taking the real part there
    # would break the projection, so they carry no energy and the field stays solenoidal
    for axis, n in enumerate(shape):
        if n % 2 == 0:
            index = [slice(None)] * 3
            index[axis] = n // 2
            density[tuple(index)] = 0.0
    return ks, k2, np.sqrt(density * dk3)


def split_wavenumber(shape: tuple[int, int, int], spacing_m: float) -> float:
    """Wavenumber (rad m-1) below which a two-level field puts the modes on the coarse grid.

    Three fundamentals of the fine grid's longest side: the fine grid's Riemann sum of the
    spectrum is fair only well above its own fundamental.
    """
    return 3.0 * 2 * np.pi / (max(shape) * spacing_m)


def _levels(
    shape: tuple[int, int, int], spacing_m: float, coarse_factor: int
) -> list[tuple[float, tuple[float, float]]]:
    """(spacing, wavenumber band) of each level."""
    if coarse_factor <= 1:
        return [(spacing_m, (0.0, np.inf))]
    k_split = split_wavenumber(shape, spacing_m)
    if not k_split < np.pi / (coarse_factor * spacing_m):
        raise ValueError(
            f"coarse_factor {coarse_factor} too large for shape {shape}: the coarse grid "
            "cannot hold the split wavenumber (need coarse_factor < min(shape)/6)"
        )
    return [(spacing_m, (k_split, np.inf)), (coarse_factor * spacing_m, (0.0, k_split))]


def grid_variance(
    shape: tuple[int, int, int],
    spacing_m: float,
    epsilon: float,
    integral_scale_m: float,
    model: Model = "von_karman",
    coarse_factor: int = 1,
) -> np.ndarray:
    """Expected variance of u, v, w of :func:`von_karman_field` on this grid (m2 s-2).

    The sum of the spectral tensor ``Phi_ii(k) dk^3`` over the wavenumbers the periodic
    grid(s) hold (Banakh et al. (1999), eq. 16 in spectral form).

    Returns
    -------
    numpy.ndarray
        ``(3,)`` variances of u, v, w.
    """
    total = np.zeros(3)
    for dx, band in _levels(shape, spacing_m, coarse_factor):
        ks, k2, amp = _tensor_amplitude(shape, dx, epsilon, integral_scale_m, model, band)
        safe = np.where(k2 > 0, k2, 1.0)
        total += np.array([np.sum(amp**2 * (1 - ks[i] ** 2 / safe)) for i in range(3)])
    return total


def _synthesise(
    shape: tuple[int, int, int],
    spacing_m: float,
    epsilon: float,
    integral_scale_m: float,
    model: Model,
    band: tuple[float, float],
    rng: np.random.Generator,
) -> np.ndarray:
    """One periodic level: projected complex Gaussian modes, real part, scaled by sqrt(2)."""
    ks, k2, amp = _tensor_amplitude(shape, spacing_m, epsilon, integral_scale_m, model, band)
    xi = (rng.standard_normal((3, *shape)) + 1j * rng.standard_normal((3, *shape))) / np.sqrt(2)
    safe = np.where(k2 > 0, k2, 1.0)
    k_dot_xi = (ks[0] * xi[0] + ks[1] * xi[1] + ks[2] * xi[2]) / safe
    n_total = int(np.prod(shape))
    velocity = np.empty((3, *shape))
    for c in range(3):  # three components; each a vectorised 3-D FFT
        coeff = amp * (xi[c] - ks[c] * k_dot_xi)
        velocity[c] = np.sqrt(2) * n_total * scipy.fft.ifftn(coeff, workers=-1).real
    return velocity


def von_karman_field(
    shape: tuple[int, int, int],
    spacing_m: float,
    *,
    epsilon: float,
    integral_scale_m: float,
    seed: int,
    model: Model = "von_karman",
    coarse_factor: int = 1,
) -> FrozenField:
    """Synthesise a frozen homogeneous isotropic von Kármán velocity field.

    Each Fourier mode gets the amplitude ``sqrt(E(k)/(4 pi k^2) dk^3)`` times the
    projection ``delta_ij - k_i k_j/k^2`` of a complex Gaussian vector, so the field is
    divergence-free and its covariance is the isotropic tensor of Banakh et al. (1999),
    eq. 16 (with the von Kármán spectrum instead of eq. 17). The real part of the
    complex field, scaled by sqrt(2), is a real Gaussian field with that covariance.

    Parameters
    ----------
    shape : tuple of int
        Grid points ``(nx, ny, nz)``; even numbers with small prime factors are fastest.
    spacing_m : float
        Grid spacing (m). Velocity fluctuations smaller than about two spacings are
        absent.
    epsilon : float
        Dissipation rate (m2 s-3).
    integral_scale_m : float
        Longitudinal integral scale L_V (m).
    seed : int
        Seed of :func:`numpy.random.default_rng`.
    model : {"von_karman", "exponential"}
        Energy spectrum: von Kármán, or the transform of Banakh et al. (1999), eq. 17
        (:func:`cwproc.physics.spectra.energy_spectrum`).
    coarse_factor : int
        With a value above 1, the wavenumbers below :func:`split_wavenumber` go on a
        second grid of the same shape and ``coarse_factor`` times the spacing (a box that
        much larger), so that scales up to and beyond ``L_V`` are present without a huge
        fine grid; the fine grid keeps the rest. 1: one level.

    Returns
    -------
    FrozenField
    """
    if len(shape) != 3 or min(shape) < 2:
        raise ValueError(f"shape must be three sizes >= 2, got {shape!r}")
    if not (spacing_m > 0 and epsilon > 0 and integral_scale_m > 0):
        raise ValueError("spacing_m, epsilon and integral_scale_m must be > 0")
    shape = tuple(int(n) for n in shape)  # type: ignore[assignment]
    rng = np.random.default_rng(seed)
    levels = [
        _synthesise(shape, dx, epsilon, integral_scale_m, model, band, rng)
        for dx, band in _levels(shape, spacing_m, int(coarse_factor))
    ]
    return FrozenField(
        velocity=levels[0],
        spacing_m=float(spacing_m),
        epsilon=float(epsilon),
        integral_scale_m=float(integral_scale_m),
        seed=int(seed),
        coarse_velocity=levels[1] if len(levels) > 1 else None,
        coarse_spacing_m=float(coarse_factor * spacing_m) if len(levels) > 1 else None,
    )
