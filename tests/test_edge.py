"""The tower_edge plant (derivation/turbine.py ``tower_edge_rhs``; docs/validation.md): the
blades' first edgewise mode, collective, in series with the shaft. Its drivetrain mode
against an independent three-inertia model and against OpenFAST's linearization, the
rigid-blade limit, the trim, and the import of the mode from ElastoDyn's blade file."""

from __future__ import annotations

import math

import numpy as np
import pytest

from wtftc import config
from wtftc.artefacts import layout as lay
from wtftc.campaign import cases
from wtftc.campaign.linearize import operating_point
from wtftc.campaign.validate import three_inertias_hz
from wtftc.model import turbine_file

#: OpenFAST 5.0.0's NREL 5-MW (ROSCO 2.10.6's deck, every ElastoDyn DOF), linearized at
#: steady 16 m/s, MBC3 over 12 azimuths: the mode where the generator swings against the
#: rotor (docs/validation.md, "Modes against OpenFAST's linearization")
OPENFAST_DRIVETRAIN_16_HZ = 1.6816


def _drivetrain_hz(plant: str, params: dict | None = None, wind: float = 16.0) -> tuple:
    """(frequency [Hz], damping ratio, pitch [rad]) of the open-loop plant's drivetrain
    mode at ``wind``: the oscillatory eigenvalue between 1 and 4 Hz that is not a pitch
    actuator's (those sit at ω_n = 11.11 rad/s, ζ = 0.6)."""
    raw = {"controller": "pi", "plant": plant}
    if params:
        raw["turbine_params"] = params
    op = operating_point(raw, wind)
    lam = [x for x in np.linalg.eigvals(op.A_p) if x.imag > 0]
    drive = [x for x in lam if 1.0 < abs(x) / (2 * math.pi) < 4.0
             and abs(-x.real / abs(x) - 0.6) > 0.05]
    slowest = min(drive, key=abs)
    return abs(slowest) / (2 * math.pi), -slowest.real / abs(slowest), op.pitch


def test_the_drivetrain_mode_is_the_three_inertia_chains_and_openfasts():
    """The generated plant's drivetrain mode at 16 m/s is the lower mode of the three
    inertias (rotor, blades' collective edge, generator) computed from the turbine file
    with numpy (wtftc.campaign.validate.three_inertias_hz, not the derivation): within
    0.5 % (the plant adds damping, the tower and the aerodynamics). It
    sits at 1.69 Hz, within 1 % of OpenFAST's 1.68 Hz, where the rigid rotor's two-mass
    drivetrain (the tower plant) has 2.22 Hz, 32 % high; its damping ratio, about 0.023,
    is OpenFAST's 0.0235 within 15 % (the tower plant's: 0.051)."""
    f, zeta, pitch = _drivetrain_hz("tower_edge")
    tp = turbine_file.load("nrel5mw").values
    assert f == pytest.approx(three_inertias_hz(tp, pitch)[0], rel=5e-3)
    assert f == pytest.approx(OPENFAST_DRIVETRAIN_16_HZ, rel=0.01)
    assert zeta == pytest.approx(0.0235, rel=0.15)
    f_rigid, zeta_rigid, _ = _drivetrain_hz("tower")
    assert f_rigid == pytest.approx(2.2226, rel=1e-3)
    assert f_rigid / OPENFAST_DRIVETRAIN_16_HZ > 1.3
    assert zeta_rigid > 2 * zeta


def test_stiff_blades_give_the_rigid_rotors_drivetrain():
    """Blades 10⁴ times stiffer edgewise: the drivetrain mode is the tower plant's
    two-mass mode √(k_s (1/J_r + 1/J_g)) within 0.1 %."""
    tp = turbine_file.load("nrel5mw").values
    f, _, _ = _drivetrain_hz("tower_edge", {"edge_stiffness": tp["edge_stiffness"] * 1e4})
    two_mass = math.sqrt(tp["k_s"] * (1 / tp["J_r"] + 1 / tp["J_g"])) / (2 * math.pi)
    assert f == pytest.approx(two_mass, rel=1e-3)


def test_a_trimmed_rotor_starts_with_its_blades_bent_by_the_torque():
    """The trim bends the blades edgewise by κ T / (3 k_e) (the plant at rest): in steady
    16 m/s the deflection holds within 1 % and the edge velocity stays below 1 mm/s; the
    deflection is the right size for a 61.5-m blade carrying a third of 4.2 MN m (tens
    of centimetres: ElastoDyn's in-plane tip deflection at rated is about 0.5 m)."""
    rc = config.make_config({"plant": "tower_edge", "controller": "pi", "t_final_s": 10.0,
                             "output_rate_hz": 100.0,
                             "wind": {"kind": "constant", "speed_mps": 16.0}})
    res = cases.run(rc, progress=False, keep_states=True)
    names = rc.loop.state_names()
    q = res.z[:, names.index("edge_q")]
    tp = lay.values("turbine_params", rc.p_turbine)
    assert q[0] == pytest.approx(tp["edge_torque_share"] * res.column("T_aero")[0]
                                 / (3 * tp["edge_stiffness"]), rel=1e-3)
    assert np.ptp(q) < 0.01 * abs(q[0])
    assert np.max(np.abs(res.z[:, names.index("edge_v")])) < 1e-3
    assert 0.1 < q[0] < 1.0


def test_import_reads_the_edge_mode_from_the_elastodyn_blade_file():
    """``turbine import`` computes the edge mode from the blade file; both shipped
    turbines hold what it computes, and the NREL 5-MW blade alone (clamped, not rotating)
    has ElastoDyn's first edgewise frequency, 1.10 Hz (Jonkman 2009, Table 9-1: 1.08 Hz
    with the rest of the turbine)."""
    pytest.importorskip("openfast_io", reason="the import extra (make setup installs it)")
    from wtftc.model.turbine_import import read_deck

    for name in ("nrel5mw", "iea15mw"):
        got, src = read_deck(config.openfast_deck(turbine_file.load(name)))
        shipped = turbine_file.load(name).values
        for key in [k for k in shipped if k.startswith("edge_")]:
            assert got[key] == pytest.approx(shipped[key], rel=1e-9), (name, key)
        assert 0 < got["edge_coupling_sin"] < 0.1 * got["edge_coupling_cos"]
    nrel, src = read_deck(config.openfast_deck(turbine_file.load("nrel5mw")))
    f_e = math.sqrt(nrel["edge_stiffness"] / nrel["edge_modal_mass"]) / (2 * math.pi)
    assert f_e == pytest.approx(1.096, abs=2e-3)
    assert "1.0958 Hz" in src["edge_stiffness"]


def test_pitch_jitter_does_not_ring_the_edge_mode():
    """Under the realistic profile's sensor noise the PI's pitch jitters near its rate
    limit; the pitch-rate terms of the edge mode's kinematics cancel in its own equation
    (derivation/turbine.py ``tower_edge_rhs``). In steady 16 m/s the shaft torque's σ
    stays below 1 % of the rated torque (here about 0.25 %; the rigid-blade tower plant's
    0.02 %) and the rotor speed's below 1e-3 rad/s. (With those terms kept on one side
    only, a 3-Hz limit cycle of ±5 MN m and 0.04 rad/s.)"""
    run = {"controller": "pi", "t_final_s": 30.0, "profile": "realistic",
           "wind": {"kind": "constant", "speed_mps": 16.0}}
    rc = config.make_config({**run, "plant": "tower_edge"})
    res = cases.run(rc, progress=False)
    tp = lay.values("turbine_params", rc.p_turbine)
    keep = res.t > 10.0
    assert np.std(res.column("theta_s")[keep]) * tp["k_s"] < 0.01 * tp["gen_torque_rated"]
    assert np.std(res.column("omega_r")[keep]) < 1e-3
