"""The exceptions tribo raises. Each carries the message the ``tribo`` command prints after
``error:`` for the same input (file, line:column, field, what was expected)."""

from __future__ import annotations


class TriboError(Exception):
    """Any failure of tribo; ``str(e)`` is the CLI's message."""


class InputError(TriboError, ValueError):
    """A rig, law set, data file, parameter or option is wrong (a missing rig, an unknown
    law, a parameter out of range, a misspelled key)."""


class PluginError(TriboError):
    """A law library cannot be loaded (not a library, wrong contract version, missing
    symbols)."""


class SimulationError(TriboError, RuntimeError):
    """A run failed: a law misbehaved (NaN, adds energy, panicked), the solver did not
    converge, or the model produced non-finite values."""


__all__ = ["TriboError", "InputError", "PluginError", "SimulationError"]
