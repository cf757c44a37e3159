"""Type stubs of the native module ``tribo._native`` (Rust, PyO3). Every job and result is JSON
text; :mod:`tribo` wraps these in typed functions and DataFrames."""

import os
from typing import List, Optional, Sequence, Tuple, Union

_Path = Union[str, os.PathLike[str]]

#: ``target/release`` of the checkout the module was built from (searched for plugins if it exists).
CHECKOUT_PLUGINS: str

def load_rig(spec: str) -> str:
    """Load and validate a rig; JSON ``{"path", "model"}``. Raises ``tribo.InputError``."""

def load_lawset(spec: str) -> str:
    """Load a law set; JSON ``{"path", "file"}``. Raises ``tribo.InputError``."""

def free_params(lawset: str, plugin_paths: Sequence[_Path], ids: Optional[Sequence[str]] = None) -> str:
    """A law set's free parameters as a JSON list of ``{id, entry, param, lower, upper, value}``."""

def laws(plugin_paths: Sequence[_Path]) -> str:
    """Every law found and every file that could not be opened, as JSON."""

def plugin_search_path(plugin_paths: Sequence[_Path]) -> List[str]:
    """The paths searched before ``TRIBO_PLUGIN_PATH``."""

def run(job: str) -> Tuple[str, Optional[Tuple[List[str], bytes]]]:
    """``tribo run --json``; with ``timeseries`` the column names and float64 rows as bytes."""

def compare(job: str) -> str:
    """``tribo compare --json``."""

def mass_response(job: str) -> str:
    """``tribo mass-response --json``."""

def fit(job: str) -> Tuple[str, str]:
    """``tribo fit --json`` and the calibrated law set's TOML."""

def sweep(job: str) -> str:
    """``tribo sweep --json``."""

def bundled_names() -> Tuple[List[str], List[str], List[str]]:
    """The bundled rigs, law sets and data files."""
