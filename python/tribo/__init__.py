"""Tribo from Python: the virtual engine-friction test bench.

Load rigs and law sets (bundled names, files, TOML texts or dicts), set parameters, run the
test cycle or the steady state, and run the CLI's studies (compare, mass response, fit, sweep);
results come back as pandas DataFrames, time series as numpy arrays. Laws are found as the
``tribo`` command finds them: ``plugin_paths=`` (its ``--plugin``), the ``target/release``
directory of the checkout the module was built from, ``TRIBO_PLUGIN_PATH``. Errors raise
:mod:`tribo.errors` exceptions carrying the CLI's messages. :mod:`tribo.study` runs designs of
experiments, serially or on Dask.

>>> import tribo
>>> r = tribo.run("crf250r-motored", lawset="stribeck-duty", steady=True)
>>> r.plateaus[["set_speed_rpm", "motoring_torque_nm"]]  # doctest: +SKIP
"""

from __future__ import annotations

from ._api import (
    DEFAULT_SPEEDS_RPM,
    DEFAULT_TEMPS_C,
    JOINTS,
    Comparison,
    FitResult,
    LawSet,
    MassResponse,
    Rig,
    RunResult,
    Sweep,
    bundled,
    compare,
    fit,
    laws,
    mass_response,
    modes,
    plugin_search_path,
    run,
    sweep,
)
from .errors import InputError, PluginError, SimulationError, TriboError

__version__ = "0.1.0"

__all__ = [
    "DEFAULT_SPEEDS_RPM",
    "DEFAULT_TEMPS_C",
    "JOINTS",
    "Comparison",
    "FitResult",
    "InputError",
    "LawSet",
    "MassResponse",
    "PluginError",
    "Rig",
    "RunResult",
    "SimulationError",
    "Sweep",
    "TriboError",
    "bundled",
    "compare",
    "fit",
    "laws",
    "mass_response",
    "modes",
    "plugin_search_path",
    "run",
    "sweep",
]
