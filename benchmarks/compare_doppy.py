"""beta and depolarisation of cwproc against doppy (ACTRIS Cloudnet) on the same files.

Needs doppy (``pip install doppy`` in a separate venv whose python sees cwproc)::

    PYTHONPATH=. /work/wt/venv31/bin/python benchmarks/compare_doppy.py [REAL_HPL_DIR]

For every real stare file with a background file (``FORMATS.md``): doppy's
``Stare.from_halo_data`` and cwproc's background correction + L1 stage, the ratio
cwproc/doppy of beta on the gates both call signal (median and 16-84 % range).
Depolarisation: co/cross pairs re-measured from each real file in the real layout
(:func:`cwproc.sim.depol.polarised_pair`: the true co SNR is the real file's corrected SNR
on its signal gates, delta = 0.1 and 0.3, each channel with its own noise and its own
background file, written under the same name in ``co/`` and ``cross/``), ``N_PAIRS``
realisations through doppy's ``StareDepol.from_halo_data`` and cwproc's pairing:
delta against doppy's and against the truth (median, 16-84 %), the truth within +-1 SE
(all gates with true signal, and those of true co SNR >= 5 noise sd), and the mean
residual of each channel's corrected SNR from its truth (in noise standard errors of the
mean, to tell a construction or correction offset from noise).
"""

from __future__ import annotations

import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np

from cwproc.io.halo import read_hpl, write_hpl
from cwproc.io.halo_background import read_halo_background
from cwproc.sim.depol import polarised_pair, write_background
from cwproc.stages.doppler_lidar import doppler_lidar_product
from cwproc.stages.snr_correction import correct_snr

PAIRS = (
    ("eriswil-2022-12-14-Stare_91_20221214_11.hpl", "eriswil-Background_141222-000013.txt"),
    ("hyytiala-2023-09-13-Stare_46_20230913_23.hpl", "hyytiala-Background_150823-122811.txt"),
)
#: realisations of each simulated pair
N_PAIRS = 20


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
        truth_l1 = cwproc_l1(hpl, bg)
        signal = np.where(
            np.isfinite(truth_l1["beta_screened"].values), truth_l1["snr"].values, 0.0
        )
        sd = float(np.nanmedian(truth_l1["snr_error"].values))
        bg_values = read_halo_background(bg)["background"].values
        for delta in (0.1, 0.3):
            depolarisation_against_doppy(read_hpl(hpl), name, bgname, bg_values, signal, sd, delta)


def depolarisation_against_doppy(co, name, bgname, bg_values, signal, sd, delta) -> None:
    """``N_PAIRS`` simulated pairs of one real file through doppy and cwproc (printed)."""
    import doppy

    vs_doppy, vs_truth, z, z_strong, res_co, res_x = [], [], [], [], [], []
    for seed in range(N_PAIRS):
        c, x, bc, bx = polarised_pair(co, bg_values, signal, delta, noise_std=sd, seed=seed)
        with tempfile.TemporaryDirectory() as tmp:
            files = {}
            for tag, ds, b in (("co", c, bc), ("cross", x, bx)):
                (Path(tmp) / tag).mkdir()
                files[tag] = (
                    write_hpl(ds, Path(tmp) / tag / name),
                    write_background(b, Path(tmp) / tag / bgname),
                )
            try:
                dd = doppy.product.StareDepol.from_halo_data(
                    co_data=[str(files["co"][0])],
                    co_data_bg=[str(files["co"][1])],
                    cross_data=[str(files["cross"][0])],
                    cross_data_bg=[str(files["cross"][1])],
                )
                d_doppy, d_mask = dd.depolarisation, dd.mask_beta
            except Exception as exc:  # doppy pairs no ray of a one-ray file
                d_doppy, d_mask = None, f"{type(exc).__name__}: {exc}"
            cc = cwproc_l1(*files["co"], *files["cross"])
        dc = cc["depolarisation_screened"].values
        true = np.isfinite(dc) & (signal > 0)
        err = cc["depolarisation_error"].values
        vs_truth.append(dc[true] / delta)
        z.append(np.abs(dc[true] - delta) <= err[true])
        strong = true & (signal >= 5 * sd)
        z_strong.append(np.abs(dc[strong] - delta) <= err[strong])
        res_co.append(np.where(signal > 0, cc["snr"].values - signal, np.nan))
        res_x.append(np.where(signal > 0, cc["snr_cross"].values - delta * signal, np.nan))
        if d_doppy is not None:
            ok = ~d_mask & np.isfinite(dc) & np.isfinite(d_doppy)
            vs_doppy.append(dc[ok] / d_doppy[ok])
    se_mean = sd / np.sqrt(np.isfinite(np.array(res_co)).sum())
    doppy_text = summary(np.concatenate(vs_doppy)) if vs_doppy else f"doppy: {d_mask}"
    print(
        f"  simulated delta={delta} ({N_PAIRS} pairs): cwproc/doppy {doppy_text}; "
        f"cwproc/truth {summary(np.concatenate(vs_truth))}; truth within 1 SE on "
        f"{np.mean(np.concatenate(z)):.3f} of the gates, {np.mean(np.concatenate(z_strong)):.3f} "
        f"of those with true SNR >= 5 sd; corrected SNR - truth on the signal gates: co "
        f"{np.nanmean(res_co) / se_mean:+.1f} SE, cross {np.nanmean(res_x) / se_mean:+.1f} SE "
        f"(SE {se_mean:.1e})"
    )


if __name__ == "__main__":
    main(Path(sys.argv[1] if len(sys.argv) > 1 else "/work/shared/real_data/hpl"))
