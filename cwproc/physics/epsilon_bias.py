"""Bias of the method-1 dissipation rate: the ratio eps_1 / eps_2, Smalikho (2020), eqs. 21-23.

Method 1 takes the transverse A-function ``A_perp`` (Smalikho (2020), eq. 16) for the
azimuth structure function, which holds without wind transport; method 2 the
theta-average ``A_2`` with transport ``mu = U / V_s`` (eq. 15). Their ratio
(:func:`epsilon_bias_ratio`, eq. 21) is the factor by which method 1 overestimates eps;
:func:`q1` and :func:`q2` are its asymptotes for ``mu >> 1`` (eqs. 22-23). The
A-functions are :mod:`cwproc.physics.afunctions`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from cwproc.physics.afunctions import a2_from_curves, a_curve_splines
from cwproc.physics.transfer import Probe

__all__ = ["epsilon_bias_ratio", "q1", "q2"]


def epsilon_bias_ratio(
    mu: ArrayLike,
    phi_deg: float,
    dy: float,
    lag_number: int,
    *,
    probe: Probe | None,
    range_m: float | None = None,
) -> np.ndarray:
    """Ratio ``eps_1 / eps_2`` of the method-1 and method-2 estimates, Smalikho (2020), eq. 21.

    ``[(A_2(l dy) - A_2(dy)) / (A_1(l dy) - A_1(dy))]^(3/2)``, ``A_1 = A_perp``, inertial
    spectrum (the constant ``C`` cancels).

    Parameters
    ----------
    mu : array_like
        ``U / V_s`` (1).
    phi_deg : float
        Elevation (degrees).
    dy : float
        Transverse sampling (m).
    lag_number : int
        ``l`` of eq. 5 (>= 2).
    probe : PulsedProbe or CWProbe or None
    range_m : float, optional
        Focus distance (m) of a cw probe.
    """
    if int(lag_number) < 2:
        raise ValueError("lag_number must be >= 2 (Smalikho (2020), eq. 5 needs l > 1)")
    mu = np.asarray(mu, dtype=float)
    lmax = float(lag_number)
    curves = a_curve_splines(
        0.02 * dy,
        lmax * dy * (1.0 + float(np.max(mu))) * 1.01,
        probe=probe,
        dy=dy,
        range_m=range_m,
    )
    a2_l = a2_from_curves(curves, lag_number * dy, mu, phi_deg)
    a2_1 = a2_from_curves(curves, dy, mu, phi_deg)
    a1_l = curves.perp(lag_number * dy)
    a1_1 = curves.perp(dy)
    return ((a2_l - a2_1) / (a1_l - a1_1)) ** 1.5


def q1(phi_deg: ArrayLike) -> np.ndarray:
    """``q1(phi) = [sin^2 phi + (7/8) cos^2 phi]^(3/2)``, Smalikho (2020), eq. 22.

    ``eps_1/eps_2 -> q1 mu`` for ``mu >> 1`` when ``l dy >> dz`` (probe length).
    """
    p = np.radians(np.asarray(phi_deg, dtype=float))
    return (np.sin(p) ** 2 + 7.0 / 8.0 * np.cos(p) ** 2) ** 1.5


def q2(phi_deg: ArrayLike) -> np.ndarray:
    """``q2(phi) = [sin^2 phi + cos^2 phi / 2]^(3/2)``, Smalikho (2020), eq. 23.

    ``eps_1/eps_2 -> q2 mu^(5/2)`` for ``mu >> 1`` when ``l dy mu << dz``.
    """
    p = np.radians(np.asarray(phi_deg, dtype=float))
    return (np.sin(p) ** 2 + np.cos(p) ** 2 / 2.0) ** 1.5
