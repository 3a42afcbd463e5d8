"""The controllers the simulator can run: one entry each, one uniform generated signature.

Adding a controller is one derivation module (its equations) plus one entry in
:data:`REGISTRY`. For each entry the generator emits

    ctrl_<name>(x_ctrl, meas, yd, sched, p_ctrl, known_fault) -> (v, x_ctrl_dot, u0, diag)
    init_<name>(meas, sched, p_ctrl) -> x_ctrl0

and lists it under "controllers" in generated/layout.json, from which wtftc reads it.

* meas = [ω_r, ω_g (HSS), β_meas,1..3]: what a turbine measures; never the plant state;
* yd = the rotor-speed reference and its four derivatives;
* sched = [∂T_aero/∂β at the measured mean pitch on the steady operating curve, from
  the Cp table (wtftc.model.aero.pitch_sensitivity_schedule); the tower-top fore-aft
  acceleration (the tower damper's: wtftc.sim.rhs.tower_acceleration, #53 in a DISCON
  host)], both built by the runtime;
* known_fault = [ρ̂_j, σ̂_j, ū_j] as eq (49) is told (nominal when the fault is unknown);
* v = the three blade pitch commands [rad]; u0 = the controller's scalar command;
* diag = four controller-specific diagnostics (named in the registry).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType

import casadi as ca
import sympy as sp

from derivation import drivetrain, paper_design, physical, pi_baseline
from derivation import fdi as fdi_module
from derivation import layout as lay
from derivation.casadi_build import FuzzyEvaluator, Translator, joint_cse

MEAS = ["omega_r", "omega_g_hss", *[f"beta_meas_{j}" for j in range(1, lay.N_BLADES + 1)]]
MEAS_UNITS = ["rad/s", "rad/s", *["rad"] * lay.N_BLADES]
#: where verification draws each measurement (the pitch beyond 0..90°)
MEAS_SAMPLES = [(1.0, 1.5), (100.0, 145.0), *[(-0.05, 1.65)] * lay.N_BLADES]
#: what the runtime computes for the controllers beside the measurements: the pitch
#: sensitivity ∂T_aero/∂β at the measured mean pitch (wtftc.model.aero) and the tower-top
#: fore-aft acceleration (the tower damper's; derivation/design.py, tower_fa_acc)
SCHED = ["dT_dbeta", "tower_fa_acc"]
N_DIAG = 4


@dataclass
class Controller:
    name: str
    doc: str
    states: list[lay.Entry]
    params: list[lay.Entry]
    states_group: str
    params_group: str
    diag: list[tuple[str, str]]  # the four diagnostics: (name, unit)
    build: Callable  # (symbols dict) -> dict of CasADi outputs v, x_ctrl_dot, u0, diag, x0
    sources: tuple[str, ...] = ()  # derivation modules it is derived in (for the manifest)
    #: the module of a controller derived as a derivation.design.ControllerDesign; where it
    #: has a design model (``design_model``), its checks alpha_<name> and its model
    #: closed_loop_<name>_model are generated and verified by every test that iterates over
    #: the registry (the paper's design has its own: alpha_derivatives, closed_loop_paper)
    design: ModuleType | None = None
    #: FDI parameters (derivation/fdi.py) this design takes in place of the defaults, with
    #: the reason: the FDI is shared, but what its estimates may be trusted with is not
    fdi: dict[str, float] = field(default_factory=dict)

    @classmethod
    def derived(cls, name: str, doc: str, module: ModuleType,
                diag: list[tuple[str, str]]) -> Controller:
        """The registry entry of a ControllerDesign module: its STATES and PARAMS become the
        layout groups <name>_states and <name>_params."""
        return cls(name, doc, module.STATES, module.PARAMS, f"{name}_states",
                   f"{name}_params", diag, from_design(module),
                   (_source(module), "derivation/design.py"), module)


def _source(module: ModuleType) -> str:
    """The module's file relative to the repository (derivation/<name>.py)."""
    path = Path(module.__file__).resolve()
    try:
        return str(path.relative_to(Path(__file__).resolve().parent.parent))
    except ValueError:  # a module outside the repository (a test's): its file name
        return path.name


def design_translator(module, sym: dict) -> tuple[Translator, object]:
    """SX for every symbol a :class:`derivation.design.ControllerDesign` may use (bound by
    name at the uniform inputs, plus any extra SX in ``sym`` such as true rates for the
    verification functions), its intermediates (κ) bound in order."""
    d = module.derive()
    params = {e.name: sym["p_ctrl"][k] for k, e in enumerate(module.PARAMS)}
    states = {e.name: sym["x_ctrl"][k] for k, e in enumerate(module.STATES)}
    meas = {n: sym["meas"][k] for k, n in enumerate(MEAS)}
    kf = sym["known_fault"]
    names = {**meas, **{f"yd_{m}": sym["yd"][m] for m in range(len(lay.REFERENCE))},
             **{n: sym["sched"][k] for k, n in enumerate(SCHED)}, **params, **states,
             **{f"{kind}_{j + 1}": kf[k * lay.N_BLADES + j]
                for k, kind in enumerate(("rho_hat", "lock_hat", "ubar_hat"))
                for j in range(lay.N_BLADES)},
             **{s.name: sym[s.name] for s in d.check_inputs if s.name in sym}}
    tr = Translator(names)
    for s, e in d.signals:
        tr.symbols[s.name] = tr(e)
    bases, groups = d.fuzzy_systems()
    if bases:
        fz = FuzzyEvaluator(ca.vertcat(*[tr.symbols[n] for n in d.fuzzy_inputs]), params,
                            [ca.vertcat(*[states[w] for w in g]) for g in groups])
        tr.symbols.update(fz.symbol_values(bases))
    for s, e in d.intermediates:
        tr.symbols[s.name] = tr(e)
    return tr, d


def from_design(module) -> Callable:
    """The build function of a controller derived as a ControllerDesign."""
    def build(sym: dict) -> dict:
        tr, d = design_translator(module, sym)
        v = (ca.vertcat(*[tr(e) for e in d.v]) if isinstance(d.v, list)
             else ca.repmat(tr(d.v), lay.N_BLADES, 1))
        return {"v": v,
                "x_ctrl_dot": ca.vertcat(*[tr(e) for e in d.x_dot]), "u0": tr(d.u0),
                "diag": ca.vertcat(*[tr(e) for e in d.diag]),
                "x0": ca.vertcat(*[tr(e) for e in d.x0])}
    return build


EXTERNAL_STATES = [lay.Entry("external_hold", 0.0, "-", "unused (a controller has a state)")]
EXTERNAL_PARAMS = [lay.Entry(f"external_pitch_cmd_{j}", 0.0, "rad",
                             f"pitch command of blade {j}, held over the call")
                   for j in range(1, lay.N_BLADES + 1)]


def _external(sym: dict) -> dict:
    """Commands from outside the compiled loop (ROSCO's libdiscon, wtftc/sim/rosco.py), held
    over one call: the plant, the FDI and the measurements still run compiled."""
    v = sym["p_ctrl"][:lay.N_BLADES]
    return {"v": v, "x_ctrl_dot": ca.SX(1, 1), "u0": ca.sum1(v) / lay.N_BLADES,
            "diag": ca.vertcat(v, 0), "x0": ca.DM.zeros(1)}


REGISTRY: dict[str, Controller] = {
    "paper": Controller(
        "paper", "Bakhshi & Alfi (2020) observer-based adaptive fuzzy backstepping, eq (49)",
        paper_design.STATES, paper_design.PARAMS, "controller_states", "controller_params",
        [(e.name, e.unit) for e in lay.CONTROLLER_STATES[:N_DIAG]],
        from_design(paper_design),
        (_source(paper_design), "derivation/design.py", "derivation/backstepping.py",
         "derivation/observer.py"), paper_design,
        # the least-squares window stays 2 s after a detection: eq (49) divides by ρ̂, and
        # the estimates of the shorter window (0.5 s) doubled this design's RMS speed error
        # after the default fault at 16 m/s, realistic profile (0.024 to 0.048 rad/s;
        # the physical AFTC's fell 5 %: docs/fdi.md)
        fdi={"fdi_T_w_fault": 2.0}),
    "pi": Controller.derived(
        "pi", "gain-scheduled PI on collective pitch with anti-windup (baseline, "
              "Jonkman 2009 / ROSCO)",
        pi_baseline, [("speed_error", "rad/s"), ("integrator", "rad"), ("Kp", "s"), ("Ki", "-")]),
    "physical": Controller.derived(
        "physical", "physically consistent adaptive fuzzy backstepping AFTC, ω_r ← β ← u, "
                    "scheduled ∂T/∂β, anti-windup, eq (49)-style accommodation (ours)",
        physical, [("z1", "rad/s"), ("z2", "rad"), ("alpha1", "rad"), ("kappa", "-")]),
    "drivetrain": Controller.derived(
        "drivetrain", "adaptive fuzzy backstepping AFTC through the drivetrain, "
                      "ω_g - (d_s/J_g)θ_s ← θ_s ← ω_r ← β ← u, scheduled ∂T/∂β, anti-windup, "
                      "eq (49)-style accommodation (ours)",
        drivetrain, [("z1", "rad/s"), ("z3", "rad/s"), ("z4", "rad"), ("kappa", "-")]),
    "external": Controller(
        "external", "pitch commands from outside the compiled loop (ROSCO's libdiscon)",
        EXTERNAL_STATES, EXTERNAL_PARAMS, "external_states", "external_params",
        [*[(f"pitch_cmd_{j}", "rad") for j in range(1, lay.N_BLADES + 1)], ("unused", "-")],
        _external),
}


def build() -> list[ca.Function]:
    """ctrl_<name> and init_<name> for every registered controller."""
    out = []
    for c in REGISTRY.values():
        sym = {"x_ctrl": ca.SX.sym("x_ctrl", len(c.states)),
               "meas": ca.SX.sym("meas", len(MEAS)),
               "yd": ca.SX.sym("yd", len(lay.REFERENCE)),
               "sched": ca.SX.sym("sched", len(SCHED)),
               "p_ctrl": ca.SX.sym("p_ctrl", len(c.params)),
               "known_fault": ca.SX.sym("known_fault", len(lay.FAULT_INPUTS))}
        res = c.build(sym)
        ins = ["x_ctrl", "meas", "yd", "sched", "p_ctrl", "known_fault"]
        outs = {"v": res["v"], "x_ctrl_dot": res["x_ctrl_dot"], "u0": res["u0"],
                "diag": res["diag"]}
        out.append(ca.Function(f"ctrl_{c.name}", [sym[k] for k in ins],
                               joint_cse(list(outs.values())), ins, list(outs)))
        out.append(ca.Function(f"init_{c.name}", [sym["meas"], sym["sched"], sym["p_ctrl"]],
                               [ca.densify(ca.SX(res["x0"]))], ["meas", "sched", "p_ctrl"],
                               ["x_ctrl0"]))
    return out + build_verification()


def sources() -> list[str]:
    """The derivation modules behind the controllers group (for the artefact headers)."""
    out = ["derivation/controllers.py", "derivation/casadi_build.py", "derivation/fuzzy.py",
           "derivation/backstepping.py", "derivation/observer.py"]
    for c in REGISTRY.values():
        out += [m for m in c.sources if m not in out]
    return out


def _fdi_overrides(c: Controller) -> dict[str, float]:
    names = {e.name for e in fdi_module.PARAMS}
    unknown = set(c.fdi) - names
    if unknown:
        raise ValueError(f"controller {c.name}: unknown FDI parameters {sorted(unknown)}")
    return dict(c.fdi)


def as_json() -> dict:
    return {
        "controllers": {c.name: {"function": f"ctrl_{c.name}", "init": f"init_{c.name}",
                                 "states": c.states_group, "params": c.params_group,
                                 "diag": [n for n, _ in c.diag],
                                 "diag_units": [u for _, u in c.diag], "doc": c.doc,
                                 "fdi": _fdi_overrides(c)}
                        | _checks_json(c)
                        for c in REGISTRY.values()},
        "measurements": [{"name": n, "unit": u, "sample": list(r)}
                         for n, u, r in zip(MEAS, MEAS_UNITS, MEAS_SAMPLES, strict=True)],
        "schedule": SCHED,
        "groups": {f"{c.states_group}": c.states for c in REGISTRY.values()
                   if c.states_group != "controller_states"}
        | {f"{c.params_group}": lay.with_controller_ranges(c.params) for c in REGISTRY.values()
           if c.params_group != "controller_params"},
    }


def _checked(c: Controller) -> bool:
    """Whether c is a derived design with checks (α_i, α̇_i) and a design model for them."""
    return c.design is not None and hasattr(c.design, "design_model")


def _checks_json(c: Controller) -> dict:
    """Where a derived design's verification functions are and how to drive its model."""
    if not _checked(c):
        return {}
    return {"checks": f"alpha_{c.name}",
            "model": {"function": f"closed_loop_{c.name}_model",
                      "states": [e.as_json() for e in c.design.MODEL_STATES],
                      "residual": c.design.MODEL_RESIDUAL.as_json()}}


def build_verification() -> list[ca.Function]:
    """alpha_<name> and closed_loop_<name>_model of every derived design with checks."""
    return [f for c in REGISTRY.values() if _checked(c) for f in design_checks(c.name, c.design)]


def design_checks(name: str, module) -> list[ca.Function]:
    """alpha_<name>: the design's named check expressions (α_i, α̇_i full and computable,
    ...) at the uniform inputs plus the true rates; closed_loop_<name>_model: the module's
    design model closed by the controller (z = [model states, controller states]), with
    the true rates along it, for finite-difference checks of the α̇_i."""
    d = module.derive()
    n_x = len(module.STATES)
    sym = {"x_ctrl": ca.SX.sym("x_ctrl", n_x), "meas": ca.SX.sym("meas", len(MEAS)),
           "yd": ca.SX.sym("yd", len(lay.REFERENCE)), "sched": ca.SX.sym("sched", len(SCHED)),
           "p_ctrl": ca.SX.sym("p_ctrl", len(module.PARAMS)),
           "known_fault": ca.DM([e.default for e in lay.FAULT_INPUTS]),
           **{s.name: ca.SX.sym(s.name) for s in d.check_inputs}}
    tr, _ = design_translator(module, sym)
    ins = ["x_ctrl", "meas", "yd", "sched", "p_ctrl", *[s.name for s in d.check_inputs]]
    alpha = ca.Function(f"alpha_{name}", [sym[k] for k in ins],
                        [ca.cse(tr(e)) for e in d.checks.values()], ins, list(d.checks))
    dist = sp.Symbol("dm_residual", real=True)
    dm = module.design_model(dist)
    n_m = len(dm["states"])
    z = ca.SX.sym("z", n_m + n_x)
    dsx = ca.SX.sym("d")
    base = {**{s.name: z[k] for k, s in enumerate(dm["states"])}, dist.name: dsx,
            **{n: sym["sched"][k] for k, n in enumerate(SCHED)},
            **{e.name: sym["p_ctrl"][k] for k, e in enumerate(module.PARAMS)}}
    trm = Translator(base)
    s2 = {**sym, "x_ctrl": z[n_m:], "meas": ca.vertcat(*[trm(dm["meas"][n]) for n in MEAS])}
    for s in d.check_inputs:
        s2[s.name] = trm(dm["true_rates"][s.name])
    tr2, _ = design_translator(module, s2)
    zdot = ca.vertcat(*[trm(e) for e in dm["rates"]],
                      (tr2(d.u0) - trm(dm["beta_mean"])) / trm(dm["tau"]),
                      *[tr2(e) for e in d.x_dot])
    true = ca.vertcat(*[s2[s.name] for s in d.check_inputs])
    loop = ca.Function(f"closed_loop_{name}_model",
                       [z, dsx, sym["yd"], sym["sched"], sym["p_ctrl"]],
                       [ca.cse(zdot), ca.cse(true), s2["meas"]],
                       ["z", "d", "yd", "sched", "p_ctrl"], ["z_dot", "true_rates", "meas"])
    return [alpha, loop]
