"""Accuracy of eps, sigma_e, sigma_V^2 and L_V on exact-statistics scans (issue 12).

Truth that is exact: :mod:`cwproc.sim.exact_gaussian` draws every block of scans as a
Gaussian vector with the exact covariance of the probe-averaged radial velocities of a
von Kármán field (Banakh et al. (1999), eqs. 15-16), including the transport by the mean
wind and the sweep of continuous scans; no grid, so no missing small-scale energy. Each
case runs the user's chain (``pipeline.process_scans`` with the ``streamline`` preset)
on ``--blocks`` independent blocks of ``n_scans`` scans and prints, per retrieval model,

- ``eps``: mean of eps_hat/eps +- its standard error, and the rms of eps_hat/eps - 1;
- ``sig_e``: mean of noise_std/sigma_e (the fitted noise where it is determined, the
  predicted one elsewhere); ``fit``: share of the blocks whose sigma_e is fitted
  (``turbulence_flag`` without bit 32), ``sig_fit``: mean of noise_std/sigma_e over those;
- ``var``, ``L_V``: mean of sigma_V^2_hat/sigma_V^2 and L_V_hat/L_V; ``L_med``: the median
  of L_V_hat/L_V (``L_V = c sigma_V^3 / eps`` of a block is skewed: where sigma_V^2
  scatters 65 % per block, as in the 90 deg sector, its mean exceeds its median by 50 %);
- ``se/sd``: mean reported standard error of eps over the scatter of eps_hat (when the
  product has ``epsilon_standard_error``); ``var_se``, ``L_se``: the same for sigma_V^2
  and L_V;
- ``lnse``: the same in logarithms, the mean relative standard error ``se/eps_hat`` over
  the scatter of ``ln eps_hat``; ``in1``: share of blocks whose ``|eps_hat - eps|`` is at
  most their standard error (0.683 for calibrated Gaussian errors). Where a block's
  relative error reaches 30-50 % (few rays, strong wind) eps_hat is skewed: its scatter
  is set by a few blocks of the upper tail, and ``se/sd`` reads low while the relative
  errors are calibrated (``lnse`` near 1, ``in1`` near 0.68);
- ``ok``: share of blocks with a valid eps.

Cases: 24- and 36-ray step-stare VADs, 72- and 180-ray continuous scans, mu = U/V_s
(Smalikho (2020), eq. 3) from 0 to 3, a 180-ray scan with a 60 deg gap and a 90 deg
continuous sector scan; last, step-stare VADs of 12, 24 and 36 rays whose rays dwell 1 s
and 3 s (pulses per ray / PRF, the beam moving 1 s between rays) at mu 0, 1, 3
(``--case dwell``).

Run (about 10-20 min on 2 cores; the 180-ray covariances take most of it)::

    python benchmarks/bench_epsilon_accuracy.py
    python benchmarks/bench_epsilon_accuracy.py --quick    # 24/72 rays, mu 0 and 1
    python benchmarks/bench_epsilon_accuracy.py --case "72 rays" --mu 1 --model von_karman
    python benchmarks/bench_epsilon_accuracy.py --case "180 rays cont" --noise 0.3  # fitted
    python benchmarks/bench_epsilon_accuracy.py --case dwell --mu 1 --blocks 20
    python benchmarks/bench_epsilon_accuracy.py --case sector --sector-fly-back 0  # back to back
    python benchmarks/bench_epsilon_accuracy.py --case "36 rays step 3s" --mu 0.1  # light wind

``--case`` and ``--mu`` select cases of the full list; every case keeps the seed it has
in the full run (``--seed`` plus its index), so a selected case repeats its row.
"""

from __future__ import annotations

import argparse
import dataclasses
import time
import warnings

import numpy as np

from cwproc.config import load_config
from cwproc.physics import spectra
from cwproc.pipeline import process_scans
from cwproc.sim import exact_gaussian as eg
from cwproc.stages.epsilon.flags import FLAG_NOISE_PREDICTED

PHI = 35.0
HEIGHT = 100.0
EPS = 1e-2
L_V = 200.0
NOISE = 0.05
N_SCANS = 10


def cases(quick: bool, fly_back_s: float = 3.0) -> list[dict]:
    """(label, pattern, mu) of every case; ``fly_back_s``: the 90 deg sector's return time
    (0: swept back to back, the scans correlated)."""
    out = []
    scans = [(24, False, 48.0), (72, True, 36.0)]
    if not quick:
        scans = [(24, False, 48.0), (36, False, 54.0), (72, True, 36.0), (180, True, 36.0)]
    for rays, continuous, period in scans:
        for mu in (0.0, 1.0) if quick else (0.0, 0.5, 1.0, 2.0, 3.0):
            kind = "cont" if continuous else "step"
            out.append(
                {
                    "label": f"{rays:3d} rays {kind}",
                    "pattern": eg.conical_pattern(
                        rays,
                        period,
                        continuous=continuous,
                        pulses_per_ray=None if continuous else 10000,
                    ),
                    "mu": mu,
                }
            )
    if not quick:
        for mu in (0.5, 1.0, 2.0):
            out.append(
                {
                    "label": "180 rays, 60° gap",
                    "pattern": eg.conical_pattern(180, 36.0, gap=(120.0, 60.0)),
                    "mu": mu,
                }
            )
            out.append(_sector(45, 90.0, mu, fly_back_s))
        out += dwell_cases()
        # issue 29's Show table: the sectors at mu 0 and 3 too (appended, so that every
        # earlier case keeps its seed)
        out += [_sector(45, 90.0, mu, fly_back_s) for mu in (0.0, 3.0)]
        out += [_sector(90, 180.0, mu, fly_back_s) for mu in (0.0, 1.0, 3.0)]
    return out


def _sector(rays: int, sector_deg: float, mu: float, fly_back_s: float) -> dict:
    """A continuous sector scan of 2 deg rays (0.2 s each) with its fly-back (s)."""
    return {
        "label": f"{rays:3d} rays, {sector_deg:g}° sector",
        "pattern": eg.conical_pattern(rays, rays * 0.2, sector_deg=sector_deg, return_s=fly_back_s),
        "mu": mu,
    }


#: time the beam takes from one azimuth of a step-stare VAD to the next (s)
MOVE_S = 1.0
#: pulse repetition frequency of the simulated Stream Line (Hz)
PRF_HZ = 15000.0


def dwell_cases() -> list[dict]:
    """Step-stare VADs whose rays dwell 1 s and 3 s (issue 29): 12, 24, 36 rays, mu 0-3.

    Each ray accumulates ``dwell x PRF`` pulses at its azimuth while the wind carries the
    field (the generator averages over the dwell, the header says the pulses), then the
    beam moves for :data:`MOVE_S`: ray period ``dwell + 1 s``, dwell fraction 0.5 / 0.75.
    The 12-ray VADs (30 deg steps) take 20 scans per block and get two lags (30 and 60
    deg; three would reach 90 deg, beyond the 60 deg limit of the structure function),
    their A_2 from :mod:`cwproc.physics.few_ray_sector`.
    """
    out = []
    for rays in (12, 24, 36):
        for dwell in (1.0, 3.0):
            period = rays * (dwell + MOVE_S)
            pattern = eg.conical_pattern(
                rays,
                period,
                continuous=False,
                pulses_per_ray=round(dwell * PRF_HZ),
                prf_hz=PRF_HZ,
            )
            for mu in (0.0, 1.0, 3.0):
                label = f"{rays:3d} rays step {dwell:g}s dwell"
                # a 12-ray VAD has 12 pairs per lag and scan: 20 scans for min_pairs 100
                scans = 20 if rays == 12 else N_SCANS
                out.append({"label": label, "pattern": pattern, "mu": mu, "n_scans": scans})
    return out


def with_extra_mu(listed: list[dict], wanted: list[float] | None) -> list[dict]:
    """``listed`` and, after them, each case at the ``wanted`` mu it does not list.

    ``--mu 0.1`` runs the cases at a mu of their own; the listed cases keep their index,
    hence their seed, and the added ones take theirs after them.
    """
    out = list(listed)
    for m in wanted or ():
        for label in dict.fromkeys(c["label"] for c in listed):
            same = [c for c in listed if c["label"] == label]
            if not any(abs(c["mu"] - m) < 1e-9 for c in same):
                out.append(same[0] | {"mu": m})
    return out


def scan_speed(pattern: eg.ScanPattern) -> float:
    """V_s = 2 pi R' / T (m s-1) of the full-circle rate of the pattern (Smalikho (2020), eq. 3)."""
    radius = HEIGHT / np.tan(np.deg2rad(PHI))
    degrees_per_s = (pattern.sweep_deg or 360.0 / pattern.n_rays) / pattern.dwell_s
    return np.deg2rad(degrees_per_s) * radius


def summarise(turb, truth_var: float, noise: float = NOISE) -> dict[str, float]:
    """Ratios to the truth over the blocks of one product."""
    eps = turb["epsilon"].values[:, 0] / EPS
    good = np.isfinite(eps)
    row = {"ok": good.mean(), "n": int(good.sum())}
    if good.sum() < 2:
        return row
    e = eps[good]
    row["eps"] = e.mean()
    row["eps_se"] = e.std(ddof=1) / np.sqrt(e.size)
    row["eps_rms"] = np.sqrt(np.mean((e - 1) ** 2))
    for name, key, truth in (
        ("noise_std", "sig_e", noise),
        ("velocity_variance", "var", truth_var),
        ("integral_scale", "L_V", L_V),
    ):
        if name in turb:
            v = turb[name].values[:, 0][good] / truth
            v = v[np.isfinite(v)]
            row[key] = v.mean() if v.size else np.nan
            if key == "L_V" and v.size:
                row["L_med"] = np.median(v)
    fitted = (turb["turbulence_flag"].values[:, 0][good].astype(int) & FLAG_NOISE_PREDICTED) == 0
    row["fit"] = fitted.mean()
    if fitted.any():
        row["sig_fit"] = np.mean(turb["noise_std"].values[:, 0][good][fitted] / noise)
    if "epsilon_standard_error" in turb:
        se = turb["epsilon_standard_error"].values[:, 0][good] / EPS
        row["se/sd"] = np.nanmean(se) / e.std(ddof=1)
        row["lnse"] = np.nanmean(se / e) / np.log(e[e > 0]).std(ddof=1)
        row["in1"] = np.mean(np.abs(e - 1.0) <= se)
    for name, key in (("velocity_variance", "var se/sd"), ("integral_scale", "L_V se/sd")):
        if f"{name}_standard_error" in turb:
            v = turb[name].values[:, 0][good]
            se = turb[f"{name}_standard_error"].values[:, 0][good]
            ok = np.isfinite(v) & np.isfinite(se)
            if ok.sum() > 2:
                row[key] = np.mean(se[ok]) / np.std(v[ok], ddof=1)
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--blocks", type=int, default=100, help="blocks per case (100)")
    parser.add_argument("--quick", action="store_true", help="a few cases only")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--case", action="append", help="cases whose label contains this")
    parser.add_argument(
        "--mu", type=float, action="append", help="only these mu (cases added at a mu they lack)"
    )
    parser.add_argument("--model", action="append", help="only these retrieval models")
    parser.add_argument(
        "--noise", type=float, default=NOISE, help=f"sigma_e of the scans, m/s ({NOISE})"
    )
    parser.add_argument(
        "--sector-fly-back",
        type=float,
        default=3.0,
        help="return time of the 90 deg sector between sweeps, s (3; 0: back to back)",
    )
    args = parser.parse_args()
    base = load_config("streamline")
    truth_var = float(spectra.variance_from(EPS, L_V, "von_karman"))
    models = [base.turbulence.model] + (["inertial"] if base.turbulence.model != "inertial" else [])
    if args.model:
        models = [m for m in models if m in args.model]
    print(
        f"truth: eps = {EPS:g} m2 s-3, L_V = {L_V:g} m (von Karman), sigma_V^2 = "
        f"{truth_var:.3f} m2 s-2, sigma_e = {args.noise} m/s; h = {HEIGHT:g} m, phi = {PHI} deg, "
        f"{N_SCANS} scans per block, {args.blocks} blocks per case"
    )
    header = f"{'case':22s} {'mu':>4s} {'model':>10s} {'eps':>15s} {'rms':>6s}"
    header += f" {'sig_e':>6s} {'var':>6s} {'L_V':>6s} {'L_med':>6s} {'se/sd':>6s} {'var_se':>6s}"
    header += f" {'L_se':>6s} {'lnse':>6s} {'in1':>6s} {'fit':>5s} {'sig_fit':>7s} {'ok':>5s}"
    header += f" {'s':>5s}"
    print(header)
    for i, case in enumerate(with_extra_mu(cases(args.quick, args.sector_fly_back), args.mu)):
        pattern, mu = case["pattern"], case["mu"]
        if args.case and not any(c in case["label"] for c in args.case):
            continue
        if args.mu and not any(abs(mu - m) < 1e-9 for m in args.mu):
            continue
        speed = mu * scan_speed(pattern)
        n_scans = case.get("n_scans", N_SCANS)
        t0 = time.perf_counter()
        scans = eg.gaussian_scans(
            pattern=pattern,
            n_scans=n_scans,
            n_blocks=args.blocks,
            elevation_deg=PHI,
            ranges_m=[HEIGHT / np.sin(np.deg2rad(PHI))],
            epsilon=EPS,
            outer_scale_m=L_V,
            wind_speed_m_s=speed,
            wind_direction_deg=250.0,
            noise_std_m_s=args.noise,
            seed=args.seed + i,
        )
        for model in models:
            config = dataclasses.replace(
                base,
                turbulence=dataclasses.replace(base.turbulence, model=model, n_scans=n_scans),
            )
            notes: list[str] = []
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                products = process_scans(scans, config, notes)
            seconds = time.perf_counter() - t0
            t0 = time.perf_counter()
            turb = products.get("turbulence")
            row = (
                summarise(turb, truth_var, args.noise) if turb is not None else {"ok": 0.0, "n": 0}
            )

            def fmt(key: str, row: dict = row) -> str:
                return f"{row[key]:6.3f}" if key in row else f"{'-':>6s}"

            eps = f"{row['eps']:.3f}±{row['eps_se']:.3f}" if "eps" in row else "-"
            print(
                f"{case['label']:22s} {mu:4.1f} {model:>10s} {eps:>15s} {fmt('eps_rms')}"
                f" {fmt('sig_e')} {fmt('var')} {fmt('L_V')} {fmt('L_med')} {fmt('se/sd')}"
                f" {fmt('var se/sd')} {fmt('L_V se/sd')} {fmt('lnse')} {fmt('in1')}"
                f" {row.get('fit', np.nan):5.2f} {row.get('sig_fit', np.nan):7.3f}"
                f" {row['ok']:5.2f} {seconds:5.1f}" + (f"  ({notes[0][:60]})" if notes else ""),
                flush=True,
            )


if __name__ == "__main__":
    main()
