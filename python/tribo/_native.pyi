"""Type stubs of the native module ``tribo._native`` (Rust, PyO3). Every job is JSON text; every
result is the Python objects ``json.loads`` would make of the CLI's ``--json`` (built directly,
without the text); :mod:`tribo` wraps these in typed functions and DataFrames."""

import os
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

_Path = Union[str, os.PathLike[str]]

#: ``target/release`` of the checkout the module was built from (searched for plugins if it exists).
CHECKOUT_PLUGINS: str

def load_rig(spec: str) -> Dict[str, Any]:
    """Load and validate a rig; ``{"path", "model"}``. Raises ``tribo.InputError``."""

def modes(spec: str) -> Dict[str, Any]:
    """The drivetrain's modal report of a rig, as ``tribo modes --json``. Raises ``tribo.InputError``."""

def load_lawset(spec: str) -> Dict[str, Any]:
    """Load a law set; ``{"path", "file"}``. Raises ``tribo.InputError``."""

def free_params(lawset: str, plugin_paths: Sequence[_Path], ids: Optional[Sequence[str]] = None) -> List[Dict[str, Any]]:
    """A law set's free parameters as a list of ``{id, entry, param, lower, upper, value}``."""

def check_lawset(lawset: str, plugin_paths: Sequence[_Path]) -> None:
    """Check every entry's parameters against its law (names, types, ranges); raises ``tribo.InputError``."""

def laws(plugin_paths: Sequence[_Path]) -> Dict[str, Any]:
    """Every law found and every file that could not be opened: ``{"laws", "broken"}``."""

def plugin_search_path(plugin_paths: Sequence[_Path]) -> List[str]:
    """The paths searched before ``TRIBO_PLUGIN_PATH``."""

def run(job: str, isolation: Optional[str] = None) -> Tuple[Dict[str, Any], Optional[Tuple[List[str], bytes]]]:
    """``tribo run --json``; with ``timeseries`` the column names and float64 rows as bytes.
    ``isolation``: JSON of ``in_process`` and the limits (default: a worker process); the same
    for the studies below."""

def compare(job: str, isolation: Optional[str] = None) -> Dict[str, Any]:
    """``tribo compare --json``."""

def mass_response(job: str, isolation: Optional[str] = None) -> Dict[str, Any]:
    """``tribo mass-response --json``."""

def fit(job: str, isolation: Optional[str] = None) -> Tuple[Dict[str, Any], str]:
    """``tribo fit --json`` and the calibrated law set's TOML."""

def sweep(job: str, isolation: Optional[str] = None) -> Dict[str, Any]:
    """``tribo sweep --json``."""

def bundled_names() -> Tuple[List[str], List[str], List[str]]:
    """The bundled rigs, law sets and data files."""

def _worker_main() -> None:
    """Serve the jobs of a parent process on the channel it set up (a worker); never returns."""
