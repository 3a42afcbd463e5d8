"""The ordering of states, inputs and parameters, read from ``generated/layout.json``.

Nothing here is retyped: names, defaults, units and sizes all come from the derivation.
"""

from __future__ import annotations

from collections.abc import Mapping
from functools import cache

import numpy as np

from wtftc.artefacts.loader import layout_json


@cache
def layout() -> dict:
    return layout_json()


def names(group: str) -> list[str]:
    return list(_names(group))


@cache
def _names(group: str) -> tuple[str, ...]:
    """The names of ``group`` (looked up several times a loop chunk: built once)."""
    _check_group(group)
    return tuple(e["name"] for e in layout()[group])


def units(group: str) -> list[str]:
    _check_group(group)
    return [e["unit"] for e in layout()[group]]


def defaults(group: str) -> np.ndarray:
    """The defaults of ``group``: a new array, the caller's to change."""
    return _defaults(group).copy()


@cache
def _defaults(group: str) -> np.ndarray:
    _check_group(group)
    return np.array([e["default"] for e in layout()[group]], dtype=float)


def index(group: str, name: str) -> int:
    at = _indices(group).get(name)
    if at is None:
        raise KeyError(f"{name!r} is not in {group}; allowed: {', '.join(_names(group))}")
    return at


@cache
def _indices(group: str) -> dict[str, int]:
    """Where each name of ``group`` sits (its first entry of that name)."""
    out: dict[str, int] = {}
    for k, n in enumerate(_names(group)):
        out.setdefault(n, k)
    return out


def size(group: str) -> int:
    """The number of entries of ``group``."""
    return len(names(group))


def n_blades() -> int:
    return int(layout()["n_blades"])


def blades() -> range:
    """The blade numbers 1..n_blades, as in the layout's names (``beta_1``, ...)."""
    return range(1, n_blades() + 1)


@cache
def block(group: str, prefix: str) -> slice:
    """Where the numbered entries ``<prefix>_1``, ``<prefix>_2``, ... sit in ``group``:
    ``block("nrel5mw_states", "beta")`` is the three blade pitch angles (not their rates).
    Looked up several times a run: found once."""
    all_names = names(group)
    at = [k for k, n in enumerate(all_names)
          if n.rsplit("_", 1)[0] == prefix and n.rsplit("_", 1)[-1].isdigit()]
    if not at:
        prefixes = sorted({n.rsplit("_", 1)[0] for n in all_names
                               if "_" in n and n.rsplit("_", 1)[-1].isdigit()})
        raise KeyError(f"no numbered entries {prefix}_<n> in {group}; prefixes: "
                       f"{', '.join(prefixes)}")
    if at != list(range(at[0], at[-1] + 1)):
        raise KeyError(f"{prefix}_<n> are not contiguous in {group}")
    return slice(at[0], at[-1] + 1)


def prefix(group: str, of: str) -> slice:
    """Where ``group`` sits at the start of group ``of`` (the paper's plant states at the
    start of the NREL 5-MW's, the fault inputs at the start of the actuator faults): checked
    by name, so that a slice never silently takes the wrong entries."""
    inner, outer = names(group), names(of)
    if outer[:len(inner)] != inner:
        raise KeyError(f"{group} is not the start of {of}: {', '.join(inner)} against "
                       f"{', '.join(outer[:len(inner)])}")
    return slice(0, len(inner))


def values(group: str, vec) -> dict[str, float]:
    """``vec`` (a vector of ``group``) by name."""
    return dict(zip(names(group), (float(x) for x in vec), strict=True))


def vector(group: str, values: Mapping[str, float] | None = None) -> np.ndarray:
    """Defaults of ``group`` with named overrides.

    A name may also be a prefix of numbered entries (``K_obs`` sets ``K_obs_1..K_obs_4``
    from a sequence). Unknown names raise a ValueError that lists what is allowed.
    """
    vec = defaults(group)
    all_names = names(group)
    for key, val in (values or {}).items():
        if key in all_names:
            vec[all_names.index(key)] = float(val)
            continue
        members = [n for n in all_names  # numbered entries only: gen_torque is no prefix
                   if n.rsplit("_", 1)[0] == key and n.rsplit("_", 1)[-1].isdigit()]
        if not members:
            prefixes = sorted({n.rsplit("_", 1)[0] for n in all_names
                               if "_" in n and n.rsplit("_", 1)[-1].isdigit()})
            raise ValueError(f"{group}: unknown field {key!r} = {val!r}; allowed names: "
                             f"{', '.join(all_names)} (or the prefixes {', '.join(prefixes)})")
        seq = np.atleast_1d(np.asarray(val, dtype=float))
        if seq.size != len(members):
            raise ValueError(f"{group}: {key} needs {len(members)} values "
                             f"({', '.join(members)}), got {seq.size}: {val!r}")
        for n, x in zip(members, seq, strict=True):
            vec[all_names.index(n)] = x
    return vec


def rule_counts() -> list[int]:
    return list(layout()["rule_counts"])


def paper_table1(key: str) -> np.ndarray:
    return np.array(layout()["paper_table1"][key], dtype=float)


def _check_group(group: str) -> None:
    if group not in _groups():
        raise KeyError(f"unknown layout group {group!r}; allowed: {', '.join(_groups())}")


@cache
def _groups() -> tuple[str, ...]:
    """The layout's groups of named entries with defaults (looked up on every loop chunk:
    built once)."""
    return tuple(k for k, v in layout().items()
                 if isinstance(v, list) and v and isinstance(v[0], dict) and "default" in v[0])
