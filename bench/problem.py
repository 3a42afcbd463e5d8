"""The benchmark's closed loops, and their inputs as functions of time.

Every method of `make bench` integrates the same problem: the right-hand side of
:func:`wtftc.sim.rhs.rhs_function` (plant, Cp interpolant, pitch-sensitivity schedule,
controller; without the FDI monitor, which the benchmarked case does not use), from the
trimmed initial state of :func:`wtftc.sim.trim.trim`, with the wind and the faults of the
configuration below as functions of time. Faults lock at a fixed angle (not "where the
blade is"), so that the inputs depend on time only.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property

import casadi as ca
import numpy as np

from wtftc import config
from wtftc.artefacts import layout as lay
from wtftc.model.faults import Schedule
from wtftc.sim import integrate, rhs

T_FINAL_S = 60.0
ONSET_S = 20.0
#: the paper's case 3 fault pattern (blade 1 locked, blades 2-3 at half effectiveness),
#: locked at 10° (about the trim pitch at 16 m/s) instead of "where it is"
FAULTS = [
    {"blade": 1, "type": "lock", "angle_deg": 10.0, "onset_s": ONSET_S},
    {"blade": 2, "type": "loss_of_effectiveness", "rho": 0.5, "onset_s": ONSET_S},
    {"blade": 3, "type": "loss_of_effectiveness", "rho": 0.5, "onset_s": ONSET_S},
]
WIND = {"kind": "ntm", "mean_mps": 16.0, "turbulence_class": "B"}
#: benchmarked loops: name -> (controller, plant)
LOOPS = {
    "paper_case3": ("paper", "nrel5mw"),
    "physical_case3": ("physical", "nrel5mw"),
}


@dataclass
class Problem:
    """One benchmark loop: ż = f(t, z) with every input resolved from t."""

    name: str
    controller: str
    plant: str
    t_final: float = T_FINAL_S

    @cached_property
    def config(self) -> config.RunConfig:
        return config.make_config({"controller": self.controller, "plant": self.plant,
                                  "case": 3, "t_final_s": self.t_final, "fault": FAULTS,
                                  "wind": WIND, "seed": 0,
                                  # the hand-written loops have the fixed rated torque
                                  "turbine_params": {"gen_torque_law": 0.0}})

    @cached_property
    def schedule(self) -> Schedule:
        return Schedule(list(self.config.faults), self.config.loop.p_turbine)

    @cached_property
    def rhs(self) -> ca.Function:
        """ż = f(z, wind, actuator_faults, sensor_faults, ctrl_fault, yd, p_turbine,
        p_ctrl), the FDI left out."""
        rc = self.config
        return rhs.rhs_function(replace(rc.loop, fdi=False))

    @cached_property
    def z0(self) -> np.ndarray:
        z = self.config.initial_state()
        return z[:self.n_states]

    @property
    def n_states(self) -> int:
        return self.rhs.size1_in("z")

    @cached_property
    def yd(self) -> np.ndarray:
        yd = np.zeros(len(lay.names("reference")))
        yd[0] = self.config.reference
        return yd

    def inputs(self, t) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(wind, actuator faults, sensor faults, faults told to eq (49)) at times t; the
        plant's faults and eq (49)'s are the same in case 3."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        af = self.schedule.actuator(t)
        return (self.config.wind(t), af, self.schedule.sensor(t),
                af[lay.prefix("fault_inputs", of="actuator_faults")])

    @property
    def events(self) -> list[float]:
        """Times where the inputs jump (the fault onsets): integrate across them in pieces."""
        return sorted({f.onset_s for f in self.config.faults})

    def segments(self, t_final: float | None = None) -> list[tuple[float, float]]:
        """[t_a, t_b] pieces between the events, over [0, t_final]."""
        t_final = self.t_final if t_final is None else t_final
        cuts = [0.0, *[e for e in self.events if 0 < e < t_final], t_final]
        return list(zip(cuts[:-1], cuts[1:], strict=True))

    def rhs_numpy(self, segment: int | None = None):
        """f(t, z) -> ż for SciPy, on the compiled right-hand side (buffer calls, the
        piecewise-constant faults of segment k, or looked up by t when None: then t at an
        event takes the inputs after it)."""
        f = integrate.Buffered(integrate.compiled(self.rhs, f"bench_rhs_{self.name}", quiet=True))
        rc = self.config
        bounds = np.array(self.events)
        mids = np.concatenate([[0.0], bounds]) + 1e-9
        seg_inputs = [[a[:, 0] for a in self.inputs(m)[1:]] for m in mids]
        wind = rc.wind
        p_sensors = lay.defaults("sensor_params")  # exact sensors: the continuous loop

        def fun(t, z):
            k = int(np.searchsorted(bounds, t, side="right")) if segment is None else segment
            af, sf, ck = seg_inputs[k]
            return f(z, float(wind(t)), af, sf, ck, self.yd, rc.p_turbine, p_sensors,
                     rc.p_ctrl, 1.0)[0][:, 0]
        return fun
