"""Turbulence spectra and structure functions of the radial velocity (cycles per metre).

Three isotropic models, all normalised so that in the inertial range the longitudinal
structure function is ``D_par = C_K eps^(2/3) r^(2/3)`` with ``C_K = 2`` (Smalikho (2020),
eqs. 12-13) and so that everything below is *per* ``eps^(2/3)``:

- ``"inertial"``: Kolmogorov, ``E(k) = alpha eps^(2/3) k^(-5/3)`` (no outer scale).
- ``"von_karman"``: ``E(k) = alpha eps^(2/3) k^4 / (k^2 + k0^2)^(17/6)``; the outer scale
  ``L_V`` is the longitudinal integral scale, ``L_V = sqrt(pi) Gamma(5/6)/Gamma(1/3) / k0``
  (angular ``k0``).
- ``"exponential"``: the model of Banakh et al. (1999), eq. 17, longitudinal correlation
  ``B_V(r) = sigma_V^2 exp(-1.21 (r/L_V)^(2/3))`` (its integral scale is 0.9987 L_V).

The 2-D spectrum of the radial velocity in the plane (``kappa1`` along the beam,
``kappa2`` across it) is, from the isotropic tensor integrated over the third wavenumber,
``Phi = 4 [I1(kappa) - kappa1^2 I2(kappa)]`` with ``I1 = (1/2pi) int_0^inf E(k)/k^2 dk3``,
``I2 = (1/2pi) int_0^inf E(k)/k^4 dk3`` (``E`` in cycles per metre). For the Kolmogorov
spectrum it is Smalikho (2020), eq. 18:
``Phi = C (k1^2 + k2^2)^(-4/3) [1 + (8/3) k2^2/(k1^2 + k2^2)]`` with ``C = 0.065239``
(:func:`exact_plane_constant`; the paper prints 0.0652, 0.06 % low). The factor 4 makes
``A = 2 int_0^inf int_0^inf Phi H_par H_perp [1 - cos(2 pi r kappa)]`` the structure
function over the first quadrant, as in Smalikho (2020), eqs. 16-17.

Variance, dissipation rate and outer scale are tied by ``L_V = c sigma_V^3 / eps``:
``c = (2 * 1.21 / C_K)^(3/2) = 1.331`` for the exponential model (Banakh et al. (1999),
eq. 19, "1.33"); ``c = 0.6973`` for von Karman with ``L_V`` its integral scale (computed
here; Banakh et al. (1999) quote "~0.67" without stating their constants — with
``C_K = 2`` and ``L_V`` the integral scale the value is 0.697).
"""

from __future__ import annotations

import math
from functools import lru_cache
from typing import TYPE_CHECKING, Literal

import numpy as np
from numpy.typing import ArrayLike

if TYPE_CHECKING:
    from scipy.interpolate import CubicSpline

Model = Literal["inertial", "von_karman", "exponential"]
MODELS: tuple[str, ...] = ("inertial", "von_karman", "exponential")

#: Kolmogorov constant of the longitudinal structure function, Smalikho (2020), eq. 12
KOLMOGOROV_CONSTANT = 2.0
#: constant of the 2-D spectrum as printed in Smalikho (2020), eq. 18
PRINTED_PLANE_CONSTANT = 0.0652
#: coefficient 1.21 of Banakh et al. (1999), eq. 17
EXPONENTIAL_COEFFICIENT = 1.21

#: int_{-inf}^{inf} (1+t^2)^(-11/6) dt = B(1/2, 4/3) = Gamma(1/2) Gamma(4/3) / Gamma(11/6)
_B1 = math.gamma(0.5) * math.gamma(4.0 / 3.0) / math.gamma(11.0 / 6.0)


def _beta(a: float, b: float) -> float:
    """Euler's beta function B(a, b) = Gamma(a) Gamma(b) / Gamma(a + b) (scalars)."""
    return math.gamma(a) * math.gamma(b) / math.gamma(a + b)


def spectral_constant() -> float:
    """``alpha`` of the 3-D energy spectrum ``E(k) = alpha eps^(2/3) k^(-5/3)`` (angular k).

    Chosen so that ``D_par = C_K eps^(2/3) r^(2/3)`` with ``C_K = 2`` (Smalikho (2020),
    eq. 12): ``C_K = (27/55) Gamma(1/3) alpha`` (Pope (2000), eq. 6.243), ``alpha = 1.5208``.
    """
    return KOLMOGOROV_CONSTANT / (27.0 / 55.0 * math.gamma(1.0 / 3.0))


def _beta_cycles() -> float:
    """``E(kappa) = beta kappa^(-5/3)`` per eps^(2/3) with kappa in cycles per metre."""
    return spectral_constant() * (2.0 * np.pi) ** (-2.0 / 3.0)


def exact_plane_constant() -> float:
    """The constant ``C`` of Smalikho (2020), eq. 18 that gives ``C_K = 2`` exactly.

    ``C = 3 beta B(1/2, 4/3) / (11 pi) = 0.065239`` with ``beta = alpha (2 pi)^(-2/3)``;
    identical to ``(8/3) / [2 (2pi)^(2/3) (-Gamma(-2/3)/2) (I(2/3) + (8/3) I(8/3))]``,
    ``I(p) = int_0^(pi/2) sin^p``.
    """
    return 3.0 * _beta_cycles() * _B1 / (11.0 * np.pi)


# --------------------------------------------------------------------------------------
# outer scale, variance, dissipation rate
# --------------------------------------------------------------------------------------


def _von_karman_k0(outer_scale_m: float) -> float:
    """Angular ``k0`` (rad m-1) of von Karman for the integral scale ``L_V`` (m)."""
    return math.sqrt(math.pi) * math.gamma(5.0 / 6.0) / math.gamma(1.0 / 3.0) / outer_scale_m


def variance_per_eps23(model: Model, outer_scale_m: float) -> float:
    """``sigma_V^2 / eps^(2/3)`` (m^(2/3)) of a model with outer scale ``L_V`` (m).

    Exponential (Banakh et al. (1999), eq. 19): ``(L_V / 1.331)^(2/3)``. Von Karman:
    ``(alpha/3) B(5/2, 1/3) k0^(-2/3)``.
    """
    _check_model(model, outer_scale_m)
    if model == "exponential":
        return (outer_scale_m / integral_scale_coefficient("exponential")) ** (2.0 / 3.0)
    if model == "von_karman":
        k0 = _von_karman_k0(outer_scale_m)
        return spectral_constant() / 3.0 * _beta(2.5, 1.0 / 3.0) * k0 ** (-2.0 / 3.0)
    raise ValueError("the inertial (Kolmogorov) model has no finite variance")


def integral_scale_coefficient(model: Model = "exponential") -> float:
    """``c`` in ``L_V = c sigma_V^3 / eps``.

    Banakh et al. (1999), eq. 19: ``c = (2 * 1.21 / C_K)^(3/2) = 1.331`` for the model of
    their eq. 17; von Karman (``L_V`` = integral scale, ``C_K = 2``): ``c = 0.6973``.
    """
    if model == "exponential":
        return (2.0 * EXPONENTIAL_COEFFICIENT / KOLMOGOROV_CONSTANT) ** 1.5
    if model == "von_karman":
        return 1.0 / variance_per_eps23("von_karman", 1.0) ** 1.5
    raise ValueError(f"no integral scale for model {model!r}")


def outer_scale_from(sigma2: ArrayLike, eps: ArrayLike, model: Model) -> np.ndarray:
    """``L_V = c sigma_V^3 / eps`` (m) from ``sigma_V^2`` (m2 s-2) and ``eps`` (m2 s-3).

    Banakh et al. (1999), eq. 19.
    """
    # the same relation as dissipation.epsilon_from_integral_scale, solved for L_V
    return (
        integral_scale_coefficient(model)
        * np.asarray(sigma2, float) ** 1.5
        / np.asarray(eps, float)
    )


def variance_from(
    eps: ArrayLike, outer_scale_m: ArrayLike, model: Model = "exponential"
) -> np.ndarray:
    """``sigma_V^2 = (eps L_V / c)^(2/3)`` (m2 s-2), Banakh et al. (1999), eq. 19."""
    c = integral_scale_coefficient(model)
    return (np.asarray(eps, float) * np.asarray(outer_scale_m, float) / c) ** (2.0 / 3.0)


def _check_model(model: str, outer_scale_m: float | None) -> None:
    if model not in MODELS:
        raise ValueError(f"unknown spectrum model {model!r}; choose one of {', '.join(MODELS)}")
    if model != "inertial" and not (
        outer_scale_m is not None and math.isfinite(outer_scale_m) and outer_scale_m > 0
    ):
        raise ValueError(f"model {model!r} needs a finite outer scale > 0 (m)")


# --------------------------------------------------------------------------------------
# structure functions (no probe-volume averaging)
# --------------------------------------------------------------------------------------


def correlation_functions(
    r: ArrayLike, model: Model, outer_scale_m: float
) -> tuple[np.ndarray, np.ndarray]:
    """Normalised longitudinal and transverse correlations ``f(r)`` and ``g = f + r f'/2`` (1).

    ``f = exp[-1.21 (r/L_V)^(2/3)]`` (Banakh et al. (1999), eq. 17) or von Karman
    ``f = 2^(2/3)/Gamma(1/3) x^(1/3) K_(1/3)(x)``, ``x = k0 r`` with integral scale
    ``L_V``; ``g`` is the transverse correlation of isotropic turbulence (eq. 16).

    Parameters
    ----------
    r : array_like
        Separation (m), >= 0.
    model : {"exponential", "von_karman"}
    outer_scale_m : float
        Integral scale L_V (m).
    """
    r = np.asarray(r, dtype=float)
    if model not in ("exponential", "von_karman"):
        raise ValueError(f"model {model!r} has no correlation function (finite variance)")
    if model == "exponential":
        x = (r / outer_scale_m) ** (2.0 / 3.0)
        f = np.exp(-EXPONENTIAL_COEFFICIENT * x)
        return f, f * (1.0 - EXPONENTIAL_COEFFICIENT / 3.0 * x)
    from scipy import special  # here: 0.2 s of imports only von Karman needs

    x = r * _von_karman_k0(outer_scale_m)
    norm = 2.0 ** (2.0 / 3.0) / math.gamma(1.0 / 3.0)
    with np.errstate(invalid="ignore"):
        f = norm * x ** (1.0 / 3.0) * special.kv(1.0 / 3.0, x)
        g = f - 0.5 * norm * x ** (4.0 / 3.0) * special.kv(2.0 / 3.0, x)
    return np.where(x == 0, 1.0, f), np.where(x == 0, 1.0, g)


def longitudinal_structure_function(
    r: ArrayLike, model: Model = "inertial", outer_scale_m: float | None = None
) -> np.ndarray:
    """``D_par(r) / eps^(2/3)`` (m^(2/3)), the longitudinal velocity structure function.

    Inertial: ``2 r^(2/3)`` (Smalikho (2020), eq. 12); finite outer scale:
    ``2 sigma_V^2 [1 - f(r)]`` with ``f`` of Banakh et al. (1999), eq. 17 or von Karman.
    """
    _check_model(model, outer_scale_m)
    r = np.abs(np.asarray(r, dtype=float))
    if model == "inertial":
        return KOLMOGOROV_CONSTANT * r ** (2.0 / 3.0)
    f, _ = correlation_functions(r, model, outer_scale_m)
    return 2.0 * variance_per_eps23(model, outer_scale_m) * (1.0 - f)


def transverse_structure_function(
    r: ArrayLike, model: Model = "inertial", outer_scale_m: float | None = None
) -> np.ndarray:
    """``D_perp(r) / eps^(2/3)`` (m^(2/3)), the transverse velocity structure function.

    Inertial: ``(8/3) r^(2/3)`` (Smalikho (2020), eq. 13); finite outer scale:
    ``2 sigma_V^2 [1 - g(r)]``, ``g = f + (r/2) df/dr`` (Banakh et al. (1999), eq. 16).
    """
    _check_model(model, outer_scale_m)
    r = np.abs(np.asarray(r, dtype=float))
    if model == "inertial":
        return 4.0 / 3.0 * KOLMOGOROV_CONSTANT * r ** (2.0 / 3.0)
    _, g = correlation_functions(r, model, outer_scale_m)
    return 2.0 * variance_per_eps23(model, outer_scale_m) * (1.0 - g)


# --------------------------------------------------------------------------------------
# energy spectra
# --------------------------------------------------------------------------------------


def _exponential_series(q: np.ndarray, n_terms: int = 90) -> np.ndarray:
    """Dimensionless spectrum of Banakh et al. (1999), eq. 17 for ``q = k L_V >= 0.5``.

    Term-by-term transform of ``exp(-a x^(2/3)) = sum (-a)^n x^(2n/3)/n!`` in
    ``E(k) = (1/pi) int_0^inf B(r) [k r sin(k r) - (k r)^2 cos(k r)] dr`` (per
    ``sigma_V^2 L_V``); the series converges for every ``q > 0`` and agrees with direct
    quadrature to 3e-7 at ``q >= 0.6`` (cancellation grows below).
    """
    from scipy import special  # here: 0.2 s of imports only the spectrum needs

    n = np.arange(n_terms)
    b = 2.0 * n / 3.0
    logc = n * math.log(EXPONENTIAL_COEFFICIENT) - special.gammaln(n + 1.0)
    amp = (
        special.gamma(b + 2.0) * np.sin(np.pi * (b + 2.0) / 2.0)
        - special.gamma(b + 3.0) * np.cos(np.pi * (b + 3.0) / 2.0)
    ) / np.pi
    coef = (-1.0) ** n * np.exp(logc) * amp
    coef[n % 3 == 0] = 0.0  # even integer powers of r transform to nothing at k > 0
    q = np.asarray(q, dtype=float)
    # sum_n coef_n q^(-2n/3 - 1): a polynomial in z = q^(-2/3), evaluated by Horner's rule
    return np.polynomial.polynomial.polyval(q ** (-2.0 / 3.0), coef) / q


@lru_cache(maxsize=1)
def _exponential_low_q() -> CubicSpline:
    """Cubic spline of ``ln e(q)`` against ``ln q`` for ``1e-3 <= q <= 1`` (quadrature)."""
    from scipy import integrate, interpolate  # here: 0.2 s of imports only this table needs

    a = EXPONENTIAL_COEFFICIENT
    qs = np.geomspace(1e-3, 1.0, 61)
    vals = []
    for q in qs:
        v, _ = integrate.quad(
            lambda x, q=q: (
                np.exp(-a * x ** (2.0 / 3.0))
                * (q * x * np.sin(q * x) - (q * x) ** 2 * np.cos(q * x))
            ),
            0.0,
            400.0,
            limit=4000,
            epsabs=0.0,
            epsrel=1e-11,
        )
        vals.append(v / np.pi)
    return interpolate.CubicSpline(np.log(qs), np.log(vals))


def _exponential_dimensionless(q: np.ndarray) -> np.ndarray:
    """``E(k) / (sigma_V^2 L_V)`` of Banakh et al. (1999), eq. 17 at ``q = k L_V`` (angular)."""
    q = np.asarray(q, dtype=float)
    out = np.empty_like(q)
    hi = q >= 0.75
    out[hi] = _exponential_series(q[hi])
    mid = (q >= 1e-3) & ~hi
    out[mid] = np.exp(_exponential_low_q()(np.log(q[mid])))
    lo = q < 1e-3
    # E ~ q^4 Gamma(15/2) / (2 pi a^(15/2)) as q -> 0 (small-q Taylor expansion)
    out[lo] = q[lo] ** 4 * math.gamma(7.5) / (2 * np.pi * EXPONENTIAL_COEFFICIENT**7.5)
    return out


def energy_spectrum(
    kappa: ArrayLike, model: Model = "inertial", outer_scale_m: float | None = None
) -> np.ndarray:
    """3-D energy spectrum ``E(kappa) / eps^(2/3)`` with ``kappa`` in cycles m-1.

    ``int_0^inf E dkappa = (3/2) sigma_V^2``. Inertial: ``alpha (2 pi)^(-2/3)
    kappa^(-5/3)``; von Karman: ``alpha (2 pi)^(-2/3) kappa^4 / (kappa^2 + kappa0^2)^(17/6)``;
    exponential: the transform of Banakh et al. (1999), eq. 17 (series/quadrature, relative
    accuracy 3e-7).
    """
    _check_model(model, outer_scale_m)
    kappa = np.abs(np.asarray(kappa, dtype=float))
    beta = _beta_cycles()
    if model == "inertial":
        return beta * kappa ** (-5.0 / 3.0)
    if model == "von_karman":
        k0 = _von_karman_k0(outer_scale_m) / (2.0 * np.pi)
        return beta * kappa**4 / (kappa**2 + k0**2) ** (17.0 / 6.0)
    s2 = variance_per_eps23("exponential", outer_scale_m)
    return (
        2.0
        * np.pi
        * s2
        * outer_scale_m
        * _exponential_dimensionless(2.0 * np.pi * kappa * outer_scale_m)
    )


@lru_cache(maxsize=1)
def _exponential_plane_splines() -> tuple[CubicSpline, CubicSpline]:
    """Splines of ``ln I1``, ``ln I2`` against ``ln q`` for the exponential model (L_V = 1).

    ``I1(q) = (1/2pi q) int_0^inf E(q cosh u) / cosh u du`` and
    ``I2(q) = (1/2pi q^3) int_0^inf E(q cosh u) / cosh^3 u du`` (``E`` in cycles per
    metre, ``kappa3 = q sinh u``); trapezoid rule in ``u`` with step 0.02 (relative error
    below 1e-7, checked against the closed form of von Karman).
    """
    from scipy import integrate, interpolate  # here: 0.2 s of imports only this table needs

    q = np.geomspace(1e-5, 1e5, 401)
    u = np.arange(0.0, 36.0, 0.02)
    ch = np.cosh(u)
    out1 = np.empty_like(q)
    out2 = np.empty_like(q)
    for i in range(0, q.size, 50):
        qq = q[i : i + 50, None]
        e = energy_spectrum(qq * ch, "exponential", 1.0)
        out1[i : i + 50] = integrate.trapezoid(e / ch, u, axis=1) / (2 * np.pi * qq[:, 0])
        out2[i : i + 50] = integrate.trapezoid(e / ch**3, u, axis=1) / (2 * np.pi * qq[:, 0] ** 3)
    lq = np.log(q)
    return interpolate.CubicSpline(lq, np.log(out1)), interpolate.CubicSpline(lq, np.log(out2))


def _plane_parts(kappa: np.ndarray, model: Model, outer_scale_m: float) -> tuple:
    """``(I1, I2)`` of the 2-D spectrum (per eps^(2/3)) at ``|kappa|`` (cycles m-1)."""
    if model == "von_karman":
        beta = _beta_cycles()
        k0 = _von_karman_k0(outer_scale_m) / (2.0 * np.pi)
        a2 = kappa**2 + k0**2
        p43 = 1.0 / (np.cbrt(a2) * a2)  # a2^(-4/3) (a cube root is cheaper than a power)
        p73 = p43 / a2  # a2^(-7/3)
        i1 = beta / (4 * np.pi) * _B1 * (p43 - (8.0 / 11.0) * k0**2 * p73)
        i2 = beta / (4 * np.pi) * _B1 * (8.0 / 11.0) * p73
        return i1, i2
    s1, s2 = _exponential_plane_splines()
    q = np.clip(kappa * outer_scale_m, 1e-5, 1e5)
    lq = np.log(q)
    i1 = np.exp(s1(lq))
    i2 = np.exp(s2(lq))
    # power-law continuation outside the tabulated range (flat below, Kolmogorov above)
    big = kappa * outer_scale_m > 1e5
    ratio = np.where(big, kappa * outer_scale_m / 1e5, 1.0)
    i1 = i1 * ratio ** (-8.0 / 3.0)
    i2 = i2 * ratio ** (-14.0 / 3.0)
    scale = outer_scale_m ** (8.0 / 3.0)  # I1 ~ L^(8/3) at fixed q, per eps^(2/3)
    return i1 * scale, i2 * scale * outer_scale_m**2


def plane_spectrum(
    kappa1: ArrayLike,
    kappa2: ArrayLike,
    model: Model = "inertial",
    outer_scale_m: float | None = None,
    *,
    constant: float | None = None,
) -> np.ndarray:
    """2-D spectrum ``Phi(kappa1, kappa2) / eps^(2/3)`` of the radial velocity (m^(8/3)).

    Smalikho (2020), eq. 18 for the inertial model:
    ``C (k1^2 + k2^2)^(-4/3) [1 + (8/3) k2^2 / (k1^2 + k2^2)]``; for finite outer scales
    ``4 [I1(kappa) - kappa1^2 I2(kappa)]`` (module docstring).

    Parameters
    ----------
    kappa1, kappa2 : array_like
        Wavenumbers along and across the beam (cycles m-1); broadcast.
    model : {"inertial", "von_karman", "exponential"}
    outer_scale_m : float, optional
        ``L_V`` (m), required for the finite-outer-scale models.
    constant : float, optional
        ``C`` of eq. 18 (inertial model only); default :func:`exact_plane_constant`,
        :data:`PRINTED_PLANE_CONSTANT` reproduces the paper's 0.0652.
    """
    _check_model(model, outer_scale_m)
    k1 = np.asarray(kappa1, dtype=float)
    k2 = np.asarray(kappa2, dtype=float)
    ksq = k1**2 + k2**2
    if model == "inertial":
        c = exact_plane_constant() if constant is None else constant
        with np.errstate(divide="ignore", invalid="ignore"):
            return c / (np.cbrt(ksq) * ksq) * (1.0 + (8.0 / 3.0) * k2**2 / ksq)
    i1, i2 = _plane_parts(np.sqrt(ksq), model, outer_scale_m)
    return 4.0 * (i1 - k1**2 * i2)
