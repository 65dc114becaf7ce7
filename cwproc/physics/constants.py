"""Instrument constants of the papers, one home each (pure Python: the configuration
imports them without loading numpy)."""

#: Stream Line pulse half width dp = c sigma_p / 2 (m), Smalikho (2020), after eq. 19
STREAMLINE_DELTA_P_M = 15.3
#: Stream Line range-gate length dR = c T_w / 2 (m), Smalikho (2020), after eq. 19
STREAMLINE_DELTA_R_M = 18.0
#: ZephIR Rayleigh-range coefficient c in Z_R = c R^2 (1/m), Wagner et al. (DTU), eq. 2
ZEPHIR_Z_R_COEFFICIENT = 0.0013
