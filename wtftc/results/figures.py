"""Figures of the paper's three cases: counterparts of Figs. 2-10, a comparison, V(t).

Every figure is saved as PNG and PDF (atomically); axes carry units; pitch is shown in
degrees (names ending _deg), speeds in rad/s.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from wtftc.artefacts import layout as lay  # noqa: E402
from wtftc.results.io import atomic_savefig  # noqa: E402
from wtftc.sim.rhs import PLANTS  # noqa: E402

CASE_COLORS = {1: "tab:blue", 2: "tab:red", 3: "tab:green", 4: "tab:purple"}


def _save(fig, out: Path, name: str) -> list[Path]:
    paths = [out / f"{name}.png", out / f"{name}.pdf"]
    fig.tight_layout()
    for p in paths:
        atomic_savefig(fig, p, dpi=130)
    plt.close(fig)
    return paths


def _onset_line(ax, onset):
    if onset is not None:
        ax.axvline(onset, color="0.5", ls="--", lw=0.8)
        ax.text(onset, ax.get_ylim()[1], " fault", va="top", fontsize=8, color="0.4")


def _title(run, text):
    diverged = run["metrics"]["diverged"]
    extra = f" — DIVERGED at t = {diverged['t_s']:.2f} s" if diverged else ""
    return f"{text} ({run.get('model', run['plant'])}, case {run['case']}){extra}"


def rotor_speed(run, out: Path, name: str, paper_fig: str) -> list[Path]:
    res, m = run["result"], run["metrics"]
    fig, ax = plt.subplots(figsize=(7, 3.6))
    ax.plot(res.t, res.column("omega_r"), label="ω_r (plant)", color=CASE_COLORS[run["case"]])
    ax.plot(res.t, res.column("y_d"), "k--", lw=1, label="y_d (reference)")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("rotor speed [rad/s]")
    ax.grid(alpha=0.3)
    _onset_line(ax, run["onset"])
    t0 = m.get("transient_s") or 0.0
    if t0 > 0:  # the start-up the metrics leave out (issue 31, docs/loads.md)
        ax.axvspan(float(res.t[0]), t0, color="0.85", zorder=0,
                   label=f"start-up, not scored (first {t0:g} s)")
    ax.legend(loc="best", fontsize=8)
    ax.set_title(_title(run, f"{paper_fig}: rotor speed, RMS error "
                              f"{m['rms_speed_error_rad_s']:.3g} rad/s from {t0:g} s"),
                 fontsize=9)
    return _save(fig, out, name)


def control(run, out: Path, name: str, paper_fig: str) -> list[Path]:
    res = run["result"]
    fig, axes = plt.subplots(2, 1, figsize=(7, 5), sharex=True)
    paper = run["rc"].controller == "paper"  # the others' mean-pitch command is theirs
    axes[0].plot(res.t, res.column("u0"), color="k", lw=1,
                 label="u0, eq (49)" if paper else f"u0, the {run['rc'].controller} "
                                                  "controller's mean pitch command")
    axes[0].set_ylabel("control signal u0 [rad]")
    axes[0].legend(fontsize=8)
    lo, hi = run["pitch_limits_deg"]
    cmd = np.clip(np.degrees(res.column("v_1")), lo, hi)
    axes[1].plot(res.t, cmd, color="0.6", lw=0.6, label=f"command v_1, clipped to {lo:g}-{hi:g}°")
    for j in lay.blades():
        axes[1].plot(res.t, np.degrees(res.column(f"beta_{j}")), label=f"β_{j} blade {j}")
    betas = np.degrees([res.column(f"beta_{j}") for j in lay.blades()])
    margin = max(2.0, 0.1 * (betas.max() - betas.min()))
    axes[1].set_ylim(betas.min() - margin, betas.max() + margin)
    axes[1].set_ylabel("pitch [deg]")
    axes[1].set_xlabel("time [s]")
    axes[1].legend(fontsize=7, ncol=2, loc="upper left")
    for ax in axes:
        ax.grid(alpha=0.3)
        _onset_line(ax, run["onset"])
    axes[0].set_title(_title(run, f"{paper_fig}: control signal and blade pitch"), fontsize=9)
    return _save(fig, out, name)


def estimates(run, out: Path, name: str, paper_fig: str) -> list[Path]:
    res = run["result"]
    n_g = run["gearbox_ratio"]
    beta_mean = np.mean([res.column(f"beta_{j}") for j in lay.blades()], axis=0)
    pairs = [("(a) rotor speed [rad/s]", res.column("omega_r"), res.column("xhat_1")),
             ("(b) torsion angle [rad]", res.column("theta_s"), res.column("xhat_2")),
             ("(c) generator speed, LSS [rad/s]", res.column("omega_g_hss") / n_g,
              res.column("xhat_3")),
             ("(d) mean pitch [rad]", beta_mean, res.column("xhat_4"))]
    fig, axes = plt.subplots(2, 2, figsize=(9, 5.5), sharex=True)
    for ax, (lab, x, xh) in zip(axes.ravel(), pairs, strict=True):
        ax.plot(res.t, x, label="plant state", lw=1.2)
        ax.plot(res.t, xh, "--", label="observer x̂", lw=1.2)
        ax.set_ylabel(lab, fontsize=8)
        ax.grid(alpha=0.3)
        _onset_line(ax, run["onset"])
    for ax in axes[1]:
        ax.set_xlabel("time [s]")
    axes[0, 0].legend(fontsize=8)
    fig.suptitle(_title(run, f"{paper_fig}: state estimations (x̂2..x̂4 are formal states: "
                              "docs/paper-notes.md)"), fontsize=9)
    return _save(fig, out, name)


def wind(run, out: Path, name: str = "fig02_wind") -> list[Path]:
    res = run["result"]
    fig, ax = plt.subplots(figsize=(7, 3.2))
    ax.plot(res.t, res.column("wind"), color="tab:gray")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("hub-height wind speed [m/s]")
    ax.grid(alpha=0.3)
    ax.set_title(f"Fig. 2: wind speed ({run['metrics']['config']['wind_resolved']['kind']}, "
                 f"seed {run['metrics']['seed']})", fontsize=9)
    return _save(fig, out, name)


def fault_shape(run, out: Path, name: str = "fig06_fault") -> list[Path]:
    res, sched = run["result"], run["schedule"]
    t = res.t
    a = sched.actuator(t)
    s = sched.sensor(t)
    fig, axes = plt.subplots(3, 1, figsize=(7, 6), sharex=True)
    rows = {n: a[lay.block("actuator_faults", n)] for n in ("rho", "lock", "omega_n")}
    for j in lay.blades():
        axes[0].plot(t, rows["rho"][j - 1], label=f"ρ_{j}")
        axes[1].plot(t, rows["lock"][j - 1], label=f"σ_{j} (lock)")
        axes[2].plot(t, rows["omega_n"][j - 1], label=f"ω_n,{j}")
    axes[0].set_ylabel("effectiveness ρ [-]")
    axes[1].set_ylabel("lock indicator σ [-]")
    axes[2].set_ylabel("actuator ω_n [rad/s]")
    axes[2].set_xlabel("time [s]")
    names = lay.names("sensor_faults")
    stuck = s[[k for k, n in enumerate(names) if n.startswith("stuck_beta_meas_")]]
    if np.any(stuck > 0):
        axes[1].plot(t, stuck.max(axis=0), "k:", label="pitch sensor stuck")
    for ax in axes:
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, ncol=3)
    locks = [f"blade {f['blade']} at " + (f"{round(a, 2) + 0.0:.2f}°"  # no "-0.00°"
                                           if isinstance(a, float) else
                                           f"its {a} angle")
             for f in sched.describe() if f["type"] == "lock"
             for a in [f.get("angle_deg", "current")]]
    axes[0].set_title("Fig. 6: fault shape" + (f" (locked: {', '.join(locks)})" if locks
                                               else ""), fontsize=9)
    return _save(fig, out, name)


def comparison(runs: list[dict], out: Path, name: str = "cases_comparison") -> list[Path]:
    fig, axes = plt.subplots(3, 1, figsize=(8, 7.5), sharex=True)
    for run in runs:
        res, c = run["result"], run["case"]
        lab = f"case {c}: {run['case_doc']}"
        if run["metrics"]["diverged"]:
            lab += f" (diverged at {run['metrics']['diverged']['t_s']:.1f} s)"
        axes[0].plot(res.t, res.column("omega_r"), color=CASE_COLORS[c], label=lab, lw=1)
        beta_mean = np.mean([res.column(f"beta_{j}") for j in lay.blades()], axis=0)
        axes[1].plot(res.t, np.degrees(beta_mean), color=CASE_COLORS[c], lw=1)
        axes[2].plot(res.t, res.column("P_gen") / 1e6, color=CASE_COLORS[c], lw=1)
    axes[0].plot(runs[0]["result"].t, runs[0]["result"].column("y_d"), "k--", lw=0.8,
                 label="y_d")
    axes[0].set_ylabel("rotor speed [rad/s]")
    axes[1].set_ylabel("mean pitch [deg]")
    axes[2].set_ylabel("generator power T_g·ω_g [MW]")
    if not PLANTS[runs[0]["plant"]]["loaded"]:
        axes[2].text(0.5, 0.5, "the paper's plant is unloaded: no generator torque",
                     transform=axes[2].transAxes, ha="center", va="center", color="tab:red")
    axes[2].set_xlabel("time [s]")
    axes[0].legend(fontsize=8)
    for ax in axes:
        ax.grid(alpha=0.3)
        _onset_line(ax, runs[-1]["onset"])
    axes[0].set_title(f"The paper's three cases on {runs[0]['plant']}", fontsize=9)
    return _save(fig, out, name)


def fdi(run, out: Path, name: str = "fdi") -> list[Path]:
    """wtftc's fault detection in the loop (case 4): per blade, the filtered residual's RMS
    against its threshold (thin, same style: the χ² bound of the sensor noise plus the
    model-uncertainty allowance, which grows with the pitch rate), the latch, the
    effectiveness estimate ρ̂ and the stuck-angle estimate."""
    res = run["result"]
    fig, axes = plt.subplots(4, 1, figsize=(7.5, 7.5), sharex=True)
    for j, ls in zip(lay.blades(), ("-", "--", ":"), strict=True):  # equal blades overlap
        kw = {"label": f"blade {j}", "ls": ls}
        line, = axes[0].semilogy(res.t, np.maximum(np.degrees(
            res.column(f"fdi_residual_rms_{j}")), 1e-12), **kw)
        axes[0].semilogy(res.t, np.degrees(res.column(f"fdi_threshold_{j}")), ls=ls, lw=0.7,
                         color=line.get_color(), alpha=0.6,
                         label="thresholds" if j == 1 else None)
        axes[1].plot(res.t, res.column(f"fdi_latch_{j}"), **kw)
        axes[2].plot(res.t, res.column(f"fdi_rho_hat_{j}"), **kw)
        axes[3].plot(res.t, np.degrees(res.column(f"fdi_c_hat_{j}")), **kw)
    # the sensors the pair tests excluded (derivation/fdi.py), if any
    for n in res.names:
        if n.startswith("fdi_excluded_") and np.max(res.column(n)) >= 0.5:
            axes[1].plot(res.t, res.column(n), "k-.", lw=1,
                         label=f"sensor {n.removeprefix('fdi_excluded_')} excluded")
    axes[1].axhline(0.5, color="k", ls=":", lw=1, label="isolation at 0.5")
    axes[0].set_ylim(bottom=1e-10)
    axes[0].set_ylabel("filtered residual RMS [deg]")
    axes[1].set_ylabel("latch [-]")
    axes[2].set_ylabel("ρ̂ effectiveness [-]")
    axes[3].set_ylabel("stuck-angle estimate ĉ [deg]")
    axes[3].set_xlabel("time [s]")
    for ax in axes:
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, ncol=4, loc="best")
        _onset_line(ax, run["onset"])
    axes[0].set_title(_title(run, "wtftc's fault detection, isolation and estimation"),
                      fontsize=9)
    return _save(fig, out, name)


def lyapunov_figure(run, V: np.ndarray, t: np.ndarray, bound, out: Path,
                    name: str = "lyapunov") -> list[Path]:
    fig, ax = plt.subplots(figsize=(7.5, 4.4))
    ax.plot(t, V, label="V_4(t), eq (47)")
    if bound.holds:
        kappa = float(np.min(bound.kappa_terms))
        ax.plot(t, V[0] * np.exp(-kappa * (t - t[0])) + bound.zeta_theta / kappa, "k--",
                label="eq (51) bound (θ* part of ζ)")
    else:
        txt = ("No eq (51) bound: it does not follow for these gains, "
               + "; ".join(f"{lab} = {v:.3g}" for lab, v in
                           zip(bound.labels, bound.kappa_terms, strict=True) if v <= 0)
               + " (each must be > 0).")
        fig.text(0.02, 0.01, txt, fontsize=7, color="tab:red", va="bottom", wrap=True)
    finite = V[np.isfinite(V) & (V > 0)]
    if finite.size and finite.max() > 100 * finite.min():
        ax.set_yscale("log")  # a divergence spans decades
    else:
        ax.ticklabel_format(axis="y", useOffset=True, style="sci", scilimits=(-3, 3))
    ax.set_xlabel("time [s]")
    ax.set_ylabel("V_4 [-] (½eᵀPe + Σ ½χ² + Σ θ̃ᵀθ̃/2γ)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(_title(run, "Lyapunov function V_4 along the run, θ* fitted on it"), fontsize=9)
    fig.tight_layout(rect=(0, 0.07, 1, 1))
    paths = [out / f"{name}.png", out / f"{name}.pdf"]
    for p in paths:
        atomic_savefig(fig, p, dpi=130)
    plt.close(fig)
    return paths
