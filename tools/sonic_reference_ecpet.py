"""Reference figures for cwproc's sonic screening from EC-PeT (issue 36).

Runs the despiking (Vickers & Mahrt (1997): ``ecpre.vmspike``; Mauder et al. (2013):
``ecpre.madspike``), the steady-state test (Foken & Wichura (1996): ``ecpre.fwstat``)
and the ITC models (Foken et al. (2004) / Thomas & Foken (2002), "as in TK3":
``ecpost.itc_w``, ``ecpost.itc_u``) of EC-PeT (Clemens Drüe, Universität Trier; PyPI
``ecpet``) on the series of ``tests/physics/sonic_series.py`` and writes what they
find to ``tests/physics/data/sonic_reference_ecpet.json``, which
``tests/physics/test_sonic_reference.py`` compares cwproc with. EC-PeT is not a cwproc
dependency: run this in a throwaway environment::

    python3 -m venv /tmp/venv_sonicref
    /tmp/venv_sonicref/bin/pip install --no-deps ecpet==2.1.0b1
    /tmp/venv_sonicref/bin/pip install numpy==2.4.6 pandas scipy netCDF4
    /tmp/venv_sonicref/bin/python tools/sonic_reference_ecpet.py

(``--no-deps``: EC-PeT's GUI dependency wxPython is not needed by these functions.)

EC-PeT's settings are chosen to be the published constants, given how EC-PeT applies
them: ``vmspike`` raises its threshold by the increment already on the first pass and
counts runs *shorter* than ``spco``, so VM97's 3.5 sigma, +0.1 per pass and runs of at
most 3 are ``spth = 3.4``, ``spin = 0.1``, ``spco = 4`` (5.0 sigma for w, EddyPro's
default: ``spth = 4.9``); ``madspike`` thresholds |x - Md| / MAD, so Mauder et al.'s
q = 7 with MAD/0.6745 is ``madth = 7 / 0.6745``.
"""

from __future__ import annotations

import json
import sys
from importlib import metadata
from pathlib import Path

import numpy as np
import pandas as pd
from ecpet import ecpost, ecpre
from ecpet import ecutils as ec

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests" / "physics"))
import sonic_series as ss  # noqa: E402

# EC-PeT's own logger setup (eclogger) adds an "insane" level; without it, a no-op
for _mod in (ecpre, ecpost):
    _mod.logger.insane = _mod.logger.debug

OUT = ROOT / "tests" / "physics" / "data" / "sonic_reference_ecpet.json"

VM97_U = {"L1": 300.0, "spth": 3.4, "spin": 0.1, "spco": 4, "spcr": 0.01, "spfill": 1}
VM97_W = dict(VM97_U, spth=4.9)
MAD = {"spfill": 1, "mader": 0, "madth": 7.0 / 0.6745, "madcr": 0.01}
FW = {"fwsub": 6, "fwlim1": 0.30, "fwlim2": 0.75}


class Conf:
    """The one method of EC-PeT's configuration object that these functions call."""

    def __init__(self, values: dict[str, float]) -> None:
        self.values = values

    def pull(self, par: str, group: str | None = None, kind: str = "float", na=None):
        value = self.values[par]
        return int(value) if kind == "int" else value


def run_vmspike(x: np.ndarray, settings: dict) -> list[int]:
    ec.metvar = ["ux"]
    dat = pd.DataFrame({"ux": x})
    _, _, res = ecpre.vmspike(Conf(settings), dat, 1.0 / ss.RATE)
    return np.flatnonzero(res["ux"].to_numpy() != x).tolist()


def run_madspike(x: np.ndarray) -> list[int]:
    ec.metvar = ["ux"]
    dat = pd.DataFrame({"ux": x})
    _, _, res = ecpre.madspike(Conf(MAD), dat)
    return np.flatnonzero(res["ux"].to_numpy() != x).tolist()


def run_fwstat(u: np.ndarray, w: np.ndarray) -> float:
    ec.metvar = ["ux"]
    dat = pd.DataFrame({"ux": u, "uz": w})
    _, qms = ecpre.fwstat(Conf(FW), dat)
    return 100.0 * float(qms["ux__qmfwd"])


def main() -> None:
    f = 2.0 * ec.omega * np.sin(np.radians(ss.ITC_LATITUDE_DEG))
    out: dict[str, object] = {
        "reference": "EC-PeT",
        "package": "ecpet",
        "version": metadata.version("ecpet"),
        "numpy": np.__version__,
        "pandas": pd.__version__,
        "script": "tools/sonic_reference_ecpet.py",
        "settings": {"vm97_u": VM97_U, "vm97_w": VM97_W, "mad": MAD, "fwstat": FW},
        "despiking": {},
        "stationarity_pct": {},
        "itc": {"latitude_deg": ss.ITC_LATITUDE_DEG, "coriolis_s-1": f, "points": []},
    }
    for name, (y, injected) in ss.spiked_cases().items():
        out["despiking"][name] = {
            "fingerprint": ss.fingerprint(y),
            "injected": np.flatnonzero(injected).tolist(),
            "vm97_u": run_vmspike(y, VM97_U),
            "vm97_w": run_vmspike(y, VM97_W),
            "mad": run_madspike(y),
        }
    for name, (u, w) in ss.flux_cases().items():
        out["stationarity_pct"][name] = {
            "fingerprint": ss.fingerprint(u) + ss.fingerprint(w),
            "rn": run_fwstat(u, w),
        }
    for zl, ustar in ss.ITC_POINTS:
        out["itc"]["points"].append(
            {
                "zl": zl,
                "ustar": ustar,
                "sigma_w_over_ustar": float(ecpost.itc_w(zl, ustar, f)),
                "sigma_u_over_ustar": float(ecpost.itc_u(zl, ustar, f)),
            }
        )
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps(out, indent=1, sort_keys=True) + "\n")
    for name, d in out["despiking"].items():
        print(name, {k: len(v) for k, v in d.items() if isinstance(v, list) and k != "fingerprint"})
    print({k: round(v["rn"], 2) for k, v in out["stationarity_pct"].items()})


if __name__ == "__main__":
    main()
