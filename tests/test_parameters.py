"""Every accepted parameter is used (issue 14, "parameters that are silently ignored").

Each turbine parameter, changed alone, changes the run in a scenario where it acts: the
traces, or the mean electrical power for the generator efficiency (applied to the shaft
power in the metrics). The table must name every entry of the layout's turbine_params, so
a new parameter needs its scenario here. Every registered controller's parameter group,
changed as a whole, changes that controller's run.
"""

import numpy as np
import pytest

from wtftc.artefacts import layout as lay
from wtftc.campaign.cases import run
from wtftc.config import CONTROLLER_FLAGS, make_config
from wtftc.results.metrics import metrics
from wtftc.sim.rhs import controllers

COLUMNS = ("omega_r", "omega_g_hss", "beta_1", "beta_2", "P_gen", "T_gen")
#: the hub-height point series (not a run's default rotor average, issue 31): its
#: sub-rotor eddies reach the pitch-rate limit and the slip's corner in 8 s
NTM = {"kind": "ntm", "rotor_radius_m": 0.0}
SCENARIOS = {
    # above rated, a hydraulic fault on blade 2: the actuator's nominal dynamics matter
    # (the fixed torque pinned: this wind dips below rated, where a run would otherwise
    # take the baseline law)
    "above": {"controller": "physical", "case": 2, "t_final_s": 8.0,
              "wind": {**NTM, "mean_mps": 16.0, "turbulence_class": "B"},
              "fault": [{"blade": 2, "type": "pressure_drop", "onset_s": 2.0}],
              "turbine_params": {"gen_torque_law": 0.0}},
    # the baseline torque law above rated (its torque ceiling)
    "above_law": {"controller": "physical", "t_final_s": 8.0,
                  "wind": {**NTM, "mean_mps": 16.0},
                  "turbine_params": {"gen_torque_law": 1.0}},
    # below rated with the torque law: region 2 and its transitions
    "below": {"controller": "physical", "t_final_s": 8.0,
              "wind": {**NTM, "mean_mps": 7.0, "turbulence_class": "A"},
              "turbine_params": {"gen_torque_law": 1.0}},
    # near rated with the torque law: region 2½ and its corner with 3 (a run now starts at
    # its wind's operating point, issue 31: from rated speed the 7-m/s run swept 2½)
    "near_rated": {"controller": "physical", "t_final_s": 8.0,
                   "wind": {**NTM, "mean_mps": 11.0, "turbulence_class": "A"},
                   "turbine_params": {"gen_torque_law": 1.0}},
    "low": {"controller": "physical", "t_final_s": 8.0,
            "wind": {"kind": "constant", "speed_mps": 4.5},
            "turbine_params": {"gen_torque_law": 1.0}},
    # the tower plant's first fore-aft mode (its base moment among the traces)
    "tower": {"plant": "tower", "controller": "physical", "t_final_s": 8.0,
              "wind": {**NTM, "mean_mps": 16.0}},
    # the tower_edge plant's blades' edgewise mode (issue 33)
    "edge": {"plant": "tower_edge", "controller": "physical", "t_final_s": 8.0,
             "wind": {**NTM, "mean_mps": 16.0}},
    # eq (4)'s first-order pitch: only the paper's plant has it
    "paper_plant": {"plant": "paper", "controller": "paper", "t_final_s": 5.0},
}
#: parameter → (scenario, value it is changed to); None: 1.1 × its default
TURBINE = {
    "J_r": ("above", None), "J_g": ("above", None), "k_s": ("above", None),
    "d_s": ("above", None), "tau_b": ("paper_plant", 0.2), "air_density": ("above", None),
    "rotor_radius": ("above", None), "gearbox_ratio": ("above", 50.0),
    "gen_torque_rated": ("above", None), "gen_constant_power": ("above", 1.0),
    "omega_g_rated": ("above", None), "gen_efficiency": ("above", 0.9),
    "omega_n_nominal": ("above", None), "zeta_nominal": ("above", None),
    "pitch_min": ("below", 0.2), "pitch_max": ("above", 0.2),
    "pitch_rate_max": ("above", 0.04), "gen_torque_law": ("above", 1.0),
    "vs_cut_in_speed": ("low", 0.8), "vs_region2_speed": ("low", 1.0),
    "vs_region2_k": ("below", None), "vs_rated_speed": ("near_rated", None),
    "vs_slip": ("near_rated", None), "vs_rated_power": ("near_rated", None),
    "vs_max_torque": ("above_law", 3.5e6),
    "tower_modal_mass": ("tower", None), "tower_stiffness": ("tower", None),
    "tower_damping_ratio": ("tower", 0.05), "tower_moment_arm": ("tower", None),
    "edge_modal_mass": ("edge", None), "edge_stiffness": ("edge", None),
    "edge_damping_ratio": ("edge", 0.05), "edge_coupling_cos": ("edge", None),
    "edge_coupling_sin": ("edge", None), "edge_torque_share": ("edge", None),
    "vs_constant_torque": ("above_law", 1.0),
}


def _outcome(raw: dict) -> tuple[np.ndarray, float]:
    rc = make_config(raw)
    res = run(rc, progress=False)
    columns = COLUMNS + (("M_tower",) if rc.plant in ("tower", "tower_edge") else ())
    return (np.column_stack([res.column(c) for c in columns]),
            metrics(rc, res)["mean_electrical_power_W"])


_BASE: dict = {}


def _base(scenario: str):
    if scenario not in _BASE:
        _BASE[scenario] = _outcome(SCENARIOS[scenario])
    return _BASE[scenario]


def test_the_table_names_every_turbine_parameter():
    assert set(TURBINE) == set(lay.names("turbine_params"))


@pytest.mark.parametrize("key", sorted(TURBINE))
def test_each_turbine_parameter_changes_the_run(key):
    scenario, value = TURBINE[key]
    raw = SCENARIOS[scenario]
    default = lay.defaults("turbine_params")[lay.index("turbine_params", key)]
    value = 1.1 * default if value is None else value
    assert value != default
    traces, power = _outcome({**raw, "turbine_params": {**raw.get("turbine_params", {}),
                                                        key: value}})
    base_traces, base_power = _base(scenario)
    changed = np.max(np.abs(traces - base_traces)) > 0 or power != base_power
    assert changed, f"turbine_params.{key} = {value} left the {scenario} run unchanged"


@pytest.mark.parametrize("controller", sorted(c for c in controllers() if c != "external"))
def test_each_controllers_parameters_change_its_run(controller):
    group = controllers()[controller]["params"]
    raw = {**SCENARIOS["above"], "controller": controller}
    changed = {n: (0.9 if "pitch_max" in n else 1.1) * v if v else 0.05  # within ±90°
               for n, v in zip(lay.names(group), lay.defaults(group), strict=True)}
    # the peak-shaving start stays below the reference speed (refused at or above it)
    changed |= {n: 0.95 * v for n, v in zip(lay.names(group), lay.defaults(group), strict=True)
                if n.endswith("_ps_speed")}
    # a switch (0 or 1) is flipped
    changed |= {n: 1.0 - v for n, v in zip(lay.names(group), lay.defaults(group), strict=True)
                if n in CONTROLLER_FLAGS}
    changed = {n: v for n, v in changed.items()
               if not n.startswith(("rho_hat", "lock_hat", "ubar_hat", "control_sign"))}
    base, _ = _outcome(raw)
    traces, _ = _outcome({**raw, "controller_params": changed})
    assert np.max(np.abs(traces - base)) > 0
