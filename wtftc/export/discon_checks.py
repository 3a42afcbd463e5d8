"""What a library wtftc builds checks in its input file at the first call: every value
against its valid range and wtftc's cross-checks, as C tables. One mechanism for both of
wtftc's DISCON-shaped libraries: the exported controller (:func:`header`,
``wtftc_discon_checks.h``, read by discon_interface.c) and the plant library
(wtftc.openfast.plant_library, ``wtftc_plant_checks.h``), each from :func:`layout_row`,
:func:`cross_checks` and :func:`c_tables`; :func:`refusal` is the same check in Python,
for a file before it is written.

The ranges are not retyped: the layout's ``valid`` entries (derivation/layout.py, emitted in
generated/layout.json, the ones wtftc.config checks); for the FDI's parameters, which wtftc
computes and a user never sets, the range of what wtftc sets each from (a turbine
parameter, an ``[fdi]`` key, the call interval) and, for its own constants, the layout's
``valid`` (derivation/fdi.py FDI_VALID); the cross-checks of wtftc.config (TURBINE_ORDER,
TURBINE_FLAGS, the controller's pitch range, the control sign, the reference inside the
envelope).
"""

from __future__ import annotations

import dataclasses
import math

from wtftc import config
from wtftc.artefacts import layout as lay
from wtftc.errors import range_text
from wtftc.sim import rhs

#: the FDI's parameters wtftc sets from a key of a run's [fdi] table: that key's range
#: (wtftc.config.FDI_KEYS)
FDI_FROM_CONFIG = {"fdi_delta": "model_uncertainty",
                   "fdi_delta_rate_limited": "rate_limited_uncertainty",
                   "fdi_k_align": "align_rate_per_s"}
#: the library's own setting, after the layout's parameters (wtftc.export.discon)
DEMAND_RATE_LIMIT = "demand_rate_limit"
#: the FDI's parameter that is the call interval (wtftc.sim.fdi.run_params sets it so)
FDI_INTERVAL = "fdi_T_s"


def _range_text(rng: tuple, unit: str) -> str:
    """What a range allows, in wtftc.config's words."""
    return range_text(*rng, unit)


def _layout_range(group: str, name: str) -> tuple[tuple | None, str]:
    """The ``valid`` range of a layout entry (None: unbounded) and its unit. An infinite
    end is open: wtftc.config refuses a value that is not finite whatever the range."""
    e = lay.layout()[group][lay.index(group, name)]
    v = e.get("valid")
    if not v:
        return None, e["unit"]
    return ((-math.inf if v["min"] is None else v["min"], math.inf if v["max"] is None
             else v["max"], v["min_open"] or v["min"] is None,
             v["max_open"] or v["max"] is None), e["unit"])


def layout_row(group: str, name: str, label: str | None = None) -> tuple:
    """One row of a check table: (label, low, high, low_open, high_open, what is allowed,
    whether an angle) from the layout entry's ``valid`` range (unbounded: any finite
    number), the one wtftc.config checks. ``label``: the name the library's message gives
    (the entry's name by default)."""
    rng, unit = _layout_range(group, name)
    rng = rng or (-math.inf, math.inf, True, True)
    return (label or name, *rng, _range_text(rng, unit),
            unit == "rad" and math.isfinite(rng[1]))


def cross_checks(names: list[str]) -> tuple[list, list]:
    """wtftc.config's cross-checks among ``names`` (the labels of a check table, by which
    they are found, with or without a ``<key>.`` prefix): ``order``, pairs (low, high) that
    must increase strictly (TURBINE_ORDER, every ``*pitch_min`` < ``*pitch_max``, every
    ``*_ps_speed`` < ``yd_0``); ``one_of``, (name, (0, 1), allowed) of the turbine's and the
    controller's switches."""
    def find(bare: str) -> str | None:
        return next((n for n in names if n == bare or n.endswith("." + bare)), None)

    order = [(find(a), find(b)) for a, b in config.TURBINE_ORDER if find(a) and find(b)]
    order += [(n, n.replace("pitch_min", "pitch_max")) for n in names
              if n.endswith("pitch_min") and n.replace("pitch_min", "pitch_max") in names
              and (n, n.replace("pitch_min", "pitch_max")) not in order]
    # peak shaving's floor rises between its start speed and the reference (wtftc.config)
    order += [(n, "yd_0") for n in names if n.endswith("_ps_speed") and "yd_0" in names]
    one_of = [(find(f), (0.0, 1.0), "0 or 1 (docs/running.md)") for f in config.TURBINE_FLAGS
              if find(f)]
    one_of += [(f, (0.0, 1.0), "0 or 1 (docs/controllers.md)") for f in config.CONTROLLER_FLAGS
               if f in names]
    return order, one_of


def in_range(row: tuple, value: float) -> bool:
    """Whether ``value`` lies in a check table row's range (as the C tables' test it:
    NaN lies in none)."""
    _, lo, hi, lo_open, hi_open, *_ = row
    return not (math.isnan(value) or value < lo or value > hi or (lo_open and value == lo)
                or (hi_open and value == hi))


def refusal(c: dict, values: dict[str, float]) -> tuple[str, float, str] | None:
    """The first refusal of a check table (``ranges``, ``order``, ``one_of`` as
    :func:`checks` gives them) on ``values`` by name, in the table's order: (name, value,
    what is allowed), as the library's message says it; None when every check passes."""
    for row in c["ranges"]:
        if not in_range(row, values[row[0]]):
            return row[0], values[row[0]], row[5]
    for lo, hi in c["order"]:
        if not values[lo] < values[hi]:
            return lo, values[lo], f"{lo} < {hi} (here {hi} = {values[hi]:g})"
    for name, pair, allowed in c["one_of"]:
        if values[name] not in pair:
            return name, values[name], allowed
    return None


def fdi_facts(rc: config.RunConfig) -> dict[str, str]:
    """The FDI's parameters that are a turbine parameter's value in wtftc (wtftc.sim.rhs.
    fdi_params: the actuator's ω_n and ζ, its limits, the gearbox ratio), by name: found by
    giving every turbine parameter a value of its own."""
    names = lay.names("turbine_params")
    probe = tuple((k + 1) * math.pi / 100 for k in range(len(names)))
    p_fdi = rhs.fdi_params(dataclasses.replace(rc.loop, p_turbine=probe))
    return {f: names[probe.index(float(v))]
            for f, v in zip(lay.names("fdi_params"), p_fdi, strict=True)
            if float(v) in probe}


def _fdi_range(name: str, unit: str, facts: dict, interval: float) -> tuple[tuple, str]:
    if name in facts:
        rng, _ = _layout_range("turbine_params", facts[name])
        return rng, f"{_range_text(rng, unit)} (as turbine_params.{facts[name]})"
    if name in FDI_FROM_CONFIG:
        key = FDI_FROM_CONFIG[name]
        _, lo, hi, _ = config.FDI_KEYS[key]
        rng = (lo, hi, False, False)
        return rng, f"{_range_text(rng, unit)} (as the [fdi] table's {key})"
    if name == FDI_INTERVAL:
        return (interval, interval, False, False), (
            f"{interval!r} [s], the call interval the library is exported for")
    own, _ = _layout_range("fdi_params", name)
    if own is None:  # a new FDI parameter: give it a range in the derivation
        raise KeyError(f"the FDI's parameter {name} has no valid range: add it to FDI_VALID "
                       "(derivation/fdi.py) and run make regenerate")
    return own, f"{_range_text(own, unit)} (the FDI's own range, derivation/fdi.py FDI_VALID)"


def checks(rc: config.RunConfig, groups: dict[str, str]) -> dict:
    """What the library checks at its first call, by parameter name: ``ranges`` (low,
    high, low_open, high_open, what is allowed, whether an angle) of every parameter in
    the library's order (``groups``: the layout group of each .IN section, in order),
    from the layout's ``valid`` ranges (the ones wtftc.config checks) and, for the FDI,
    :func:`fdi_facts`, :data:`FDI_FROM_CONFIG` and the layout's ``valid`` of the FDI's own
    constants (derivation/fdi.py FDI_VALID); ``order``, pairs (low, high) that must
    increase strictly (wtftc.config.TURBINE_ORDER, every ``*pitch_min`` < ``*pitch_max``
    and ``*_ps_speed`` < ``yd_0``); ``one_of``, (name, (a, b), allowed) (the turbine's
    and the controller's switches, the control sign); ``envelope``, the
    reference and the rated speed it must stay near (layout.json envelope, as
    wtftc.config checks the reference)."""
    facts = fdi_facts(rc)
    ranges = []
    for group in groups.values():
        for name, unit in zip(lay.names(group), lay.units(group), strict=True):
            if group == "fdi_params":
                rng, text = _fdi_range(name, unit, facts, rc.control_interval)
                ranges.append((name, *rng, text, unit == "rad" and math.isfinite(rng[1])))
            else:
                ranges.append(layout_row(group, name))
    ranges.append((DEMAND_RATE_LIMIT, 0.0, 1.0, False, False, "0 or 1", False))
    names = [r[0] for r in ranges]
    order, one_of = cross_checks(names)
    one_of.insert(len([f for f in config.TURBINE_FLAGS if f in names]), (
        DEMAND_RATE_LIMIT, (0.0, 1.0), "0 (a host with the benchmark pitch actuator) or 1 "
        "(a host without one; docs/discon.md)"))
    if "control_sign" in names:  # wtftc.config._control_sign
        one_of.append(("control_sign", (-1.0, 1.0), "-1 (corrected, default) or +1 (as "
                       "written, stalls the rotor: paper-notes defect 2)"))
    env = lay.layout()["envelope"]
    return {"ranges": ranges, "order": order, "one_of": one_of,
            "envelope": ("yd_0", "omega_g_rated", env["stall_under_rated"],
                         env["overspeed_over_rated"])}


def _c_double(x: float) -> str:
    return repr(float(x)) if math.isfinite(x) else ("HUGE_VAL" if x > 0 else "-HUGE_VAL")


def _c_string(text: str) -> str:
    text.encode("ascii")  # the messages are ASCII: a host prints them as bytes
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def c_rows(rows: list[tuple]) -> str:
    """Check table rows (:func:`layout_row`'s shape) as the initialisers of a WtftcRange
    array."""
    return ",\n    ".join(
        f"{{{_c_double(lo)}, {_c_double(hi)}, {int(lo_open)}, {int(hi_open)}, {int(angle)}, "
        f"{_c_string(text)}}} /* {name} */"
        for name, lo, hi, lo_open, hi_open, text, angle in rows)


def c_tables(c: dict, size: str, title: str) -> str:
    """A check table (``ranges``, ``order``, ``one_of``) as C: the WtftcRange and WtftcOneOf
    types and the arrays WTFTC_RANGE (``size`` rows: a macro of the library's own header),
    WTFTC_ORDER and WTFTC_ONE_OF, which each library's first call walks. ``title``: what
    the header holds and where it comes from (its first comment)."""
    names = [r[0] for r in c["ranges"]]
    order = ", ".join(f"{{{names.index(a)}, {names.index(b)}}}" for a, b in c["order"])
    one_of = ",\n    ".join(f"{{{names.index(n)}, {_c_double(a)}, {_c_double(b)}, "
                            f"{_c_string(text)}}}" for n, (a, b), text in c["one_of"])
    return f"""/* {title}. Generated: do not edit. */
typedef struct {{
    double lo, hi;
    int lo_open, hi_open, angle; /* angle: a value in rad (a degrees hint when refused) */
    const char *allowed;
}} WtftcRange;
static const WtftcRange WTFTC_RANGE[{size}] = {{
    {c_rows(c["ranges"])}
}};
/* pairs (low, high) that must increase strictly */
#define WTFTC_N_ORDER {len(c["order"])}
static const int WTFTC_ORDER[{max(1, len(c["order"]))}][2] = {{{order or "{0, 0}"}}};
/* values that must be one of two */
typedef struct {{
    int k;
    double a, b;
    const char *allowed;
}} WtftcOneOf;
#define WTFTC_N_ONE_OF {len(c["one_of"])}
static const WtftcOneOf WTFTC_ONE_OF[{max(1, len(c["one_of"]))}] = {{
    {one_of or '{0, 0.0, 0.0, ""}'}
}};
"""


def header(rc: config.RunConfig, groups: dict[str, str]) -> str:
    """wtftc_discon_checks.h: :func:`checks` as C tables (:func:`c_tables`) and the
    envelope of the reference."""
    c = checks(rc, groups)
    names = [r[0] for r in c["ranges"]]
    ref, rated, low, high = c["envelope"]
    title = (f"wtftc export discon: the checks of every input-file value of "
             f"{rc.loop.controller}\n * (wtftc/export/discon.py, checks: the layout's valid "
             "ranges, the FDI's, wtftc.config's\n * cross-checks)")
    return c_tables(c, "WTFTC_N_PARAMS", title) + f"""\
/* the reference inside the operating envelope: (LOW, HIGH) x the rated speed */
#define WTFTC_ENVELOPE_REF {names.index(ref)}
#define WTFTC_ENVELOPE_RATED {names.index(rated)}
#define WTFTC_ENVELOPE_LOW {_c_double(low)}
#define WTFTC_ENVELOPE_HIGH {_c_double(high)}
"""
