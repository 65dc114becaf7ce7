"""Background correction of the SNR on the real Stream Line stares (and against doppy).

For each real stare of ``../shared/real_data/hpl`` with a background file of the same
site (Eriswil, Hyytiala; the sample set has no Warsaw background), prints:

* the gates passing the SNR screen (``qc.snr_min`` = 0.008) before and after the
  correction, and passing a screen at 5 noise standard deviations of the corrected SNR;
* the noise floor F found (median over range, intensity units) and the noise sd
  (scaled MAD of the SNR of the signal-free gates) before and after;
* when doppy is installed: cwproc's corrected SNR against doppy's corrected SNR on the
  same files, as the ratio of the intensities (SNR + 1) over all gates beyond 90 m and
  as the ratio of the SNRs of gates where both give SNR >= 0.008 (median, 16 and 84 %).

The background files were measured on other dates than the stares (Eriswil: 11 h
earlier on the same day; Hyytiala: 29 days earlier); they are matched by site with no
age limit (``max_age_h=None``), which the pipeline does only when configured so.

Run: ``python benchmarks/bench_background.py [--shared ../shared]``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from cwproc.io import read_file
from cwproc.io.halo_background import read_halo_background
from cwproc.physics.snr_background import signal_free_gates
from cwproc.stages.snr_correction import correct_snr

#: (site, stare file, background file) of the real sample set
CASES = (
    (
        "Eriswil",
        "eriswil-2022-12-14-Stare_91_20221214_11.hpl",
        "eriswil-Background_141222-000013.txt",
    ),
    (
        "Hyytiala",
        "hyytiala-2023-09-13-Stare_46_20230913_23.hpl",
        "hyytiala-Background_150823-122811.txt",
    ),
    ("Warsaw", "warsaw-2022-12-13-Stare_213_20221213_04.hpl", None),
)
SNR_MIN = 0.008


def doppy_snr(stare: Path, background: Path) -> np.ndarray | None:
    """doppy's background- and noise-corrected SNR of one stare, or None without doppy."""
    try:
        import doppy
    except ImportError:
        return None
    name = background.name[background.name.index("Background_") :]  # doppy needs the bare name
    product = doppy.product.Stare.from_halo_data(
        data=[str(stare)],
        data_bg=[(background.read_bytes(), name)],
        bg_correction_method=doppy.options.BgCorrectionMethod.FIT,
    )
    return np.asarray(product.snr, dtype=float)


def percentiles(x: np.ndarray) -> str:
    x = x[np.isfinite(x)]
    if x.size == 0:
        return "no gates"
    p16, p50, p84 = np.percentile(x, [16, 50, 84])
    return f"median {p50:.4f}, 16-84 % {p16:.4f} - {p84:.4f} ({x.size} gates)"


def noise_sd(snr: np.ndarray, rng: np.ndarray) -> float:
    """Scaled MAD of the SNR of the signal-free gates."""
    free = signal_free_gates(snr + 1.0, rng)
    x = snr[free]
    return float(1.4826 * np.median(np.abs(x - np.median(x))))


def run_case(site: str, hpl: Path, bg: Path | None) -> None:
    ds = read_file(hpl)
    rng = np.asarray(ds["range"].values, dtype=float)
    print(f"{site}: {hpl.name} ({ds.sizes['ray']} rays x {rng.size} gates)")
    if bg is None:
        print("  no background file of this site in the sample set: SNR not corrected")
        return
    background = read_halo_background(bg)
    notes: list[str] = []
    out = correct_snr(ds, [background], max_age_h=None, notes=notes)
    before, after = out["snr_uncorrected"].values, out["snr"].values
    sd0, sd1 = noise_sd(before, rng), noise_sd(after, rng)
    age_d = (ds["time"].values[0] - background["time"].values) / np.timedelta64(86400, "s")
    print(f"  background {bg.name}: {background.sizes['range']} gates, {age_d:.2f} days before")
    print(f"  method: {out.attrs['snr_correction']}")
    print(f"  noise floor F (median over range): {np.round(out['noise_floor'].values, 6)}")
    print(f"  noise sd of SNR (signal-free gates): before {sd0:.5f}, after {sd1:.5f}")
    far = rng > 90.0  # gates within 90 m are left as the instrument gave them
    print(
        f"  gates with SNR >= {SNR_MIN}: before {int((before >= SNR_MIN).sum())}, "
        f"after {int((after >= SNR_MIN).sum())} of {before.size}; beyond 90 m: "
        f"{int((before[:, far] >= SNR_MIN).sum())} -> {int((after[:, far] >= SNR_MIN).sum())}"
    )
    print(
        f"  gates with SNR >= 5 noise sd: before {int((before >= 5 * sd0).sum())} "
        f"(>= {5 * sd0:.5f}), after {int((after >= 5 * sd1).sum())} (>= {5 * sd1:.5f})"
    )
    ref = doppy_snr(hpl, bg)
    if ref is None:
        print("  doppy not installed: no comparison")
        return
    ratio_i = ((after + 1.0) / (ref + 1.0))[:, far].ravel()
    both = (after >= SNR_MIN) & (ref >= SNR_MIN)
    print(f"  (SNR+1) cwproc / doppy, gates beyond 90 m: {percentiles(ratio_i)}")
    print(f"  SNR cwproc / doppy, both >= {SNR_MIN}: {percentiles((after / ref)[both])}")
    print(
        f"  doppy: gates with SNR >= {SNR_MIN}: {int((ref >= SNR_MIN).sum())} "
        f"(beyond 90 m {int((ref[:, far] >= SNR_MIN).sum())}), "
        f"noise sd {noise_sd(ref, rng):.5f}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument(
        "--shared", default=str(Path(__file__).resolve().parents[1].parent / "shared")
    )
    args = parser.parse_args()
    folder = Path(args.shared) / "real_data" / "hpl"
    if not folder.is_dir():
        raise SystemExit(f"real data not found: {folder}")
    for site, stare, bg in CASES:
        run_case(site, folder / stare, folder / "background" / bg if bg else None)


if __name__ == "__main__":
    main()
