"""A controller as data: the ``[controller]`` table of a run's configuration, and the
named presets shipped in ``wtftc/data/presets.toml`` (docs/controllers.md).

A table names a design, how it accommodates a pitch fault, and any of its settings::

    [controller]
    preset = "aftc-nrel5mw"    # optional: start from a preset; the keys below change it
    design = "physical"        # physical, pi, paper, drivetrain, rosco, discon (or any registered)
    accommodation = "fdi"      # none | known (told the fault: an oracle) | fdi
    phys_obs_omega = 3.0       # the design's parameters, by their generated/layout.json name
    vs_constant_torque = 1     # the torque law's options (turbine_params gen_*, vs_*)
    omega_n_rad_s = 0.6        # the pitch loop's target mode (wtftc.campaign.tune)
    zeta = 0.7

:func:`expand` turns it into the keys every engine reads (``controller``, ``case``,
``controller_params``, ``turbine_params``, ``tuning``); their ranges are checked there
(wtftc.config), and a refusal names ``controller.<key>``.

``design = "discon"`` runs a Bladed-style DISCON library wtftc did not build, in OpenFAST
behind the plant library's actuator, faults and sensors, as ROSCO runs (docs/openfast.md)::

    [controller]
    design = "discon"
    library = "build/libdiscon.so"   # a shared object; relative: to the folder wtftc runs in
    input = "build/DISCON.IN"        # its input file, given to it as it is (not copied)

Both are kept absolute with their sha256 (``library_sha256``, ``input_sha256``): a table
that gives a hash refuses a file that no longer has it.
"""

from __future__ import annotations

import copy
import functools
import importlib.resources
import math
import numbers
import os
import tomllib
from dataclasses import dataclass
from pathlib import Path

from wtftc.artefacts import layout as lay
from wtftc.errors import ConfigError

#: the cases of a run (wtftc.config.CASES): no fault; a fault the controller is not told;
#: one told to eq (49) as it happens (an oracle); one detected by wtftc's FDI
FAULT_FREE_CASE, UNAWARE_CASE, ORACLE_CASE, FDI_CASE = 1, 2, 3, 4
#: how a controller meets a pitch fault, and the case it runs in under one
ACCOMMODATIONS = {"none": UNAWARE_CASE, "known": ORACLE_CASE, "fdi": FDI_CASE}
#: the pitch loop's target mode (wtftc.campaign.tune): key → (default, low, high)
TUNING_KEYS = {"omega_n_rad_s": (None, 0.01, 10.0), "zeta": (None, 0.1, 2.0),
               "design_wind_mps": (16.0, 3.0, 40.0), "c2_over_c1": (2.0, 1.0, 10.0)}
#: the torque law's settings a controller table may set (the rest of turbine_params are
#: the turbine's facts, set in its file or in [turbine_params])
TORQUE_FLAGS = ("gen_torque_law", "gen_constant_power", "vs_constant_torque")
#: a table's keys that are not settings
META_KEYS = ("preset", "design", "accommodation", "doc", "tuned_for")
#: the presets' file, in wtftc/data
PRESETS_FILE = "presets.toml"
#: the default of a turbine file that names no recommended preset
FALLBACK_PRESET = "pi"
#: a DISCON library's keys (design = "discon"; the run's [discon] table): its files, and the
#: sha256 each must have
DISCON_KEYS = ("library", "input", "library_sha256", "input_sha256")
#: an ELF file's first bytes, and its e_type of a shared object (ET_DYN)
ELF_MAGIC, ELF_SHARED = b"\x7fELF", 3


def designs() -> dict[str, str]:
    """Every design a table may name → its description: the registered controllers
    (generated/layout.json) and ROSCO."""
    from wtftc.sim.rhs import controllers

    regs = {k: v["doc"] for k, v in controllers().items() if k != "external"}
    return regs | {"rosco": "NREL's ROSCO 2.10.6 through its ControllerInterface "
                            "(pip install 'wtftc[rosco]')",
                   "discon": "any Bladed-style DISCON library with its input file (library, "
                             "input; engine = openfast)"}


def torque_keys() -> tuple[str, ...]:
    """The turbine parameters that set the torque law (gen_torque_law, vs_*)."""
    return tuple(n for n in lay.names("turbine_params")
                 if n in TORQUE_FLAGS or n.startswith("vs_"))


def design_params(design: str) -> tuple[str, ...]:
    """The parameters of ``design`` a table may set: its layout group's, less the paper's
    control sign (a top-level key) and the fault estimates its case sets."""
    from wtftc.sim.rhs import controllers

    if design in ("rosco", "discon"):
        return ()
    return tuple(n for n in lay.names(controllers()[design]["params"])
                 if n != "control_sign" and not n.startswith(("rho_hat", "lock_hat",
                                                              "ubar_hat")))


@dataclass(frozen=True)
class Controller:
    """A controller's settings: a design, its accommodation and its settings other than
    their defaults, each a tuple of (name, value) in the order given."""

    design: str
    accommodation: str
    params: tuple = ()   # the design's parameters (controller_params)
    torque: tuple = ()   # the torque law's options (turbine_params)
    tuning: tuple = ()   # the pitch loop's target mode ([tuning])
    doc: str = ""
    #: the preset its settings came from, where they did (a record)
    preset: str | None = None
    #: the turbine its settings are tuned for (a preset's), where they are
    tuned_for: str | None = None
    #: a DISCON library's files (design = "discon"): (key, value) of :data:`DISCON_KEYS`,
    #: the paths absolute
    files: tuple = ()

    @property
    def fault_case(self) -> int:
        """The case it runs in under a fault (without one: case 1)."""
        return ACCOMMODATIONS[self.accommodation]

    @property
    def uses_fdi(self) -> bool:
        """Whether it detects faults itself, with wtftc's FDI (no oracle)."""
        return self.accommodation == "fdi"

    def table(self) -> dict:
        """Its [controller] table, every setting written out (no preset to look up)."""
        return {"design": self.design, "accommodation": self.accommodation,
                **({"doc": self.doc} if self.doc else {}), **dict(self.files),
                **dict(self.params), **dict(self.torque), **dict(self.tuning)}

    def run_keys(self, faulty: bool, torque_default: bool = False) -> dict:
        """The run configuration's keys it sets: the design, the case (its accommodation's
        under a fault, else 1), [tuning], [controller_params] and [turbine_params];
        ``torque_default``: every design but ROSCO on the baseline torque law unless it
        says otherwise (the campaigns' convention: wtftc.campaign.compare)."""
        cfg = {"controller": self.design, "case": self.fault_case if faulty else 1}
        if self.files:
            cfg["discon"] = dict(self.files)
        if self.tuning:
            cfg["tuning"] = dict(self.tuning)
        if self.params:
            cfg["controller_params"] = copy.deepcopy(dict(self.params))
        torque = dict(self.torque)
        if torque_default and self.design not in LIBRARIES:
            # ROSCO commands the generator torque itself; every other pitch controller
            # runs with the NREL 5-MW baseline variable-speed torque law (Jonkman 2009,
            # 7.1) unless it says otherwise, so that all compete with a standard one
            torque = {"gen_torque_law": 1.0, **torque}
        if torque:
            cfg["turbine_params"] = torque
        return cfg


def _number(val, field: str):
    """A finite number as a float, or for a numbered prefix a list of them."""
    if isinstance(val, list):
        return [_number(x, f"{field}[{i}]") for i, x in enumerate(val)]
    if isinstance(val, bool) or not isinstance(val, numbers.Real) \
            or not math.isfinite(float(val)):
        raise ConfigError(field, val, "a finite number")
    return float(val)


def _known_names(design: str) -> str:
    if design == "discon":
        return ", ".join([*META_KEYS, *DISCON_KEYS])
    return ", ".join([*META_KEYS, *design_params(design), *torque_keys(), *TUNING_KEYS])


def parse(tab, field: str = "controller", name: str | None = None) -> Controller:
    """A [controller] table (or a preset's name) as a :class:`Controller`: its preset's
    settings first, then its own; a key or value refused is one line naming
    ``<field>.<key>``."""
    if isinstance(tab, str):
        return lookup(tab, field)
    if not isinstance(tab, dict):
        raise ConfigError(field, tab, "a table: design, accommodation and the design's "
                          "settings, or preset = <name> (wtftc presets lists them)")
    base = None
    if "preset" in tab:
        if not isinstance(tab["preset"], str):
            raise ConfigError(f"{field}.preset", tab["preset"], "a preset's name: "
                              + ", ".join(presets()))
        base = preset(tab["preset"], f"{field}.preset")
    design = tab.get("design", base.design if base else None)
    regs = designs()
    if not isinstance(design, str) or design not in regs:
        raise ConfigError(f"{field}.design", design, "one of " + ", ".join(regs)
                          + " (docs/controllers.md)")
    if base is not None and design != base.design:
        raise ConfigError(f"{field}.design", design, f"{base.design}, the design of preset "
                          f"{base.preset} (or leave preset out)")
    acc = tab.get("accommodation", base.accommodation if base else default_accommodation(
        design))
    allowed = accommodations(design)
    if acc not in allowed:
        raise ConfigError(f"{field}.accommodation", acc, " or ".join(allowed) + f" for "
                          f"{design}" + ("" if len(allowed) > 1 else
                                         " (it has no fault accommodation)"))
    doc = tab.get("doc", base.doc if base else "")
    tuned = tab.get("tuned_for", base.tuned_for if base else None)
    for key, val in (("doc", doc), ("tuned_for", tuned)):
        if val is not None and not isinstance(val, str):
            raise ConfigError(f"{field}.{key}", val, "a string")
    params, torque, tuning = _settings(tab, design, base, field)
    files = discon_files(tab, field) if design == "discon" else ()
    return Controller(design, acc, tuple(params.items()), tuple(torque.items()),
                      tuple(tuning.items()), doc,
                      preset=base.preset if base and set(tab) <= {"preset", "doc"} else None,
                      tuned_for=tuned, files=files)


def _settings(tab: dict, design: str, base: Controller | None, field: str
              ) -> tuple[dict, dict, dict]:
    """A table's settings over its preset's: the design's parameters, the torque law's
    options, the target mode."""
    params, torque, tuning = (dict(x) for x in ((base.params, base.torque, base.tuning)
                                                if base else ((), (), ())))
    own, tq = design_params(design), torque_keys()
    numbered = {n.rsplit("_", 1)[0]: [m for m in own if m.rsplit("_", 1)[0]
                                      == n.rsplit("_", 1)[0]]
                for n in own if n.rsplit("_", 1)[-1].isdigit()}
    for key, val in tab.items():
        if key in META_KEYS or (design == "discon" and key in DISCON_KEYS):
            continue
        where = f"{field}.{key}"
        if design == "discon":
            raise ConfigError(where, val, "a key of a DISCON library's table: "
                              + _known_names(design) + " (its settings are its input file's)")
        if key in own or key in numbered:
            v = _number(val, where)
            if key in numbered and (not isinstance(v, list) or len(v) != len(numbered[key])):
                raise ConfigError(where, val, f"a list of {len(numbered[key])} finite "
                                  f"numbers ({', '.join(numbered[key])})")
            if key not in numbered and isinstance(v, list):
                raise ConfigError(where, val, "a finite number")
            params[key] = v
        elif key in tq:
            torque[key] = _number(val, where)
            if isinstance(torque[key], list):
                raise ConfigError(where, val, "a finite number")
        elif key in TUNING_KEYS:
            _, lo, hi = TUNING_KEYS[key]
            v = _number(val, where)
            if isinstance(v, list) or not lo <= v <= hi:
                raise ConfigError(where, val, f"a number in [{lo:g}, {hi:g}]")
            tuning[key] = v
        else:
            import difflib

            near = difflib.get_close_matches(key, _known_names(design).split(", "), n=1)
            raise ConfigError(where, val, (f"did you mean {near[0]}? " if near else "")
                              + f"a setting of {design}: " + _known_names(design))
    if tuning and not {"omega_n_rad_s", "zeta"} <= set(tuning):
        raise ConfigError(f"{field}.omega_n_rad_s" if "omega_n_rad_s" not in tuning
                          else f"{field}.zeta", None, "both omega_n_rad_s and zeta: the "
                          "pitch loop's target mode (or neither)")
    if tuning and design not in RETUNABLE:
        raise ConfigError(f"{field}.omega_n_rad_s", tuning["omega_n_rad_s"], "a design "
                          "tuned from a target mode: " + ", ".join(RETUNABLE))
    return params, torque, tuning


#: the designs a target mode retunes (wtftc.campaign.tune.resolve)
RETUNABLE = ("rosco", "pi", "physical")
#: the designs that are a DISCON library commanding the blade pitch and the generator
#: torque itself, called at its own interval: ROSCO's, and any other (design = "discon")
LIBRARIES = ("rosco", "discon")


def _user_file(val, field: str, what: str) -> Path:
    """``val`` as the absolute path of an existing, readable regular file (relative: to
    the folder wtftc runs in); else one line naming ``field``."""
    if not isinstance(val, str) or not val.strip():
        raise ConfigError(field, val, f"the path of {what}")
    path = Path(val).expanduser().absolute()
    if not path.is_file():
        raise ConfigError(field, val, f"an existing regular file: {what} ("
                          + ("a folder" if path.is_dir() else "no such file" if not
                             path.exists() else "not a regular file") + f" at {path})")
    if not os.access(path, os.R_OK):
        raise ConfigError(field, val, f"a file wtftc may read: {what} ({path} is not "
                          "readable)")
    return Path(os.path.normpath(path))


def _check_shared_object(path: Path, val, field: str) -> None:
    """A shared object's ELF header (the magic, e_type ET_DYN in the file's byte order)."""
    try:
        with open(path, "rb") as f:
            head = f.read(18)
    except OSError as exc:
        raise ConfigError(field, val, f"a file wtftc may read ({exc.strerror})") from None
    order = "big" if head[5:6] == b"\x02" else "little"
    if head[:4] != ELF_MAGIC or int.from_bytes(head[16:18], order) != ELF_SHARED:
        raise ConfigError(field, val, "a DISCON library: a shared object (ELF, .so; "
                          f"{path} is " + ("an ELF file of another kind" if
                                           head[:4] == ELF_MAGIC else "no ELF file") + ")")


@functools.lru_cache(maxsize=64)
def _sha256(path: str, mtime_ns: int, size: int) -> str:
    from wtftc.files import file_sha256

    return file_sha256(path)


def sha256_of(path: Path) -> str:
    """The sha256 of a file's bytes (computed once while its size and time stay)."""
    st = Path(path).stat()
    return _sha256(str(path), st.st_mtime_ns, st.st_size)


def discon_files(tab: dict, field: str) -> tuple:
    """A DISCON library's table (``library``, ``input``, and optionally the sha256 each
    must have) as ((key, value), ...) of :data:`DISCON_KEYS`: the paths absolute, each
    file's sha256 as it is now; a hash given that the file no longer has is refused, so
    that a saved configuration never runs a changed library silently."""
    lib = _user_file(tab.get("library"), f"{field}.library", "the DISCON library, a shared "
                     "object (.so)")
    _check_shared_object(lib, tab.get("library"), f"{field}.library")
    inp = _user_file(tab.get("input"), f"{field}.input", "the library's input file (its "
                     "DISCON.IN)")
    out = {"library": str(lib), "input": str(inp)}
    for key, path in (("library", lib), ("input", inp)):
        digest, given = sha256_of(path), tab.get(f"{key}_sha256")
        if given is not None and given != digest:
            raise ConfigError(f"{field}.{key}_sha256", given, f"{digest}, the sha256 of "
                              f"{path} now: the file changed since this configuration was "
                              f"written (restore it, or leave {key}_sha256 out to run it "
                              "as it is)")
        out[f"{key}_sha256"] = digest
    return tuple(out.items())


def accommodations(design: str) -> tuple[str, ...]:
    """The accommodations ``design`` has: none for ROSCO and the PI (no fault
    accommodation); none, known or fdi for the AFTC designs (eq (49)'s inputs)."""
    from wtftc.sim.rhs import controllers

    if design in ("rosco", "pi", "discon") or design not in controllers():
        return ("none",)
    return tuple(ACCOMMODATIONS)


def default_accommodation(design: str) -> str:
    """wtftc's own FDI where the design accommodates faults; else none."""
    return "fdi" if "fdi" in accommodations(design) else "none"


@functools.cache
def _presets_file() -> dict:
    text = (importlib.resources.files("wtftc") / "data" / PRESETS_FILE).read_text("utf-8")
    return tomllib.loads(text)


@functools.cache
def presets() -> dict[str, Controller]:
    """The shipped presets by name, in the file's order."""
    from dataclasses import replace

    return {name: replace(parse(tab, f"presets.{name}"), preset=name)
            for name, tab in _presets_file()["presets"].items()}


def preset(name: str, field: str = "--preset") -> Controller:
    """A shipped preset; a name that is none is refused naming ``field``."""
    table = presets()
    if name not in table:
        raise ConfigError(field, name, "a preset: " + ", ".join(table)
                          + " (wtftc presets describes them)")
    return table[name]


@functools.cache
def former_names() -> dict[str, Controller]:
    """The controller names earlier wtftc versions used in campaigns, each a preset or a
    table: what lets their folders read and their sweep files run as they did."""
    from dataclasses import replace

    out = {}
    for name, val in _presets_file()["former_names"].items():
        c = parse(val, f"former_names.{name}")
        out[name] = c if isinstance(val, str) else replace(c, preset=None)
    return out


def lookup(name, field: str = "controllers") -> Controller:
    """A controller by name: a preset, or a name earlier wtftc versions used."""
    if isinstance(name, str):
        if name in presets():
            return presets()[name]
        if name in former_names():
            return former_names()[name]
    raise ConfigError(field, name, "a preset (" + ", ".join(presets()) + ") or a "
                      "[controller] table (docs/controllers.md)")


def recommended(turbine) -> tuple[str, str | None]:
    """The preset a turbine file recommends (its ``recommended_preset``), and a note when
    it names none (then :data:`FALLBACK_PRESET`)."""
    name = getattr(turbine, "recommended_preset", None)
    if name is None:
        return FALLBACK_PRESET, (f"{turbine.name}'s turbine file names no recommended_preset:"
                                 f" running {FALLBACK_PRESET} ({presets()[FALLBACK_PRESET].doc});"
                                 " choose one with --preset (wtftc presets)")
    if name not in presets():
        raise ConfigError("recommended_preset", name, "a preset: " + ", ".join(presets()),
                          where=turbine.path)
    return name, None


#: the keys of a run's configuration a [controller] table sets in its place
RUN_KEYS = ("controller_params", "tuning", "discon")


def expand(cfg: dict) -> tuple[dict, dict]:
    """``cfg`` with its [controller] table (if it has one) turned into the keys every
    engine reads: ``controller`` (the design), ``case``, ``controller_params``,
    ``tuning`` and the torque law's ``turbine_params``, and ``controller_preset`` (the
    preset it came from, a record); and the map of those keys' fields back to the table's
    (``controller_params.x`` → ``controller.x``) for the refusals of their ranges.

    The case: 1 without a fault, else the accommodation's; a ``case`` given is run as it
    says (2: the design unaware of the fault, 3: told it, 4: its FDI), where the design
    has that accommodation."""
    tab = cfg.get("controller")
    if not isinstance(tab, dict):
        return cfg, {}
    c = parse(tab)
    for key in RUN_KEYS:
        if key in cfg:
            what = {"controller_params": "design's settings", "tuning": "target mode",
                    "discon": "library and input"}[key]
            raise ConfigError(key, cfg[key], f"none beside a [controller] table: set the "
                              f"{what} in it (docs/controllers.md)")
    faulty = bool(cfg.get("fault"))
    keys = c.run_keys(faulty)
    out = {k: v for k, v in cfg.items() if k != "controller"}
    if "case" in cfg:  # a case given runs the design in it: its accommodation
        case = cfg["case"]
        want = {v: k for k, v in ACCOMMODATIONS.items()}.get(case) \
            if isinstance(case, numbers.Integral) and not isinstance(case, bool) else None
        if want is not None and want not in accommodations(c.design):
            raise ConfigError("case", case, f"1 or {UNAWARE_CASE} with {c.design} (it has "
                              "no fault accommodation; a case follows from the "
                              "[controller] table's accommodation and the fault)")
        keys["case"] = case
    turbine = cfg.get("turbine_params", {})
    if not isinstance(turbine, dict):
        raise ConfigError("turbine_params", turbine, "a table of turbine_params names = "
                          "numbers (see generated/layout.json)")
    if "turbine_params" in keys:
        both = sorted(k for k in set(turbine) & set(keys["turbine_params"])
                      if turbine[k] != keys["turbine_params"][k])
        if both:
            raise ConfigError(f"turbine_params.{both[0]}", turbine[both[0]], "none, or "
                              f"{keys['turbine_params'][both[0]]:g}: the [controller] "
                              "table sets it (its torque law)")
        keys["turbine_params"] = {**turbine, **keys["turbine_params"]}
    names = {f"controller_params.{k}": f"controller.{k}" for k, _ in c.params} \
        | {f"turbine_params.{k}": f"controller.{k}" for k, _ in c.torque} \
        | {f"tuning.{k}": f"controller.{k}" for k, _ in c.tuning}
    if c.design == "discon":  # the run's refusals of a DISCON library, by the table's keys
        names |= {"controller": "controller.design",
                  **{f"discon.{k}": f"controller.{k}" for k in DISCON_KEYS}}
    if c.preset and keys["case"] in (FAULT_FREE_CASE, c.fault_case):
        keys["controller_preset"] = c.preset
    return out | keys, names


def check_record(cfg: dict) -> None:
    """Refuse a ``controller_preset`` record (a saved run's) that the keys beside it do
    not hold: the design, the design's parameters, the torque law and the case of that
    preset, nothing more (a record that would name settings it does not describe)."""
    name = cfg.get("controller_preset")
    if name is None:
        return
    if not isinstance(name, str) or name not in presets():
        raise ConfigError("controller_preset", name, "the name of the preset the "
                          "controller's settings came from (a record): " + ", ".join(presets()))
    p = presets()[name]
    torque = {k: v for k, v in (cfg.get("turbine_params") or {}).items()
              if k in torque_keys()} if isinstance(cfg.get("turbine_params"), dict) else {}
    held = (cfg.get("controller") == p.design
            and (cfg.get("controller_params") or {}) == dict(p.params)
            and all(torque.get(k) == v for k, v in p.torque)
            and (cfg.get("case", FAULT_FREE_CASE) in (FAULT_FREE_CASE, p.fault_case)
                 or accommodations(p.design) == ("none",))  # (a case it cannot act on)
            and (not p.tuning or cfg.get("rosco") == {"omega_pc_rad_s": dict(p.tuning)[
                "omega_n_rad_s"], "zeta_pc": dict(p.tuning)["zeta"]}))
    if not held:
        raise ConfigError("controller_preset", name, "a record of the preset whose settings "
                          "the keys beside it hold; they are not this preset's (remove the "
                          "record, or run --preset " + name + ")")
