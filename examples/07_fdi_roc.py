"""The FDI's trade-off between detection delay and false alarms, as its threshold's target
false-alarm rate varies (an ROC-style curve; issue 15, docs/fdi.md).

For each target ([fdi] target_false_alarms_per_hour), in the realistic profile (100 Hz
sampled control, the benchmark's sensor noise) with ±10 % model mismatch drawn per run:
fault-free 10-minute runs of the physical AFTC with its own FDI give the false alarms
per simulated hour; 60-s runs with one actuator fault (lock, loss of effectiveness
ρ = 0.5, pressure drop, air in oil; blade 2 at 20 s) give the detection delays. Winds:
IEC NTM class B at 12-20 m/s at the hub-height point, a seed per run. Writes
fdi_roc.png/.pdf and fdi_roc.csv.

    python examples/07_fdi_roc.py [OUT_DIR] [--runs N]    # default out/examples/07_fdi_roc, N 4
"""

import argparse
import sys
from pathlib import Path

import numpy as np

from wtftc import config
from wtftc.campaign import cases
from wtftc.results.io import atomic_savefig, atomic_write_text
from wtftc.results.metrics import metrics

TARGETS = [1e3, 1e1, 1e-1, 1e-3, 1e-6]  # false alarms per hour the threshold allows
FAULTS = [{"type": "lock", "angle_deg": "current"},
          {"type": "loss_of_effectiveness", "rho": 0.5},
          {"type": "pressure_drop"}, {"type": "air_in_oil"}]
MISMATCH = ("inertia", "shaft_stiffness", "shaft_damping", "air_density", "cp_scale",
            "actuator_omega_n", "actuator_zeta")


def _config(target: float, k: int, fault: dict | None, rng) -> dict:
    cfg = {"controller": "physical", "profile": "realistic", "seed": k,
           # the hub-height point (rotor_radius_m = 0), as the FDI's campaigns keep
           # (docs/loads.md), not a run's default rotor average (docs/wind.md)
           "wind": {"kind": "ntm", "mean_mps": float(rng.uniform(12, 20)),
                    "turbulence_class": "B", "rotor_radius_m": 0.0},
           "mismatch": {m: float(rng.uniform(0.9, 1.1)) for m in MISMATCH},
           "fdi": {"target_false_alarms_per_hour": target}, "output_rate_hz": 20.0}
    if fault is None:
        return {**cfg, "case": 1, "t_final_s": 600.0}
    return {**cfg, "case": 4, "t_final_s": 60.0,
            "fault": [{"blade": 2, "onset_s": 20.0, **fault}]}


def measure(target: float, runs: int) -> dict:
    """False alarms per hour and the detection delays at one target."""
    rng = np.random.default_rng(7)
    alarms, hours, delays, missed = 0, 0.0, [], 0
    for k in range(runs):
        rc = config.make_config(_config(target, k, None, rng))
        res = cases.run(rc, progress=False)
        alarms += sum(res.column(f"fdi_latch_{j}").max() >= 0.5 for j in (1, 2, 3))
        hours += rc.t_final / 3600.0
        for fault in FAULTS:
            rc = config.make_config(_config(target, k, fault, rng))
            rep = metrics(rc, cases.run(rc, progress=False))["fdi"]["faults"][0]
            if rep["detected"] and rep["isolated_blade"] == 2:
                delays.append(rep["detection_delay_s"])
            else:
                missed += 1
    return {"target_per_h": target, "false_alarms_per_h": alarms / hours,
            "hours": hours, "delay_median_s": float(np.median(delays)) if delays else None,
            "delay_p90_s": float(np.percentile(delays, 90)) if delays else None,
            "missed": missed, "faults": runs * len(FAULTS)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", nargs="?", type=Path, default=Path("out/examples/07_fdi_roc"))
    ap.add_argument("--runs", type=int, default=4, help="runs per target (each: one "
                    "fault-free 10-min run and one 60-s run per fault type)")
    args = ap.parse_args(argv)
    rows = []
    for target in TARGETS:
        rows.append(measure(target, args.runs))
        r = rows[-1]
        print(f"target {target:g}/h: {r['false_alarms_per_h']:.3g} false alarms/h over "
              f"{r['hours']:.2f} h, delay median {r['delay_median_s']} s, "
              f"missed {r['missed']}/{r['faults']}", flush=True)
    head = list(rows[0])
    atomic_write_text(args.out / "fdi_roc.csv", "\n".join(
        [",".join(head)] + [",".join("" if r[h] is None else str(r[h]) for h in head)
                            for r in rows]) + "\n")
    _figure(rows, args.out)
    print(f"written: {args.out}/fdi_roc.csv, fdi_roc.png, fdi_roc.pdf")
    return 0


def _figure(rows: list[dict], out: Path) -> None:
    """Left: the measured false-alarm rate against the target (0 drawn at the campaign's
    resolution, one alarm in its hours, as a down-pointing marker); right: the detection
    delay against the target: what a looser threshold buys."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a, b) = plt.subplots(1, 2, figsize=(9, 3.8))
    target = [r["target_per_h"] for r in rows]
    floor = 1.0 / rows[0]["hours"]
    for r in rows:
        fa = r["false_alarms_per_h"]
        a.loglog(r["target_per_h"], fa if fa > 0 else floor, "v" if fa == 0 else "o",
                 color="tab:blue")
    a.loglog(target, target, "k--", lw=0.8, label="measured = target")
    a.axhline(floor, color="grey", lw=0.8, ls=":",
              label=f"resolution: 1 in {rows[0]['hours']:.0f} h")
    a.set_xlabel("target false-alarm rate [1/h]")
    a.set_ylabel("measured false alarms [1/h] (▼: none)")
    a.legend(fontsize=7)
    b.semilogx(target, [r["delay_median_s"] for r in rows], "o-", label="median")
    b.semilogx(target, [r["delay_p90_s"] for r in rows], "s--", label="90th percentile")
    b.set_xlabel("target false-alarm rate [1/h]")
    b.set_ylabel("detection delay [s]")
    b.legend(fontsize=7)
    for ax in (a, b):
        ax.grid(alpha=0.3, which="both")
    fig.suptitle("wtftc's FDI as its threshold's target varies (physical AFTC, realistic "
                 "profile, ±10 % mismatch, NTM B 12-20 m/s; 4 actuator fault types)",
                 fontsize=8)
    fig.tight_layout()
    for ext in ("png", "pdf"):
        atomic_savefig(fig, out / f"fdi_roc.{ext}")
    plt.close(fig)


if __name__ == "__main__":
    sys.exit(main())
