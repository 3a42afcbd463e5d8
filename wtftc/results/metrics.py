"""What a run scores: regulation, actuation, power, and the FDI's detection and isolation."""

from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np

from wtftc.artefacts import layout as lay
from wtftc.config import CASES, RunConfig, loads_options, rated_wind_speed
from wtftc.model.faults import HYDRAULIC, SENSOR_SIGNALS, TYPES
from wtftc.results import loads
from wtftc.sim import integrate
from wtftc.sim.rhs import sensor_names


@dataclass
class Signals:
    """The series the metrics read after the start-up window, at the simulation rate where
    the run kept its states (``integrate.Result.full``), else at the output rate.

    ``rate``: "simulation" or "output"; ``dt``: their interval [s]; ``t0``: the window's end,
    the first time scored [s]. The shaft torque is k_s θ_s + d_s (ω_r − ω_g) (eq (6)); the
    tower base's moment k_t x_t h (derivation/turbine.py), None without a tower; a run in
    OpenFAST carries both as OpenFAST computes them (``shaft_torque``, ``tower_moment``:
    ElastoDyn's RotTorq and TwrBsMyt, wtftc.openfast.engine), and the blades' root
    flapwise bending moments (``blade_flap``, (samples, blades) [N m]: RootMyb1-3), which
    wtftc's own plants have not (None)."""

    t: np.ndarray
    dt: float
    rate: str
    omega_r: np.ndarray
    beta: np.ndarray  # (samples, blades) [rad]
    shaft: np.ndarray
    tower: np.ndarray | None
    t0: float
    blade_flap: np.ndarray | None = None


def signals(rc: RunConfig, res: integrate.Result, t0: float) -> Signals:
    """The run's metric series from ``t0`` on (Signals)."""
    tp = lay.values("turbine_params", rc.p_plant if rc.p_plant is not None else rc.p_turbine)
    full = res.every_step
    if full:
        t, dt, col, rate = np.arange(len(res.full)) * res.dt, res.dt, res.state, "simulation"
        omega_g = col("omega_g")
    else:
        t, dt, col, rate = res.t, rc.dt * rc.decimate, res.column, "output"
        omega_g = res.column("omega_g_hss") / tp["gearbox_ratio"]
    keep = t >= t0 - 1e-9 * max(1.0, t0)
    w = col("omega_r")
    if full and "shaft_torque" in res.full_names:  # OpenFAST's own (wtftc.openfast)
        shaft = col("shaft_torque")
    else:
        shaft = tp["k_s"] * col("theta_s") + tp["d_s"] * (w - omega_g)
    tower = None
    if full and "tower_moment" in res.full_names:
        tower = col("tower_moment")
    elif full and "tower_x" in res.full_names:
        tower = tp["tower_stiffness"] * col("tower_x") * tp["tower_moment_arm"]
    elif not full and "M_tower" in res.names:
        tower = res.column("M_tower")
    beta = np.column_stack([col(f"beta_{j}") for j in lay.blades()])
    flap = None
    if full and "blade_root_flap_1" in res.full_names:  # OpenFAST's RootMyb1-3
        flap = np.column_stack([col(f"blade_root_flap_{j}") for j in lay.blades()])[keep]
    return Signals(t=t[keep], dt=dt, rate=rate, omega_r=w[keep], beta=beta[keep],
                   shaft=shaft[keep], tower=None if tower is None else tower[keep], t0=t0,
                   blade_flap=flap)


def metrics(rc: RunConfig, res: integrate.Result) -> dict:
    """Regulation and actuation figures of one run (units in every key), over the run after
    its start-up window (``[loads] transient_s``, config.transient_window), from the states
    at every step (issue 31); the FDI's false alarms from t = 0 (an alarm at the start is an
    alarm), the settling time over the whole run (it measures the start)."""
    t0, why = rc.transient
    if res.steps * rc.dt <= t0 + rc.dt:  # it diverged inside the window: score it whole
        t0, why = 0.0, (f"none: the run ended at {res.steps * rc.dt:g} s, inside the "
                        f"{t0:g}-s window")
    sig = signals(rc, res, t0)
    t, w = sig.t, sig.omega_r
    e = w - rc.reference
    beta = sig.beta
    rate = np.gradient(beta, sig.dt, axis=0) if len(t) > 2 else np.zeros_like(beta)
    settled = _settling_time(rc, res)
    onset = min((f.onset_s for f in rc.faults), default=None)
    post = t >= onset if onset is not None else np.zeros_like(t, dtype=bool)
    eta = rc.p_turbine[lay.index("turbine_params", "gen_efficiency")]
    rated = rc.p_turbine[lay.index("turbine_params", "omega_g_rated")]
    # the mean power from the outputs (P_gen = T_g ω_g is not a state): a mean's samples
    # at 10 Hz or 1 kHz agree to within 0.01 % on these runs (tests/test_metrics_rate.py)
    scored = res.t >= t0 - 1e-9 * max(1.0, t0)
    m = {
        "label": rc.label, "case": rc.case, "case_doc": CASES[rc.case], "plant": rc.plant,
        "fdi": fdi_report(rc, res),
        "controller": rc.raw["controller"], "control_sign": rc.raw["control_sign"],
        # the measurements (docs/sensors.md): the profile and what it resolved to
        "profile": rc.raw.get("profile", "ideal"),
        "control_interval_s": float(rc.raw.get("control_interval_s", 0.0)),
        "sensors": dict(rc.raw.get("sensors", {})),
        "transient_s": t0, "transient_why": why,
        "metrics_rate_hz": 1.0 / sig.dt, "metrics_from": sig.rate,
        "reference_rad_s": rc.reference,
        "rms_speed_error_rad_s": _rms(e),
        "max_abs_speed_error_rad_s": float(np.max(np.abs(e))) if e.size else None,
        "rms_speed_error_after_fault_rad_s": _rms(e[post]) if post.any() else None,
        "settling_time_s": settled,
        "settling_band_rad_s": 0.01 * rc.reference,
        "overspeed_peak_rad_s": float(np.max(w)) if w.size else None,
        "overspeed_peak_over_rated": float(np.max(w) / rated) if w.size else None,
        **_after_onset(w, post, rated), **loads_after_onset(sig, post),
        "energy_after_onset_J": energy_after(res.t, res.column("P_gen") * eta, onset),
        "pitch_min_deg": float(np.degrees(beta.min())) if beta.size else None,
        "pitch_max_deg": float(np.degrees(beta.max())) if beta.size else None,
        "pitch_rate_rms_deg_s": float(np.degrees(np.sqrt(np.mean(rate**2)))) if beta.size
        else None,
        "pitch_rate_max_abs_deg_s": _max_abs_deg(rate),  # WEIS's test bench's, any blade
        "actuator_travel_deg": float(np.degrees(np.sum(np.abs(np.diff(beta, axis=0))))),
        "mean_electrical_power_W": (float(np.mean(res.column("P_gen")[scored]) * eta)
                                    if scored.any() else None),
        "output_interval_s": rc.dt * rc.decimate,
        "diverged": res.diverged,
        "simulated_s": float(res.steps * rc.dt),
        "wall_s": res.wall_s,
        "realtime_factor": float(res.steps * rc.dt / max(res.wall_s, 1e-9)),
        "seed": rc.seed,
        "config": res.config,
    }
    return m | cost(rc, res, sig)


def _after_onset(w: np.ndarray, post: np.ndarray, rated: float) -> dict:
    """The extremes of a fault's effect on the rotor speed, from its onset on (None
    without a fault): its peak and its minimum over rated."""
    return {"overspeed_peak_over_rated_after_onset":
            float(np.max(w[post]) / rated) if post.any() else None,
            "speed_min_over_rated_after_onset":
            float(np.min(w[post]) / rated) if post.any() else None}


def loads_after_onset(sig: Signals, post: np.ndarray) -> dict:
    """The largest |load| from the fault's onset on (``post``: the samples of ``sig`` at
    or after it): the shaft torque's, the tower base's and the largest of the blades' root
    flapwise moments [N m]; None without a fault, or on a plant without that load."""
    def peak(x):
        return float(np.max(np.abs(x[post]))) if x is not None and post.any() else None

    return {"shaft_torque_max_abs_after_onset_Nm": peak(sig.shaft),
            "tower_base_max_abs_after_onset_Nm": peak(sig.tower),
            "blade_root_flap_max_abs_after_onset_Nm": peak(sig.blade_flap)}


def energy_after(t: np.ndarray, power: np.ndarray, onset: float | None) -> float | None:
    """The electrical energy [J] from ``onset`` [s] to the run's end, ∫ P dt by the
    trapezoidal rule over the samples at or after it (a run that ended early, a turbine
    brought down, keeps what it made until then); None without a fault."""
    if onset is None:
        return None
    sel = t >= onset - 1e-9 * max(1.0, onset)
    tt, p = t[sel], power[sel]
    if tt.size < 2:
        return 0.0
    return float(np.sum(0.5 * (p[1:] + p[:-1]) * np.diff(tt)))


def _max_abs_deg(x: np.ndarray) -> float | None:
    """The largest |x| in degrees (x in rad or rad/s), None for no sample."""
    return float(np.degrees(np.max(np.abs(x)))) if x.size else None


def _rms(x: np.ndarray) -> float | None:
    return float(np.sqrt(np.mean(x**2))) if x.size else None


def speed_series(res: integrate.Result) -> tuple[np.ndarray, np.ndarray]:
    """The rotor speed and its times: at every step where the run kept its states."""
    return res.series("omega_r")


def _settling_time(rc: RunConfig, res: integrate.Result) -> float | None:
    """When the rotor speed entered ±1 % of the reference for good, over the whole run, if
    it stayed there for at least the last 20 % of the run (a run that merely ends inside
    the band has not settled); at the states' every step where kept."""
    t, w = speed_series(res)
    outside = np.nonzero(np.abs(w - rc.reference) > 0.01 * rc.reference)[0]
    t_in = float(t[outside[-1] + 1]) if len(outside) and outside[-1] + 1 < len(t) else (
        0.0 if not len(outside) else None)
    return t_in if t_in is not None and t_in <= t[-1] - 0.2 * (t[-1] - t[0]) else None


def cost(rc: RunConfig, res: integrate.Result, sig: Signals) -> dict:
    """What the regulation cost (docs/loads.md) over the scored window ``sig``: the shaft
    torque's and the tower base's fatigue, the pitch actuator's duty, and the speed against
    the controller's own reference."""
    opts = loads_options(rc.raw)
    # the span the samples stand for, n dt: the same at every rate
    duration = max(len(sig.t), 1) * sig.dt
    m = opts["shaft_wohler_exponent"]
    fat = loads.fatigue(sig.shaft, duration, m)
    rate_max = rc.p_turbine[lay.index("turbine_params", "pitch_rate_max")]
    duty = loads.pitch_duty(sig.beta, sig.dt, rate_max,
                            np.radians(opts["reversal_hysteresis_deg"]))
    above, below = own_speed_errors(rc, sig)
    rated = rc.p_turbine[lay.index("turbine_params", "omega_g_rated")]
    blade = blade_cost(sig, duration, opts.get("blade_wohler_exponent",
                                               loads.BLADE_WOHLER_EXPONENT))
    return tower_cost(sig, duration, opts["tower_wohler_exponent"]) | blade | spectra(
        sig, blade["blade_root_flap_worst_blade"]) | {
        "shaft_torque_del_1hz_Nm": fat["del_1hz"],
        "shaft_torque_damage_per_10min": fat["damage_per_10min"],
        "shaft_torque_max_abs_Nm": fat["max_abs"],
        # issue 34's goal: the fault-free σ within 1.2 × ROSCO's in every wind bin
        "shaft_torque_std_Nm": float(np.std(sig.shaft)) if len(sig.shaft) else None,
        "shaft_wohler_exponent": m,
        "pitch_adc": duty["adc"],
        "pitch_travel_rate_deg_s": duty["travel_rate_deg_s"],
        "pitch_travel_per_blade_deg": duty["travel_deg"],
        "pitch_reversals": duty["reversals"],
        "pitch_reversals_per_s": duty["reversals"] / duration,
        "rms_speed_error_own_above_rated_rad_s": above,
        "rms_speed_error_own_below_rated_rad_s": below,
        "time_above_1p1_rated_s": float(np.count_nonzero(sig.omega_r > 1.1 * rated) * sig.dt),
    }


def tower_cost(sig: Signals, duration: float, m: float) -> dict:
    """The tower-base fore-aft bending moment's fatigue and extreme on the tower plant
    (None on a plant without a tower)."""
    keys = ("tower_base_del_1hz_Nm", "tower_base_damage_per_10min", "tower_base_max_abs_Nm")
    if sig.tower is None:
        return dict.fromkeys(keys) | {"tower_wohler_exponent": m}
    fat = loads.fatigue(sig.tower, duration, m)
    return dict(zip(keys, (fat["del_1hz"], fat["damage_per_10min"], fat["max_abs"]),
                    strict=True)) | {"tower_wohler_exponent": m}


def blade_cost(sig: Signals, duration: float, m: float) -> dict:
    """The blade-root flapwise bending moment's fatigue and extreme (None on a plant
    without blades that bend: wtftc's own): the 1-Hz DEL and the damage per 10 min of the
    blade whose DEL is the largest (``blade_root_flap_worst_blade``, 1-based), and the
    largest |moment| over every blade."""
    keys = ("blade_root_flap_del_1hz_Nm", "blade_root_flap_damage_per_10min",
            "blade_root_flap_max_abs_Nm", "blade_root_flap_worst_blade")
    if sig.blade_flap is None or not len(sig.blade_flap):
        return dict.fromkeys(keys) | {"blade_wohler_exponent": m}
    fats = [loads.fatigue(sig.blade_flap[:, k], duration, m)
            for k in range(sig.blade_flap.shape[1])]
    worst = max(range(len(fats)), key=lambda k: fats[k]["del_1hz"])
    return dict(zip(keys, (fats[worst]["del_1hz"], fats[worst]["damage_per_10min"],
                           max(f["max_abs"] for f in fats), worst + 1), strict=True)) | {
        "blade_wohler_exponent": m}


def spectra(sig: Signals, blade: int | None) -> dict:
    """The tower base's and the blade root's content in the 1P and 3P bands (the standard
    deviation in n × the mean rotor frequency ± loads.BAND_HALF_WIDTH, loads.harmonic_std)
    over the scored window [N m]; the blade's is the blade with the largest flapwise DEL
    (``blade``, 1-based: blade_cost's). None where the plant has not the load, or the
    rotor stands."""
    f_rotor = float(np.mean(sig.omega_r)) / (2 * np.pi) if len(sig.omega_r) else 0.0
    flap = None if sig.blade_flap is None or blade is None else sig.blade_flap[:, blade - 1]
    out = {}
    for name, x in (("tower_base", sig.tower), ("blade_root_flap", flap)):
        for n in (1, 3):
            out[f"{name}_{n}p_std_Nm"] = (None if x is None else
                                          loads.harmonic_std(x, sig.dt, f_rotor, n))
    return out


def own_reference(rc: RunConfig, wind: np.ndarray) -> np.ndarray:
    """The speed the controller pursues (docs/loads.md): below rated, with a
    variable-speed torque law, the optimal tip-speed ratio's, min(ω_rated, λ_opt v / R);
    with the fixed rated torque or on the paper's plant, rated speed throughout."""
    tp = lay.values("turbine_params", rc.p_turbine)
    rated = np.full_like(wind, rc.reference)
    torque_law = rc.library_controller or tp["gen_torque_law"] > 0.5
    if rc.plant == "paper" or not torque_law:
        return rated
    _, tsr_opt, _ = rc.table.cp_max()
    return np.minimum(rated, tsr_opt * wind / tp["rotor_radius"])


def own_speed_errors(rc: RunConfig, sig: Signals) -> tuple:
    """The RMS error against the own reference while the wind is at or above the
    turbine's rated wind, and below it (None where no sample falls)."""
    wind = np.asarray(rc.wind(sig.t), dtype=float)
    e = sig.omega_r - own_reference(rc, wind)
    above = wind >= rated_wind_speed(rc.p_turbine, rc.table)

    def rms(sel):
        return float(np.sqrt(np.mean(e[sel] ** 2))) if sel.any() else None

    return rms(above), rms(~above)

def _has_fdi(res: integrate.Result) -> bool:
    """Whether the run recorded wtftc's FDI: not a run in OpenFAST of a controller library
    without it (ROSCO), whose FDI columns are NaN."""
    return "fdi_latch_1" in res.names and not np.all(np.isnan(res.column("fdi_latch_1")))


def fdi_ran(report: dict | None) -> bool:
    """Whether a run's FDI report (:func:`fdi_report`, metrics.json's ``"fdi"``) says that
    wtftc's FDI ran; a metrics.json written before ``ran`` holds null where none ran."""
    return report is not None and bool(report.get("ran", True))


#: the report of a run without wtftc's FDI: nothing detected, nothing to judge
NO_FDI = {"ran": False, "blades": {}, "false_alarms": [], "faults": [],
          "isolation_correct": None}


def fdi_report(rc: RunConfig, res: integrate.Result) -> dict:
    """Detection, isolation, classification and estimation of wtftc's FDI, per fault and
    per blade, and its false alarms with their times. ``ran`` says whether the FDI ran at
    all: a run in OpenFAST of a controller library without it (ROSCO) has none, and its
    report is :data:`NO_FDI` (no blades, faults or false alarms; isolation None).

    An actuator fault (lock, loss of effectiveness, pressure drop, air in oil) on blade j
    should raise blade j's actuator latch after its onset and no other; the estimates are
    read at the end of the run. A sensor fault should exclude its sensor (the FDI's pair
    tests, derivation/fdi.py) and raise no actuator latch. An actuator latch on a blade
    with no fault there, or before the fault's onset, and a sensor excluded that has no
    fault, are false alarms; an actuator latch on a blade whose pitch sensor failed is a
    misclassification (its fault's ``correct`` is false).
    """
    if not _has_fdi(res):
        return copy.deepcopy(NO_FDI)
    t = res.t
    faults = res.schedule.faults if res.schedule is not None else rc.faults  # angles bound
    faulty = {f.blade: f for f in faults if TYPES[f.type].acts_on == "actuator"}
    sensed = {f.blade: f for f in faults if TYPES[f.type].signal == "pitch"}
    out = {"ran": True, "blades": {}, "false_alarms": [], "isolation_correct": True}
    first = {j: _first(*_latch(res, j)) for j in lay.blades()}
    for j in lay.blades():
        b = _blade_estimates(res, j)
        b["detected_at_s"] = t_det = first[j]
        f = faulty.get(j)
        if f is not None:
            b.update(_against_truth(f, b, res, j))
            if t_det is not None and t_det < f.onset_s:
                out["false_alarms"].append({"blade": j, "t_s": t_det,
                                            "why": "before the fault's onset"})
        elif t_det is not None and (j not in sensed or t_det < sensed[j].onset_s):
            out["false_alarms"].append({"blade": j, "t_s": t_det, "why": "no fault there"})
        out["blades"][str(j)] = b
    excluded = {s: _first(t, res.column(f"fdi_excluded_{s}")) for s in sensor_names()}
    failed = {sensor_of(f): f for f in faults if TYPES[f.type].acts_on == "sensor"}
    for s, t_x in excluded.items():
        f = failed.get(s) or failed.get(partner(s))
        if t_x is not None and (f is None or t_x < f.onset_s):
            out["false_alarms"].append({"sensor": s, "t_s": t_x, "why": "no fault there"
                                        if f is None else "before the fault's onset"})
    out["faults"] = [_fault_entry(f, first, excluded, out["blades"], res) for f in faults]
    out["isolation_correct"] = not out["false_alarms"] and all(
        e["correct"] or e["type"] in _UNSEEN for e in out["faults"])
    return out


#: fault types the FDI cannot see by design when they are mild: none (every type counts)
_UNSEEN: tuple[str, ...] = ()


def _latch(res: integrate.Result, j: int) -> tuple[np.ndarray, np.ndarray]:
    """Blade j's actuator latch and its times: at every step where the run kept it."""
    return res.series(f"fdi_latch_{j}")


def _first(t: np.ndarray, latch: np.ndarray) -> float | None:
    """When a latch first reached 1/2, or None."""
    hit = np.nonzero(latch >= 0.5)[0]
    return float(t[hit[0]]) if len(hit) else None


def sensor_of(f) -> str:
    """The name of the sensor a sensor fault acts on (derivation/sensors.py)."""
    ft = TYPES[f.type]
    base = SENSOR_SIGNALS[ft.signal][0]
    return (f"{base}_{f.blade}" if ft.signal == "pitch" else base) + f"_m{f.sensor}"


def partner(sensor: str) -> str:
    """The other sensor of the same quantity."""
    return sensor[:-1] + ("2" if sensor.endswith("1") else "1")


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
    if f.type in ("lock", "runaway") and f.angle is not None:
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


def _fault_entry(f, first: dict, excluded: dict, blades: dict, res) -> dict:
    """One fault as the FDI saw it: detected, delay, the blade (and sensor) it isolated,
    the class and type it identified, and its estimate."""
    ft = TYPES[f.type]
    entry = {"type": f.type, "class": ft.acts_on, "blade": f.blade or None,
             "onset_s": f.onset_s}
    if ft.acts_on == "sensor":
        entry["sensor"] = sensor_of(f)
        return entry | _sensor_entry(f, first, excluded, res)
    after = {j: t for j, t in first.items() if t is not None and t >= f.onset_s}
    # its own blade if that one alarmed after the onset, else the first that did
    hit = (f.blade if f.blade in after else min(after, key=after.get)) if after else None
    entry["detected"] = hit is not None
    entry["detection_delay_s"] = after[hit] - f.onset_s if hit is not None else None
    entry["isolated_blade"] = hit
    entry["isolated_sensor"] = None
    entry["identified_class"] = "actuator" if hit is not None else None
    entry["identified_type"] = _identified(blades[str(hit)]) if hit is not None else None
    entry["estimate"] = ({k: blades[str(hit)][k] for k in ("rho_hat", "c_hat_deg",
                                                            "omega_n_hat_rad_s", "zeta_hat")}
                         if hit is not None else None)
    # a runaway is a lock at its target to the FDI (eq (19)): told as one
    expected = "lock" if f.type == "runaway" else f.type
    entry["correct"] = bool(hit == f.blade and entry["identified_type"] == expected)
    return entry


def _sensor_entry(f, first: dict, excluded: dict, res) -> dict:
    """A sensor fault: the sensor the pair test excluded (its own or its partner), or the
    blade's actuator latch (a misclassification), whichever came first after the onset."""
    s = sensor_of(f)
    seen = {k: excluded[k] for k in (s, partner(s))
            if excluded[k] is not None and excluded[k] >= f.onset_s}
    act = first.get(f.blade) if f.blade else None
    act = act if act is not None and act >= f.onset_s else None
    hit = min(seen, key=seen.get) if seen else None
    t_hit = seen[hit] if hit else None
    d = {"detected": hit is not None or act is not None, "isolated_sensor": hit,
         "isolated_blade": f.blade or None}
    if act is not None and (t_hit is None or act < t_hit):
        d.update(detection_delay_s=act - f.onset_s, identified_class="actuator",
                 identified_type=None, estimate=None, correct=False)
        return d
    if hit is None:
        d.update(detection_delay_s=None, isolated_blade=None, identified_class=None,
                 identified_type=None, estimate=None, correct=False)
        return d
    kinds, est = _sensor_kind(res, hit, t_hit, f.end_s)
    types = [f.type.rsplit("_", 1)[0] + "_" + k for k in kinds]
    d.update(detection_delay_s=t_hit - f.onset_s, identified_class="sensor",
             identified_type=types[0] if types else None, ambiguous_with=types[1:],
             estimate=est, correct=bool(hit == s and f.type in types))
    return d


def _sensor_kind(res, s: str, t0: float, t1: float) -> tuple[list[str], dict | None]:
    """The kinds of fault a sensor's readings against its partner's point to after the
    FDI excluded it (identified offline, by the report, over at most 30 s), best first:
    stuck (it reads a constant); else the models of the difference d = y − y_partner:
    offset (d = a), gain (d = b·y_partner) and drift (d = a + c·(t − t0), its second
    parameter charged 25 noise variances), every one whose residual sum of squares is
    within 25 noise variances of the best's (an F-test at 5σ: a gain on a speed that
    hardly varies is an offset to the data); precision (more noise) when none explains a
    fifth of d."""
    t = res.t
    sel = (t >= t0) & (t <= min(t1, t0 + 30.0))
    y, y_p = res.column(f"sensor_{s}")[sel], res.column(f"sensor_{partner(s)}")[sel]
    if y.size < 3:
        return [], None
    if np.ptp(y) <= 1e-9 * max(1.0, float(np.max(np.abs(y)))):
        return ["stuck"], {"value": float(y[0])}
    d, tt = y - y_p, t[sel] - t0
    # the gain's regressor: the partner's reading averaged over about 1 s (its own noise
    # is in d too: regressing on it raw takes an offset for a gain)
    width = max(1, min(d.size, int(round(1.0 / max(t[1] - t[0], 1e-9)))))
    ones = np.ones(width)
    smooth = np.convolve(y_p, ones, mode="same") / np.convolve(np.ones_like(y_p), ones,
                                                               mode="same")
    fits = {}
    for kind, x in (("offset", np.ones_like(d)), ("gain", smooth)):
        k = float(x @ d / max(x @ x, 1e-300))
        fits[kind] = (float(np.sum((d - k * x) ** 2)), k)
    # a drift began before the exclusion: d = a + c·(t − t0), two parameters
    A = np.column_stack([np.ones_like(tt), tt])
    (a, c), *_ = np.linalg.lstsq(A, d, rcond=None)
    fits["drift"] = (float(np.sum((d - a - c * tt) ** 2)), float(c))
    noise = min(f[0] for f in fits.values()) / d.size  # the best fit's residual variance
    # the drift's second parameter must earn its place: 25 noise variances (5σ)
    score = {k: f[0] + (25 * noise if k == "drift" else 0.0) for k, f in fits.items()}
    best = min(score, key=score.get)
    if fits[best][0] > 0.8 * float(d @ d):
        return ["precision"], {"rms_difference": float(np.sqrt(np.mean(d**2)))}
    # a drift whose slope is not significant is the offset again, not another reading
    idle = fits["offset"][0] - fits["drift"][0] < 25 * noise and best != "drift"
    close = sorted((k for k in score if score[k] - score[best] <= 25 * noise
                    and not (k == "drift" and idle)), key=score.get)
    key = {"offset": "offset", "gain": "gain", "drift": "rate_per_s"}
    return close, {key[k]: 1 + fits[k][1] if k == "gain" else fits[k][1] for k in close}
