"""wtftc modes (issue 33 item 2): MBC3 against the known answer of a rotor of identical
blades and against its own definition, the .lin reader on a hand-written file whose modes
are known in closed form, the naming of the modes on both sides, the cache, a trim that
does not converge, bad input; and ONE short OpenFAST linearization (rigid DOFs, NREL 5-MW,
16 m/s, 2 azimuths: about 45 s) against wtftc's tower plant."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from wtftc.cli import main
from wtftc.errors import EngineError
from wtftc.openfast import lin_modes as lm

pytest.importorskip("openfast_io", reason="openfast-io reads .lin files")

TFA = "ED 1st tower fore-aft bending mode DOF (internal DOF index = DOF_TFA1), m"
GEN = "ED Variable speed generator DOF (internal DOF index = DOF_GeAz), rad"
DRTR = "ED Drivetrain rotational-flexibility DOF (internal DOF index = DOF_DrTr), rad"


def _rate(desc: str) -> str:
    return desc.replace("ED ", "ED First time derivative of ", 1).replace("), m", "), m/s") \
        .replace("), rad", "), rad/s")


def _blade_descs(kind: str = "1st edgewise bending-mode") -> list[str]:
    return [f"ED {kind} DOF of blade {b} (internal DOF index = DOF_BE({b},1)), m"
            for b in (1, 2, 3)]


def _lin(A_stack, desc_q, rotating_q, psi, omega) -> lm.Linearization:
    nd = len(desc_q)
    return lm.Linearization(A=A_stack, desc=desc_q + [_rate(d) for d in desc_q],
                            rotating=np.array(rotating_q * 2), order=np.full(2 * nd, 2),
                            azimuth=np.asarray(psi, float), rotor_speed=np.full(len(psi), omega))


# ----------------------------------------------------------------------------- MBC3

def test_mbc3_moves_the_whirling_modes_of_identical_blades_by_one_rotor_speed():
    """Three identical, uncoupled blade oscillators (ω0, ζ) on a rotor turning at Ω: in
    the rotating frame A is the same at every azimuth; in the fixed frame (Coleman) the
    collective mode stays at λ0 and the cyclic pair moves to λ0 ± iΩ, exactly (Bir 2008,
    §3). Without MBC the eigenvalues would all be λ0."""
    w0, zeta, Om = 2 * math.pi * 1.1, 0.02, 1.2673
    one = np.array([[0.0, 1.0], [-w0 ** 2, -2 * zeta * w0]])
    A = np.zeros((6, 6))
    for b in range(3):
        A[np.ix_([b, b + 3], [b, b + 3])] = one
    psi = np.linspace(0, 2 * np.pi, 5, endpoint=False) + 0.3
    lin = _lin(np.repeat(A[:, :, None], 5, axis=2), _blade_descs(), [True] * 3, psi, Om)
    A_nr, trip = lm.mbc3(lin)
    assert trip == [(0, 1, 2)]
    lam0 = -zeta * w0 + 1j * w0 * math.sqrt(1 - zeta ** 2)
    want = np.array([lam0 - 1j * Om, lam0, lam0 + 1j * Om])
    for k in range(5):
        lam = np.linalg.eigvals(A_nr[:, :, k])
        got = sorted(lam[lam.imag > 0], key=lambda x: x.imag)
        assert np.allclose(got, want, rtol=0, atol=1e-10)
    names = lm.fixed_frame_names(lin, trip)
    assert names[:3] == [f"1st edgewise bending-mode {k}" for k in
                         ("collective", "cosine", "sine")]


def _L(psi: float, nd_fixed: int) -> np.ndarray:
    """x = L(ψ) x_n by the definition q_b = q0 + qc cos ψ_b + qs sin ψ_b (displacements)."""
    az = psi + 2 * np.pi / 3 * np.arange(3)
    T = np.eye(nd_fixed + 3)
    T[nd_fixed:, nd_fixed:] = np.column_stack([np.ones(3), np.cos(az), np.sin(az)])
    return T


def test_mbc3_recovers_a_fixed_frame_system_from_its_periodic_rotating_form():
    """A random fixed-frame system (a tower DOF coupled to a blade triplet) put into the
    rotating frame at 4 azimuths with L̇ from central differences of the definition (not
    the T2, T3 of the code): MBC3 gives the system back at every azimuth (to the
    differences' 1e-7), though A(ψ) itself varies by O(1) with the azimuth."""
    rng = np.random.default_rng(3)
    nd, Om, h = 4, 1.1, 1e-5
    K = rng.normal(size=(nd, nd)) * 4 - 8 * np.eye(nd)
    C = rng.normal(size=(nd, nd)) * 0.3 - np.eye(nd)
    A_n = np.block([[np.zeros((nd, nd)), np.eye(nd)], [K, C]])
    psi = np.array([0.2, 1.77, 3.34, 4.91])
    stack = []
    for p in psi:
        def big(q):
            T = _L(q, 1)
            dT = (_L(q + Om * h, 1) - _L(q - Om * h, 1)) / (2 * h)
            return np.block([[T, np.zeros((nd, nd))], [dT, T]])
        L = big(p)
        Ld = (big(p + Om * h) - big(p - Om * h)) / (2 * h)
        stack.append((L @ A_n + Ld) @ np.linalg.inv(L))
    A = np.stack(stack, axis=2)
    assert np.abs(A[:, :, 0] - A[:, :, 1]).max() > 0.5
    lin = _lin(A, [TFA] + _blade_descs(), [False, True, True, True], psi, Om)
    A_nr, _ = lm.mbc3(lin)
    for k in range(len(psi)):
        assert np.abs(A_nr[:, :, k] - A_n).max() < 1e-6 * np.abs(A_n).max()


# ---------------------------------------------------------- a hand-written .lin file

#: a tower (m_t, k_t, c_t) and a two-mass drivetrain (J_r, J_g, k, c) in ElastoDyn's DOFs
TOWER = (4.0e5, 1.7e6, 1.6e4)
SHAFT = (3.87e7, 5.03e6, 8.68e8, 6.2e6)


def _lin_text(A: np.ndarray, psi: float) -> str:
    """A .lin file as OpenFAST 5.0 writes it (rigid DOFs: tower fore-aft, generator,
    drivetrain twist), two inputs (openfast-io reads a one-column B as a vector)."""
    x = [0.2, 4.7, 4.8e-3, 2e-3, 1.268, -2e-4]
    rows = [f"   {i + 1:8d}    {v: .3E}                                 F               2"
            f"         {d}" for i, (v, d) in enumerate(zip(x, [TFA, GEN, DRTR] + [
                _rate(d) for d in (TFA, GEN, DRTR)], strict=True))]
    head = ["", "Linearized model: Predictions were generated on 26-Nov-2026 using OpenFAST",
            "", "Simulation information:", "   Simulation time:                    39.6750 s",
            "   Rotor Speed:                         1.2673 rad/s",
            f"   Azimuth:                             {psi:.4f} rad",
            "   Wind Speed:                         16.0000 m/s",
            "   Number of continuous states:         6",
            "   Number of discrete states:           0",
            "   Number of constraint states:         0",
            "   Number of inputs:                    2",
            "   Number of outputs:                   0",
            "   Jacobians included in this file?    No", "", "Order of continuous states:",
            "   Row/Column Operating Point                     Rotating Frame? Derivative "
            "Order Description", "   ---------- ---------------                     "
            "--------------- ---------------- -----------"]
    deriv = ["", "Order of continuous state derivatives:", *head[-2:],
             *[r.replace("         ED ", "         ED First time derivative of ", 1)
               for r in rows]]
    inputs = ["", "Order of inputs:", "     Column   Operating Point                     "
              "Rotating Frame? Derivative Order Description", head[-1],
              "          1    4.309E+04                                 F               0"
              "         ED Generator torque, Nm",
              "          2    2.088E-01                                 F               0"
              "         ED Extended input: collective blade-pitch command, rad"]
    mats = ["", "", "Linearized state matrices:", "", "A: 6 x 6",
            *["  " + "  ".join(f"{v: .9E}" for v in r) for r in A], "",
            "B: 6 x 2", *[f"   {v: .9E}   0.0" for v in np.r_[0, 0, 0, 0, 1 / SHAFT[1], 0]],
            ""]
    return "\n".join(head + rows + deriv + inputs + mats) + "\n"


def _rigid_A() -> np.ndarray:
    m_t, k_t, c_t = TOWER
    J_r, J_g, k, c = SHAFT
    M = np.diag([m_t, 0, 0]).astype(float)
    M[1:, 1:] = [[J_g + J_r, J_r], [J_r, J_r]]  # KE: ½J_g θ̇_g² + ½J_r (θ̇_g + θ̇_d)²
    Kq, Cq = np.diag([k_t, 0, k]), np.diag([c_t, 0, c])
    Mi = np.linalg.inv(M)
    return np.block([[np.zeros((3, 3)), np.eye(3)], [-Mi @ Kq, -Mi @ Cq]])


def test_a_hand_written_lin_file_gives_its_closed_form_modes(tmp_path):
    """Two azimuths of a tower and a two-mass drivetrain in ElastoDyn's DOFs, read by
    openfast-io, averaged, the azimuth dropped: the drivetrain is ω² = k/J_eff, ζ = c /
    (2 √(k J_eff)), J_eff = J_r J_g/(J_r + J_g), the tower √(k_t/m_t), exactly (the file
    holds 10 digits); the rotor's free rotation, a zero eigenvalue, is gone with the
    generator azimuth."""
    A = _rigid_A()
    files = []
    for k, psi in enumerate((0.0014, 3.1430)):
        files.append(tmp_path / f"T.{k + 1}.lin")
        files[-1].write_text(_lin_text(A, psi))
    lin = lm.read(files)
    assert lin.A.shape == (6, 6, 2) and not lin.rotating.any()
    assert np.allclose(lin.azimuth, [0.0014, 3.1430])
    A_avg, names = lm.averaged(lin)
    assert A_avg.shape == (5, 5) and names.count(lm.AZIMUTH) == 1
    found = lm.find(lm.modes(A_avg, names), names)
    J_r, J_g, k, c = SHAFT
    J_eff = J_r * J_g / (J_r + J_g)
    assert found["drivetrain"]["f_hz"] == pytest.approx(math.sqrt(k / J_eff) / (2 * math.pi),
                                                        rel=1e-8)
    assert found["drivetrain"]["zeta"] == pytest.approx(c / (2 * math.sqrt(k * J_eff)),
                                                        rel=1e-8)
    m_t, k_t, c_t = TOWER
    assert found["tower_fa"]["f_hz"] == pytest.approx(math.sqrt(k_t / m_t) / (2 * math.pi),
                                                      rel=1e-8)
    assert found["tower_ss"] is None


def test_the_drivetrain_is_the_generator_against_the_rotor_not_the_hub_against_the_blades():
    """A three-inertia chain as with flexible blades: generator (J_g) - shaft (k) - hub
    (J_h) - collective edgewise spring (k_e) - blades (J_b). Two modes twist the shaft;
    in the upper one the hub swings against the blades with the generator nearly still,
    and it has the larger twist share (here 1.54 Hz, share 0.35, twist / generator angle
    −0.53 against 3.50 Hz, 0.65, −2.8; ElastoDyn's NREL 5-MW: 1.68 Hz, 0.45, −0.65
    against 3.98 Hz, 0.51, −3.6). The generator-against-rotor mode is the lower."""
    J_g, J_h, J_b, k, k_e = 5.0e6, 5.0e6, 3.4e7, 8.7e8, 1.0e9
    # DOFs: generator angle, twist (hub − generator), edge (blades − hub)
    M = np.array([[J_g + J_h + J_b, J_h + J_b, J_b], [J_h + J_b, J_h + J_b, J_b],
                  [J_b, J_b, J_b]])
    Kq = np.diag([0.0, k, k_e])
    Mi = np.linalg.inv(M)
    A = np.block([[np.zeros((3, 3)), np.eye(3)], [-Mi @ Kq, -Mi @ (1e-3 * Kq)]])
    names = [lm.AZIMUTH, lm.DRIVETRAIN, "1st edgewise bending-mode collective"] * 2
    keep = [1, 2, 3, 4, 5]  # the generator azimuth removed, as from a .lin
    ms = lm.modes(A[np.ix_(keep, keep)], [names[i] for i in keep])
    assert len(ms) == 2
    lower, upper = ms
    assert upper["share"][lm.DRIVETRAIN] > lower["share"][lm.DRIVETRAIN]
    assert lm.find(ms, [names[i] for i in keep])["drivetrain"] is lower


# ------------------------------------------------------------------- wtftc's side

def test_wtftcs_tower_plant_modes_are_named_by_their_states():
    """The tower plant at 16 m/s: the drivetrain is the two-mass √(k_s (1/J_r + 1/J_g)),
    the tower fore-aft mode the one of tower_x/tower_v, the actuator modes left out."""
    from wtftc import config
    from wtftc.campaign import modes

    op, ms, found = modes.wtftc_modes({"plant": "tower"}, 16.0)
    rc = config.make_config({"controller": "pi", "plant": "tower"})
    k, J_r, J_g = (rc.param(n) for n in ("k_s", "J_r", "J_g"))
    assert found["drivetrain"]["f_hz"] == pytest.approx(
        math.sqrt(k * (1 / J_r + 1 / J_g)) / (2 * math.pi), rel=2e-3)
    assert 0.3 < found["tower_fa"]["f_hz"] < 0.35
    assert found["tower_fa"]["share"]["tower_x"] > 0.3
    assert all(m is not found["drivetrain"] for m in ms if m["share"]["beta_1"] > 0.2)


# ------------------------------------------------------------- the cache and the trim

def test_a_trim_that_does_not_converge_is_refused_and_not_cached(tmp_path, monkeypatch):
    """OpenFAST's 'Steady state not found' (it then forces one linearization) is
    TrimNotConverged, exit 4, and leaves no linearization in the cache: the failed case is
    kept beside the entries, as failed-<key> without a lin.json, and the message names it
    (to rerun by hand)."""
    from wtftc.openfast import engine
    from wtftc.openfast import linearization as oflin

    monkeypatch.setattr(oflin, "cache_dir", lambda: tmp_path / "cache")

    def fake(folder, fst, watch=None, every_s=5.0):
        return 1.0, None, ("Steady state not found before end of simulation. Forcing "
                           "linearization.\nOpenFAST terminated normally.")
    monkeypatch.setattr(engine, "simulate_in", fake)
    g = oflin.Guess(1.2671, math.radians(11.97), 0.21, 43093.55, 97.0, 2.22)
    from wtftc.config import openfast_deck
    from wtftc.model import turbine_file
    deck = openfast_deck(turbine_file.load("nrel5mw"))
    with pytest.raises(oflin.TrimNotConverged, match="no steady state") as exc:
        oflin.linearize(deck, 16.0, "rigid", 2, g, progress=False)
    assert isinstance(oflin.TrimNotConverged("x"), EngineError)
    left = [p for p in (tmp_path / "cache" / "openfast_lin").iterdir()
            if not p.name.startswith(".")]
    assert [p.name.startswith("failed-") for p in left] == [True], left
    assert not list(left[0].rglob("lin.json")) and str(left[0]) in str(exc.value)


def test_sigterm_during_a_linearization_leaves_nothing_in_the_cache(tmp_path, monkeypatch):
    """SIGTERM while OpenFAST runs (here: a stand-in that receives it) stops the command as
    Ctrl-C does, and neither its work folder nor a case is left in the cache."""
    import os
    import signal

    from wtftc.config import openfast_deck
    from wtftc.model import turbine_file
    from wtftc.openfast import engine
    from wtftc.openfast import linearization as oflin

    monkeypatch.setattr(oflin, "cache_dir", lambda: tmp_path / "cache")
    seen = []

    def killed(folder, fst, watch=None, every_s=5.0):
        seen.append(sorted(p.name[:6] for p in (tmp_path / "cache" / "openfast_lin").iterdir()))
        os.kill(os.getpid(), signal.SIGTERM)
        raise AssertionError("SIGTERM did not stop the run")
    monkeypatch.setattr(engine, "simulate_in", killed)
    g = oflin.Guess(1.2671, math.radians(11.97), 0.21, 43093.55, 97.0, 2.22)
    with pytest.raises(KeyboardInterrupt):
        oflin.linearize(openfast_deck(turbine_file.load("nrel5mw")), 16.0, "rigid", 2, g,
                        progress=False)
    assert ".work-" in seen[0]  # the work folder was there while OpenFAST ran
    assert list((tmp_path / "cache" / "openfast_lin").iterdir()) == []
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL


@pytest.mark.parametrize("argv, flag", [
    (["--plant", "nrel5mw"], "--plant"), (["--dofs", "half"], "--dofs"),
    (["--azimuths", "1"], "--azimuths"), (["--azimuths", "37"], "[2, 36]"),
    (["--azimuths", "1000000000"], "[2, 36]"), (["--winds", "0"], "--winds"),
    (["--winds", "10"], "above the turbine's rated wind"),
    (["--turbine", "nonsense"], "turbine")])
def test_bad_input_is_one_line(argv, flag, tmp_path, capsys):
    assert main(["modes", *argv, "--out", str(tmp_path / "m")]) == 2
    err = capsys.readouterr().err.strip()
    assert flag in err and len(err.splitlines()) == 1 and "Traceback" not in err
    assert not (tmp_path / "m").exists()


def test_without_openfast_it_is_one_line_exit_4(tmp_path, capsys, monkeypatch):
    from wtftc.openfast import install

    monkeypatch.setattr(install, "find", lambda *a, **k: None)
    assert main(["modes", "--out", str(tmp_path / "m")]) == 4
    err = capsys.readouterr().err.strip()
    assert "OpenFAST" in err and len(err.splitlines()) == 1
    assert not (tmp_path / "m").exists()


def test_without_openfast_io_it_is_one_line_exit_2(tmp_path, capsys, monkeypatch):
    """A missing Python package is a refusal naming it and its pip line, as for Dask (no
    program failed)."""
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "openfast_io" else real(name, *a))
    assert main(["modes", "--out", str(tmp_path / "m")]) == 2
    err = capsys.readouterr().err.strip()
    assert "openfast-io" in err and "pip install" in err and len(err.splitlines()) == 1


# ------------------------------------------------------ ONE OpenFAST linearization

@pytest.fixture(scope="module")
def rigid16(tmp_path_factory):
    """`wtftc modes --winds 16 --dofs rigid` into a fresh cache: OpenFAST runs (~45 s)."""
    from wtftc.openfast import install
    from wtftc.openfast import linearization as oflin

    if install.find() is None:
        pytest.skip("OpenFAST is not installed (make openfast)")
    base = tmp_path_factory.mktemp("modes")
    mp = pytest.MonkeyPatch()
    mp.setattr(oflin, "cache_dir", lambda: base / "cache")
    try:
        assert main(["modes", "--winds", "16", "--dofs", "rigid", "--quiet",
                     "--out", str(base / "out")]) == 0
        yield base, mp
    finally:
        mp.undo()


def test_openfast_rigid_modes_agree_with_wtftcs_tower_plant(rigid16):
    """The like-for-like check: OpenFAST with wtftc's DOFs (generator, shaft twist, 1st
    tower fore-aft) against wtftc's tower plant, NREL 5-MW at 16 m/s.

    Drivetrain within 0.5 %: both are the same two-mass shaft (ElastoDyn's k_s, d_s,
    J_g; J_r differs by 0.2 % between Jonkman's table and ElastoDyn's integral, which
    moves f by J_g/(J_r + J_g)/2 of that, 0.01 %; the aerodynamic torque's speed
    derivative acts on the rigid-body pole, not this mode); the .lin files' 4 digits
    allow 0.05 %. ζ within 5 %: the shaft's damping d_s on both. Measured: 2.2230 Hz
    against 2.2226 Hz (−0.02 %), ζ 0.0508 both.
    The tower within issue 33's 3 %: wtftc's modal mass and stiffness are ElastoDyn's
    with one tower mode (the assembly on top moving and tilting, gravity's destiffening;
    wtftc.model.turbine_import.tower_mode); measured 0.3264 Hz against wtftc's 0.3281 Hz
    structural (Jonkman's 0.324 Hz before issue 33's fix: −1.0 %)."""
    base, _ = rigid16
    doc = json.loads((base / "out" / "modes.json").read_text())
    rows = {r["mode"]: r for r in doc["winds"][0]["compare"]}
    assert set(rows) == {"drivetrain", "tower_fa"}
    dt, tw = rows["drivetrain"], rows["tower_fa"]
    assert abs(dt["f_difference_pct"]) < 0.5, dt
    assert dt["wtftc_zeta"] == pytest.approx(dt["openfast_zeta"], rel=0.05)
    assert abs(tw["f_difference_pct"]) < 3.0, tw
    assert 2.1 < dt["openfast_f_hz"] < 2.3 and 0.30 < tw["openfast_f_hz"] < 0.35
    of = doc["winds"][0]["openfast"]
    assert not of["cached"] and abs(of["pitch_deg"] - doc["winds"][0]["wtftc"]["pitch_deg"]) < 1
    assert len(of["lin_files"]) == 2 and all((base / "out" / f).is_file()
                                             for f in of["lin_files"])
    csv = (base / "out" / "modes.csv").read_text().splitlines()
    assert csv[0].startswith("wind_mps,mode,openfast_f_hz")
    float(csv[1].split(",")[2])  # plain numbers
    assert "within 3 %" in (base / "out" / "modes.md").read_text()


def test_a_second_call_comes_from_the_cache(rigid16):
    """The same call again reads the cached .lin files: OpenFAST does not run."""
    from wtftc.openfast import engine

    base, mp = rigid16
    mp.setattr(engine, "simulate_in", lambda *a, **k: pytest.fail("OpenFAST ran again"))
    assert main(["modes", "--winds", "16", "--dofs", "rigid", "--quiet",
                 "--out", str(base / "out")]) == 0
    doc = json.loads((base / "out" / "modes.json").read_text())
    assert doc["winds"][0]["openfast"]["cached"]
