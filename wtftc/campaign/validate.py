"""`wtftc validate` (issue 33 item 1): one controller, one scenario, on both engines.

OpenFAST 5.0.0 on the turbine's deck (wtftc.openfast, its TurbSim field for an NTM) and
wtftc's plant (by default ``tower_edge``, the tower plant with edgewise-flexible blades)
on the same field, read back as the rotor's wind (``wtftc/``: as the three blades sample
it, by default, or its disk average) and as the hub-height point (``wtftc_hub/``); the same
seeds, sensors and faults. Per metric, the value on each engine, their ratio (wtftc /
OpenFAST) and a verdict against a tolerance; the overlaid time series and spectra as
figures.

The spectra are Welch's (Hann windows of :data:`SEGMENT_S` or the whole series if shorter,
half overlapping) of the
shaft torque and the tower-base moment after the start-up window. Their peaks are looked
for around the modes of wtftc's own plant, a factor of two either side: the drivetrain's
free-free torsion, √(k_s (1/J_r + 1/J_g)) / 2π (on ``tower_edge``, rotor, blades' edge
and generator together: :func:`three_inertias_hz`), and the tower's first fore-aft mode,
√(k_t / m_t) / 2π; the damping from the half-power width, ζ ≈ Δf / (2 f).
"""

from __future__ import annotations

import copy
import math
import sys
from pathlib import Path

import numpy as np

from wtftc import config
from wtftc.artefacts import layout as lay
from wtftc.campaign import cases
from wtftc.files import check_out_folder, owned_folder
from wtftc.openfast.turbsim import ensure_field
from wtftc.results.io import atomic_savefig, atomic_write_json, atomic_write_text
from wtftc.results.metrics import metrics, signals
from wtftc.sim.rhs import PLANTS
from wtftc.sim.trim import operating_point

#: the run folders under --out: OpenFAST, wtftc's plant on the rotor's wind, and on the
#: hub-height point
ENGINES = ("openfast", "wtftc", "wtftc_hub")
#: Welch's segment [s]: 0.017-Hz bins. The half-power width of a mode with ζ 3 % at 1.7 Hz
#: is 0.10 Hz; with 20-s segments the window widened it to ζ 4.9 %, with 60-s ones 3.3 %
#: (tests/test_validate.py). A shorter run has one segment of its length: its damping is
#: an upper bound
SEGMENT_S = 60.0
#: the spectra figure's frequency range [Hz]: the tower's, the drivetrain's and the
#: blades' edgewise modes
SPECTRA_HZ = 4.0
#: the tolerance of each kind of figure, |wtftc / OpenFAST - 1| (issue 33's goals: σ and
#: DELs within 15 %, modal frequencies within 3 %; means within 5 %; damping within 50 %)
TOLERANCE = {"mean": 0.05, "std": 0.15, "del": 0.15, "extreme": 0.05, "frequency": 0.03,
             "damping": 0.5}


def scenario(raw: dict) -> dict:
    """The validation's configuration from ``raw`` (wtftc run's keys): an NTM of class B
    where no wind kind is given, the realistic profile (a library is called every control
    interval in OpenFAST)."""
    raw = copy.deepcopy(raw)
    wind = raw.get("wind")
    if not isinstance(wind, dict) or "kind" not in wind:
        mean = (wind or {}).get("mean_mps", 16.0) if isinstance(wind, dict) else 16.0
        raw["wind"] = {"kind": "ntm", "mean_mps": mean, "turbulence_class": "B"}
    raw.setdefault("profile", "realistic")
    for key in ("engine", "plant", "openfast"):
        raw.pop(key, None)
    return raw


#: wtftc's plant a validation runs by default: the one issue 33 validated (docs/validation.md)
PLANT = "tower_edge"
#: the rotor's wind of wtftc's run by default (wtftc.model.wind.ROTOR_WINDS): the field as the
#: blades sample it, whose loads agree best with OpenFAST's (docs/validation.md)
ROTOR_WIND = "blades"


def engine_configs(raw: dict, plant: str = PLANT, rotor_wind: str = ROTOR_WIND
                   ) -> dict[str, dict]:
    """Each engine's configuration of the scenario ``raw``: OpenFAST, and wtftc's
    ``plant`` (one with a tower) on the same TurbSim field (an NTM), as the rotor sees it
    (``rotor_wind``: "blades" or "disk") and at the hub."""
    out = {"openfast": {**raw, "engine": "openfast"}}
    native = {**raw, "plant": plant}
    if raw["wind"].get("kind") == "ntm":
        wind = {**raw["wind"], "field": "turbsim"}
        for key in ("rotor_radius_m", "rotor_wind", "blade_speed_rad_s"):
            wind.pop(key, None)
        out["wtftc"] = {**native, "wind": {**wind, "rotor_wind": rotor_wind}}
        out["wtftc_hub"] = {**native, "wind": {**wind, "rotor_radius_m": 0.0}}
    else:  # the same series on both engines already (a uniform wind file in OpenFAST)
        out["wtftc"] = native
    return out


def three_inertias_hz(tp: dict, pitch: float) -> list[float]:
    """The undamped modes [Hz] of rotor, blades' collective edge and generator on the shaft
    (derivation/turbine.py ``tower_edge_rhs`` without aerodynamics, tower and damping):
    M q̈ + K q = 0 on q = (θ_r, q_e, θ_g), M = [[J_r, 3S, 0], [3S, 3 m_e, 0], [0, 0, J_g]],
    S = S_c cos β - S_s sin β, from the turbine's parameters ``tp``."""
    s = tp["edge_coupling_cos"] * math.cos(pitch) - tp["edge_coupling_sin"] * math.sin(pitch)
    m = np.array([[tp["J_r"], 3 * s, 0], [3 * s, 3 * tp["edge_modal_mass"], 0],
                  [0, 0, tp["J_g"]]])
    k = np.array([[tp["k_s"], 0, -tp["k_s"]], [0, 3 * tp["edge_stiffness"], 0],
                  [-tp["k_s"], 0, tp["k_s"]]])
    w2 = np.linalg.eigvals(np.linalg.solve(m, k)).real
    return sorted(math.sqrt(x) / (2 * math.pi) for x in w2 if x > 1e-6)


def modes(rc: config.RunConfig) -> dict[str, float]:
    """wtftc's own drivetrain and tower frequencies [Hz] on ``rc``'s plant (the module's
    docstring); on a plant with the blades' edgewise mode the drivetrain is the lower
    mode of :func:`three_inertias_hz` at the pitch of the operating point of the run's
    mean wind."""
    tp = lay.values("turbine_params", rc.p_turbine)
    if PLANTS[rc.plant].get("edge"):
        wind = rc.raw["wind"]
        mean = wind.get("mean_mps", wind.get("speed_mps"))
        if mean is None:  # a wind file, steps: the mean of the series over the run
            mean = float(np.mean(rc.wind(np.linspace(0.0, rc.t_final, 2001))))
        _, _, pitch = operating_point(rc.loop, mean)
        drive = three_inertias_hz(tp, pitch)[0]
    else:
        drive = math.sqrt(tp["k_s"] * (1 / tp["J_r"] + 1 / tp["J_g"])) / (2 * math.pi)
    tower = math.sqrt(tp["tower_stiffness"] / tp["tower_modal_mass"]) / (2 * math.pi)
    return {"drivetrain": drive, "tower": tower}


def welch(x: np.ndarray, dt: float, segment_s: float = SEGMENT_S) -> tuple[np.ndarray, ...]:
    """One-sided PSD of ``x`` (frequency [Hz], density [unit²/Hz]): Hann segments of
    ``segment_s`` (or the whole series if shorter), half overlapping, mean removed."""
    n = min(len(x), max(8, int(round(segment_s / dt))))
    step = max(1, n // 2)
    win = np.hanning(n)
    scale = 1.0 / (np.sum(win**2) / dt)
    segs = [x[k:k + n] for k in range(0, len(x) - n + 1, step)]
    p = np.mean([np.abs(np.fft.rfft((s - s.mean()) * win))**2 for s in segs], axis=0) * scale
    p[1:-1] *= 2
    return np.fft.rfftfreq(n, dt), p


def peak(f: np.ndarray, p: np.ndarray, centre: float) -> tuple[float | None, float | None]:
    """The highest PSD peak within a factor of two of ``centre`` [Hz]: its frequency and
    its damping from the half-power width (None where the band holds no interior peak)."""
    band = np.flatnonzero((f >= centre / 2) & (f <= 2 * centre))
    if len(band) < 3:
        return None, None
    k = band[np.argmax(p[band])]
    if k in (band[0], band[-1]) or k == 0 or k == len(p) - 1:
        return None, None
    half = p[k] / 2
    lo, hi = k, k
    while lo > 0 and p[lo] > half:
        lo -= 1
    while hi < len(p) - 1 and p[hi] > half:
        hi += 1
    # the half-power crossings, linear between the samples
    f_lo = np.interp(half, [p[lo], p[lo + 1]], [f[lo], f[lo + 1]])
    f_hi = np.interp(half, [p[hi], p[hi - 1]], [f[hi], f[hi - 1]])
    return float(f[k]), float((f_hi - f_lo) / (2 * f[k]))


def figures_of(rc: config.RunConfig, res, centre: dict[str, float]) -> dict:
    """The validation's figures of one run, after its start-up window; the spectral peaks
    looked for around ``centre`` (:func:`modes` of wtftc's plant)."""
    t0 = rc.transient[0]
    sig = signals(rc, res, t0)
    keep = res.t >= t0 - 1e-9
    power = res.column("P_gen")[keep]
    out = {"rotor_speed": sig.omega_r, "pitch": sig.beta.mean(axis=1),
           "shaft_torque": sig.shaft, "tower_moment": sig.tower}
    figs = {}
    for name, x in out.items():
        if x is not None:
            figs[f"{name}_mean"] = ("mean", float(np.mean(x)))
            figs[f"{name}_std"] = ("std", float(np.std(x)))
    figs["power_mean"] = ("mean", float(np.mean(power)))
    figs["power_std"] = ("std", float(np.std(power)))
    m = metrics(rc, res)
    figs["shaft_del"] = ("del", m["shaft_torque_del_1hz_Nm"])
    figs["tower_del"] = ("del", m["tower_base_del_1hz_Nm"])
    figs["rotor_speed_max"] = ("extreme", m["overspeed_peak_rad_s"])
    for mode, x in (("drivetrain", sig.shaft), ("tower", sig.tower)):
        f, p = welch(x, sig.dt) if x is not None else (np.zeros(1), np.zeros(1))
        freq, zeta = peak(f, p, centre[mode])
        figs[f"{mode}_frequency"] = ("frequency", freq)
        figs[f"{mode}_damping"] = ("damping", zeta)
    return {"figures": figs, "signals": sig, "metrics": m}


#: units of the figures, by their name's start
UNITS = {"rotor_speed": "rad/s", "pitch": "rad", "shaft": "N m", "tower_moment": "N m",
         "tower_del": "N m", "power": "W", "drivetrain_frequency": "Hz",
         "tower_frequency": "Hz", "drivetrain_damping": "-", "tower_damping": "-"}


def unit_of(name: str) -> str:
    return next((u for k, u in UNITS.items() if name.startswith(k)), "-")


#: below these a figure is zero (round-off: OpenFAST's pitch σ at fine pitch is 1e-24 rad),
#: by unit; a ratio to it means nothing
ZERO = {"rad": 1e-9, "rad/s": 1e-9, "N m": 1e-3, "W": 1e-3}


def _is_zero(v, unit: str) -> bool:
    return v is not None and abs(v) < ZERO.get(unit, 0.0)


def compare_figures(runs: dict[str, dict]) -> dict:
    """validation.json's ``metrics``: per figure, each engine's value, wtftc's ratio to
    OpenFAST's and the verdict: "agrees" or "differs" against the tolerance, "both zero"
    (both below :data:`ZERO`, no ratio), "not found" (a peak one engine lacks)."""
    table = {}
    for name, (kind, ref) in runs["openfast"]["figures"].items():
        unit = unit_of(name)
        row = {"unit": unit, "tolerance": TOLERANCE[kind], "openfast": ref}
        for eng in ENGINES[1:]:
            if eng in runs:
                v = runs[eng]["figures"][name][1]
                row[eng] = v
                row[f"ratio_{eng}"] = (None if v is None or not ref or _is_zero(ref, unit)
                                       else v / ref)
        r = row.get("ratio_wtftc")
        row["verdict"] = ("both zero" if _is_zero(ref, unit) and _is_zero(row.get("wtftc"), unit)
                          else "differs" if _is_zero(ref, unit) and row.get("wtftc") is not None
                          else "not found" if r is None else
                          "agrees" if abs(r - 1) <= TOLERANCE[kind] else "differs")
        table[name] = row
    return table


def markdown(table: dict, title: str) -> str:
    lines = [f"# {title}", "", "| figure | unit | OpenFAST | wtftc | wtftc / OpenFAST | "
             "wtftc (hub) / OpenFAST | tolerance | verdict |", "|---|---|---|---|---|---|---|---|"]

    def g(v):
        return "—" if v is None else f"{v:.4g}"
    for name, r in table.items():
        lines.append(f"| {name} | {r['unit']} | {g(r['openfast'])} | {g(r.get('wtftc'))} | "
                     f"{g(r.get('ratio_wtftc'))} | {g(r.get('ratio_wtftc_hub'))} | "
                     f"±{100 * r['tolerance']:.0f} % | {r['verdict']} |")
    return "\n".join(lines) + "\n"


#: the legend of wtftc's run by its rotor wind
WIND_LABELS = {"blades": "the blades' wind", "disk": "disk-average wind"}


def plot(runs: dict, out: Path, plant: str = PLANT, rotor_wind: str | None = ROTOR_WIND
         ) -> list[Path]:
    """Overlaid time series and spectra (PNG and PDF), wtftc's on ``plant`` in the wind
    ``rotor_wind`` ("blades", "disk"; None: the scenario's own, not an NTM)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    style = {"openfast": ("k", "OpenFAST 5.0.0"),
             "wtftc": ("tab:blue", f"wtftc {plant} plant, " + WIND_LABELS.get(rotor_wind,
                                                                            "the same wind")),
             "wtftc_hub": ("tab:orange", f"wtftc {plant} plant, hub wind")}
    rows = [("omega_r", "rotor speed [rad/s]", 1.0), ("pitch", "mean blade pitch [deg]",
            180 / math.pi), ("shaft", "LSS torque [MN m]", 1e-6),
            ("tower", "tower-base fore-aft moment [MN m]", 1e-6)]
    paths = []
    fig, axes = plt.subplots(len(rows), 1, figsize=(9, 10), sharex=True)
    for ax, (key, label, scale) in zip(axes, rows, strict=True):
        for eng, r in runs.items():
            sig = r["signals"]
            x = sig.beta.mean(axis=1) if key == "pitch" else getattr(sig, key)
            if x is not None:
                ax.plot(sig.t, np.asarray(x) * scale, color=style[eng][0], lw=0.8,
                        label=style[eng][1])
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    axes[-1].set_xlabel("time [s]")
    fig.tight_layout()
    for ext in ("png", "pdf"):
        atomic_savefig(fig, out / f"time_series.{ext}", dpi=130)
        paths.append(out / f"time_series.{ext}")
    plt.close(fig)
    fig, axes = plt.subplots(2, 1, figsize=(9, 7))
    for ax, (key, label) in zip(axes, (("shaft", "LSS torque PSD [(MN m)²/Hz]"),
                                       ("tower", "tower-base moment PSD [(MN m)²/Hz]")),
                                strict=True):
        for eng, r in runs.items():
            sig = r["signals"]
            x = getattr(sig, key)
            if x is not None:
                f, p = welch(np.asarray(x) * 1e-6, sig.dt)
                shown = (f > 0) & (f <= SPECTRA_HZ)  # the y axis scales to what is shown
                ax.semilogy(f[shown], p[shown], color=style[eng][0], lw=0.8,
                            label=style[eng][1])
        ax.set_xlim(0, SPECTRA_HZ)
        ax.set_xlabel("frequency [Hz]")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3, which="both")
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    for ext in ("png", "pdf"):
        atomic_savefig(fig, out / f"spectra.{ext}", dpi=130)
        paths.append(out / f"spectra.{ext}")
    plt.close(fig)
    return paths


def run_validate(raw: dict, out_dir: Path, progress: bool = True,
                 plant: str = PLANT, rotor_wind: str = ROTOR_WIND) -> dict:
    """Both engines on the scenario ``raw`` into ``out_dir`` (new, empty, or an earlier
    validation's: wtftc.files.owned_folder), wtftc on ``plant`` in the ``rotor_wind``;
    validation.json's content."""
    check_out_folder(out_dir, "--out")  # before any work, a TurbSim field too
    raw = scenario(raw)
    cfgs = engine_configs(raw, plant, rotor_wind)
    for cfg in cfgs.values():  # every configuration checked before a field is made
        config.check_before_field(cfg)
    for cfg in cfgs.values():
        ensure_field(cfg)
    rcs = {eng: config.make_config(cfg) for eng, cfg in cfgs.items()}  # all checked first
    note = config.cut_out_note(rcs["openfast"])
    if note:
        print(note, file=sys.stderr, flush=True)
    runs, centre = {}, modes(rcs["wtftc"])
    with owned_folder(out_dir, "--out", command="validate") as tmp:
        for eng, rc in rcs.items():
            if progress:
                print(f"[{eng}] {rc.label}: {rc.t_final:g} s", flush=True)
            res, _, _ = cases.run_and_write(rc, tmp / eng, progress=progress)
            runs[eng] = figures_of(rc, res, centre)
        table = compare_figures(runs)
        rc = rcs["openfast"]
        doc = {"scenario": {"controller": rc.raw["controller"], "plant": plant,
                            "rotor_wind": rcs["wtftc"].raw["wind"].get("rotor_wind"),
                            "turbine": rc.raw.get("turbine"),
                            "wind": rc.raw["wind"], "t_final_s": rc.t_final, "seed": rc.seed,
                            "transient_s": rc.transient[0], "faults": rc.raw.get("fault")},
               "modes_wtftc_hz": centre, "metrics": table}
        atomic_write_json(tmp / "validation.json", doc)
        atomic_write_text(tmp / "validation.md", markdown(
            table, f"wtftc validate: {rc.raw['controller']}, {rc.raw['wind'].get('kind')} "
                   f"{rc.raw['wind'].get('mean_mps', rc.raw['wind'].get('speed_mps', ''))} "
                   f"m/s, {rc.t_final:g} s, seed {rc.seed}"))
        plot(runs, tmp, plant, rcs["wtftc"].raw["wind"].get("rotor_wind"))
    return doc
