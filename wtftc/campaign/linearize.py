"""``wtftc linearize``: exact linear models of the generated loop (ours; docs/turbines.md).

At each wind speed the closed loop (case 1, continuous time, exact sensors, no FDI) is run
in constant wind until it rests; at that operating point CasADi differentiates the
generated functions exactly (automatic differentiation of the same expressions the
simulator runs, no finite differences):

* the open-loop plant ẋ_p = A_p x_p + B_p v + E_p w, with the rotor speed as output (the
  three blade commands v, the wind w; the generator torque law inside);
* the controller ẋ_c = A_c x_c + B_c x_p, v = C_c x_c + D_c x_p (it reads the plant
  through exact sensors);
* the closed loop A_cl = [[A_p + B_p D_c, B_p C_c], [B_c, A_c]], checked against the
  Jacobian of the closed-loop right-hand side itself;
* the pitch loop broken at the collective command: L(s) = -(mean command)/(collective
  input), whose gain and phase margins python-control computes (negative feedback).

Every model is also a python-control ``StateSpace`` (``control`` on PyPI).

Only an operating point is linearized (:class:`NotAtRest` otherwise, issue 30): the loop
must come to rest (max |ż| below REST_TOLERANCE) with its rotor inside the Cp table; ROSCO,
an external DISCON library, is refused.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cache

import casadi as ca
import numpy as np

from wtftc import config
from wtftc.artefacts import layout as lay
from wtftc.campaign import cases
from wtftc.errors import ConfigError
from wtftc.model.faults import nominal_actuator
from wtftc.sim.rhs import (
    controller_block,
    loop_symbols,
    measure,
    plant_block,
    rhs_function,
    tower_acceleration,
    true_signals,
)
from wtftc.sim.stability import _jacobian_function

#: how long the loop runs in constant wind to reach its operating point [s]
SETTLE_S = 400.0


@dataclass
class OperatingPoint:
    """One wind speed's linear models and what they say."""

    wind: float
    z: np.ndarray  # plant then controller states at rest
    pitch: float  # mean blade pitch [rad]
    A_p: np.ndarray
    B_p: np.ndarray
    E_p: np.ndarray
    C_p: np.ndarray  # rotor speed from the plant state
    A_c: np.ndarray
    B_c: np.ndarray
    C_c: np.ndarray
    D_c: np.ndarray
    A_cl: np.ndarray
    residual: float  # |ż| at the operating point (its rest)
    #: the controller's own path from the wind (the tower damper reads the tower-top
    #: acceleration, which the thrust in the wind sets): ∂ẋ_c/∂w and ∂v/∂w; zero without
    E_c: np.ndarray | None = None
    F_c: np.ndarray | None = None

    def eigenvalues(self) -> np.ndarray:
        return np.linalg.eigvals(self.A_cl)

    def coupled_eigenvalues(self) -> np.ndarray:
        """The eigenvalues without those of dormant states: a state no other state's rate
        depends on (its column of A is zero off the diagonal) only follows the loop, and
        its own mode is not one of the loop's (the PI's filter state and the physical
        AFTC's speed observer when switched off)."""
        off = self.A_cl - np.diag(np.diag(self.A_cl))
        keep = np.flatnonzero(np.any(off != 0.0, axis=0))
        return np.linalg.eigvals(self.A_cl[np.ix_(keep, keep)])

    def state_spaces(self) -> dict:
        """python-control StateSpace objects: the plant (inputs the three blade commands
        and the wind, output ω_r), the controller (input the plant state, output the
        three commands), the closed loop (input the wind, output ω_r) and the pitch loop
        L(s) (collective, negative-feedback convention)."""
        import control

        n_p, n_c = self.A_p.shape[0], self.A_c.shape[0]
        E_c = np.zeros((n_c, 1)) if self.E_c is None else self.E_c
        F_c = np.zeros((self.B_p.shape[1], 1)) if self.F_c is None else self.F_c
        B_w = np.vstack([self.E_p + self.B_p @ F_c, E_c])
        C_w = np.hstack([self.C_p, np.zeros((1, self.A_c.shape[0]))])
        return {"plant": control.ss(self.A_p, np.hstack([self.B_p, self.E_p]), self.C_p, 0),
                "controller": control.ss(self.A_c, self.B_c, self.C_c, self.D_c),
                "closed_loop": control.ss(self.A_cl, B_w, C_w, 0),
                "pitch_loop": control.ss(*self.pitch_loop()),
                "n_plant": n_p}

    def pitch_loop(self) -> tuple:
        """(A, B, C, D) of L(s) = -T(s), T from a collective input added to every blade's
        command to the mean of the controller's three commands."""
        n_p, n_c = self.A_p.shape[0], self.A_c.shape[0]
        A = np.block([[self.A_p, np.zeros((n_p, n_c))], [self.B_c, self.A_c]])
        B = np.vstack([self.B_p.sum(axis=1, keepdims=True), np.zeros((n_c, 1))])
        C = -np.hstack([self.D_c, self.C_c]).mean(axis=0, keepdims=True)
        return A, B, C, np.zeros((1, 1))


@cache
def _block_functions(loop) -> ca.Function:
    """(x_p, x_c, v, wind, parameters) → the plant's, the controller's and the closed
    loop's Jacobians, by automatic differentiation of the generated blocks."""
    n_p, n_c, _ = loop.n_states
    sym = loop_symbols(loop, n_p + n_c)
    xp, xc = ca.SX.sym("x_p", n_p), ca.SX.sym("x_c", n_c)
    v, wind = ca.SX.sym("v", lay.n_blades()), sym["wind"]
    true = true_signals(loop, xp, sym["p_turbine"])  # exact sensors: no lag, no noise
    readings = measure(true, true, ca.DM.zeros(len(lay.layout()["sensors"])), sym)
    sym["tower_fa_acc"] = tower_acceleration(loop, xp, sym)  # the tower damper's input
    ctl = controller_block(loop, xc, ca.SX.zeros(0), readings, sym)
    pl = plant_block(loop, xp, v, sym)
    f_p, f_c = pl["x_plant_dot"], ctl["x_ctrl_dot"]
    omega = xp[lay.index("nrel5mw_states", "omega_r")]
    params = [sym[n] for n in ("actuator_faults", "sensor_faults", "ctrl_fault", "yd",
                               "p_turbine", "p_sensors", "p_ctrl", "cp_scale")]
    outs = [ca.jacobian(f_p, xp), ca.jacobian(f_p, v), ca.jacobian(f_p, wind),
            ca.jacobian(omega, xp), ca.jacobian(f_c, xc), ca.jacobian(f_c, xp),
            ca.jacobian(ctl["v"], xc), ca.jacobian(ctl["v"], xp), ctl["v"],
            ca.jacobian(f_c, wind), ca.jacobian(ctl["v"], wind)]
    return ca.Function("linear_blocks", [xp, xc, v, wind, *params], outs)


def _values(rc: config.RunConfig, loop) -> list:
    return [nominal_actuator(loop.p_turbine), lay.defaults("sensor_faults"),
            lay.defaults("fault_inputs"), rc.yd, np.array(loop.p_turbine),
            lay.defaults("sensor_params"), rc.p_ctrl, 1.0]


def _run_config(raw: dict, wind: float, **timing) -> config.RunConfig:
    """The run configuration ``raw`` as linearized: case 1, continuous time, exact
    sensors, no fault, in constant ``wind`` (so that the settling run and the operating
    point share one plant: below rated wind the baseline torque law, config._torque_law).
    ROSCO is refused: an external DISCON library, with nothing here to differentiate."""
    if raw.get("controller") == "rosco":
        raise ConfigError("controller", "rosco", "a controller generated by wtftc (" + ", ".join(
            linearizable()) + "): ROSCO is an external DISCON library, not differentiable "
            "here")
    return config.make_config({**raw, "case": 1, "profile": "ideal", "fault": [],
                               "wind": {"kind": "constant", "speed_mps": wind}, **timing})


def linearizable() -> list[str]:
    """The controllers ``wtftc linearize`` can differentiate: the registered ones (not
    ROSCO, which runs as an external DISCON library)."""
    from wtftc.sim.rhs import controllers

    return [k for k in controllers() if k != "external"]


class NotAtRest(ConfigError):
    """No operating point at this wind: the loop diverged while settling, or the state
    it reached is not at rest (max |ż| above REST_TOLERANCE); ``field`` is ``wind``."""

    def __init__(self, wind: float, allowed: str):
        super().__init__("wind", wind, allowed)


def settle(raw: dict, wind: float) -> np.ndarray:
    """The loop's state (plant, controller) after SETTLE_S in constant ``wind``."""
    rc = _run_config(raw, wind, t_final_s=SETTLE_S, output_rate_hz=1.0)
    try:
        res = cases.run(rc, progress=False, keep_states=True)
    except ConfigError as exc:  # no operating point to start from (wtftc.sim.trim)
        if exc.field != "wind":
            raise
        raise NotAtRest(wind, exc.allowed) from None
    if res.diverged is not None:
        raise NotAtRest(wind, f"a wind at which the {rc.controller} loop comes to rest (it "
                        f"diverged at t = {res.diverged['t_s']:.4g} s while settling: "
                        f"{res.diverged['reason']})")
    n_p, n_c, _ = rc.loop.n_states
    return np.asarray(res.z_final, dtype=float)[:n_p + n_c]


def rest(raw: dict, wind: float, z: np.ndarray, steps: int = 30) -> np.ndarray:
    """The operating point from near it: Newton's method on ż = 0 with the exact
    Jacobian (the state the settling run nears, to machine precision; the adaptive laws'
    σ-modification makes that approach slow)."""
    rc = _run_config(raw, wind)
    loop = replace(rc.loop, fdi=False)
    rhs, jac = rhs_function(loop), _jacobian_function(loop)
    vals = dict(zip(_PARAMS, _values(rc, loop), strict=True))
    for _ in range(steps):
        f = np.array(rhs.call({"z": z, "wind": wind, **vals})["z_dot"]).ravel()
        if np.abs(f).max() < 1e-13:
            break
        J = np.array(jac.call({"z": z, "wind": wind, **vals})["dz_dot_dz"])
        z = z - np.linalg.lstsq(J, f, rcond=None)[0]
    return z


def operating_point(raw: dict, wind: float, z: np.ndarray | None = None) -> OperatingPoint:
    """The loop of the run configuration ``raw`` at rest in constant ``wind`` [m/s] (from
    ``z`` if given, else after a settling run), and its linear models there."""
    z = rest(raw, wind, settle(raw, wind) if z is None else z)
    rc = _run_config(raw, wind)
    loop = replace(rc.loop, fdi=False)
    n_p = loop.n_states[0]
    xp, xc = z[:n_p], z[n_p:]
    vals = _values(rc, loop)
    blocks = _block_functions(loop)
    v0 = np.array(blocks(xp, xc, np.zeros(lay.n_blades()), wind, *vals)[8]).ravel()
    out = [np.array(m) for m in blocks(xp, xc, v0, wind, *vals)]
    A_p, B_p, E_p, C_p, A_c, B_c, C_c, D_c = out[:8]
    A_cl = np.block([[A_p + B_p @ D_c, B_p @ C_c], [B_c, A_c]])
    rhs = rhs_function(loop)
    zdot = np.array(rhs.call({"z": z, "wind": wind, **dict(zip(_PARAMS, vals, strict=True))})[
        "z_dot"]).ravel()
    beta = z[lay.block("nrel5mw_states", "beta")]
    residual = float(np.abs(zdot).max())
    _check_rest(rc, wind, z, residual)
    return OperatingPoint(wind, z, float(np.mean(beta)), A_p, B_p, E_p, C_p, A_c, B_c, C_c,
                          D_c, A_cl, residual, E_c=out[9], F_c=out[10])


#: the largest max |ż| [SI] of a point reported as at rest: the operating points of the
#: default winds rest to 1e-13 or better; the loops that do not rest (the paper's design
#: at 16 m/s, in a limit cycle of ±1° pitch) leave 0.1 and more
REST_TOLERANCE = 1e-6


def _check_rest(rc: config.RunConfig, wind: float, z: np.ndarray, residual: float) -> None:
    """Refuse (:class:`NotAtRest`) a point that is not an operating point of the turbine:
    one not at rest (max |ż| above REST_TOLERANCE after the settling run and Newton's
    method), or one whose tip-speed ratio or pitch lies beyond the Cp table, where the
    aerodynamics are the table's edge (inputs clipped: no slope in λ or β, so no pitch
    loop) rather than the turbine's: below cut-in the rotor idles at a λ far beyond it
    (at 0.5 m/s, λ 91 on the NREL 5-MW's table of 2-14.5), beyond cut-out the pitch."""
    what = f"a wind at which the {rc.raw['controller']} loop comes to rest"
    if not np.all(np.isfinite(z)) or not residual <= REST_TOLERANCE:
        raise NotAtRest(wind, f"{what} (here max |ż| = {residual:.3g} [SI] at the point "
                        f"reached after {SETTLE_S:g} s and Newton's method, above "
                        f"{REST_TOLERANCE:g}: it does not rest)")
    table, tp = rc.loop.table, lay.values("turbine_params", rc.loop.p_turbine)
    omega = float(z[lay.index("nrel5mw_states", "omega_r")])
    tsr = omega * tp["rotor_radius"] / wind
    beta = float(np.mean(z[lay.block("nrel5mw_states", "beta")]))
    lo, hi = float(table.tsr.min()), float(table.tsr.max())
    plo, phi = float(table.pitch_rad.min()), float(table.pitch_rad.max())
    if not (lo <= tsr <= hi and plo <= beta <= phi):
        raise NotAtRest(wind, f"{what} inside its Cp table (here the rotor rests at "
                        f"{omega:.4g} rad/s, λ = {tsr:.3g}, pitch {np.degrees(beta):.3g}°; "
                        f"the table holds λ {lo:g}-{hi:g}, pitch {np.degrees(plo):g}-"
                        f"{np.degrees(phi):g}°: below cut-in the rotor idles beyond it, "
                        f"and there the model has no aerodynamics)")


#: the loop's parameter inputs, in _values' order
_PARAMS = ("actuator_faults", "sensor_faults", "ctrl_fault", "yd", "p_turbine", "p_sensors",
           "p_ctrl", "cp_scale")


def closed_loop_jacobian(raw: dict, op: OperatingPoint) -> np.ndarray:
    """∂ż/∂z of the closed-loop right-hand side itself at ``op`` (the check of A_cl)."""
    rc = _run_config(raw, op.wind)
    loop = replace(rc.loop, fdi=False)
    vals = dict(zip(_PARAMS, _values(rc, loop), strict=True))
    return np.array(_jacobian_function(loop).call({"z": op.z, "wind": op.wind, **vals})[
        "dz_dot_dz"])


def modes(op: OperatingPoint) -> list[dict]:
    """Each closed-loop mode (one of a complex pair): eigenvalue, natural frequency
    [rad/s], damping ratio [-], slowest first; dormant states' modes left out."""
    out = []
    for lam in sorted(op.coupled_eigenvalues(), key=lambda x: abs(x)):
        if lam.imag < -1e-12:
            continue
        wn = abs(lam)
        out.append({"real": lam.real, "imag": lam.imag, "omega_n_rad_s": wn,
                    "damping": -lam.real / wn if wn > 0 else 1.0})
    return out


def least_stable(op: OperatingPoint) -> dict:
    """The closed-loop mode of largest real part, over every eigenvalue (the adaptive
    laws' slow modes too): real part [1/s], natural frequency [rad/s], damping [-]. The
    loop is asymptotically stable at ``op`` if and only if its real part is negative."""
    lam = max(op.eigenvalues(), key=lambda x: (x.real, abs(x.imag)))
    wn = abs(lam)
    return {"real": float(lam.real), "imag": float(abs(lam.imag)), "omega_n_rad_s": wn,
            "damping": float(-lam.real / wn) if wn > 0 else 0.0}


def margins(op: OperatingPoint) -> dict:
    """Gain margin [dB], phase margin [deg] and their crossover frequencies [rad/s] of the
    pitch loop L(s) (python-control's stability_margins; inf where there is none)."""
    import control

    A, *_ = loop = op.pitch_loop()
    # python-control finds the crossovers as roots of the loop's polynomials, and evaluates
    # them at every root: a spurious root near 6e7 rad/s overflows a double there (the tower
    # plant at 16 m/s), harmlessly, as it is dropped below
    with np.errstate(over="ignore"):
        gm, pm, _, wg, wp, _ = control.stability_margins(control.ss(*loop))
    # a phase crossover far beyond the model's fastest mode is the round-off of a loop
    # whose phase only tends to -180° (measured: 2e8 rad/s): no gain margin there
    fastest = float(np.abs(np.linalg.eigvals(A)).max())
    if not np.isfinite(wg) or wg > 10 * fastest:
        gm, wg = float("inf"), float("nan")
    gm_db = 20 * np.log10(gm) if np.isfinite(gm) and gm > 0 else float("inf")
    return {"gain_margin_dB": float(gm_db), "phase_margin_deg": float(pm),
            "phase_crossover_rad_s": float(wg), "gain_crossover_rad_s": float(wp)}


#: the winds of `wtftc linearize` by default [m/s]: above rated, to cut-out
WINDS = (12.0, 14.0, 16.0, 18.0, 20.0, 22.0, 24.0)
#: modes slower than this are the adaptive laws' σ-modification (1/σ), not the pitch
#: loop's: left out of the summary's dominant mode [rad/s]
SLOW_ADAPTATION = 0.05


def summary_row(op: OperatingPoint) -> dict:
    """The table row of one wind: pitch, the dominant (slowest, beyond the adaptive
    laws') and the least-damped modes, the margins."""
    ms = [m for m in modes(op) if m["omega_n_rad_s"] > SLOW_ADAPTATION]
    dom, weak = ms[0], min(ms, key=lambda m: m["damping"])
    return {"wind_mps": op.wind, "pitch_deg": float(np.degrees(op.pitch)),
            "dominant_omega_n_rad_s": dom["omega_n_rad_s"], "dominant_damping": dom["damping"],
            "least_damped_omega_n_rad_s": weak["omega_n_rad_s"],
            "least_damped_damping": weak["damping"], **margins(op),
            "rest_residual": op.residual}


UNITS = {"wind_mps": "wind [m/s]", "pitch_deg": "pitch [deg]",
         "dominant_omega_n_rad_s": "dominant mode ω_n [rad/s]",
         "dominant_damping": "dominant mode ζ [-]",
         "least_damped_omega_n_rad_s": "least-damped mode ω_n [rad/s]",
         "least_damped_damping": "least-damped mode ζ [-]",
         "gain_margin_dB": "gain margin [dB]", "phase_margin_deg": "phase margin [deg]",
         "phase_crossover_rad_s": "phase crossover [rad/s]",
         "gain_crossover_rad_s": "gain crossover [rad/s]",
         "rest_residual": "max abs(ż) at rest [SI]"}


def run_linearize(raw: dict, winds, out_dir, progress: bool = True) -> list[dict]:
    """Every wind's operating point, its matrices (``linear_<wind>mps.npz``), the modes
    (``modes.csv``), the summary (``linearize.md``, ``.csv``) and a figure, in out_dir,
    swapped in whole (wtftc.files.owned_folder: a folder holding anything wtftc did not
    write is refused)."""
    from wtftc.files import owned_folder

    with owned_folder(out_dir, "--out", command="linearize", legacy=is_legacy_linearize) \
            as tmp:
        return _write_linearize(raw, winds, tmp, progress)


def is_legacy_linearize(out) -> bool:
    """A `wtftc linearize` folder written before the marker existed."""
    from wtftc.results.io import is_legacy_tree

    return is_legacy_tree(out, (r"linearize\.(md|csv|png|pdf)", r"modes\.csv",
                                r"linear_[0-9.e+-]+mps\.npz"))


def _write_linearize(raw: dict, winds, out, progress: bool) -> list[dict]:
    from wtftc.results.io import atomic_savez, atomic_write_text

    rows, mode_lines = [], ["wind_mps,real_1_per_s,imag_rad_s,omega_n_rad_s,damping"]
    for w in winds:
        op = operating_point(raw, float(w))
        rows.append(summary_row(op))
        mode_lines += [",".join([f"{w:g}", *(repr(float(m[k])) for k in (
            "real", "imag", "omega_n_rad_s", "damping"))]) for m in modes(op)]
        atomic_savez(out / f"linear_{w:g}mps.npz", **{
            k: getattr(op, k) for k in ("A_p", "B_p", "E_p", "C_p", "A_c", "B_c", "C_c",
                                        "D_c", "E_c", "F_c", "A_cl", "z")}, wind_mps=op.wind)
        if progress:
            r = rows[-1]
            print(f"  {w:g} m/s: pitch {r['pitch_deg']:.2f}°, dominant mode "
                  f"{r['dominant_omega_n_rad_s']:.3f} rad/s ζ {r['dominant_damping']:.2f}, "
                  f"GM {r['gain_margin_dB']:.1f} dB, PM {r['phase_margin_deg']:.1f}°",
                  flush=True)
    atomic_write_text(out / "modes.csv", "\n".join(mode_lines) + "\n")
    keys = list(UNITS)
    atomic_write_text(out / "linearize.csv", ",".join(keys) + "\n" + "".join(
        ",".join(repr(float(r[k])) for k in keys) + "\n" for r in rows))
    md = ["| " + " | ".join(UNITS[k] for k in keys) + " |", "|" + "---|" * len(keys)]
    md += ["| " + " | ".join(f"{r[k]:.4g}" for k in keys) + " |" for r in rows]
    atomic_write_text(out / "linearize.md", "\n".join(md) + "\n")
    _figure(out, rows)
    return rows


def _figure(out, rows: list[dict]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from wtftc.results.io import atomic_savefig

    w = [r["wind_mps"] for r in rows]
    fig, ax = plt.subplots(1, 3, figsize=(13, 3.8))
    ax[0].plot(w, [r["dominant_omega_n_rad_s"] for r in rows], "o-", label="dominant")
    ax[0].plot(w, [r["least_damped_omega_n_rad_s"] for r in rows], "s--", label="least damped")
    ax[0].set(xlabel="wind [m/s]", ylabel="mode ω_n [rad/s]", yscale="log")
    ax[1].plot(w, [r["dominant_damping"] for r in rows], "o-", label="dominant")
    ax[1].plot(w, [r["least_damped_damping"] for r in rows], "s--", label="least damped")
    ax[1].set(xlabel="wind [m/s]", ylabel="damping ratio ζ [-]")
    ax[2].plot(w, [min(r["gain_margin_dB"], 60.0) for r in rows], "o-",
               label="gain margin [dB] (60: none)")
    ax[2].plot(w, [r["phase_margin_deg"] for r in rows], "s-", label="phase margin [deg]")
    ax[2].set(xlabel="wind [m/s]", ylabel="margin")
    for a in ax:
        a.grid(True, alpha=0.3)
        a.legend(fontsize=8)
    fig.suptitle("Closed loop linearised at rest in constant wind (exact Jacobians)")
    fig.tight_layout()
    for ext in ("png", "pdf"):
        atomic_savefig(fig, out / f"linearize.{ext}")
    plt.close(fig)
