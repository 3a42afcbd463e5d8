"""Finite-difference checks of every controller derived as a ControllerDesign.

For each registered controller whose layout entry names ``checks`` (``alpha_<name>``: the
α_i, their total derivatives α̇_i and the computable parts) and a ``model``
(``closed_loop_<name>_model``: the design model closed by the controller, with the true
rates and the measurements along it), :func:`alpha_dot_fd` integrates the model by RK4
and compares central differences of every α_i with the generated α̇_i over a ladder of
steps h: the error must fall as O(h²). Nothing here knows a controller by name: the
registry (generated/layout.json) says what to check and where the model starts.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wtftc.artefacts import layout as lay
from wtftc.artefacts.loader import load
from wtftc.sim.integrate import rk4_path
from wtftc.verify.checks import Signals

#: the runtime inputs during the checks: ∂T_aero/∂β [N m/rad], the NREL 5-MW near 12 m/s
#: (docs/paper-notes.md, defect 2), constant so that its rate (b_dot) is zero; the tower-top
#: fore-aft acceleration [m/s^2], constant and not zero, so that a tower damper's state
#: moves along the checks (with the gain of 0.05 rad s/m the tests use, its 0.03-rad
#: pitch reaches about 0.7° in the first second, within its ±2° clip)
SCHED = np.array([-9.0e6, 0.3])
#: the reference's swing during the checks: y_d = y_d,default + A sin(W t)
REF_AMPLITUDE, REF_FREQUENCY = 0.01, 0.7  # rad/s, rad/s
#: the residual's swing: d = d_default + (half its sample range) sin(D t)
RESIDUAL_FREQUENCY = 1.1  # rad/s
H_VALUES = (1e-2, 3e-3, 1e-3, 3e-4, 1e-4, 3e-5, 1e-5)


def derived() -> list[str]:
    """The registered controllers that carry generated checks and a design model."""
    return [c for c, reg in lay.layout()["controllers"].items() if "checks" in reg]


@dataclass
class DesignModel:
    """A derived controller's design model and checks, with the signals that drive them."""

    controller: str
    #: parameters other than the defaults, by name (a design's option switched on)
    params: dict[str, float] | None = None

    def __post_init__(self):
        reg = lay.layout()["controllers"][self.controller]
        if "checks" not in reg:
            raise KeyError(f"{self.controller!r} is not derived as a ControllerDesign; "
                           f"derived: {', '.join(derived())}")
        self.model = load(reg["model"]["function"])
        self.checks = load(reg["checks"])
        self.n_model = len(reg["model"]["states"])
        res = reg["model"]["residual"]
        self.d0, self.d_amp = res["default"], (res["sample"][1] - res["sample"][0]) / 2
        self.p_ctrl = lay.vector(reg["params"], self.params or {})
        self.y0 = lay.defaults("reference")[0]
        # the model at its defaults; the controller as a run starts it (init_<name>)
        x_model = np.array([e["default"] for e in reg["model"]["states"]])
        meas = self.evaluate(0.0, np.concatenate([x_model, lay.defaults(reg["states"])]))["meas"]
        x_ctrl = load(reg["init"])(meas=meas, sched=SCHED, p_ctrl=self.p_ctrl)["x_ctrl0"]
        self.z0 = np.concatenate([x_model, np.array(x_ctrl).ravel()])
        #: the α_i that have a generated total derivative α_i_dot_full
        self.alphas = [n for n in self.checks.name_out()
                       if f"{n}_dot_full" in self.checks.name_out()]
        #: the true rates the checks take besides the controller's uniform inputs
        self.rate_inputs = [n for n in self.checks.name_in()
                            if n not in ("x_ctrl", "meas", "yd", "sched", "p_ctrl")]

    def signals(self, t: float) -> tuple[np.ndarray, float]:
        yd = Signals(self.y0, REF_AMPLITUDE, REF_FREQUENCY).yd(t)
        return yd, self.d0 + self.d_amp * np.sin(RESIDUAL_FREQUENCY * t)

    def evaluate(self, t: float, z: np.ndarray) -> dict:
        yd, d = self.signals(t)
        return self.model(z=z, d=d, yd=yd, sched=SCHED, p_ctrl=self.p_ctrl)

    def rhs(self, t: float, z: np.ndarray) -> np.ndarray:
        return np.array(self.evaluate(t, z)["z_dot"]).ravel()

    def rk4(self, z: np.ndarray, t0: float, t1: float, n: int) -> np.ndarray:
        """The state after n RK4 steps from t0 to t1 (t1 < t0 runs backward)."""
        return rk4_path(self.rhs, z, t0, t1, n)[1][-1]

    def check_values(self, z: np.ndarray, t: float) -> dict[str, float]:
        """Every output of the checks function at model state z, with the true rates."""
        out = self.evaluate(t, z)
        yd, _ = self.signals(t)
        rates = np.array(out["true_rates"]).ravel()
        res = self.checks(x_ctrl=z[self.n_model:], meas=out["meas"], yd=yd, sched=SCHED,
                          p_ctrl=self.p_ctrl,
                          **dict(zip(self.rate_inputs, rates, strict=True)))
        return {k: float(v) for k, v in res.items()}


@dataclass
class DesignFD:
    controller: str
    alphas: list[str]
    h: np.ndarray
    errors: np.ndarray  # (len(h), len(alphas)): |FD - α̇| / |α̇|
    slopes: np.ndarray  # fitted log-log slope per α_i (2 for O(h²))
    alpha_dot: np.ndarray  # the generated α̇_i at the check point
    kappa: float  # the adaptation switch at the check point (1: integrating)


def alpha_dot_fd(controller: str, t_point: float = 1.0, h_values=H_VALUES,
                 substep: float = 2e-4, params: dict[str, float] | None = None) -> DesignFD:
    """Central differences of every α_i along the design model against the generated α̇_i.

    The model runs by RK4 from its start to ``t_point``; the states at t ± h are reached
    with steps ≤ ``substep``, so the integration error stays far below the differencing
    error. ``params`` overrides the design's defaults by name. Slopes are fitted where
    truncation dominates (:func:`_truncation_slope`).
    """
    m = DesignModel(controller, params)
    z = m.rk4(m.z0, 0.0, t_point, int(np.ceil(t_point / 5e-4)))
    at = m.check_values(z, t_point)
    exact = np.array([at[f"{a}_dot_full"] for a in m.alphas])
    h_values = np.asarray(h_values, dtype=float)
    errors = np.empty((h_values.size, len(m.alphas)))
    for i, h in enumerate(h_values):
        n = max(1, int(np.ceil(h / substep)))
        plus = m.check_values(m.rk4(z, t_point, t_point + h, n), t_point + h)
        minus = m.check_values(m.rk4(z, t_point, t_point - h, n), t_point - h)
        fd = np.array([(plus[a] - minus[a]) / (2 * h) for a in m.alphas])
        errors[i] = np.abs(fd - exact) / np.maximum(np.abs(exact), 1e-300)
    slopes = np.array([_truncation_slope(h_values, errors[:, k])
                       for k in range(len(m.alphas))])
    return DesignFD(controller, m.alphas, h_values, errors, slopes, exact,
                    at.get("kappa", 1.0))


def _truncation_slope(h: np.ndarray, err: np.ndarray) -> float:
    """The log-log slope of err(h) over the two decades below the largest h, where the
    truncation error (O(h²)) dominates: below them, rounding and the integration's own
    error (about 1e-9 relative here) flatten the curve before it turns up."""
    sel = h >= 1e-2 * h.max()
    return float(np.polyfit(np.log(h[sel]), np.log(err[sel]), 1)[0])
