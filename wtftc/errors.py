"""User-facing errors: each names the field, the value and what is allowed.

The CLI turns a :class:`ConfigError` into one line on stderr and exit code 2, with no
traceback and no partial output.
"""

from __future__ import annotations


class ConfigError(ValueError):
    """Bad user input: ``field`` had ``value``; ``allowed`` says what would be accepted."""

    def __init__(self, field: str, value, allowed: str, where: str | None = None):
        self.field, self.value, self.allowed, self.where = field, value, allowed, where
        loc = f"{where}: " if where else ""
        super().__init__(f"{loc}{field} = {value!r} is not allowed: {allowed}")


class MissingExtra(ConfigError):
    """A command or option needs an optional dependency that is not installed: one line
    naming it and the pip line that installs it (``install``, else the extra's), exit
    code 2, as any refusal: the machine lacks what the command needs, no program
    failed."""

    def __init__(self, field: str, needs: str, extra: str | None, what: str = "",
                 install: str | None = None):
        self.field, self.value, self.where = field, needs, None
        self.allowed = install or f"pip install 'wtftc[{extra}]'"
        ValueError.__init__(self, f"{field} needs {needs}{f' ({what})' if what else ''}, "
                                  f"which is not installed: {self.allowed}")


def range_text(low: float, high: float, low_open: bool, high_open: bool,
               unit: str = "") -> str:
    """What a range allows, as every refusal says it: 'a number > 0 [m]', 'a number in
    [0, 100) [%]', 'a finite number [-]' (an infinite end: unbounded there)."""
    u = f" [{unit}]" if unit else ""
    if low == -float("inf") and high == float("inf"):
        return f"a finite number{u}"
    if high == float("inf"):
        return f"a number {'>' if low_open else '>='} {low:g}{u}"
    if low == -float("inf"):
        return f"a number {'<' if high_open else '<='} {high:g}{u}"
    return (f"a number in {'(' if low_open else '['}{low:.6g}, {high:.6g}"
            f"{')' if high_open else ']'}{u}")


class EngineError(RuntimeError):
    """An external program wtftc runs (OpenFAST, TurbSim) is missing, cannot be installed
    or failed: one line saying what and how to get it. The CLI prints it without a
    traceback and exits with code 4."""


class ProgramKilled(EngineError):
    """An external program (OpenFAST, TurbSim) was ended by a signal that wtftc did not
    send for a reason of the run's own (another process, the machine, wtftc's own stop):
    the run is unfinished, not failed, and a resumed campaign runs it again."""
