"""The tower plant (derivation/turbine.py ``tower_rhs``; docs/loads.md): the first
fore-aft mode's frequency and damping, the aerodynamic damping the thrust adds through the
relative wind, the static deflection, the rigid-tower limit, and the tower-base moment's
fatigue in metrics.json."""

from __future__ import annotations

import math
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from wtftc import config
from wtftc.artefacts import layout as lay
from wtftc.artefacts.loader import load
from wtftc.campaign import cases
from wtftc.model import turbine_file
from wtftc.results import loads
from wtftc.results.metrics import metrics

TOWER = ("tower_x", "tower_v")


def _frequency_hz(turbine: str) -> float:
    v = turbine_file.load(turbine).values
    return math.sqrt(v["tower_stiffness"] / v["tower_modal_mass"]) / (2 * math.pi)


#: OpenFAST 5.0.0's first tower fore-aft mode with wtftc's degrees of freedom (generator,
#: drivetrain, first tower fore-aft; rigid blades), 16 m/s: `wtftc modes --dofs rigid`
#: (docs/validation.md, "Modes against OpenFAST's linearization")
OPENFAST_RIGID_TOWER_HZ = {"nrel5mw": 0.3264, "iea15mw": 0.2331}


def test_the_towers_first_fore_aft_frequency_is_elastodyns():
    """The tower's modal mass and stiffness as ElastoDyn's equations have them (the
    rotor-nacelle assembly moving and tilting with the top, gravity's destiffening):
    0.3281 Hz on the NREL 5-MW (Jonkman 2009, Table 9-1: 0.324 Hz with flexible blades,
    not rotating), 0.2360 Hz on the IEA 15-MW clamped at 15 m; each within 1.5 % of
    OpenFAST's rigid-blade linearization (Rayleigh's quotient on the tower alone was 6 %
    and 12 % high). 1 % damping; the rotor 89.56 m over the NREL 5-MW's base."""
    for name, openfast_hz in OPENFAST_RIGID_TOWER_HZ.items():
        assert _frequency_hz(name) == pytest.approx(openfast_hz, rel=0.015), name
    assert _frequency_hz("nrel5mw") == pytest.approx(0.3281, abs=5e-4)
    assert _frequency_hz("iea15mw") == pytest.approx(0.2360, abs=5e-4)
    v = turbine_file.load("nrel5mw").values
    assert v["tower_damping_ratio"] == 0.01
    assert v["tower_moment_arm"] == pytest.approx(87.6 + 1.96256)


def test_import_reads_the_tower_from_the_elastodyn_files():
    """``turbine import`` computes the modal mass and stiffness from ElastoDyn's tower file
    (mode shape, mass and stiffness distributions) and main file (the assembly on top):
    both shipped turbines hold what it computes; the bending part alone is Rayleigh's
    quotient (0.3465 Hz on the NREL 5-MW with the assembly as a point mass)."""
    pytest.importorskip("openfast_io", reason="the import extra (make setup installs it)")
    from wtftc.model.turbine_import import read_deck

    for name in ("nrel5mw", "iea15mw"):
        got, src = read_deck(config.openfast_deck(turbine_file.load(name)))
        shipped = turbine_file.load(name).values
        for key in ("tower_modal_mass", "tower_stiffness", "tower_damping_ratio",
                    "tower_moment_arm"):
            assert got[key] == pytest.approx(shipped[key], rel=1e-9), (name, key)
    nrel, src = read_deck(config.openfast_deck(turbine_file.load("nrel5mw")))
    assert "(1.91269e+06 N/m)" in src["tower_stiffness"]
    assert "0.3281 Hz" in src["tower_stiffness"]
    assert math.sqrt(1.91269e6 / 403589.3) / (2 * math.pi) == pytest.approx(0.3465, abs=5e-4)


def _tower_jacobian(wind: float, ct: float) -> tuple[np.ndarray, dict]:
    """∂(ẋ_t, v̇_t)/∂(x_t, v_t) of the generated plant at a point, Ct held."""
    f = load("turbine_tower", "interpreted")
    states = lay.names("tower_states")
    x = ca.SX.sym("x", len(states))
    pt = lay.defaults("turbine_params")
    out = f(x_plant=x, v=ca.DM.zeros(3), wind=wind, cp=0.45, ct=ct,
            actuator_faults=lay.defaults("actuator_faults"), p_turbine=pt)["x_plant_dot"]
    idx = [states.index(n) for n in TOWER]
    jac = ca.Function("j", [x], [ca.jacobian(out[idx], x[idx])])
    x0 = lay.defaults("tower_states")
    x0[states.index("omega_r")] = x0[states.index("omega_g")] = 1.2
    return np.array(jac(x0)), lay.values("turbine_params", pt)


def test_the_free_tower_rings_at_its_frequency_with_its_damping():
    """With no thrust (Ct = 0) the tower is the modal oscillator: eigenvalues
    −ζω ± iω√(1 − ζ²) with ω = √(k/m)."""
    jac, tp = _tower_jacobian(12.0, 0.0)
    lam = np.linalg.eigvals(jac)
    w = math.sqrt(tp["tower_stiffness"] / tp["tower_modal_mass"])
    z = tp["tower_damping_ratio"]
    assert sorted(lam.imag) == pytest.approx([-w * math.sqrt(1 - z * z),
                                              w * math.sqrt(1 - z * z)], rel=1e-12)
    assert lam.real == pytest.approx([-z * w, -z * w], rel=1e-12)


@pytest.mark.parametrize("wind, ct", [(8.0, 0.8), (16.0, 0.2)])
def test_the_thrust_damps_the_tower_through_the_relative_wind(wind, ct):
    """The rotor sees v − ẋ_t: a tower moving upwind meets more thrust, so the thrust
    adds the aerodynamic damping ∂F/∂ẋ_t = ρ π R² v Ct (Ct held) to the structure's
    2ζ√(km): at 8 m/s (Ct 0.8) about 5 times the structural damping, a damping ratio
    of 5.4 % against 1 %."""
    jac, tp = _tower_jacobian(wind, ct)
    m = tp["tower_modal_mass"]
    c_struct = 2 * tp["tower_damping_ratio"] * math.sqrt(tp["tower_stiffness"] * m)
    c_aero = tp["air_density"] * math.pi * tp["rotor_radius"] ** 2 * wind * ct
    assert -jac[1, 1] * m == pytest.approx(c_struct + c_aero, rel=1e-12)
    assert jac[1, 0] * m == pytest.approx(-tp["tower_stiffness"], rel=1e-12)
    if wind == 8.0:
        assert c_aero / (2 * math.sqrt(tp["tower_stiffness"] * m)) == pytest.approx(0.0545,
                                                                                   abs=1e-3)


RUN = {"plant": "tower", "controller": "pi", "t_final_s": 30.0, "output_rate_hz": 100.0,
       "wind": {"kind": "constant", "speed_mps": 16.0}}


def test_a_trimmed_tower_stays_bent_by_the_thrust():
    """In a steady wind the trim bends the tower by F_T / k_t and it stays there: the
    tower-top moves less than 1 mm, the base moment is k_t x_t H, 30 MN m at 16 m/s."""
    rc = config.make_config(RUN)
    res = cases.run(rc, progress=False)
    tp = lay.values("turbine_params", rc.p_turbine)
    x, thrust = res.column("tower_x"), res.column("thrust")
    assert np.ptp(x) < 1e-3
    assert x[-1] == pytest.approx(thrust[-1] / tp["tower_stiffness"], rel=1e-3)
    assert res.column("M_tower") == pytest.approx(
        tp["tower_stiffness"] * tp["tower_moment_arm"] * x, rel=1e-12)
    assert 2.0e7 < res.column("M_tower")[-1] < 4.5e7


def test_a_stiff_tower_is_the_two_mass_plant():
    """With the tower 10⁴ times stiffer (its top moves micrometres) the rotor speed under
    turbulence is the nrel5mw plant's within 1e-5 rad/s."""
    over = {"wind": {"kind": "ntm", "mean_mps": 16.0, "turbulence_class": "B"},
            "t_final_s": 20.0}
    stiff = dict(config.make_config({**RUN, **over}).raw.get("turbine_params", {}))
    k = turbine_file.load("nrel5mw").values["tower_stiffness"] * 1e4
    tower = cases.run(config.make_config({**RUN, **over, "turbine_params": {
        **stiff, "tower_stiffness": k}}), progress=False)
    rigid = cases.run(config.make_config({**RUN, **over, "plant": "nrel5mw"}),
                      progress=False)
    assert np.max(np.abs(tower.column("omega_r") - rigid.column("omega_r"))) < 1e-5
    assert np.max(np.abs(tower.column("tower_v"))) < 1e-3


def test_metrics_count_the_tower_base_moment():
    """metrics.json's tower-base DEL is the rainflow DEL of the M_tower trace with the
    [loads] tower exponent, over the run after its start-up window (issue 31), here
    written at every step so that the trace is what the metrics read; a plant without a
    tower has none."""
    rc = config.make_config({**RUN, "wind": {"kind": "ntm", "mean_mps": 16.0},
                             "loads": {"tower_wohler_exponent": 3.0}})
    rc = config.make_config({**RUN, "wind": {"kind": "ntm", "mean_mps": 16.0},
                             "loads": {"tower_wohler_exponent": 3.0},
                             "output_rate_hz": 1.0 / rc.dt})
    res = cases.run(rc, progress=False)
    m = metrics(rc, res)
    scored = res.t >= m["transient_s"]
    moment = res.column("M_tower")[scored]
    assert m["tower_wohler_exponent"] == 3.0
    assert m["tower_base_del_1hz_Nm"] == pytest.approx(
        loads.del_1hz(moment, scored.sum() * rc.dt, 3.0), rel=1e-9)
    assert m["tower_base_max_abs_Nm"] == pytest.approx(np.max(np.abs(moment)), rel=1e-12)
    assert 0 < m["tower_base_del_1hz_Nm"] < m["tower_base_max_abs_Nm"]
    rigid = config.make_config({**RUN, "plant": "nrel5mw", "t_final_s": 2.0})
    m2 = metrics(rigid, cases.run(rigid, progress=False))
    assert m2["tower_base_del_1hz_Nm"] is None and m2["tower_base_max_abs_Nm"] is None


def test_a_table_without_ct_is_refused_on_the_tower_plant(tmp_path):
    """The tower plant needs the thrust coefficient: a Cp-only table is refused naming it."""
    from wtftc.errors import ConfigError
    from wtftc.model.aero import cp_interpolant
    from wtftc.model.cp_table import read_cp_table

    src = Path(turbine_file.load("nrel5mw").cp_path).read_text().splitlines()
    cut = next(i for i, ln in enumerate(src) if "Thrust" in ln)
    end = next(i for i, ln in enumerate(src) if "Torque" in ln)
    path = tmp_path / "cp_only.txt"
    path.write_text("\n".join(src[:cut] + src[end:]) + "\n")
    table = read_cp_table(path)
    assert table.ct is None
    with pytest.raises(ConfigError, match="CT block"):
        cp_interpolant(table, "ct")


def test_each_blade_carries_its_share_of_cp_and_ct_at_its_own_pitch():
    """Per-blade aerodynamics (issue 18): on the tower plant the rotor's Cp and Ct are the
    mean of the table at each blade's (λ, β_j). With blade 2 run away to feather the blades
    differ by up to 90°, and the reported Cp and Ct are that mean to 1e-12, not the table
    at the mean pitch (which differs by more than 0.05 in Cp)."""
    from wtftc.model.aero import cp_interpolant
    rc = config.make_config({**RUN, "wind": {"kind": "constant", "speed_mps": 10.0},
                             "t_final_s": 20.0, "case": 2, "fault": [
                                 {"blade": 2, "type": "runaway", "onset_s": 5.0,
                                  "target_deg": 90.0}]})
    res = cases.run(rc, progress=False)
    tsr, betas = res.column("tsr"), [res.column(f"beta_{j}") for j in lay.blades()]
    for q in ("cp", "ct"):
        fn = cp_interpolant(rc.table, q)
        per_blade = np.mean([np.array(fn(tsr, b)).ravel() for b in betas], axis=0)
        at_mean = np.array(fn(tsr, np.mean(betas, axis=0))).ravel()
        assert np.max(np.abs(res.column(q) - per_blade)) < 1e-12
        if q == "cp":
            assert np.max(np.abs(res.column(q) - at_mean)) > 0.05


@pytest.mark.parametrize(("plant", "held"), [("tower", True), ("nrel5mw", False)])
def test_a_rotor_with_one_blade_feathered_is_held_only_with_per_blade_aerodynamics(plant,
                                                                                  held):
    """A runaway to feather at 6 m/s (DLC 2.1): with each blade's share of the torque at
    its own pitch, the two blades left at fine pitch keep the rotor turning (the physical
    AFTC with its own FDI, realistic profile), but only idling: the feathered blade, read
    at the table's 30°, brakes it to about 40 % of rated speed, below the torque law's
    cut-in, and no power is made. Read at the mean pitch (the two-mass plant, the paper's
    model) one feathered blade counts as all three at 30° and the rotor stalls out of the
    envelope (below 0.3 × rated): the limit docs/loads.md names."""
    rc = config.make_config({
        "controller": "physical", "case": 4, "plant": plant, "profile": "realistic",
        "t_final_s": 80.0, "wind": {"kind": "ntm", "mean_mps": 6.0, "rotor_radius_m": 63.0},
        "turbine_params": {"gen_torque_law": 1.0},
        "fault": [{"blade": 2, "type": "runaway", "onset_s": 30.0, "target_deg": 90.0}]})
    res = cases.run(rc, progress=False)
    m = metrics(rc, res)
    assert (m["diverged"] is None) == held
    if held:
        post = res.t > 50.0
        rated = rc.p_turbine[lay.index("turbine_params", "omega_g_rated")]
        speed = res.column("omega_r")[post]
        assert 0.3 * rated < speed.min() and speed.mean() < 0.5 * rated
        assert np.mean(res.column("P_gen")[post]) < 0.02 * np.mean(
            res.column("P_gen")[res.t < 30.0])
