"""The plant-side actuator, fault and sensor library OpenFAST loads (issue 32; ours).

``libwtftc_plant.so`` is a DISCON-shaped library: ServoDyn calls it, it calls the real
controller library, and between the two it puts wtftc's pitch actuator with its faults
and wtftc's sensors (``plant_library.c`` says how). This module builds it (the generated
``pitch_actuator`` and ``sensors`` functions as C, with the hand-written interface,
compiled once into wtftc's cache), writes its settings file, its noise table and reads
its records back.

Why this way: this is how the field injects pitch faults without patching OpenFAST, and
controller and plant stay apart; ROSCO's own fault modes (PF_Mode) act inside ROSCO.
"""

from __future__ import annotations

import hashlib
import math
import os
import shutil
import stat
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import casadi as ca
import numpy as np

from wtftc.artefacts import layout as lay
from wtftc.artefacts.loader import built_once, cache_dir, compiler, load, manifest
from wtftc.errors import ConfigError, EngineError, range_text
from wtftc.export import discon_checks
from wtftc.model.faults import HYDRAULIC, Fault, Schedule

HERE = Path(__file__).resolve().parent
SOURCE = HERE / "plant_library.c"
#: the renamed generated functions the library calls (their own names would be global
#: symbols of a library loaded into OpenFAST's process)
FUNCTIONS = {"pitch_actuator": "wtftcp_actuator", "sensors": "wtftcp_sensors"}
#: fault type codes of the settings file (plant_library.c)
LOE, LOCK, HYDRAULIC_CODE = 1, 2, 3
FAULT_CODES = f"{LOE} (loss of effectiveness), {LOCK} (lock) or {HYDRAULIC_CODE} (hydraulic)"
#: the columns of the records file, before the controller's logged channels
RECORD_COLUMNS = ("t", "v_1", "v_2", "v_3", "beta_1", "beta_2", "beta_3", "beta_rate_1",
                  "beta_rate_2", "beta_rate_3", "read_omega_r", "read_omega_g_hss",
                  "read_beta_1", "read_beta_2", "read_beta_3", "torque_demand_hss")
#: the actuator's integration step inside each call [s]: wtftc's own plant step
ACTUATOR_DT = 0.001
#: the most actuator steps one call may take (a step of 1e-9 s in a 10-ms call would take
#: 1e7 RK4 steps, minutes a call)
MAX_SUBSTEPS = 100_000
#: the most fault lines a settings file holds (plant_library.c)
MAX_FAULTS = 32
#: the settings file's number vectors: key -> layout group, in the file's order
VECTORS = {"p_turbine": "turbine_params", "p_sensors": "sensor_params",
           "sensor_faults": "sensor_faults"}
#: the sensor chain's fault inputs at rest, by prefix (longest first): their ranges as a
#: sensor fault sets them (wtftc.model.faults: a gain and a precision factor > 0, a stuck
#: weight in [0, 1], offsets and stuck values any finite number)
_SENSOR_FAULT_RANGES = {"stuck_value_": (-math.inf, math.inf, True, True),
                        "noise_factor_": (0.0, math.inf, True, True),
                        "gain_": (0.0, math.inf, True, True),
                        "stuck_": (0.0, 1.0, False, False),
                        "offset_": (-math.inf, math.inf, True, True)}
#: the noise table's column counts (the draws of the ten sensors, and the sensor faults'
#: inputs where the run has sensor faults: noise_table)
NOISE_COLUMNS = (2 * (2 + lay.layout()["n_blades"]),
                 2 * (2 + lay.layout()["n_blades"]) + len(lay.names("sensor_faults")))


def _row(label: str, rng: tuple, unit: str, note: str = "") -> tuple:
    """A check table row (discon_checks.layout_row's shape) of a range wtftc states here."""
    text = (f"{rng[0]:g}" + (f" [{unit}]" if unit else "") if rng[0] == rng[1]
            else range_text(*rng, unit))
    return (label, *rng, text + note, False)


def _vector_row(key: str, group: str, name: str) -> tuple:
    label = f"{key}.{name}"
    if group == "sensor_faults":
        prefix = next(p for p in _SENSOR_FAULT_RANGES if name.startswith(p))
        unit = next(e["unit"] for e in lay.layout()[group] if e["name"] == name)
        return _row(label, _SENSOR_FAULT_RANGES[prefix], unit)
    if name.startswith("lag_"):  # the library's sensors have no lag state
        return _row(label, (0.0, 0.0, False, False), "s", " (the plant library's sensors "
                    "have no lag: wtftc refuses one with engine = openfast)")
    return discon_checks.layout_row(group, name, label)


def checks() -> dict:
    """What the library checks at its first call, as the exported controller's table
    (wtftc.export.discon_checks): ``ranges`` of every number of p_turbine, p_sensors and
    sensor_faults (labelled ``<key>.<name>``: the layout's ``valid`` ranges, the ones
    wtftc.config checks; a lag 0; the sensor faults' inputs as wtftc.model.faults bounds
    them) and of the ``actuator`` switch; ``order`` and ``one_of``, wtftc.config's
    cross-checks (discon_checks.cross_checks); ``faults``, the ranges of a fault line's
    onset and ramp, and per fault code the names and ranges of its two numbers."""
    ranges = [_vector_row(key, group, name) for key, group in VECTORS.items()
              for name in lay.names(group)]
    ranges.append(("actuator", 0.0, 1.0, False, False, "0 or 1", False))
    order, one_of = discon_checks.cross_checks([r[0] for r in ranges])
    one_of.append(("actuator", (0.0, 1.0), "0 (the blades follow the demands) or 1 "
                   "(wtftc's pitch actuator)"))
    tp = {e["name"]: e["unit"] for e in lay.layout()["turbine_params"]}
    pos, half_pi = (0.0, math.inf, True, True), math.pi / 2
    numbers = {
        LOE: (_row("rho", (0.0, 1.0, True, False), "-", " (the blade's effectiveness)"),
              _row("unused", (0.0, 0.0, False, False), "", " (a loss of effectiveness has "
                   "one number)")),
        LOCK: (_row("angle_rad", (0.0, half_pi, False, False), "rad", ", or nan: where the "
                    "blade is at onset"),
               _row("unused", (0.0, 0.0, False, False), "", " (a lock has one number)")),
        HYDRAULIC_CODE: (_row("omega_n", pos, tp["omega_n_nominal"]),
                         _row("zeta", pos, tp["zeta_nominal"]))}
    times = (_row("onset_s", (0.0, math.inf, False, True), "s"),
             _row("ramp_s", (0.0, math.inf, False, True), "s"))
    return {"ranges": ranges, "order": order, "one_of": one_of,
            "faults": {"times": times, "numbers": numbers}}


def _checks_header() -> str:
    """wtftc_plant_checks.h: :func:`checks` as the C tables of discon_checks.c_tables, the
    labels the messages give, and the fault lines' tables."""
    c = checks()
    labels = ", ".join(f'"{r[0]}"' for r in c["ranges"])
    f = c["faults"]
    codes = sorted(f["numbers"])
    numbers = ",\n    ".join("{" + discon_checks.c_rows(f["numbers"][k]) + "}" for k in codes)
    names = ", ".join("{" + ", ".join(f'"{r[0]}"' for r in f["numbers"][k]) + "}"
                      for k in codes)
    title = ("wtftc's plant library: the checks of every number of its settings file\n"
             " * (wtftc.openfast.plant_library.checks: the layout's valid ranges and "
             "wtftc.config's cross-checks)")
    return discon_checks.c_tables(c, str(len(c["ranges"])), title) + f"""\
#define WTFTCP_N_CHECKED {len(c["ranges"])}
static const char *const WTFTCP_NAMES[WTFTCP_N_CHECKED] = {{{labels}}};
/* a fault line: its onset and ramp, and per code (1-3) its two numbers */
static const WtftcRange WTFTCP_FAULT_TIMES[2] = {{
    {discon_checks.c_rows(f["times"])}
}};
static const WtftcRange WTFTCP_FAULT_NUMBERS[3][2] = {{
    {numbers}
}};
static const char *const WTFTCP_FAULT_NAMES[3][2] = {{{names}}};
#define WTFTCP_FAULT_CODES "{FAULT_CODES}"
#define WTFTCP_NAN_OK_CODE {LOCK}
#define WTFTCP_MAX_SUBSTEPS {MAX_SUBSTEPS}
"""


def _renamed(name: str, new: str) -> ca.Function:
    f = load(name, "interpreted")
    ins = [ca.SX.sym(f.name_in(i), f.sparsity_in(i)) for i in range(f.n_in())]
    return ca.Function(new, ins, f.call(ins), f.name_in(), f.name_out())


def _meta_header() -> str:
    tp = lay.names("turbine_params")
    af = lay.names("actuator_faults")
    lines = ["/* written by wtftc.openfast.plant_library: the layout's sizes and indices */",
             f"#define WTFTCP_N_TURBINE {len(tp)}",
             f"#define WTFTCP_OMEGA_N_NOMINAL {tp.index('omega_n_nominal')}",
             f"#define WTFTCP_ZETA_NOMINAL {tp.index('zeta_nominal')}",
             f"#define WTFTCP_N_SENSOR_PARAMS {len(lay.names('sensor_params'))}",
             f"#define WTFTCP_N_SENSOR_FAULTS {len(lay.names('sensor_faults'))}",
             f"#define WTFTCP_N_ACT_FAULTS {len(af)}"]
    for key in ("rho", "lock", "ubar", "omega_n", "zeta"):
        lines.append(f"#define WTFTCP_AF_{key.upper()} {af.index(key + '_1')}")
    return "\n".join(lines) + "\n"


def _key() -> str:
    h = hashlib.sha256(SOURCE.read_bytes())
    h.update(_meta_header().encode())
    h.update(_checks_header().encode())
    arts = manifest()["artefacts"]
    for name in FUNCTIONS:
        h.update(str(arts.get(name + ".casadi")).encode())
    return h.hexdigest()[:20]


def build() -> Path:
    """``libwtftc_plant.so``, compiled into wtftc's cache once per source and generated
    code (a fresh folder renamed into place: never half-built)."""
    cc = compiler()
    if cc is None:
        raise EngineError("the plant library needs a C compiler: set CC or install gcc")

    def make(tmp: Path) -> None:
        from wtftc.export.discon import compile_library

        cg = ca.CodeGenerator("wtftc_plant_gen.c", {"with_header": False, "verbose": False})
        for name, new in FUNCTIONS.items():
            cg.add(_renamed(name, new))
        cg.generate(str(tmp) + "/")
        (tmp / "wtftc_plant_meta.h").write_text(_meta_header())
        (tmp / "wtftc_plant_checks.h").write_text(_checks_header())
        shutil.copy(SOURCE, tmp / SOURCE.name)
        compile_library([cc, "-O2", "-std=c99", "-shared", "-fPIC", "-fvisibility=hidden", "-o",
                         str(tmp / LIBRARY), str(tmp / "wtftc_plant_gen.c"),
                         str(tmp / SOURCE.name), "-ldl", "-lm"], cc)

    return built_once(cache_dir() / f"plant_library-{_key()}", LIBRARY, make)


#: the files `wtftc export discon --with-actuator` adds beside the controller's
LIBRARY, SETTINGS, RECORDS = "libwtftc_plant.so", "wtftc_plant.in", "wtftc_plant_records.bin"


def add_to_export(rc, folder: Path) -> None:
    """`wtftc export discon --with-actuator`: the plant library and its settings beside an
    exported controller in ``folder`` (wtftc.export.discon.export calls this before the
    folder is swapped in). ServoDyn calls the plant library, which calls the controller:
    the turbine's benchmark actuator (rc's turbine parameters), no fault (a ``fault`` line
    added by hand adds one: docs/discon.md), sensors exact (no noise table). Its records
    go to ``wtftc_plant_records.bin`` beside the settings; every path is relative to them."""
    from wtftc.export import discon

    c = rc.loop.controller
    shutil.copy2(build(), folder / LIBRARY)
    Settings(folder / f"libwtftc_{c}.so", folder / f"wtftc_{c}.IN", folder / RECORDS,
             rc.p_turbine, rc.p_sensors, base=folder,
             interval=rc.control_interval).write(folder / SETTINGS)
    (folder / "servodyn_snippet.txt").write_text(
        discon.servodyn_snippet(c, rc.control_interval, LIBRARY, SETTINGS))
    with open(folder / "README.txt", "a", encoding="utf-8") as f:
        f.write(actuator_readme(c, rc.control_interval))


def actuator_readme(controller: str, interval: float) -> str:
    """The README's section on the plant library an export with --with-actuator holds."""
    sensors = " ".join(e["name"] for e in lay.layout()["sensors"])
    return f"""
WITH THE ACTUATOR (--with-actuator). {LIBRARY} is wtftc's plant-side pitch actuator
library: ServoDyn calls it (servodyn_snippet.txt names it and {SETTINGS}: the steps
above put it in as they are), it reads {SETTINGS}, passes the readings to
libwtftc_{controller}.so and drives each blade through the benchmark actuator (the
turbine parameters in {SETTINGS}: omega_n, zeta, rate and position limits), integrated
at {ACTUATOR_DT:g} s inside each call of {interval:g} s. Every path in {SETTINGS} is
relative to its folder. Each call appends a row to {RECORDS} there (wtftc's
plant_library.read_records reads it: the demands, the blades, the readings).
Faults: none; a line 'fault <blade 1-3> <1 loss of effectiveness|2 lock|3 hydraulic>
<onset s> <end s> <ramp s> <rho|angle rad|omega_n> <0|0|zeta>' adds one.
Sensors: exact (the resolution in p_sensors only) unless two lines name a noise table:
'noise <file>' and 'noise_columns {NOISE_COLUMNS[0]}'. The file holds float64
little-endian rows of {NOISE_COLUMNS[0]} standard normal draws, one row per call, the
sensors in this order: {sensors}; the noise sigma of p_sensors scales them. A
`wtftc run --engine openfast --out OUT` writes its run's draws as
OUT/openfast/wtftc_noise.bin: with that table, the wind file of OUT/openfast/ and the
operating point of step 4, your deck runs that run (tests/test_export_openfast.py).
Every value of {SETTINGS} is checked at the first call against wtftc's own ranges (the
turbine's, the sensors', a fault's; pitch_min below pitch_max; actuator_dt dividing the
call interval): a bad one stops OpenFAST with one line naming the key, the value and
what is allowed.
"""


def _numbers(values) -> str:
    return " ".join(repr(float(v)) for v in np.asarray(values, dtype=float).ravel())


def fault_numbers(faults: Sequence[Fault], p_turbine) -> list[tuple]:
    """The actuator faults as the seven numbers of the settings file's ``fault`` lines:
    blade, code, onset, end, ramp and two numbers (ρ | the angle, NaN for "where the blade
    is" | ω_n, ζ of the hydraulic fault at its severity, as Schedule.actuator blends them);
    a sensor fault is in the noise table instead."""
    tp = lay.values("turbine_params", p_turbine)
    wn0, z0 = tp["omega_n_nominal"], tp["zeta_nominal"]
    out = []
    for f in faults:
        if f.type == "loss_of_effectiveness":
            code, a, b = LOE, f.rho, 0.0
        elif f.type in ("lock", "runaway"):
            code, a, b = LOCK, (math.nan if f.angle is None else f.angle), 0.0
        elif f.type in HYDRAULIC:
            wf, zf = HYDRAULIC[f.type]
            code, a, b = HYDRAULIC_CODE, wn0 + f.severity * (wf - wn0), z0 + f.severity * (zf - z0)
        else:
            continue
        out.append((float(f.blade), float(code), float(f.onset_s), float(f.end_s),
                    float(f.ramp_s), float(a), float(b)))
    return out


def fault_lines(faults: Sequence[Fault], p_turbine) -> list[str]:
    """The actuator faults as the settings file's ``fault`` lines (:func:`fault_numbers`,
    blade and code as integers)."""
    return [f"fault {int(v[0])} {int(v[1])} {_numbers(v[2:])}"
            for v in fault_numbers(faults, p_turbine)]


def check_fault(k: int, v: Sequence[float], spec: dict) -> None:
    """A fault line's seven numbers (:func:`fault_numbers`) against ``spec`` (checks()'s
    ``faults``), as the library checks them: a ConfigError naming ``fault[k].<word>``."""
    pre = f"fault[{k}]."
    if v[0] not in (1.0, 2.0, 3.0):
        raise ConfigError(pre + "blade", v[0], "1, 2 or 3")
    if v[1] not in spec["numbers"]:
        raise ConfigError(pre + "code", v[1], FAULT_CODES)
    for w, row in zip((2, 4), spec["times"], strict=True):
        if not discon_checks.in_range(row, v[w]):
            raise ConfigError(pre + row[0], v[w], row[5])
    if not v[3] > v[2]:
        raise ConfigError(pre + "end_s", v[3], f"a time after onset_s = {v[2]:g} s, or inf "
                          "(no end)")
    for i, row in enumerate(spec["numbers"][int(v[1])]):
        if i == 0 and v[1] == LOCK and math.isnan(v[5]):
            continue  # a lock where the blade is at onset
        if not discon_checks.in_range(row, v[5 + i]):
            raise ConfigError(pre + row[0], v[5 + i], row[5])


def check_step(dt: float, interval: float | None) -> None:
    """The actuator's step: finite and > 0; with the call interval known, not above it,
    dividing it into whole steps, at most MAX_SUBSTEPS of them (as the library checks it
    against #3 at its first call)."""
    if not (math.isfinite(dt) and dt > 0):
        raise ConfigError("actuator_dt", dt, "a number > 0 [s]")
    if interval is None:
        return
    n = round(interval / dt)
    if not (1 <= n <= MAX_SUBSTEPS and abs(n * dt - interval) <= 1e-6 * interval):
        raise ConfigError("actuator_dt", dt, f"a step in [{interval / MAX_SUBSTEPS:.4g}, "
                          f"{interval:.6g}] [s] that divides the call interval ({interval:.6g}"
                          f" s) into whole steps, at most {MAX_SUBSTEPS} a call")


def _regular(key: str, path: Path, what: str) -> os.stat_result:
    try:
        st = os.stat(path)
    except OSError as exc:
        raise ConfigError(key, str(path), f"{what} ({exc.strerror})") from None
    if not stat.S_ISREG(st.st_mode):
        kind = "folder" if stat.S_ISDIR(st.st_mode) else (
            "FIFO" if stat.S_ISFIFO(st.st_mode) else "special file")
        raise ConfigError(key, str(path), f"{what} (this is a {kind})")
    return st


@dataclass
class Settings:
    """What the library reads at its first call."""

    controller_library: Path
    controller_infile: Path
    records: Path
    p_turbine: np.ndarray
    p_sensors: np.ndarray
    faults: Sequence[Fault] = ()
    noise: Path | None = None
    noise_columns: int = 0
    actuator: bool = True
    actuator_dt: float = ACTUATOR_DT
    #: the call interval ServoDyn will call the library at [s] (DLL_DT), when known: the
    #: actuator step is checked against it before the file is written
    interval: float | None = None
    #: the folder the settings file lies in when the files under it are to be named
    #: relative to it (a case or an export that can be moved whole); None: absolute
    base: Path | None = None

    def _path(self, p: Path) -> str:
        p = Path(p).resolve()
        if self.base is not None and p.is_relative_to(Path(self.base).resolve()):
            return os.path.relpath(p, Path(self.base).resolve())
        return str(p)

    def text(self) -> str:
        sf0 = Schedule([], tuple(self.p_turbine)).sensor(np.zeros(1))[:, 0]
        lines = ["# wtftc plant-side actuator, fault and sensor library (wtftc.openfast)",
                 f"controller_library {self._path(self.controller_library)}",
                 f"controller_infile {self._path(self.controller_infile)}",
                 f"records {self._path(self.records)}",
                 f"actuator {int(self.actuator)}",
                 f"actuator_dt {self.actuator_dt!r}",
                 "# p_turbine, in this order [SI]: " + " ".join(lay.names("turbine_params")),
                 f"p_turbine {_numbers(self.p_turbine)}",
                 "# p_sensors, in this order [SI] (the noise σ act only with a noise table): "
                 + " ".join(lay.names("sensor_params")),
                 f"p_sensors {_numbers(self.p_sensors)}",
                 "# sensor_faults at rest, in this order: " + " ".join(lay.names("sensor_faults")),
                 f"sensor_faults {_numbers(sf0)}",
                 "# fault <blade 1-3> <1 loss of effectiveness | 2 lock | 3 hydraulic> <onset s>"
                 " <end s> <ramp s> <rho | angle rad (nan: where the blade is) | omega_n rad/s>"
                 " <0 | 0 | zeta>",
                 *fault_lines(self.faults, self.p_turbine)]
        if self.noise is not None:
            lines += [f"noise {self._path(self.noise)}",
                      f"noise_columns {self.noise_columns}"]
        return "\n".join(lines) + "\n"

    def values(self) -> dict[str, float]:
        """The numbers the file gives, by the labels of :func:`checks`."""
        vecs = {"p_turbine": self.p_turbine, "p_sensors": self.p_sensors,
                "sensor_faults": Schedule([], tuple(self.p_turbine)).sensor(np.zeros(1))[:, 0]}
        out = {}
        for key, group in VECTORS.items():
            names, vec = lay.names(group), np.asarray(vecs[key], dtype=float).ravel()
            if vec.size != len(names):
                raise ConfigError(key, f"{vec.size} numbers", f"{len(names)} ({names[0]} ... "
                                  f"{names[-1]})")
            out.update({f"{key}.{n}": float(v) for n, v in zip(names, vec, strict=True)})
        out["actuator"] = float(self.actuator)
        return out

    def check(self) -> None:
        """Refuse what the library would refuse at its first call (the same tables:
        :func:`checks`), so that a bad value never reaches OpenFAST: a ConfigError naming
        the key, the value and what is allowed."""
        c = checks()
        bad = discon_checks.refusal(c, self.values())
        if bad is not None:
            raise ConfigError(*bad)
        check_step(float(self.actuator_dt), self.interval)
        lines = fault_numbers(self.faults, self.p_turbine)
        if len(lines) > MAX_FAULTS:
            raise ConfigError("fault", f"{len(lines)} actuator faults", f"at most {MAX_FAULTS}")
        for k, v in enumerate(lines):
            check_fault(k, v, c["faults"])
        self._check_paths()

    def _check_paths(self) -> None:
        _regular("controller_library", self.controller_library,
                 "an existing regular file, the controller's DISCON library")
        _regular("controller_infile", self.controller_infile,
                 "an existing regular file, the controller's input file")
        rec = Path(self.records)
        if not rec.parent.is_dir() or (rec.exists() and not rec.is_file()):
            raise ConfigError("records", str(rec), "a regular file or none, in an existing "
                              "folder")
        if self.noise is None:
            return
        if self.noise_columns not in NOISE_COLUMNS:
            raise ConfigError("noise_columns", self.noise_columns, f"{NOISE_COLUMNS[0]} (the "
                              f"sensors' noise draws) or {NOISE_COLUMNS[1]} (and the sensor "
                              "faults' inputs)")
        size = _regular("noise", self.noise, "an existing regular file, the noise table").st_size
        if size == 0 or size % (8 * self.noise_columns):
            raise ConfigError("noise_columns", self.noise_columns, f"the noise table's size, "
                              f"{size} bytes, is no whole number of its rows "
                              f"({8 * self.noise_columns} bytes each)")

    def write(self, path: Path) -> Path:
        """The settings file at ``path``, after :meth:`check` (nothing written when it
        refuses)."""
        self.check()
        _atomic_write(path, self.text().encode())
        return path


def _atomic_write(path: Path, data: bytes) -> None:
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_bytes(data)
    os.replace(tmp, path)


def noise_table(noise_seed: int, n_calls: int, interval: float, schedule: Schedule | None,
                path: Path) -> int:
    """The standard normal draws of every sensor, one per call, from the same streams as
    wtftc's sampled loop (one generator per sensor from the run's noise seed,
    ``integrate._noise_streams``), and, where the run has sensor faults, their inputs at
    each call (Schedule.sensor); written as float64 rows. Returns the column count."""
    names = [e["name"] for e in lay.layout()["sensors"]]
    gens = [np.random.default_rng(np.random.SeedSequence(noise_seed, spawn_key=(7, k)))
            for k in range(len(names))]
    cols = [g.standard_normal(n_calls) for g in gens]
    table = np.column_stack(cols)
    if schedule is not None and schedule.has_sensor_faults:
        table = np.hstack([table, schedule.sensor(np.arange(n_calls) * interval).T])
    _atomic_write(path, np.ascontiguousarray(table, dtype="<f8").tobytes())
    return table.shape[1]


def read_records(path: Path) -> dict[str, np.ndarray]:
    """The library's records: RECORD_COLUMNS and ``logged_<k>`` per call."""
    try:
        data = Path(path).read_bytes()
    except OSError as exc:
        raise EngineError(f"the plant library wrote no records ({path}): {exc.strerror}") \
            from None
    head, _, body = data.partition(b"\n")
    words = head.decode(errors="replace").split()
    if words[:4] != ["wtftc", "plant", "records", "1"]:
        raise EngineError(f"{path} is not a records file of the plant library")
    n_cols, n_log = int(words[5]), int(words[7])
    rows = np.frombuffer(body[:len(body) - len(body) % (8 * n_cols)], dtype="<f8")
    rows = rows.reshape(-1, n_cols)
    names = [*RECORD_COLUMNS, *[f"logged_{k + 1}" for k in range(n_log)]]
    return {n: rows[:, i].copy() for i, n in enumerate(names)}
