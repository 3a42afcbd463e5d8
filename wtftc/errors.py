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
