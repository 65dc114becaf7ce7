"""beta and depolarisation of cwproc against doppy (ACTRIS Cloudnet) on the same files.

Needs doppy (``pip install doppy`` in a separate venv whose python sees cwproc)::

    PYTHONPATH=. /work/wt/venv31/bin/python benchmarks/compare_doppy.py [REAL_HPL_DIR]

For every real stare file with a background file (``FORMATS.md``): doppy's
``Stare.from_halo_data`` and cwproc's background correction + L1 stage, the ratio
cwproc/doppy of beta on the gates both call signal (median and 16-84 % range).
Depolarisation: cross-polarised files simulated from each real co file in the real
layout (:func:`cwproc.sim.depol.cross_polarised`, delta = 0.1 and 0.3, written with
``write_hpl`` under the same name in a ``cross/`` folder with a copy of the background),
through doppy's ``StareDepol.from_halo_data`` and cwproc's pairing.
"""

from __future__ import annotations

import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np

from cwproc.io.halo import read_hpl, write_hpl
from cwproc.io.halo_background import read_halo_background
from cwproc.sim.depol import cross_polarised
from cwproc.stages.background import correct_snr
from cwproc.stages.doppler_lidar import doppler_lidar_product, ray_noise_std

PAIRS = (
    ("eriswil-2022-12-14-Stare_91_20221214_11.hpl", "eriswil-Background_141222-000013.txt"),
    ("hyytiala-2023-09-13-Stare_46_20230913_23.hpl", "hyytiala-Background_150823-122811.txt"),
)


def cwproc_l1(hpl: Path, bg: Path, cross: Path | None = None, cross_bg: Path | None = None):
    co = correct_snr(read_hpl(hpl), [read_halo_background(bg)], max_age_h=None)
    x = None
    if cross is not None:
        x = correct_snr(read_hpl(cross), [read_halo_background(cross_bg)], max_age_h=None)
    return doppler_lidar_product(co, x)


def summary(ratio: np.ndarray) -> str:
    r = ratio[np.isfinite(ratio)]
    if r.size == 0:
        return "no common signal gates"
    p16, p50, p84 = np.percentile(r, [16, 50, 84])
    return f"median {p50:.4f}, 16-84 % {p16:.4f}-{p84:.4f} ({r.size} gates)"


def main(folder: Path) -> None:
    import doppy

    print(f"doppy {doppy.__version__}")
    work = Path(tempfile.mkdtemp())
    for name, bgname in PAIRS:
        hpl = folder / name
        bg = Path(shutil.copy(folder / "background" / bgname, work / bgname.split("-", 1)[1]))
        bgname = bg.name  # doppy takes the time from a name that starts "Background_"
        d = doppy.product.Stare.from_halo_data(data=[str(hpl)], data_bg=[str(bg)])
        c = cwproc_l1(hpl, bg)
        both = ~d.mask_beta & np.isfinite(c["beta_screened"].values)
        print(
            f"{name}: beta cwproc/doppy {summary(np.where(both, c.beta.values / d.beta, np.nan))}"
        )
        agree = np.mean(d.mask_beta == ~np.isfinite(c["beta_screened"].values))
        print(f"  signal/noise mask agreement {agree:.3f}")
        co = read_hpl(hpl)
        sd = float(np.nanmedian(ray_noise_std(co["snr"].values, co["range"].values, 90.0)))
        for delta in (0.1, 0.3):
            with tempfile.TemporaryDirectory() as tmp:
                xdir = Path(tmp) / "cross"
                xdir.mkdir()
                xhpl = write_hpl(cross_polarised(co, delta, sd, seed=1), xdir / name)
                xbg = Path(shutil.copy(bg, xdir / bgname))
                dd = doppy.product.StareDepol.from_halo_data(
                    co_data=[str(hpl)],
                    co_data_bg=[str(bg)],
                    cross_data=[str(xhpl)],
                    cross_data_bg=[str(xbg)],
                )
                cc = cwproc_l1(hpl, bg, xhpl, xbg)
            dc = cc["depolarisation_screened"].values
            z = (dc - delta) / cc["depolarisation_error"].values
            z = z[np.isfinite(z)]
            ok = ~dd.mask_beta & np.isfinite(dc) & np.isfinite(dd.depolarisation)
            print(
                f"  simulated delta={delta}: depolarisation cwproc/doppy "
                f"{summary(np.where(ok, dc / dd.depolarisation, np.nan))}; "
                f"cwproc/truth {summary(np.where(ok, dc / delta, np.nan))}; "
                f"truth within 1 SE on {np.mean(np.abs(z) <= 1):.2f} of {z.size} gates"
            )


if __name__ == "__main__":
    main(Path(sys.argv[1] if len(sys.argv) > 1 else "/work/shared/real_data/hpl"))
