"""What a run scores: regulation, actuation, power, and the FDI's detection and isolation."""

from __future__ import annotations

import numpy as np

from wtftc.artefacts import layout as lay
from wtftc.config import CASES, RunConfig
from wtftc.model.faults import HYDRAULIC, TYPES
from wtftc.sim import integrate


def metrics(rc: RunConfig, res: integrate.Result) -> dict:
    """Regulation and actuation figures of one run (units in every key)."""
    t = res.t
    w = res.column("omega_r")
    e = w - rc.reference
    beta = np.column_stack([res.column(f"beta_{j}") for j in lay.blades()])
    dt_out = rc.dt * rc.decimate
    rate = np.gradient(beta, dt_out, axis=0) if len(t) > 2 else np.zeros_like(beta)
    # settled: inside ±1 % from this time to the end, and for at least the last 20 % of
    # the run (a run that merely ends inside the band has not settled)
    band = 0.01 * rc.reference
    outside = np.nonzero(np.abs(e) > band)[0]
    t_in = float(t[outside[-1] + 1]) if len(outside) and outside[-1] + 1 < len(t) else (
        0.0 if not len(outside) else None)
    settled = t_in if t_in is not None and t_in <= t[-1] - 0.2 * (t[-1] - t[0]) else None
    onset = min((f.onset_s for f in rc.faults), default=None)
    post = t >= onset if onset is not None else np.zeros_like(t, dtype=bool)
    eta = rc.p_turbine[lay.index("turbine_params", "gen_efficiency")]
    rated = rc.p_turbine[lay.index("turbine_params", "omega_g_rated")]
    m = {
        "label": rc.label, "case": rc.case, "case_doc": CASES[rc.case], "plant": rc.plant,
        "fdi": fdi_report(rc, res),
        "controller": rc.raw["controller"], "control_sign": rc.raw["control_sign"],
        # the measurements (docs/sensors.md): the profile and what it resolved to
        "profile": rc.raw.get("profile", "ideal"),
        "control_interval_s": float(rc.raw.get("control_interval_s", 0.0)),
        "sensors": dict(rc.raw.get("sensors", {})),
        "reference_rad_s": rc.reference,
        "rms_speed_error_rad_s": float(np.sqrt(np.mean(e**2))),
        "max_abs_speed_error_rad_s": float(np.max(np.abs(e))),
        "rms_speed_error_after_fault_rad_s": (float(np.sqrt(np.mean(e[post] ** 2)))
                                              if post.any() else None),
        "settling_time_s": settled,
        "settling_band_rad_s": band,
        "overspeed_peak_rad_s": float(np.max(w)),
        "overspeed_peak_over_rated": float(np.max(w) / rated),
        "pitch_min_deg": float(np.degrees(beta.min())),
        "pitch_max_deg": float(np.degrees(beta.max())),
        "pitch_rate_rms_deg_s": float(np.degrees(np.sqrt(np.mean(rate**2)))),
        "actuator_travel_deg": float(np.degrees(np.sum(np.abs(np.diff(beta, axis=0))))),
        "mean_electrical_power_W": float(np.mean(res.column("P_gen")) * eta),
        "output_interval_s": rc.dt * rc.decimate,
        "diverged": res.diverged,
        "simulated_s": float(res.steps * rc.dt),
        "wall_s": res.wall_s,
        "realtime_factor": float(res.steps * rc.dt / max(res.wall_s, 1e-9)),
        "seed": rc.seed,
        "config": res.config,
    }
    return m

def fdi_report(rc: RunConfig, res: integrate.Result) -> dict:
    """Detection, isolation, classification and estimation of wtftc's FDI, per fault and
    per blade, and its false alarms with their times.

    An actuator fault (lock, loss of effectiveness, pressure drop, air in oil) on blade j
    should raise blade j's latch after its onset and no other; the estimates are read at
    the end of the run. This FDI watches the pitch actuators: a pitch sensor fault raises
    its blade's latch too but is classified ``actuator`` (it cannot tell the two apart
    yet), and a speed sensor fault is not watched (``detected`` false). A latch that rises
    on a blade with no actuator fault, or before the fault's onset, is a false alarm.
    """
    t = res.t
    faults = res.schedule.faults if res.schedule is not None else rc.faults  # angles bound
    actuator = [f for f in faults if TYPES[f.type].acts_on == "actuator"]
    faulty = {f.blade: f for f in actuator}
    # a pitch sensor's fault raises its blade's latch too: not a false alarm there
    sensed = {f.blade: f for f in faults if TYPES[f.type].signal == "pitch"}
    out = {"blades": {}, "false_alarms": [], "isolation_correct": True}
    first = {}
    for j in lay.blades():
        latch = res.column(f"fdi_latch_{j}")
        hit = np.nonzero(latch >= 0.5)[0]
        t_det = float(t[hit[0]]) if len(hit) else None
        first[j] = t_det
        b = _blade_estimates(res, j)
        b["detected_at_s"] = t_det
        f = faulty.get(j)
        if f is not None:
            b.update(_against_truth(f, b, res, j))
            if t_det is None:
                out["isolation_correct"] = False
            elif t_det < f.onset_s:
                out["false_alarms"].append({"blade": j, "t_s": t_det,
                                            "why": "before the fault's onset"})
        elif t_det is not None and (j not in sensed or t_det < sensed[j].onset_s):
            out["false_alarms"].append({"blade": j, "t_s": t_det, "why": "no fault there"})
            out["isolation_correct"] = False
        out["blades"][str(j)] = b
    out["faults"] = [_fault_entry(f, first, out["blades"]) for f in faults]
    return out


def _blade_estimates(res: integrate.Result, j: int) -> dict:
    """What the FDI holds for blade j at the end of the run."""
    return {"rho_hat": float(res.column(f"fdi_rho_hat_{j}")[-1]),
            "c_hat_deg": float(np.degrees(res.column(f"fdi_c_hat_{j}")[-1])),
            "omega_n_hat_rad_s": float(res.column(f"fdi_omega_n_hat_{j}")[-1]),
            "zeta_hat": float(res.column(f"fdi_zeta_hat_{j}")[-1])}


def _against_truth(f, b: dict, res: integrate.Result, j: int) -> dict:
    """The fault on blade j and the errors of the FDI's estimates against it."""
    t_det = b["detected_at_s"]
    d = {"fault": f.type, "detection_delay_s": None if t_det is None else t_det - f.onset_s}
    if f.type == "loss_of_effectiveness":
        d["rho_error"] = b["rho_hat"] - f.rho
    if f.type == "lock" and f.angle is not None:
        d["stuck_angle_error_deg"] = b["c_hat_deg"] - float(np.degrees(f.angle))
    if f.type in HYDRAULIC:
        d["dynamics_identified"] = bool(np.isclose(b["omega_n_hat_rad_s"], HYDRAULIC[f.type][0]))
    return d


def _identified(b: dict) -> str:
    """The fault type the FDI's estimates point to on a detected blade."""
    if b["detected_at_s"] is None:
        return "none"
    for typ, (w, _) in HYDRAULIC.items():
        if np.isclose(b["omega_n_hat_rad_s"], w):
            return typ
    if abs(b["rho_hat"]) < 0.1:
        return "lock"
    return "loss_of_effectiveness" if b["rho_hat"] < 0.95 else "unidentified"


def _fault_entry(f, first: dict, blades: dict) -> dict:
    """One fault as the FDI saw it: detected, delay, the blade it isolated, the class and
    type it identified, and its estimate."""
    ft = TYPES[f.type]
    entry = {"type": f.type, "class": ft.acts_on, "blade": f.blade or None,
             "onset_s": f.onset_s}
    watched = ft.acts_on == "actuator" or ft.signal == "pitch"
    after = {j: t for j, t in first.items() if t is not None and t >= f.onset_s}
    # its own blade if that one alarmed after the onset, else the first that did
    hit = (f.blade if f.blade in after else min(after, key=after.get)) \
        if watched and after else None
    entry["detected"] = hit is not None
    entry["detection_delay_s"] = after[hit] - f.onset_s if hit is not None else None
    entry["isolated_blade"] = hit
    entry["identified_class"] = "actuator" if hit is not None else None
    entry["identified_type"] = _identified(blades[str(hit)]) if hit is not None else None
    entry["estimate"] = ({k: blades[str(hit)][k] for k in ("rho_hat", "c_hat_deg",
                                                            "omega_n_hat_rad_s", "zeta_hat")}
                         if hit is not None else None)
    entry["correct"] = bool(hit == f.blade and entry["identified_class"] == ft.acts_on
                            and entry["identified_type"] == f.type)
    return entry
