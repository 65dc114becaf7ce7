"""Declarations of the DBS statistics of WindCube lines of sight (stage ``dbs``).

Part of :mod:`cwproc.metadata` (the one home of names, units and flags), kept apart for
its size. :func:`cwproc.stages.dbs.dbs_statistics` returns these intermediate
variables; :func:`cwproc.stages.wind_record_product` keeps a few of them in the wind
product (``*_variance_dbs``). :data:`DBS_VARIABLES` is merged into ``VARIABLES``;
:data:`DBS_OVERRIDES` holds the names the DBS statistics share with the stare product
in another sense (the table ``"dbs"`` of :func:`cwproc.metadata.described`).
"""

from __future__ import annotations

from cwproc.metadata.canonical import VarMeta
from cwproc.references import PEARSON_2009, SATHE_2011

_CROSS = f"{SATHE_2011} (isotropic von Karman turbulence)"
_WHAT = {
    "along": "the along-wind component",
    "u": "the eastward wind",
    "v": "the northward wind",
    "w": "the upward air velocity",
}


def _component(c: str) -> dict[str, VarMeta]:
    """The variances and ratios of one DBS component over an interval."""
    what = _WHAT[c]
    out = {
        f"{c}_variance_measured": VarMeta(
            f"variance of {what} from the DBS lines of sight over the interval, as measured",
            "m2 s-2",
        ),
        f"{c}_noise_variance": VarMeta(
            f"instrumental noise variance of the DBS estimate of {what}, from the CNR",
            "m2 s-2",
            references=PEARSON_2009 + ", eq. 3",
        ),
        f"{c}_cross_ratio": VarMeta(
            f"DBS cross-contamination ratio of {what}: variance of the point-probe DBS "
            "estimate over the true variance",
            "1",
            references=_CROSS,
        ),
        f"{c}_full_ratio": VarMeta(
            f"combined DBS and pulsed-probe ratio of {what}: variance of the DBS estimate "
            "over the true variance",
            "1",
            references=_CROSS,
        ),
        f"{c}_variance": VarMeta(
            f"variance of {what} over the interval, corrected for noise, pulsed-probe "
            "averaging and DBS cross-contamination",
            "m2 s-2",
            references=_CROSS,
        ),
    }
    return out


#: variables of the DBS statistics not declared elsewhere
DBS_VARIABLES: dict[str, VarMeta] = {
    "u_mean": VarMeta("eastward wind, mean of the DBS cycles of the interval", "m s-1"),
    "v_mean": VarMeta("northward wind, mean of the DBS cycles of the interval", "m s-1"),
    "n_cycles": VarMeta("number of complete DBS beam cycles in the interval", "1"),
    "volume_ratio": VarMeta(
        "ratio of the pulsed probe's radial-velocity variance to the point variance",
        "1",
        references=_CROSS,
    ),
    "w_mismatch": VarMeta(
        "mean upward velocity from the four inclined beams minus that of the vertical beam",
        "m s-1",
    ),
    "turbulence_intensity_noise": VarMeta(
        "turbulence intensity with the noise variance subtracted (no other correction)",
        "1",
        references=PEARSON_2009 + ", eq. 3",
    ),
    "turbulence_intensity_volume": VarMeta(
        "turbulence intensity divided by the pulsed probe's variance ratio (no other correction)",
        "1",
        references=_CROSS,
    ),
    "turbulence_intensity_cross": VarMeta(
        "turbulence intensity divided by the DBS cross-contamination ratio (no other correction)",
        "1",
        references=_CROSS,
    ),
    "w_std_corrected": VarMeta(
        "standard deviation of the upward air velocity over the interval, corrected for "
        "noise, pulsed-probe averaging and DBS cross-contamination",
        "m s-1",
        references=_CROSS,
    ),
}
for _c in ("along", "u", "v", "w"):
    DBS_VARIABLES.update(
        {k: v for k, v in _component(_c).items() if k not in ("w_noise_variance", "w_variance")}
    )

#: names the stare product declares in another sense: their DBS meaning
DBS_OVERRIDES: dict[str, VarMeta] = {
    k: v for k, v in _component("w").items() if k in ("w_noise_variance", "w_variance")
}
