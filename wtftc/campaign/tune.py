"""``wtftc turbine tune``: a controller's gains from a desired closed-loop mode (ours;
docs/turbines.md, "Tuning").

As ROSCO tunes its pitch PI, the designer chooses the natural frequency ω_n and damping ζ
of the speed loop's dominant mode, at a design wind above rated; the gains follow from the
turbine:

* **PI**: its law is this pole placement on a rigid rotor (K_p = 2ζω_n J/|∂T/∂β|,
  K_i = ω_n² J/|∂T/∂β|, scheduled), so ``pi_omega_n`` and ``pi_zeta`` are the targets;
* **physical AFTC**: its dominant mode is set by the backstepping gain c1 and the adaptive
  law's rate γ together (the adaptive law integrates the speed error: docs/turbines.md,
  "What it shows"); c2 = 3 c1 keeps the pitch loop three times faster than the speed
  loop. (c1, γ) are solved by Newton's method so that the dominant mode of the exact
  linear closed loop (wtftc.campaign.linearize) at the design wind has the target ω_n
  and ζ;
* the facts of the turbine (inertia, limits, actuator, the FDI's model) come from the
  turbine file for every controller (wtftc.model.tuning).

Each result is checked on the exact linear model: the achieved mode and the margins.
"""

from __future__ import annotations

import functools

import numpy as np

from wtftc import config
from wtftc import controller as settings
from wtftc.artefacts import layout as lay
from wtftc.campaign import linearize as lin
from wtftc.errors import ConfigError
from wtftc.model import tuning
from wtftc.sim.rhs import controllers

TUNABLE = ("physical", "pi")
#: c2 / c1 of the physical AFTC: the pitch loop faster than the speed loop. Revised from
#: 3 to 2 (issue 18): the sensor noise reaches the pitch command with a gain ∝ c1 c2, and
#: at 3 the tuned loop drove the drivetrain's 2.2-Hz mode above 20 m/s (docs/compare.md,
#: "Tuned families"); 2 is the lowest that still reaches ROSCO's (0.6, 0.7) at 16 m/s
C2_OVER_C1 = 2.0


#: the [tuning] table: the pitch loop's target mode, for every tunable controller alike
#: (docs/compare.md, "Tuned families"): key → (default, low, high)
TUNING_KEYS = settings.TUNING_KEYS
assert TUNING_KEYS["c2_over_c1"][0] == C2_OVER_C1


def _dominant(raw: dict, wind: float, z: np.ndarray) -> tuple[float, float, np.ndarray]:
    op = lin.operating_point(raw, wind, z)
    row = lin.summary_row(op)
    return row["dominant_omega_n_rad_s"], row["dominant_damping"], op.z


def _physical_raw(base: dict, c1: float, gamma: float, ratio: float = C2_OVER_C1) -> dict:
    return {**base, "controller_params": {**base.get("controller_params", {}),
                                          "phys_c1": c1, "phys_c2": ratio * c1,
                                          "phys_gamma": gamma}}


def _solve_physical(base: dict, wind: float, omega_n: float, zeta: float,
                    ratio: float = C2_OVER_C1) -> dict:
    """(c1, γ) by damped Newton on log-gains, the mode's sensitivities by differences;
    c2 = ``ratio`` c1."""
    x = np.log([2.0, 2.0])  # from the NREL 5-MW's hand choice
    z = lin.settle(_physical_raw(base, *np.exp(x), ratio), wind)
    target = np.array([omega_n, zeta])
    for _ in range(25):
        wn, ze, z = _dominant(_physical_raw(base, *np.exp(x), ratio), wind, z)
        r = np.array([wn, ze]) - target
        if np.abs(r / target).max() < 1e-4:
            break
        J = np.empty((2, 2))
        for k in range(2):
            dx = np.zeros(2)
            dx[k] = 1e-4
            wn2, ze2, _ = _dominant(_physical_raw(base, *np.exp(x + dx), ratio), wind, z)
            J[:, k] = (np.array([wn2, ze2]) - np.array([wn, ze])) / 1e-4
        step = np.linalg.lstsq(J, -r, rcond=None)[0]
        x = x + np.clip(step, -0.5, 0.5)
    else:
        raise ConfigError("--omega-n/--zeta", (omega_n, zeta), "a mode the physical AFTC "
                          f"reaches with c2 = {ratio:g} c1 (closest found: ω_n = "
                          f"{wn:.3g} rad/s, ζ = {ze:.3g})")
    c1, gamma = np.exp(x)
    return {"phys_c1": float(c1), "phys_c2": float(ratio * c1), "phys_gamma": float(gamma)}


def tune(controller: str, turbine: str | None, omega_n: float, zeta: float,
         wind: float, ratio: float = C2_OVER_C1, preset: str | None = None) -> dict:
    """The gains (``controller_params``), the turbine facts used, and the achieved mode
    and margins at ``wind`` on the exact linear model; ``preset``: retuned from that
    preset's settings (its design's gains replaced), and ``raw`` its [controller] table."""
    if preset is not None:
        controller = settings.preset(preset).design
        if controller not in TUNABLE:
            raise ConfigError("--preset", preset, "a preset of a design tuned here: "
                              + ", ".join(n for n, p in settings.presets().items()
                                          if p.design in TUNABLE))
    if controller not in TUNABLE:
        raise ConfigError("--controller", controller, "one of " + ", ".join(TUNABLE))
    for name, val, key in (("--omega-n", omega_n, "omega_n_rad_s"), ("--zeta", zeta, "zeta"),
                           ("--wind", wind, "design_wind_mps"), ("--c2-ratio", ratio,
                                                                  "c2_over_c1")):
        _, lo, hi = TUNING_KEYS[key]
        if not (lo <= val <= hi):
            raise ConfigError(name, val, f"a number in [{lo:g}, {hi:g}]")
    where = {"turbine": turbine} if turbine else {}
    base = {k: v for k, v in settings.expand({"controller": {"preset": preset}, **where})[0]
            .items() if k != "controller_preset"} if preset \
        else {"controller": controller, **where}  # (retuned: no longer the preset)
    rc = config.make_config(base)
    try:
        if controller == "pi":
            gains = {"pi_omega_n": omega_n, "pi_zeta": zeta}
        else:
            gains = _solve_physical(base, wind, omega_n, zeta, ratio)
        op = lin.operating_point({**base, "controller_params": {
            **base.get("controller_params", {}), **gains}}, wind)
    except lin.NotAtRest as exc:  # no operating point at the design wind
        raise ConfigError("--wind", wind, exc.allowed) from None
    group = controllers()[controller]["params"]
    values = lay.values(group, rc.p_ctrl)
    facts = tuning.turbine_params_of(group, rc.p_turbine)
    return {"gains": gains, "facts": {k: values[k] for k in facts},
            "achieved": lin.summary_row(op), "least_stable": lin.least_stable(op),
            "rated_wind_mps": config.rated_wind_speed(rc.loop.p_turbine, rc.loop.table),
            "raw": {**where, "controller": {"preset": preset, **gains}} if preset
            else {**base, "controller_params": gains}}


def check_stable(r: dict, omega_n: float, zeta: float, wind: float) -> None:
    """Refuse a tuning result (:func:`tune`) whose loop is not asymptotically stable on
    the exact linear model at ``wind``: a mode with ζ <= 0. ``wtftc turbine tune
    --omega-n 9 --zeta 0.7`` reached its dominant mode and wrote a design whose drivetrain
    mode had ζ -0.005 (gain margin -24 dB), exit 0 (issue 30)."""
    s, a = r["least_stable"], r["achieved"]
    if s["real"] < 0:
        return
    found = (f"this one has a mode of {s['omega_n_rad_s']:.4g} rad/s at ζ {s['damping']:.3g}, "
             f"gain margin {a['gain_margin_dB']:.3g} dB; nothing written")
    if wind < r["rated_wind_mps"]:  # the pitch rests at its stop: no pitch loop to tune
        raise ConfigError("--wind", wind, f"a design wind above the rated "
                          f"{r['rated_wind_mps']:.3g} m/s, where the pitch loop acts and "
                          f"can be stable (every mode ζ > 0); {found}")
    raise ConfigError("--omega-n/--zeta", (omega_n, zeta), "a target whose tuned loop is "
                      f"stable on the exact linear model at {wind:g} m/s (every mode ζ > 0; "
                      f"a lower --omega-n); {found}")


#: the controllers a [tuning] table retunes: ROSCO by its DISCON.IN's gain schedule, the
#: PI by its targets, the physical AFTC by (c1, γ) solved on the exact linear loop
RETUNABLE = settings.RETUNABLE


def resolve(cfg: dict) -> dict:
    """``cfg`` with its [tuning] table turned into the controller's own settings: ROSCO's
    [rosco] target, the PI's ``pi_omega_n``/``pi_zeta``, the physical AFTC's (c1, c2, γ)
    (:func:`_solve_physical` at the design wind, on the run's turbine; solved once per
    process and target). Without [tuning], ``cfg`` as it is. A [controller] table is
    turned into those keys first (wtftc.controller.expand)."""
    tab = cfg.get("controller")
    if isinstance(tab, dict) and not settings.parse(tab).tuning:
        return cfg  # (expanded by make_config, which names its keys controller.<key>)
    cfg, _ = settings.expand(cfg)
    if "tuning" not in cfg:
        return cfg
    tab, out = cfg["tuning"], {k: v for k, v in cfg.items() if k != "tuning"}
    if not isinstance(tab, dict) or set(tab) - set(TUNING_KEYS):
        raise ConfigError("tuning", tab, "a table with " + ", ".join(TUNING_KEYS))
    vals = {}
    for key, (default, lo, hi) in TUNING_KEYS.items():
        v = tab.get(key, default)
        if isinstance(v, bool) or not isinstance(v, int | float) or not lo <= v <= hi:
            raise ConfigError(f"tuning.{key}", v, f"a number in [{lo:g}, {hi:g}]")
        vals[key] = float(v)
    controller = cfg.get("controller", config.DEFAULTS["controller"])
    if controller not in RETUNABLE:
        raise ConfigError("tuning", tab, "controller = " + ", ".join(RETUNABLE) + " (the "
                          "designs tuned from a target mode)")
    w, z = vals["omega_n_rad_s"], vals["zeta"]
    if controller == "rosco":
        return out | {"rosco": {"omega_pc_rad_s": w, "zeta_pc": z}}
    gains = ({"pi_omega_n": w, "pi_zeta": z} if controller == "pi" else
             _physical_gains(cfg.get("turbine"), w, z, vals["design_wind_mps"],
                             vals["c2_over_c1"]))
    return out | {"controller_params": {**cfg.get("controller_params", {}), **gains}}


@functools.cache
def _physical_gains(turbine: str | None, omega_n: float, zeta: float, wind: float,
                    ratio: float = C2_OVER_C1) -> dict:
    base = {"controller": "physical", **({"turbine": turbine} if turbine else {})}
    try:
        import control  # noqa: F401 - the linear loop's modes (wtftc.campaign.linearize)
    except ImportError:
        raise ConfigError("tuning", {"omega_n_rad_s": omega_n, "zeta": zeta},
                          "python-control installed to tune the physical AFTC: pip install "
                          "'wtftc[linear]' (the control package)") from None
    try:
        return _solve_physical(base, wind, omega_n, zeta, ratio)
    except ConfigError as exc:
        raise ConfigError("tuning", {"omega_n_rad_s": omega_n, "zeta": zeta},
                          exc.allowed) from None
