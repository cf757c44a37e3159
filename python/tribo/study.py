"""Designs of experiments over rig parameters, law parameters and oil temperature, run serially
or on Dask.

A design is a DataFrame with one column per factor and one row per point:

* ``"oil_temp_c"``: the oil temperature, C (otherwise ``oil_temp_c=`` of :func:`run_design`);
* ``"rig:DOTTED.PATH"``: a rig value, as ``--set DOTTED.PATH=VALUE`` (``rig:bodies.rod.mass_scale``);
* ``"law:JOINT.LAW.PARAM"``: a law parameter of the law set (``law:piston.stribeck-duty.mu_boundary``).

Each point is one steady-state sweep of the law set at that temperature over ``speeds``, with
exactly the library calls of ``tribo sweep``. :func:`run_design` returns one DataFrame, one row
per point and speed, in design order, and the same numbers whether the points ran here or on
Dask workers (a :class:`dask.distributed.LocalCluster` by default, or any scheduler by
address). Workers find the laws as this process does: the plugin paths are sent with every
task as absolute paths, with this process's ``TRIBO_PLUGIN_PATH``.
"""

from __future__ import annotations

import itertools
import os
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np
import pandas as pd

from . import _api
from .errors import InputError

__all__ = ["full_factorial", "latin_hypercube", "run_design", "evaluate_point"]


def full_factorial(levels: Mapping[str, Sequence[float]]) -> pd.DataFrame:
    """Every combination of the factors' levels, the last factor varying fastest."""
    names = list(levels)
    rows = list(itertools.product(*(list(levels[n]) for n in names)))
    return pd.DataFrame(rows, columns=names, dtype=float)


def latin_hypercube(ranges: Mapping[str, Tuple[float, float]], n: int, seed: int = 0) -> pd.DataFrame:
    """``n`` points over the factors' ``(low, high)`` ranges: each factor's range cut into
    ``n`` equal strata, one point in each, the strata paired at random (reproducible by
    ``seed``)."""
    if n < 1:
        raise InputError(f"latin_hypercube: n must be at least 1, got {n}")
    rng = np.random.default_rng(seed)
    cols = {}
    for name, (lo, hi) in ranges.items():
        if not (np.isfinite(lo) and np.isfinite(hi) and lo <= hi):
            raise InputError(f"latin_hypercube: factor `{name}`: range ({lo}, {hi}) must be finite with low <= high")
        u = (rng.permutation(n) + rng.random(n)) / n
        cols[name] = lo + u * (hi - lo)
    return pd.DataFrame(cols)


def _split(columns: Sequence[str]) -> None:
    for c in columns:
        if c != "oil_temp_c" and not c.startswith(("rig:", "law:")):
            raise InputError(
                f"design column `{c}`: name a factor `oil_temp_c`, `rig:DOTTED.PATH` (a rig value) or `law:JOINT.LAW.PARAM` (a law parameter)"
            )


def evaluate_point(
    point: Mapping[str, float],
    rig: Dict[str, Any],
    lawset: Dict[str, Any],
    speeds: Sequence[float],
    oil_temp_c: float,
    plugin_paths: Sequence[str],
    plugin_env: Optional[str],
) -> List[Dict[str, Any]]:
    """One design point: the rig (a spec) with the point's ``rig:`` values set, the law set with
    its ``law:`` values, swept at the point's temperature over ``speeds``. Rows of the result
    (factor values, speed, torque, per joint). Runs on a Dask worker as well as here."""
    if plugin_env is not None:
        os.environ["TRIBO_PLUGIN_PATH"] = plugin_env
    sets = {k[4:]: float(v) for k, v in point.items() if k.startswith("rig:")}
    params = {k[4:]: float(v) for k, v in point.items() if k.startswith("law:")}
    temp = float(point.get("oil_temp_c", oil_temp_c))
    rig_obj = _api.Rig._from_spec(rig).set(sets) if sets else _api.Rig._from_spec(rig)
    ls = _api.LawSet._from_spec(lawset)
    if params:
        ls = ls.set_params(params, plugin_paths=plugin_paths)
    sw = _api.sweep(rig_obj, lawsets=ls, temps=[temp], speeds=speeds, plugin_paths=plugin_paths)
    rows = []
    for r in sw.table.to_dict("records"):
        r.pop("lawset")
        rows.append({**{k: float(v) for k, v in point.items()}, **r})
    return rows


def _client(scheduler: Any, n_workers: int):
    """A Dask client and the cluster to close afterwards (``None`` if given by the caller)."""
    from dask.distributed import Client, LocalCluster

    if isinstance(scheduler, Client):
        return scheduler, None, False
    if scheduler is None or scheduler == "local":
        cluster = LocalCluster(
            n_workers=n_workers, threads_per_worker=1, processes=True, dashboard_address=None
        )
        return Client(cluster), cluster, True
    return Client(scheduler), None, True


def run_design(
    design: pd.DataFrame,
    *,
    rig: _api.RigLike = None,
    lawset: _api.LawSetLike = "stribeck-duty",
    speeds: Sequence[float] = _api.DEFAULT_SPEEDS_RPM,
    oil_temp_c: float = 80.0,
    dask: Union[bool, str, Any] = False,
    n_workers: int = 2,
    plugin_paths: Optional[Sequence[_api.PathLike]] = None,
) -> pd.DataFrame:
    """Run every point of ``design``: serially (``dask=False``), on a new local Dask cluster of
    ``n_workers`` processes (``dask=True`` or ``"local"``), on the scheduler at an address
    (``dask="tcp://host:8786"``) or through a :class:`dask.distributed.Client`. One row per
    point and speed, in design order: ``point``, the factors, ``oil_temp_c``, ``speed_rpm``,
    ``viscosity_pa_s``, ``torque_nm`` and ``<joint>_nm``. Inputs are checked here before any
    task is sent."""
    _split(list(design.columns))
    rig_spec = _api._rig_spec(rig)
    ls_spec = _api._lawset_spec(lawset)
    # Checked once here (a bad rig, law set or factor fails before the cluster starts).
    _api.Rig._from_spec(rig_spec)
    base = _api.LawSet._from_spec(ls_spec)
    law_factors = [c[4:] for c in design.columns if c.startswith("law:")]
    paths = _api._plugin_paths(plugin_paths)
    # Every point's law values are checked against the laws' ranges before any task is sent.
    for _, row in design.iterrows() if law_factors else ():
        base.set_params({p: float(row[f"law:{p}"]) for p in law_factors}, plugin_paths=paths)
    env = os.environ.get("TRIBO_PLUGIN_PATH")
    speeds = [float(s) for s in speeds]
    points = design.to_dict("records")
    args = (rig_spec, ls_spec, speeds, float(oil_temp_c), paths, env)
    if dask is False or dask is None:
        results = [evaluate_point(p, *args) for p in points]
    else:
        client, cluster, own = _client(None if dask is True else dask, n_workers)
        try:
            futures = client.map(
                evaluate_point, points, *[[a] * len(points) for a in args], pure=False
            )
            results = client.gather(futures)
        finally:
            if own:
                client.close()
            if cluster is not None:
                cluster.close()
    rows = []
    for i, point_rows in enumerate(results):
        for r in point_rows:
            rows.append({"point": i, **r})
    return pd.DataFrame(rows)
