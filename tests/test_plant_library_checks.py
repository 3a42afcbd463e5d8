"""The plant library's settings file (``wtftc_plant.in``) checked at the library's first
call, as the exported controller library checks its .IN: every number against wtftc's own
ranges (the layout's ``valid`` entries and wtftc.config's cross-checks, through
wtftc.export.discon_checks), every fault line, the actuator's step against the call
interval, the noise table's size and every path. A refused file makes the first call
return aviFAIL = -1 with one line in avcMSG naming the key, the value and what is allowed;
OpenFAST then stops with that line and never "terminates normally".

The hostile files are mutations of a valid settings file, table-driven: each row says
what the library must answer (None: accepted and run; else a text its message must hold,
the key it names). They run through tests/discon_host.py's driver in a process of their
own (a crash or a hang fails the test naming its case). A few go through the real
OpenFAST on a 2-s case; Python's :class:`Settings` refuses the same values before it
writes a file.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from wtftc.artefacts import layout as lay
from wtftc.artefacts.loader import compiler
from wtftc.errors import ConfigError
from wtftc.export import discon_checks
from wtftc.model.faults import parse_faults
from wtftc.openfast import plant_library as pl

ROOT = Path(__file__).resolve().parent.parent
INTERVAL = 0.01
#: the noise table's rows (a whole number of 10 columns, none of 60)
NOISE_ROWS = 7
#: ServoDyn's avcMSG capacity (#49), as tests/test_discon_fuzz.py gives it
CAPACITY = 1025
#: a controller that demands 0.1 rad on every blade and a fixed torque
STILL = r"""
void DISCON(float *s, int *fail, char *in, char *out, char *msg) {
    s[41] = s[42] = s[43] = s[44] = 0.1f; s[46] = 1000.0f; *fail = 0;
}
"""


@pytest.fixture(scope="module")
def base(tmp_path_factory) -> dict:
    """A valid settings file (absolute paths) around a still controller, with a noise table
    and a loss-of-effectiveness fault line, and the special files the mutations name."""
    folder = tmp_path_factory.mktemp("plant_checks")
    (folder / "still.c").write_text(STILL)
    lib = folder / "libstill.so"
    subprocess.run([compiler(), "-shared", "-fPIC", "-o", str(lib), str(folder / "still.c")],
                   check=True)
    infile = folder / "still.IN"
    infile.write_text("! the still controller reads nothing\n")
    noise = folder / "noise.bin"
    noise.write_bytes(np.zeros((NOISE_ROWS, pl.NOISE_COLUMNS[0])).tobytes())
    fault = parse_faults([{"type": "loss_of_effectiveness", "blade": 2, "onset_s": 0.5,
                           "rho": 0.5}])
    s = pl.Settings(lib, infile, folder / "records.bin", lay.defaults("turbine_params"),
                    lay.defaults("sensor_params"), fault, noise=noise,
                    noise_columns=pl.NOISE_COLUMNS[0], interval=INTERVAL)
    text = s.text()
    os.mkfifo(folder / "fifo")
    (folder / "a_folder").mkdir()
    return {"folder": folder, "text": text, "lib": lib, "infile": infile, "noise": noise,
            "records": folder / "records.bin", "settings": s}


# -- mutations of the settings file's text ---------------------------------------------

def _lines(text: str) -> list[str]:
    return text.splitlines()


def _key_line(lines: list[str], key: str) -> int:
    return next(k for k, ln in enumerate(lines) if ln.split(" ", 1)[0] == key)


def vec(key: str, name: str, token: str, *more: tuple[str, str, str]):
    """The number ``name`` of vector ``key`` set to ``token`` (and so each of ``more``):
    a mutation of values only (``values_only``), which Python's checks see too."""
    def mutate(text: str, b: dict) -> str:
        ls = _lines(text)
        for key_, name_, token_ in ((key, name, token), *more):
            k = _key_line(ls, key_)
            words = ls[k].split()
            words[1 + lay.index(pl.VECTORS[key_], name_)] = token_
            ls[k] = " ".join(words)
        return "\n".join(ls) + "\n"
    mutate.values_only = True
    return mutate


def line(key: str, value: str | None):
    """The line of ``key`` given ``value`` (None: the line removed)."""
    def mutate(text: str, b: dict) -> str:
        ls = _lines(text)
        k = _key_line(ls, key)
        if value is None:
            del ls[k]
        else:
            ls[k] = f"{key} {value.format(**b)}" if value else key
        return "\n".join(ls) + "\n"
    return mutate


def doubled(key: str):
    def mutate(text: str, b: dict) -> str:
        ls = _lines(text)
        k = _key_line(ls, key)
        return "\n".join([*ls[:k + 1], ls[k], *ls[k + 1:]]) + "\n"
    return mutate


def fault(words: str):
    """The fault line replaced by ``fault <words>``."""
    return line("fault", words)


def extra(*added: str):
    def mutate(text: str, b: dict) -> str:
        return text + "".join(a + "\n" for a in added)
    return mutate


def raw(fn):
    """Any change of the whole text."""
    return lambda text, b: fn(text)


P = "p_turbine."
DEFAULTS = lay.values("turbine_params", lay.defaults("turbine_params"))
#: (case, mutation, what the first call answers: None accepted, else a text its message
#: holds). The first group is the defects found by hand; the rest, hostile files.
CASES = [
    # a natural frequency that is NaN or negative, a negative damping, a rate limit of 0
    ("omega_n nan", vec("p_turbine", "omega_n_nominal", "nan"),
     "p_turbine.omega_n_nominal = nan is not allowed: a number > 0 [rad/s]"),
    ("omega_n negative", vec("p_turbine", "omega_n_nominal", "-11.11"),
     "p_turbine.omega_n_nominal = -11.11 is not allowed"),
    ("zeta negative", vec("p_turbine", "zeta_nominal", "-0.6"),
     "p_turbine.zeta_nominal = -0.6 is not allowed: a number > 0"),
    ("rate limit 0", vec("p_turbine", "pitch_rate_max", "0"),
     "p_turbine.pitch_rate_max = 0 is not allowed: a number > 0 [rad/s]"),
    ("pitch_min above pitch_max", vec("p_turbine", "pitch_min", "1.0",
                                      ("p_turbine", "pitch_max", "0.5")),
     "p_turbine.pitch_min = 1 is not allowed: p_turbine.pitch_min < p_turbine.pitch_max "
     "(here p_turbine.pitch_max = 0.5)"),
    ("actuator_dt inf", line("actuator_dt", "inf"), "actuator_dt = inf is not allowed"),
    ("actuator_dt 1e9", line("actuator_dt", "1e9"), "actuator_dt = 1e+09 is not "
     "allowed: a step in [1e-07, 0.01] [s]"),
    ("fault onset nan", fault("2 1 nan inf 0.0 0.5 0.0"),
     "fault[0].onset_s = nan is not allowed: a number >= 0 [s]"),
    ("air density -5", vec("p_turbine", "air_density", "-5"),
     "p_turbine.air_density = -5 is not allowed: a number in (0, 2] [kg/m^3]"),
    ("hydraulic omega_n nan", fault("1 3 0.5 inf 0.0 nan 0.45"),
     "fault[0].omega_n = nan is not allowed: a number > 0 [rad/s]"),
    ("hydraulic omega_n negative", fault("1 3 0.5 inf 0.0 -3.4 0.45"),
     "fault[0].omega_n = -3.4 is not allowed"),
    ("hydraulic zeta negative", fault("1 3 0.5 inf 0.0 3.42 -0.45"),
     "fault[0].zeta = -0.45 is not allowed: a number > 0"),
    # every turbine number: NaN, infinite, negative, huge, a word, degrees for radians
    ("J_r inf", vec("p_turbine", "J_r", "inf"), "p_turbine.J_r = inf"),
    ("J_r -inf", vec("p_turbine", "J_r", "-inf"), "p_turbine.J_r = -inf"),
    ("J_r 1e400", vec("p_turbine", "J_r", "1e400"), "p_turbine.J_r = inf"),
    ("J_r 1e300 is a number", vec("p_turbine", "J_r", "1e300"), None),
    ("J_r hexadecimal", vec("p_turbine", "J_r", "0x1p25"), None),
    ("J_r a word", vec("p_turbine", "J_r", "abc"), "p_turbine.J_r = 'abc' is not allowed: "
     "a number"),
    ("J_r a comma", vec("p_turbine", "J_r", "1,5"), "p_turbine.J_r = '1,5'"),
    ("J_r cut exponent", vec("p_turbine", "J_r", "1.5e"), "p_turbine.J_r = '1.5e'"),
    ("k_s 0", vec("p_turbine", "k_s", "0"), "p_turbine.k_s = 0"),
    ("rotor radius huge", vec("p_turbine", "rotor_radius", "1e300"),
     "p_turbine.rotor_radius = 1e+300 is not allowed: a number in (0, 250] [m]"),
    ("gearbox negative", vec("p_turbine", "gearbox_ratio", "-97"), "p_turbine.gearbox_ratio"),
    ("efficiency 1.5", vec("p_turbine", "gen_efficiency", "1.5"), "p_turbine.gen_efficiency"),
    ("efficiency 1", vec("p_turbine", "gen_efficiency", "1"), None),
    ("pitch_max in degrees", vec("p_turbine", "pitch_max", "90"),
     "(radians: this looks like degrees)"),
    ("pitch_min = pitch_max", vec("p_turbine", "pitch_min", repr(DEFAULTS["pitch_max"])),
     "p_turbine.pitch_min < p_turbine.pitch_max"),
    ("cut-in above region 2", vec("p_turbine", "vs_cut_in_speed", "1.0"),
     "p_turbine.vs_cut_in_speed < p_turbine.vs_region2_speed"),
    ("torque law 0.5", vec("p_turbine", "gen_torque_law", "0.5"),
     "p_turbine.gen_torque_law = 0.5 is not allowed: 0 or 1"),
    ("torque law 1", vec("p_turbine", "gen_torque_law", "1"), None),
    ("constant torque 2", vec("p_turbine", "vs_constant_torque", "2"),
     "p_turbine.vs_constant_torque"),
    ("slip 1", vec("p_turbine", "vs_slip", "1"), "p_turbine.vs_slip = 1 is not allowed: "
     "a number in (0, 1)"),
    ("tower damping 0", vec("p_turbine", "tower_damping_ratio", "0"),
     "p_turbine.tower_damping_ratio"),
    ("edge coupling sin negative", vec("p_turbine", "edge_coupling_sin", "-1e6"), None),
    ("tau_b -0.0", vec("p_turbine", "tau_b", "-0.0"), "p_turbine.tau_b = -0"),
    # the sensors' numbers and the sensor faults' inputs at rest
    ("sigma negative", vec("p_sensors", "sigma_omega_r_m1", "-0.1"),
     "p_sensors.sigma_omega_r_m1 = -0.1 is not allowed: a number >= 0 [rad/s]"),
    ("sigma 0.01", vec("p_sensors", "sigma_omega_r_m1", "0.01"), None),
    ("bias negative", vec("p_sensors", "bias_beta_meas_2_m2", "-0.5"), None),
    ("bias nan", vec("p_sensors", "bias_beta_meas_2_m2", "nan"),
     "p_sensors.bias_beta_meas_2_m2 = nan is not allowed: a finite number [rad]"),
    ("resolution inf", vec("p_sensors", "resolution_omega_g_hss_m1", "inf"),
     "p_sensors.resolution_omega_g_hss_m1 = inf"),
    ("a sensor lag", vec("p_sensors", "lag_omega_r_m1", "0.1"),
     "p_sensors.lag_omega_r_m1 = 0.1 is not allowed: 0 [s] (the plant library's sensors "
     "have no lag"),
    ("gain 0", vec("sensor_faults", "gain_omega_r_m1", "0"), "sensor_faults.gain_omega_r_m1"),
    ("gain 1.2", vec("sensor_faults", "gain_omega_r_m1", "1.2"), None),
    ("stuck 2", vec("sensor_faults", "stuck_beta_meas_1_m1", "2"),
     "sensor_faults.stuck_beta_meas_1_m1 = 2 is not allowed: a number in [0, 1]"),
    ("stuck value nan", vec("sensor_faults", "stuck_value_beta_meas_1_m1", "nan"),
     "sensor_faults.stuck_value_beta_meas_1_m1 = nan"),
    ("noise factor -1", vec("sensor_faults", "noise_factor_omega_r_m2", "-1"),
     "sensor_faults.noise_factor_omega_r_m2"),
    ("offset 3", vec("sensor_faults", "offset_omega_r_m2", "3"), None),
    # the scalars
    ("actuator 2", line("actuator", "2"), "actuator = 2 is not allowed"),
    ("actuator 0", line("actuator", "0"), None),
    ("actuator 1.0", line("actuator", "1.0"), None),
    ("actuator a word", line("actuator", "yes"), "actuator = 'yes' is not allowed: a number"),
    ("actuator nan", line("actuator", "nan"), "actuator = nan"),
    ("actuator_dt 0", line("actuator_dt", "0"), "actuator_dt = 0 is not allowed"),
    ("actuator_dt negative", line("actuator_dt", "-0.001"), "actuator_dt = -0.001"),
    ("actuator_dt nan", line("actuator_dt", "nan"), "actuator_dt = nan"),
    ("actuator_dt 1e-9: 1e7 steps a call", line("actuator_dt", "1e-9"),
     "actuator_dt = 1e-09 is not allowed"),
    ("actuator_dt not dividing the call", line("actuator_dt", "0.003"), "actuator_dt = 0.003"),
    ("actuator_dt above the call", line("actuator_dt", "0.02"), "actuator_dt = 0.02"),
    ("actuator_dt the whole call", line("actuator_dt", "0.01"), None),
    ("actuator_dt 0.5 ms", line("actuator_dt", "0.0005"), None),
    ("actuator_dt two numbers", line("actuator_dt", "0.001 0.002"),
     "actuator_dt has 2 numbers: 1 are needed"),
    ("actuator_dt a word", line("actuator_dt", "fast"), "actuator_dt = 'fast'"),
    # keys missing, doubled, unknown, without a value
    *[(f"{k} missing", line(k, None), f"{k} is missing")
      for k in ("controller_library", "controller_infile", "records", "actuator",
                "actuator_dt", "p_turbine", "p_sensors", "sensor_faults")],
    ("p_turbine twice", doubled("p_turbine"), "p_turbine is set twice (first on line"),
    ("actuator_dt twice", doubled("actuator_dt"), "actuator_dt is set twice"),
    ("records twice", doubled("records"), "records is set twice"),
    ("unknown key", extra("pturbine 1 2 3"), "unknown key 'pturbine'"),
    ("key without value", line("actuator_dt", ""), "actuator_dt has no value"),
    ("p_turbine one number short", raw(lambda t: t.replace(
        " " + repr(DEFAULTS["vs_constant_torque"]) + "\n", "\n", 1)),
     f"p_turbine has {len(DEFAULTS) - 1} numbers: {len(DEFAULTS)} are needed"),
    ("p_turbine one number more", raw(lambda t: "\n".join(
        ln + " 1.0" if ln.startswith("p_turbine ") else ln for ln in t.splitlines()) + "\n"),
     f"p_turbine has {len(DEFAULTS) + 1} numbers"),
    ("no fault line", line("fault", None), None),
    ("a second fault line", extra("fault 3 2 1.0 inf 0.0 nan 0.0"), None),
    # the paths
    ("library missing", line("controller_library", "{folder}/nothing.so"),
     "controller_library = '"),
    ("library a folder", line("controller_library", "{folder}/a_folder"), "this is a folder"),
    ("library a FIFO", line("controller_library", "{folder}/fifo"), "this is a FIFO"),
    ("library /dev/null", line("controller_library", "/dev/null"), "this is a special file"),
    ("library not a library", line("controller_library", "{infile}"),
     "cannot load the controller library"),
    ("infile a FIFO", line("controller_infile", "{folder}/fifo"),
     "controller_infile = '"),
    ("infile missing", line("controller_infile", "{folder}/none.IN"),
     "No such file or directory"),
    ("records a folder", line("records", "{folder}/a_folder"), "records = '"),
    ("records a FIFO", line("records", "{folder}/fifo"), "this is a special file"),
    ("records in no folder", line("records", "{folder}/no/records.bin"),
     "a file in an existing folder"),
    ("records relative", line("records", "relative_records.bin"), None),
    ("noise a FIFO", line("noise", "{folder}/fifo"), "noise = '"),
    ("noise missing", line("noise", "{folder}/none.bin"), "noise = '"),
    ("noise_columns 11", line("noise_columns", "11"), "noise_columns = 11 is not allowed: "
     "10 (the sensors' noise draws) or 60"),
    ("noise_columns 60 on a 10-column table", line("noise_columns", "60"),
     "the noise table's size, 560 bytes, is no whole number of its rows (480 bytes each)"),
    ("noise_columns a word", line("noise_columns", "ten"), "noise_columns = 'ten'"),
    ("noise without its columns", line("noise_columns", None),
     "noise without noise_columns"),
    ("columns without noise", line("noise", None), "noise_columns without noise"),
    ("a path of 5000 bytes", line("controller_library", "/" + "x" * 5000),
     "controller_library is 5001 bytes long"),
    # the text itself
    ("cut in a line", raw(lambda t: t[:t.index("p_sensors ") + 40]), "p_sensors has"),
    ("cut at half", raw(lambda t: t[:len(t) // 2]), "is missing"),
    ("empty", raw(lambda t: ""), "controller_library is missing"),
    ("only comments", raw(lambda t: "# nothing\n#\n"), "is missing"),
    ("a NUL byte in a number", raw(lambda t: t.replace("actuator_dt 0.001",
                                                       "actuator_dt 0.0\x0001")),
     "a NUL byte: the settings file is text"),
    ("a NUL byte first", raw(lambda t: "\x00" + t), "line 1: a NUL byte"),
    ("CRLF line ends", raw(lambda t: t.replace("\n", "\r\n")), None),
    ("tabs between words", raw(lambda t: t.replace("p_turbine ", "p_turbine\t\t")), None),
    ("trailing spaces", raw(lambda t: t.replace("\n", "   \n")), None),
    ("no last newline", raw(lambda t: t.rstrip("\n")), None),
    ("blank lines and indents", raw(lambda t: "\n\n" + t.replace("\nactuator ", "\n  actuator ")),
     None),
    ("Latin-1 in a comment", raw(lambda t: "# r\udce9glages\n" + t), None),
    ("Latin-1 in a number", vec("p_turbine", "J_r", "3\udcb0"), "p_turbine.J_r = '3?'"),
    ("a line of 2 MB", raw(lambda t: t + "# " + "y" * (2 << 20) + "\n"),
     "its settings file is larger than 1 MiB"),
    # the fault lines
    ("blade 0", fault("0 1 0.5 inf 0.0 0.5 0.0"), "fault[0].blade = 0 is not allowed: 1, 2 or 3"),
    ("blade 4", fault("4 1 0.5 inf 0.0 0.5 0.0"), "fault[0].blade = 4"),
    ("blade 1.5", fault("1.5 1 0.5 inf 0.0 0.5 0.0"), "fault[0].blade = 1.5"),
    ("blade nan", fault("nan 1 0.5 inf 0.0 0.5 0.0"), "fault[0].blade = nan"),
    ("code 0", fault("1 0 0.5 inf 0.0 0.5 0.0"), "fault[0].code = 0 is not allowed: 1 (loss"),
    ("code 4", fault("1 4 0.5 inf 0.0 0.5 0.0"), "fault[0].code = 4"),
    ("code 2.5", fault("1 2.5 0.5 inf 0.0 0.5 0.0"), "fault[0].code = 2.5"),
    ("onset negative", fault("1 1 -1 inf 0.0 0.5 0.0"), "fault[0].onset_s = -1"),
    ("onset inf", fault("1 1 inf inf 0.0 0.5 0.0"), "fault[0].onset_s = inf"),
    ("end at onset", fault("1 1 0.5 0.5 0.0 0.5 0.0"), "fault[0].end_s = 0.5 is not allowed: "
     "a time after onset_s = 0.5 s, or inf"),
    ("end before onset", fault("1 1 0.5 0.2 0.0 0.5 0.0"), "fault[0].end_s = 0.2"),
    ("end nan", fault("1 1 0.5 nan 0.0 0.5 0.0"), "fault[0].end_s = nan"),
    ("end finite", fault("1 1 0.5 1.0 0.1 0.5 0.0"), None),
    ("ramp negative", fault("1 1 0.5 inf -1 0.5 0.0"), "fault[0].ramp_s = -1"),
    ("ramp nan", fault("1 1 0.5 inf nan 0.5 0.0"), "fault[0].ramp_s = nan"),
    ("ramp inf", fault("1 1 0.5 inf inf 0.5 0.0"), "fault[0].ramp_s = inf"),
    ("rho 0", fault("1 1 0.5 inf 0.0 0 0.0"), "fault[0].rho = 0 is not allowed: a number in "
     "(0, 1] [-]"),
    ("rho 1.5", fault("1 1 0.5 inf 0.0 1.5 0.0"), "fault[0].rho = 1.5"),
    ("rho -5", fault("1 1 0.5 inf 0.0 -5 0.0"), "fault[0].rho = -5"),
    ("rho nan", fault("1 1 0.5 inf 0.0 nan 0.0"), "fault[0].rho = nan"),
    ("rho 1", fault("1 1 0.5 inf 0.0 1 0.0"), None),
    ("loss of effectiveness with a second number", fault("1 1 0.5 inf 0.0 0.5 3"),
     "fault[0].unused = 3 is not allowed: 0"),
    ("lock where the blade is", fault("1 2 0.5 inf 0.0 nan 0.0"), None),
    ("lock at 0.2 rad", fault("1 2 0.5 inf 0.0 0.2 0.0"), None),
    ("lock at 2 rad", fault("1 2 0.5 inf 0.0 2.0 0.0"), "fault[0].angle_rad = 2 is not "
     "allowed: a number in [0, 1.5708] [rad], or nan"),
    ("lock at inf", fault("1 2 0.5 inf 0.0 inf 0.0"), "fault[0].angle_rad = inf"),
    ("hydraulic omega_n 0", fault("1 3 0.5 inf 0.0 0 0.45"), "fault[0].omega_n = 0"),
    ("hydraulic zeta 0", fault("1 3 0.5 inf 0.0 3.42 0"), "fault[0].zeta = 0"),
    ("hydraulic zeta inf", fault("1 3 0.5 inf 0.0 3.42 inf"), "fault[0].zeta = inf"),
    ("hydraulic", fault("1 3 0.5 inf 0.0 3.42 0.45"), None),
    ("a fault of 6 numbers", fault("1 1 0.5 inf 0.0 0.5"), "a fault line has 6 numbers: 7 "
     "are needed"),
    ("a fault of 8 numbers", fault("1 1 0.5 inf 0.0 0.5 0.0 1"), "a fault line has 8 numbers"),
    ("a fault with a word", fault("1 loe 0.5 inf 0.0 0.5 0.0"), "fault[0].code = 'loe'"),
    ("33 fault lines", extra(*["fault 1 1 0.5 inf 0.0 0.9 0.0"] * 32),
     "fault[32]: at most 32 fault lines"),
    ("32 fault lines", extra(*["fault 1 1 0.5 inf 0.0 0.9 0.0"] * 31), None),
    # every number of every vector NaN, and every bounded one beyond its bound
    *[(f"{key}.{n} nan", vec(key, n, "nan"), f"{key}.{n} = nan is not allowed")
      for key, group in pl.VECTORS.items() for n in lay.names(group)],
    *[(f"{row[0]} past its end", vec(*row[0].split("."), repr(row[2] * 2 + 1)),
       f"{row[0]} = ") for row in pl.checks()["ranges"][:-1] if math.isfinite(row[2])],
]


def _case_file(folder: Path, k: int, text: str) -> Path:
    """The case's bytes: UTF-8, a lone surrogate a raw byte (a Latin-1 one)."""
    path = folder / f"case_{k:03d}.in"
    path.write_bytes(text.encode("utf-8", "surrogateescape"))
    return path


def _run(lib: Path, cases: list[dict], folder: Path, tag: str) -> list[list[dict]]:
    """The cases through tests/discon_host.py's driver in a process of its own."""
    spec, out = folder / f"{tag}.json", folder / f"{tag}.jsonl"
    spec.write_text(json.dumps(cases))
    done = subprocess.run([sys.executable, str(ROOT / "tests" / "discon_host.py"), str(lib),
                           str(spec), str(out)], capture_output=True, text=True, timeout=300,
                          cwd=folder)
    rows = [json.loads(r) for r in out.read_text().splitlines()] if out.exists() else []
    got = {r["case"]: r["calls"] for r in rows if "calls" in r}
    started = [r["case"] for r in rows if r.get("start")]
    assert done.returncode == 0 and len(got) == len(cases), (
        f"the host ended with {done.returncode} in case {started[-1] if started else None}: "
        f"{done.stderr[-800:]}")
    return [got[k] for k in range(len(cases))]


def _calls(path: Path) -> list[list[float]]:
    """A first call and a second one a call interval later, at rated speed."""
    return [[0, 0.0, 1.26711, 122.9, 0.1, 0.1, 0.1],
            [1, INTERVAL, 1.26711, 122.9, 0.1, 0.1, 0.1]]


@pytest.fixture(scope="module")
def answers(base) -> dict[str, list[dict]]:
    """Every case's calls, by case name (one host process for all)."""
    folder = base["folder"] / "cases"
    folder.mkdir()
    specs = []
    for k, (_, mutate, _) in enumerate(CASES):
        text = mutate(base["text"], {"folder": base["folder"], "infile": base["infile"]})
        path = _case_file(folder, k, text)
        specs.append({"infile": str(path), "capacity": CAPACITY, "calls": _calls(path),
                      "dt": INTERVAL})
    results = _run(pl.build(), specs, folder, "cases")
    return {name: calls for (name, *_), calls in zip(CASES, results, strict=True)}


def test_the_cases_are_many_and_named_once():
    names = [c[0] for c in CASES]
    assert len(names) == len(set(names))
    assert sum(1 for c in CASES if c[2] is None) >= 20
    assert sum(1 for c in CASES if c[2] is not None) >= 100


def test_the_valid_settings_file_runs(base, answers):
    """The unmutated file (as Settings writes it) is accepted: the oracle's baseline."""
    folder = base["folder"] / "valid"
    folder.mkdir()
    path = _case_file(folder, 0, base["text"])
    (calls,) = _run(pl.build(), [{"infile": str(path), "capacity": CAPACITY,
                                  "calls": _calls(path), "dt": INTERVAL}], folder, "valid")
    assert [c["fail"] for c in calls] == [0, 0], calls[0]["msg"]


@pytest.mark.parametrize("name, expect", [(c[0], c[2]) for c in CASES],
                         ids=[c[0] for c in CASES])
def test_a_settings_file_is_run_or_refused_at_the_first_call_naming_why(answers, name,
                                                                        expect):
    """Accepted: both calls return aviFAIL = 0 with finite demands. Refused: the first
    call returns aviFAIL = -1 with one line within #49 naming the key, the value and what
    is allowed, and so does every later call (nothing runs after a refusal)."""
    first, second = answers[name]
    if expect is None:
        assert (first["fail"], second["fail"]) == (0, 0), first["msg"] or second["msg"]
        assert all(math.isfinite(d) for d in second["demands"])
        return
    msg = first["msg"]
    assert first["fail"] == -1, f"accepted: {name}"
    assert all(c["within"] and c["terminated"] for c in (first, second))
    assert msg.startswith("wtftc plant library: ") and "\n" not in msg
    assert expect in msg, msg
    assert first["msg_len"] < CAPACITY
    assert second["fail"] == -1 and "before its first call" in second["msg"]


def test_a_refusal_names_the_line_of_the_value(base, answers):
    ls = base["text"].splitlines()
    no = _key_line(ls, "p_turbine") + 1
    assert f".in line {no}: p_turbine.air_density = -5" in answers["air density -5"][0]["msg"]
    no = _key_line(ls, "fault") + 1
    assert f"line {no}: fault[0].onset_s" in answers["fault onset nan"][0]["msg"]


def test_the_settings_file_itself_a_folder_a_fifo_or_missing(base):
    """The file ServoDyn names (DLL_InFile): never opened when it is no regular file."""
    folder = base["folder"]
    specs = [{"infile": str(p), "capacity": CAPACITY, "calls": _calls(p), "dt": INTERVAL}
             for p in (folder / "a_folder", folder / "fifo", folder / "none.in")]
    calls = _run(pl.build(), specs, folder, "special")
    msgs = [c[0]["msg"] for c in calls]
    assert [c[0]["fail"] for c in calls] == [-1] * 3
    assert "not a regular file" in msgs[0] and "not a regular file" in msgs[1]
    assert "cannot open its settings file (No such file or directory)" in msgs[2]


def test_the_message_fits_the_room_the_host_gives(base):
    """A refusal within #49 bytes whatever the host gives, a path of 4000 bytes shown by
    its end: the key and the value are never cut away by a long path."""
    deep = base["folder"] / ("d" * 200) / ("e" * 200)
    deep.mkdir(parents=True)
    path = deep / "plant.in"
    path.write_text(vec("p_turbine", "air_density", "-5")(base["text"], {}))
    specs = [{"infile": str(path), "capacity": cap, "calls": _calls(path)[:1],
              "dt": INTERVAL} for cap in (1025, 200, 80, 1, 0)]
    calls = _run(pl.build(), specs, base["folder"], "room")
    for spec, (call,) in zip(specs, calls, strict=True):
        assert call["fail"] == -1 and call["within"] and call["terminated"]
        if spec["capacity"] > 1:
            assert call["msg_len"] <= spec["capacity"] - 1
    assert "p_turbine.air_density = -5 is not allowed" in calls[0][0]["msg"]
    assert calls[0][0]["msg_len"] < 500 and calls[3][0]["untouched"] is False


def test_the_call_interval_bounds_the_actuator_step(base):
    """actuator_dt against the interval ServoDyn calls at (#3): the default 1 ms is
    refused in a call of 2.5 ms (no whole number of steps) and of 200 s (2e5 steps)."""
    folder = base["folder"] / "interval"
    folder.mkdir()
    path = _case_file(folder, 0, base["text"])
    specs = [{"infile": str(path), "capacity": CAPACITY, "calls": _calls(path)[:1], "dt": dt}
             for dt in (0.0025, 200.0, 0.005, 0.0, float("nan"))]
    calls = _run(pl.build(), specs, folder, "interval")
    assert [c[0]["fail"] for c in calls] == [-1, -1, 0, -1, -1]
    assert "actuator_dt = 0.001 is not allowed" in calls[0][0]["msg"]
    assert "at most 100000 a call" in calls[1][0]["msg"]
    assert "the call interval (#3, ServoDyn's DLL_DT) = 0 s" in calls[3][0]["msg"]


# -- the Python side: the same values refused before a file is written -----------------

#: (what is changed, the field Settings.check names)
PY_CASES = [
    ({"p_turbine": ("omega_n_nominal", math.nan)}, "p_turbine.omega_n_nominal"),
    ({"p_turbine": ("omega_n_nominal", -11.11)}, "p_turbine.omega_n_nominal"),
    ({"p_turbine": ("zeta_nominal", -0.6)}, "p_turbine.zeta_nominal"),
    ({"p_turbine": ("pitch_rate_max", 0.0)}, "p_turbine.pitch_rate_max"),
    ({"p_turbine": ("pitch_min", 1.6)}, "p_turbine.pitch_min"),
    ({"p_turbine": ("air_density", -5.0)}, "p_turbine.air_density"),
    ({"p_sensors": ("lag_omega_r_m1", 0.1)}, "p_sensors.lag_omega_r_m1"),
    ({"actuator_dt": math.inf}, "actuator_dt"),
    ({"actuator_dt": 1e9}, "actuator_dt"),
    ({"actuator_dt": 1e-9}, "actuator_dt"),
    ({"actuator_dt": math.nan}, "actuator_dt"),
    ({"fault": {"onset_s": math.nan}}, "fault[0].onset_s"),
    ({"fault": {"rho": -5.0}}, "fault[0].rho"),
    ({"fault": {"end_s": 0.5}}, "fault[0].end_s"),
    ({"fault": {"blade": 4}}, "fault[0].blade"),
    ({"noise_columns": 11}, "noise_columns"),
    ({"noise_columns": 60}, "noise_columns"),
    ({"controller_library": "fifo"}, "controller_library"),
    ({"controller_infile": "a_folder"}, "controller_infile"),
    ({"records": "a_folder"}, "records"),
]


def _changed(base: dict, change: dict) -> pl.Settings:
    import copy
    import dataclasses

    s = copy.deepcopy(base["settings"])
    for key, val in change.items():
        if key in ("p_turbine", "p_sensors"):
            name, v = val
            vec_ = np.array(getattr(s, key), dtype=float)
            vec_[lay.index(pl.VECTORS[key], name)] = v
            setattr(s, key, vec_)
        elif key == "fault":
            s.faults = [dataclasses.replace(s.faults[0], **val)]
        elif key in ("controller_library", "controller_infile", "records"):
            setattr(s, key, base["folder"] / val)
        else:
            setattr(s, key, val)
    return s


@pytest.mark.parametrize("change, field", PY_CASES, ids=[f for _, f in PY_CASES])
def test_settings_refuses_what_the_library_refuses_before_writing(base, tmp_path, change,
                                                                  field):
    """Settings.write checks with the library's own tables: a ConfigError naming the same
    key, and no file (nor a temporary one) written."""
    with pytest.raises(ConfigError) as exc:
        _changed(base, change).write(tmp_path / "wtftc_plant.in")
    assert exc.value.field == field
    assert not list(tmp_path.iterdir())


def test_settings_and_the_library_give_the_same_verdict_on_every_number(base, answers):
    """Every case of the table that changes numbers only: Python's check of the same
    values (discon_checks.refusal on plant_library.checks, what Settings.check runs)
    refuses exactly where the library refused, naming the same key."""
    checked = 0
    for name, mutate, expect in CASES:
        if not getattr(mutate, "values_only", False):
            continue
        text = mutate(base["text"], {})
        words = {ln.split()[0]: ln.split()[1:] for ln in text.splitlines()
                 if ln.split() and ln.split()[0] in pl.VECTORS}
        try:
            values = {f"{key}.{n}": float.fromhex(w) if w.startswith("0x") else float(w)
                      for key, ws in words.items()
                      for n, w in zip(lay.names(pl.VECTORS[key]), ws, strict=True)}
        except ValueError:
            continue  # a word: the file's form, not a value
        values["actuator"] = 1.0
        bad = discon_checks.refusal(pl.checks(), values)
        if expect is None:
            assert bad is None, (name, bad)
        else:
            assert bad is not None and f"{bad[0]} = " in answers[name][0]["msg"], (name, bad)
        checked += 1
    assert checked >= 35


def test_a_refused_file_touches_no_file(base):
    """Refused at the first call: the records file it names is neither created nor
    truncated, and the noise table is left as it was."""
    folder = base["folder"] / "untouched"
    folder.mkdir()
    kept = folder / "records.bin"
    kept.write_bytes(b"a user's file")
    noise = base["noise"].read_bytes()
    texts = [line("records", str(kept))(vec("p_turbine", "air_density", "-5")(
                 base["text"], {}), {}),
             line("records", str(folder / "new.bin"))(fault("1 1 nan inf 0 0.5 0")(
                 base["text"], {}), {})]
    specs = [{"infile": str(_case_file(folder, k, t)), "capacity": CAPACITY,
              "calls": _calls(folder)[:1], "dt": INTERVAL} for k, t in enumerate(texts)]
    calls = _run(pl.build(), specs, folder, "untouched")
    assert [c[0]["fail"] for c in calls] == [-1, -1]
    assert kept.read_bytes() == b"a user's file" and not (folder / "new.bin").exists()
    assert base["noise"].read_bytes() == noise
