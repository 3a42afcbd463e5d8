"""Commands that succeeded on nonsense now refuse it (issue 30, defect 7): one line on
stderr naming the option or key, the value and what is allowed; exit 2; nothing written.

* ``turbine tune --omega-n 9 --zeta 0.7`` wrote a design it printed as unstable;
* ``linearize --controller rosco`` wrote the model of a loop without ROSCO in it;
* ``linearize`` at 0.5 m/s reported a point that was not at rest, and a loop in a limit
  cycle was linearized as if it rested;
* ``dt_s = 1e-9`` was accepted, 6e10 steps with no estimate and no progress;
* ``output_rate_hz`` above 1/dt_s was lowered silently, the saved configuration keeping
  the rate asked for.
"""

from __future__ import annotations

import math
import subprocess
import sys

import pytest

from wtftc import cli, config
from wtftc.errors import ConfigError

control = pytest.importorskip("control", reason="python-control: pip install "
                              "'wtftc[linear]' (in the dev extra, so make test has it)")

from wtftc.campaign import linearize as lin  # noqa: E402


def _refused(capsys, argv: list[str], field: str) -> str:
    """``wtftc argv`` exits 2 with one line on stderr naming ``field``; that line."""
    code = cli.main(argv)
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.startswith("wtftc: error: ") and err.count("\n") == 1, err
    assert f"{field} = " in err and "Traceback" not in err, err
    return err


# --------------------------------------------------------------------------- turbine tune

def test_tune_refuses_a_design_it_finds_unstable_and_writes_nothing(tmp_path, capsys):
    """The issue's own example: the physical AFTC reaches the asked-for dominant mode,
    and the drivetrain mode beside it is unstable (ζ -0.005, gain margin -24 dB). What
    was found is still printed; the refusal names the target and the damping found."""
    out = tmp_path / "tuned.toml"
    code = cli.main(["turbine", "tune", "--omega-n", "9", "--zeta", "0.7", "--out", str(out)])
    captured = capsys.readouterr()
    assert code == 2, captured.err
    err = captured.err
    assert err.startswith("wtftc: error: --omega-n/--zeta = (9.0, 0.7) is not allowed")
    assert err.count("\n") == 1 and "ζ -0.00" in err and "stable" in err, err
    assert "achieved on the exact linear model" in captured.out  # what it found
    assert not out.exists()


def test_tune_below_rated_wind_is_refused_naming_the_wind(tmp_path, capsys):
    """At 8 m/s the pitch rests at its stop: the PI's gains make no pitch loop, and the
    design is refused naming --wind (the loop's modes at zero: not stable)."""
    out = tmp_path / "tuned.toml"
    err = _refused(capsys, ["turbine", "tune", "--controller", "pi", "--wind", "8",
                            "--out", str(out)], "--wind")
    assert "rated" in err
    assert not out.exists()


@pytest.mark.parametrize("option,value", [
    ("--omega-n", "nan"), ("--omega-n", "inf"), ("--omega-n", "-0.6"), ("--omega-n", "0"),
    ("--zeta", "nan"), ("--zeta", "-inf"), ("--zeta", "-0.7"),
    ("--wind", "nan"), ("--wind", "inf"), ("--wind", "-16"),
    ("--c2-ratio", "nan"), ("--c2-ratio", "inf"), ("--c2-ratio", "-2"),
])
def test_tune_options_out_of_range_are_one_line(option, value, tmp_path, capsys):
    out = tmp_path / "tuned.toml"
    err = _refused(capsys, ["turbine", "tune", f"{option}={value}", "--out", str(out)],
                   option)
    assert "a number in [" in err
    assert not out.exists()


# ------------------------------------------------------------------------------ linearize

def test_linearize_refuses_rosco(tmp_path, capsys):
    """ROSCO runs as an external DISCON library: nothing here differentiates it, and the
    'model' written used to be that of the loop without it."""
    out = tmp_path / "lin"
    err = _refused(capsys, ["linearize", "--controller", "rosco", "--winds", "16",
                            "--out", str(out)], "--controller")
    assert "physical" in err and "pi" in err  # what is allowed
    assert not out.exists()
    with pytest.raises(ConfigError) as exc:  # the library refuses it too
        lin.operating_point({"controller": "rosco"}, 16.0)
    assert exc.value.field == "controller"


def test_linearize_below_cut_in_is_refused_naming_winds_and_writes_nothing(tmp_path, capsys):
    """At 0.5 m/s the rotor idles (its torque law's region 1) at λ 91, far beyond the Cp
    table's 2-14.5: the model has no aerodynamics there. It used to be reported, not even
    at rest (the settling run and the linearization had different torque laws: max |ż|
    0.1); a good wind beside it writes nothing either."""
    out = tmp_path / "lin"
    err = _refused(capsys, ["linearize", "--controller", "pi", "--winds", "16", "0.5",
                            "--out", str(out), "--quiet"], "--winds")
    # issue 31: the run starts at its wind's operating point, and at 0.5 m/s there is none
    # inside the table: refused before the settling run (it idled at λ 91 before)
    assert "--winds = 0.5" in err and "operating point" in err and "Cp table" in err
    assert not out.exists()


def test_a_loop_that_does_not_rest_is_never_reported_as_resting():
    """The drivetrain design at 16 m/s (ideal profile) settles into a limit cycle of
    about ±1.5° pitch: the point Newton's method ends at has max |ż| 0.14 (the pitch rate
    limit), and is refused rather than linearized."""
    with pytest.raises(lin.NotAtRest) as exc:
        lin.operating_point({"controller": "drivetrain"}, 16.0)
    assert exc.value.field == "wind" and exc.value.value == 16.0
    assert "does not rest" in exc.value.allowed


def test_an_operating_point_at_rest_is_below_the_tolerance():
    """Where the loop rests, it rests to round-off (the tolerance 1e-6 is far above it),
    in region 2 below rated too, now that the settling run and the linearization share
    the torque law of the wind."""
    for wind in (8.0, 16.0):
        op = lin.operating_point({"controller": "pi"}, wind)
        assert op.residual < 1e-12 < lin.REST_TOLERANCE
    assert lin.least_stable(op)["real"] < 0


# ----------------------------------------------------------------------- dt_s, the budget

def test_a_step_budget_refuses_dt_1e_9_naming_dt_and_t_final():
    with pytest.raises(ConfigError) as exc:
        config.make_config({"dt_s": 1e-9})
    e = exc.value
    assert e.field == "dt_s" and e.value == 1e-9
    assert "t_final_s = 60" in e.allowed and "6e+10" in e.allowed
    assert f"{config.MAX_STEPS:.3g}" in e.allowed
    # at the budget: accepted (nothing runs); one step beyond it: refused
    config.make_config({"dt_s": 1e-6, "t_final_s": config.MAX_STEPS * 1e-6})
    with pytest.raises(ConfigError, match="dt_s"):
        config.make_config({"dt_s": 1e-6, "t_final_s": config.MAX_STEPS * 1e-6 + 1.0})
    with pytest.raises(ConfigError, match="dt_s"):  # t_final / dt overflows to inf
        config.make_config({"dt_s": 5e-324})


def test_run_with_dt_1e_9_exits_2_at_once(tmp_path):
    out = tmp_path / "run"
    p = subprocess.run([sys.executable, "-m", "wtftc.cli", "run", "--dt", "1e-9", "--out",
                        str(out), "--quiet"], capture_output=True, text=True, timeout=120)
    assert p.returncode == 2, p.stderr
    assert p.stderr.startswith("wtftc: error: dt_s (--dt) = 1e-09") and p.stderr.count("\n") == 1
    assert "t_final_s" in p.stderr
    assert not out.exists()


# ---------------------------------------------------------------------- output_rate_hz

@pytest.mark.parametrize("dt,rate", [(0.01, 200.0), (0.001, 1500.0), (0.001, 1e6),
                                     (0.001, 800.0)])
def test_an_output_rate_the_step_cannot_reach_is_refused(dt, rate):
    """Above 1/dt_s (one output per step at most) it used to be lowered to 1/dt_s with no
    word, and so were rates between 1/(1.5 dt) and 1/dt (800 Hz at 1 ms)."""
    with pytest.raises(ConfigError) as exc:
        config.make_config({"dt_s": dt, "t_final_s": 1.0, "output_rate_hz": rate})
    assert exc.value.field == "output_rate_hz" and exc.value.value == rate
    if rate * dt > 1:
        assert f"at most 1/dt_s = {1 / dt:g} Hz" in exc.value.allowed


@pytest.mark.parametrize("dt", [0.001, 0.002, 0.003, 0.02, 0.05, 0.09])
def test_the_saved_configuration_records_the_output_rate_used(dt):
    """The default rate (50 Hz) where dt_s cannot reach it is the rate the run keeps, and
    the configuration (config.toml, a sweep's config_json) records that rate, not 50."""
    rc = config.make_config({"dt_s": dt, "t_final_s": round(90 * dt, 12)})
    used = 1.0 / (rc.decimate * rc.dt)
    assert math.isclose(rc.raw["output_rate_hz"], used, rel_tol=1e-12)
    again = config.make_config({"dt_s": dt, "t_final_s": round(90 * dt, 12),
                                "output_rate_hz": rc.raw["output_rate_hz"]})
    assert again.decimate == rc.decimate  # the recorded rate runs as it ran
