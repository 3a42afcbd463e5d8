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
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import casadi as ca
import numpy as np

from wtftc.artefacts import layout as lay
from wtftc.artefacts.loader import built_once, cache_dir, compiler, load, manifest
from wtftc.errors import EngineError
from wtftc.model.faults import HYDRAULIC, Fault, Schedule

HERE = Path(__file__).resolve().parent
SOURCE = HERE / "plant_library.c"
#: the renamed generated functions the library calls (their own names would be global
#: symbols of a library loaded into OpenFAST's process)
FUNCTIONS = {"pitch_actuator": "wtftcp_actuator", "sensors": "wtftcp_sensors"}
#: fault type codes of the settings file (plant_library.c)
LOE, LOCK, HYDRAULIC_CODE = 1, 2, 3
#: the columns of the records file, before the controller's logged channels
RECORD_COLUMNS = ("t", "v_1", "v_2", "v_3", "beta_1", "beta_2", "beta_3", "beta_rate_1",
                  "beta_rate_2", "beta_rate_3", "read_omega_r", "read_omega_g_hss",
                  "read_beta_1", "read_beta_2", "read_beta_3", "torque_demand_hss")
#: the actuator's integration step inside each call [s]: wtftc's own plant step
ACTUATOR_DT = 0.001


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
             rc.p_turbine, rc.p_sensors, base=folder).write(folder / SETTINGS)
    (folder / "servodyn_snippet.txt").write_text(
        discon.servodyn_snippet(c, rc.control_interval, LIBRARY, SETTINGS))
    with open(folder / "README.txt", "a", encoding="utf-8") as f:
        f.write(f"""
WITH THE ACTUATOR (--with-actuator). {LIBRARY} is wtftc's plant-side pitch actuator
library: ServoDyn calls it (servodyn_snippet.txt), it reads {SETTINGS}, passes the
readings to libwtftc_{c}.so and drives each blade through the benchmark actuator (the
turbine parameters in {SETTINGS}: omega_n, zeta, rate and position limits), integrated
at {ACTUATOR_DT:g} s inside each call. Sensors: exact. Faults: none; a line
'fault <blade 1-3> <1 loss of effectiveness|2 lock|3 hydraulic> <onset s> <end s> <ramp s>
<rho|angle rad|omega_n> <0|0|zeta>' adds one. Each call appends a row to {RECORDS}.
""")
def _numbers(values) -> str:
    return " ".join(repr(float(v)) for v in np.asarray(values, dtype=float).ravel())


def fault_lines(faults: Sequence[Fault], p_turbine) -> list[str]:
    """The actuator faults as the settings file's ``fault`` lines: blade, code, onset,
    end, ramp and two numbers (ρ | the angle, NaN for "where the blade is" | ω_n, ζ of
    the hydraulic fault at its severity, as Schedule.actuator blends them)."""
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
            continue  # a sensor fault: in the noise table
        out.append(f"fault {f.blade} {code} {_numbers([f.onset_s, f.end_s, f.ramp_s, a, b])}")
    return out


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

    def write(self, path: Path) -> Path:
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
