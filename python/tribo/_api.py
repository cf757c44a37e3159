"""Rigs, law sets, runs and studies: the Python face of ``tribo._native``.

Every function hands one job to the native module, which runs it with the same library
calls as ``tribo ... --json --in-process`` (the GIL released), and turns the answer into
pandas DataFrames. ``raw`` on every result holds the CLI's JSON as Python objects, exactly as
``json.loads`` would read what the CLI prints (the native module builds these objects straight
from the result, without the text).
"""

from __future__ import annotations

import copy
import json
import math
import os
import warnings
from typing import Any, Dict, Iterable, List, Mapping, Optional, Sequence, Union

import numpy as np
import pandas as pd

from . import _native

PathLike = Union[str, "os.PathLike[str]"]

#: The joints of every rig, in the solver's order.
JOINTS = ("main_a", "main_b", "big_end", "small_end", "piston")


# ---------------------------------------------------------------------------------------------
# isolation


def _isolation(
    in_process: bool,
    time_limit_s: Optional[float],
    memory_limit_mb: Optional[int],
    call_limit_s: Optional[float],
) -> str:
    """The isolation keywords every running function takes, as JSON for the native module
    (``None``: the CLI's default)."""
    iso: Dict[str, Any] = {"in_process": bool(in_process)}
    if time_limit_s is not None:
        iso["time_limit_s"] = float(time_limit_s)
    if memory_limit_mb is not None:
        iso["memory_limit_mb"] = int(memory_limit_mb)
    if call_limit_s is not None:
        iso["call_limit_s"] = float(call_limit_s)
    return json.dumps(iso)


# ---------------------------------------------------------------------------------------------
# plugins


def _plugin_paths(plugin_paths: Optional[Iterable[PathLike]]) -> List[str]:
    """Absolute plugin paths (so a Dask worker in another directory finds the same files)."""
    if plugin_paths is None:
        return []
    if isinstance(plugin_paths, (str, os.PathLike)):
        plugin_paths = [plugin_paths]
    return [os.path.abspath(os.fspath(p)) for p in plugin_paths]


def plugin_search_path(plugin_paths: Optional[Iterable[PathLike]] = None) -> List[str]:
    """The paths searched for law libraries, in order: ``plugin_paths`` (as the CLI's
    ``--plugin``), the ``target/release`` directory of the checkout this module was built from
    (where ``tribo`` and the bundled laws are built; only if it exists), then every directory
    in ``TRIBO_PLUGIN_PATH`` (not listed here) and the Python executable's directory."""
    return [os.fspath(p) for p in _native.plugin_search_path(_plugin_paths(plugin_paths))]


def laws(plugin_paths: Optional[Iterable[PathLike]] = None) -> pd.DataFrame:
    """Every law found (``tribo laws``): columns ``name`` and ``file``. Files that could not be
    opened are in ``.attrs["broken"]`` (file and reason), each also a ``RuntimeWarning``. The
    libraries are opened in worker processes, as ``tribo laws`` opens them: one whose
    initialiser ends, crashes or hangs its process is listed as broken, never the end of this
    interpreter."""
    out = _native.laws(_plugin_paths(plugin_paths))
    for b in out["broken"]:
        warnings.warn(f"skipped a plugin file that cannot be used: {b['error']}", RuntimeWarning, stacklevel=2)
    df = pd.DataFrame(out["laws"], columns=["name", "file"])
    df.attrs["broken"] = out["broken"]
    return df


def bundled() -> Dict[str, List[str]]:
    """The rigs, law sets and data files compiled into tribo, usable by name."""
    rigs, lawsets, data = _native.bundled_names()
    return {"rigs": list(rigs), "lawsets": list(lawsets), "data": list(data)}


# ---------------------------------------------------------------------------------------------
# rigs and law sets


def _toml_value(value: Any) -> str:
    """A Python value as a TOML value for a ``--set KEY=VALUE``; a ``str`` is passed as the CLI
    would take it (TOML if it parses, else a string)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, str):
        return value
    if isinstance(value, Mapping):
        inner = ", ".join(f"{k} = {_toml_literal(v)}" for k, v in value.items())
        return "{" + inner + "}"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_literal(v) for v in value) + "]"
    raise TypeError(f"cannot set a rig value to {value!r} ({type(value).__name__})")


def _toml_literal(value: Any) -> str:
    """Like :func:`_toml_value`, strings quoted (inside a table or list)."""
    if isinstance(value, str):
        return json.dumps(value)
    return _toml_value(value)


def _sets(overrides: Optional[Union[Mapping[str, Any], Sequence[str]]]) -> List[str]:
    """``{"bodies.rod.mass_scale": 0.6}`` or ``["bodies.rod.mass_scale=0.6"]`` as ``--set``s."""
    if overrides is None:
        return []
    if isinstance(overrides, Mapping):
        return [f"{k}={_toml_value(v)}" for k, v in overrides.items()]
    return [str(s) for s in overrides]


class Rig:
    """A rig: a bundled name (``"crf250r-motored"``) or a TOML file, a TOML text
    (:meth:`from_text`) or a dict (:meth:`from_dict`), with ``--set`` overrides (``set``) and
    an ``--oil`` file. Loaded and validated at once: a bad rig raises :class:`InputError` with
    the CLI's message. Immutable; :meth:`set` returns a new rig."""

    def __init__(
        self,
        source: PathLike = "crf250r-motored",
        *,
        set: Optional[Union[Mapping[str, Any], Sequence[str]]] = None,
        oil: Optional[PathLike] = None,
    ) -> None:
        spec: Dict[str, Any] = {"source": os.fspath(source), "sets": _sets(set)}
        if oil is not None:
            spec["oil"] = os.path.abspath(os.fspath(oil))
        self._init(spec)

    def _init(self, spec: Dict[str, Any]) -> None:
        loaded = _native.load_rig(json.dumps(spec))
        self._spec = spec
        self._path: str = loaded["path"]
        self._model: Dict[str, Any] = loaded["model"]

    @classmethod
    def _from_spec(cls, spec: Dict[str, Any]) -> "Rig":
        rig = cls.__new__(cls)
        rig._init(spec)
        return rig

    @classmethod
    def from_text(
        cls,
        text: str,
        name: str = "<python>.toml",
        *,
        set: Optional[Union[Mapping[str, Any], Sequence[str]]] = None,
    ) -> "Rig":
        """A rig from TOML text; ``name`` names it in messages (and ``extends`` is looked up
        beside it, then among the bundled rigs)."""
        return cls._from_spec({"text": text, "name": name, "sets": _sets(set)})

    @classmethod
    def from_dict(
        cls,
        table: Mapping[str, Any],
        name: str = "<python>.toml",
        *,
        set: Optional[Union[Mapping[str, Any], Sequence[str]]] = None,
    ) -> "Rig":
        """A rig from a dict shaped like the rig file (``{"extends": "crf250r-motored.toml",
        "bodies": {"rod": {"mass_scale": 0.6}}}`` works)."""
        return cls._from_spec({"table": dict(table), "name": name, "sets": _sets(set)})

    def set(
        self, overrides: Optional[Mapping[str, Any]] = None, **values: Any
    ) -> "Rig":
        """A new rig with more overrides by dotted path (``rig.set({"bodies.rod.mass_scale":
        0.6})``); keyword arguments use ``__`` for dots (``bodies__rod__mass_scale=0.6``)."""
        more = dict(overrides or {})
        more.update({k.replace("__", "."): v for k, v in values.items()})
        spec = copy.deepcopy(self._spec)
        spec["sets"] = spec.get("sets", []) + _sets(more)
        return Rig._from_spec(spec)

    @property
    def name(self) -> str:
        """The rig's ``name``."""
        return str(self._model.get("name", ""))

    @property
    def path(self) -> str:
        """The file it came from (``<bundled>/NAME.toml`` for a bundled rig)."""
        return self._path

    @property
    def model(self) -> Dict[str, Any]:
        """The validated, merged model as a dict (a copy)."""
        return copy.deepcopy(self._model)

    @property
    def spec(self) -> Dict[str, Any]:
        """How to load this rig again (what a Dask worker receives)."""
        return copy.deepcopy(self._spec)

    def __reduce__(self):  # noqa: D105 - pickled by its spec, reloaded (and checked) on arrival
        return (Rig._from_spec, (self._spec,))

    def __repr__(self) -> str:
        return f"Rig({self.name!r}, path={self._path!r}, sets={self._spec.get('sets', [])!r})"


class LawSet:
    """A law set: a bundled name (``"stribeck-duty"``) or file, a TOML text or a dict, plus
    ``--law JOINT=LAW[:PARAMS.toml]`` arguments (``laws``). Loaded at once; immutable."""

    def __init__(self, source: PathLike, *, laws: Sequence[str] = ()) -> None:
        self._init({"source": os.fspath(source), "laws": list(laws)})

    def _init(self, spec: Dict[str, Any]) -> None:
        loaded = _native.load_lawset(json.dumps(spec))
        self._spec = spec
        self._path: str = loaded["path"]
        self._file: Dict[str, Any] = loaded["file"]

    @classmethod
    def _from_spec(cls, spec: Dict[str, Any]) -> "LawSet":
        ls = cls.__new__(cls)
        ls._init(spec)
        return ls

    @classmethod
    def from_text(cls, text: str, name: str = "<python>.toml", *, laws: Sequence[str] = ()) -> "LawSet":
        """A law set from TOML text, named ``name`` in messages."""
        return cls._from_spec({"text": text, "name": name, "laws": list(laws)})

    @classmethod
    def from_dict(
        cls, table: Mapping[str, Any], name: str = "<python>.toml", *, laws: Sequence[str] = ()
    ) -> "LawSet":
        """A law set from a dict shaped like the file: ``{"name": ..., "laws": [{"joint": ...,
        "law": ..., "params": {...}, "free": {...}}]}``."""
        return cls._from_spec({"table": dict(table), "name": name, "laws": list(laws)})

    def with_laws(self, *laws: str) -> "LawSet":
        """A new law set with ``--law JOINT=LAW[:PARAMS.toml]`` arguments added."""
        spec = copy.deepcopy(self._spec)
        spec["laws"] = spec.get("laws", []) + list(laws)
        return LawSet._from_spec(spec)

    def set_params(
        self,
        values: Optional[Mapping[str, Any]] = None,
        *,
        plugin_paths: Optional[Iterable[PathLike]] = None,
        **kw: Any,
    ) -> "LawSet":
        """A new law set with law parameters set by ``JOINT.LAW.PARAM`` (the ids of
        :meth:`free_params` and ``tribo fit --params``): every entry of that law on that joint
        gets the value. Checked now, against the law's own declaration (found as a run would
        find it, ``plugin_paths`` first): an id that names no entry, a parameter the law does
        not have, or a value outside its range raises :class:`InputError`."""
        from .errors import InputError

        values = dict(values or {})
        values.update(kw)
        table = copy.deepcopy(self._file)
        for pid, v in values.items():
            parts = pid.split(".")
            if len(parts) != 3:
                raise InputError(
                    f"{self._path}: `{pid}`: a law parameter is named JOINT.LAW.PARAM, e.g. piston.stribeck-duty.mu_b"
                )
            joint, law, param = parts
            hits = [e for e in table["laws"] if e["joint"] == joint and e["law"] == law]
            if not hits:
                have = ", ".join(f"{e['joint']}.{e['law']}" for e in table["laws"])
                raise InputError(
                    f"{self._path}: `{pid}`: law set `{self.name}` has no law `{law}` on joint `{joint}`; it has {have}"
                )
            for e in hits:
                e.setdefault("params", {})[param] = v
        if "text" in self._spec or "table" in self._spec:
            name = self._spec.get("name", "<python>.toml")
        else:
            name = self._path
        out = LawSet._from_spec({"table": table, "name": name, "laws": self._spec.get("laws", [])})
        _native.check_lawset(json.dumps(out._spec), _plugin_paths(plugin_paths))
        return out

    @property
    def name(self) -> str:
        """The law set's name (names result rows)."""
        return str(self._file["name"])

    @property
    def path(self) -> str:
        """The file it came from."""
        return self._path

    @property
    def file(self) -> Dict[str, Any]:
        """The content as a dict (a copy)."""
        return copy.deepcopy(self._file)

    @property
    def spec(self) -> Dict[str, Any]:
        """How to load this law set again."""
        return copy.deepcopy(self._spec)

    def free_params(
        self,
        ids: Optional[Sequence[str]] = None,
        plugin_paths: Optional[Iterable[PathLike]] = None,
    ) -> pd.DataFrame:
        """The free parameters (those the file marks, or ``ids``): ``id``, ``entry``, ``param``,
        ``lower``, ``upper``, ``value`` (bounds from the file or the law's range)."""
        out = _native.free_params(
            json.dumps(self._spec),
            _plugin_paths(plugin_paths),
            list(ids) if ids is not None else None,
        )
        return pd.DataFrame(out, columns=["id", "entry", "param", "lower", "upper", "value"])

    def __reduce__(self):  # noqa: D105
        return (LawSet._from_spec, (self._spec,))

    def __repr__(self) -> str:
        return f"LawSet({self.name!r}, path={self._path!r})"


RigLike = Union[Rig, PathLike, Mapping[str, Any], None]
LawSetLike = Union[LawSet, PathLike, Mapping[str, Any]]


def _rig_spec(rig: RigLike, set: Any = None, oil: Optional[PathLike] = None) -> Dict[str, Any]:
    if rig is None:
        spec: Dict[str, Any] = {"source": "crf250r-motored", "sets": []}
    elif isinstance(rig, Rig):
        spec = rig.spec
    elif isinstance(rig, Mapping):
        spec = {"table": dict(rig), "name": "<python>.toml", "sets": []}
    else:
        spec = {"source": os.fspath(rig), "sets": []}
    spec["sets"] = spec.get("sets", []) + _sets(set)
    if oil is not None:
        if spec.get("oil"):
            raise TypeError("the rig already has an oil file; give oil= once")
        spec["oil"] = os.path.abspath(os.fspath(oil))
    return spec


def _lawset_spec(ls: LawSetLike, laws: Sequence[str] = ()) -> Dict[str, Any]:
    if isinstance(ls, LawSet):
        spec = ls.spec
    elif isinstance(ls, Mapping):
        spec = {"table": dict(ls), "name": "<python>.toml", "laws": []}
    else:
        spec = {"source": os.fspath(ls), "laws": []}
    spec["laws"] = spec.get("laws", []) + list(laws)
    return spec


def _lawset_specs(
    lawsets: Optional[Union[LawSetLike, Sequence[LawSetLike]]], laws: Sequence[str] = ()
) -> List[Dict[str, Any]]:
    if lawsets is None:
        if laws:
            from . import _native as n

            names = n.bundled_names()[1]
            defaults = [x for x in ("fedem-baseline", "stribeck-duty", "mixed-film") if x in names]
            return [_lawset_spec(x, laws) for x in defaults]
        return []
    if isinstance(lawsets, (str, os.PathLike, LawSet, Mapping)):
        lawsets = [lawsets]
    return [_lawset_spec(x, laws) for x in lawsets]


def _data(arg: Optional[PathLike]) -> Optional[str]:
    return None if arg is None else os.fspath(arg)


def _many(arg: Union[None, PathLike, Sequence[PathLike]]) -> List[str]:
    if arg is None:
        return []
    if isinstance(arg, (str, os.PathLike)):
        return [os.fspath(arg)]
    return [os.fspath(a) for a in arg]


# ---------------------------------------------------------------------------------------------
# results


def _joint_rows(plateaus: List[Dict[str, Any]]) -> List[Dict[str, Any]]:
    rows = []
    for p in plateaus:
        for j in p["joints"]:
            row = {"set_speed_rpm": p["set_speed_rpm"], "joint": j["joint"], "law": j["law"]}
            row.update({k: j[k] for k in ("friction_torque_nm", "power_w", "mean_normal_load_n")})
            row.update({f"regime_{k}": v for k, v in j["regime_share"].items()})
            rows.append(row)
    return rows


def _plateau_frame(plateaus: List[Dict[str, Any]]) -> pd.DataFrame:
    cols = ["set_speed_rpm", "mean_speed_rpm", "motoring_torque_nm", "oil_temp_c", "viscosity_pa_s", "revolutions"]
    # Built from columns in one call: adding columns to a frame one by one costs as much again.
    data: Dict[str, List[Any]] = {k: [p[k] for p in plateaus] for k in cols}
    data["window_start_s"] = [p["window_s"][0] for p in plateaus]
    data["window_end_s"] = [p["window_s"][1] for p in plateaus]
    return pd.DataFrame(data, columns=[*cols, "window_start_s", "window_end_s"])


class RunResult:
    """One run (``tribo run --json``): :attr:`plateaus` and :attr:`joints` as DataFrames (built
    when first asked for), :attr:`timeseries` as numpy arrays, :attr:`raw` the CLI's JSON."""

    def __init__(self, raw: Dict[str, Any], series: Optional[Dict[str, np.ndarray]] = None) -> None:
        self.raw = raw
        self.timeseries = series
        self._plateaus: Optional[pd.DataFrame] = None
        self._joints: Optional[pd.DataFrame] = None

    @property
    def plateaus(self) -> pd.DataFrame:
        """One row per plateau: speeds, motoring torque, oil, window."""
        if self._plateaus is None:
            self._plateaus = _plateau_frame(self.raw["plateaus"])
        return self._plateaus

    @property
    def joints(self) -> pd.DataFrame:
        """One row per plateau, joint and law: friction torque, power, load, regime shares."""
        if self._joints is None:
            self._joints = pd.DataFrame(_joint_rows(self.raw["plateaus"]))
        return self._joints

    @property
    def energy(self) -> Dict[str, float]:
        """The energy balance of the run."""
        return dict(self.raw["energy"])

    @property
    def warnings(self) -> List[str]:
        """Warnings of the run (a drive at its torque limit, say)."""
        return list(self.raw["warnings"])

    def __repr__(self) -> str:
        return f"RunResult(rig={self.raw['rig']!r}, drive={self.raw['drive']!r}, plateaus={len(self.raw['plateaus'])})"


def modes(
    rig: RigLike = "crf250r-testbed",
    *,
    set: Optional[Union[Mapping[str, Any], Sequence[str]]] = None,
    oil: Optional[PathLike] = None,
) -> Dict[str, Any]:
    """``tribo modes RIG --json``: the drivetrain of a rig with a ``[drivetrain]`` linearised at
    crank speed: ``inertias`` (``name``, ``inertia_kg_m2``), ``springs`` (``name``, ``between``,
    ``stiffness_nm_per_rad``) and ``modes`` (``frequency_hz``, ``shape``, the dominant spring
    and the engine orders crossing it at the plateau speeds). The transducer's figures of a run
    are in each plateau's ``instrument`` of :func:`run` with ``steady=True``."""
    return _native.modes(json.dumps(_rig_spec(rig, set, oil)))


def run(
    rig: RigLike = None,
    *,
    lawset: Optional[LawSetLike] = None,
    laws: Sequence[str] = (),
    set: Optional[Union[Mapping[str, Any], Sequence[str]]] = None,
    oil: Optional[PathLike] = None,
    steady: bool = False,
    timeseries: bool = False,
    plugin_paths: Optional[Iterable[PathLike]] = None,
    in_process: bool = False,
    time_limit_s: Optional[float] = None,
    memory_limit_mb: Optional[int] = None,
    call_limit_s: Optional[float] = None,
) -> RunResult:
    """``tribo run RIG [--lawset] [--law]... [--set]... [--oil] [--steady]``: the rig through
    its test cycle (or each plateau's steady state). ``timeseries=True`` (transient only) also
    returns every accepted step as numpy arrays (time, crank angle and speed, motoring torque,
    filtered torque, normal load per joint).

    The laws run in a worker process (this interpreter started again with only the native
    module), so a law that crashes, exits or hangs raises :class:`tribo.SimulationError` naming
    it instead of ending the script; ``in_process=True`` runs them here (a few tens of ms
    faster per call; a crashing law then ends the interpreter). ``time_limit_s`` (default 1800),
    ``memory_limit_mb`` (4096) and ``call_limit_s`` (10, one law call) limit the worker as the
    CLI's ``--time-limit-s``, ``--memory-limit-mb`` and ``--call-limit-s`` do; 0 is no limit."""
    job = {
        "rig": _rig_spec(rig, set, oil),
        "lawset": None if lawset is None else _lawset_spec(lawset),
        "laws": list(laws),
        "steady": bool(steady),
        "timeseries": bool(timeseries),
        "plugin_paths": _plugin_paths(plugin_paths),
    }
    raw, series = _native.run(json.dumps(job), _isolation(in_process, time_limit_s, memory_limit_mb, call_limit_s))
    arrays = None
    if series is not None:
        names, data = series
        table = np.frombuffer(data, dtype=np.float64).reshape(-1, len(names))
        arrays = {n: table[:, i].copy() for i, n in enumerate(names)}
    return RunResult(raw, arrays)


class Comparison:
    """A comparison (``tribo compare --json``): :attr:`table` (speed, measured, one model column
    per law set), :attr:`sets` (rank, RMSE, scores per set), :attr:`joints` (per set, speed,
    joint), :attr:`raw` the CLI's JSON."""

    def __init__(self, raw: Dict[str, Any]) -> None:
        self.raw = raw
        data = raw["data"]
        table = pd.DataFrame(
            {
                "speed_rpm": [r["speed_rpm"] for r in data],
                "oil_temp_c": [r["oil_temp_c"] for r in data],
                "measured_nm": [r["torque_nm"] for r in data],
            }
        )
        for s in raw["sets"]:
            table[s["lawset"]] = [p["motoring_torque_nm"] for p in s["run"]["plateaus"]]
        self.table = table
        rows = []
        for s in raw["sets"]:
            sc = s["scores"]
            rows.append(
                {
                    "lawset": s["lawset"],
                    "rank": s["rank"],
                    "rmse_nm": s["rmse_nm"],
                    "max_abs_error_nm": s["max_abs_error_nm"],
                    "cv_rmse_nm": sc.get("cv_rmse_nm"),
                    "free_params": sc.get("free_params"),
                    "aicc": sc.get("aicc"),
                    "bic": sc.get("bic"),
                    "file": s["file"],
                }
            )
        self.sets = pd.DataFrame(rows)
        joints = []
        for s in raw["sets"]:
            for r in _joint_rows(s["run"]["plateaus"]):
                joints.append({"lawset": s["lawset"], **r})
        self.joints = pd.DataFrame(joints)

    @property
    def verdict(self) -> str:
        """What the scores let a user conclude, in one sentence (the CLI's ``Verdict:`` line;
        the rule that chose it is ``raw["verdict"]["rule"]``)."""
        return str(self.raw["verdict"]["sentence"])

    @property
    def errors(self) -> pd.DataFrame:
        """Model minus measurement at each speed, one column per law set."""
        df = pd.DataFrame({"speed_rpm": self.table["speed_rpm"]})
        for s in self.raw["sets"]:
            df[s["lawset"]] = s["errors_nm"]
        return df

    def __repr__(self) -> str:
        return f"Comparison(rig={self.raw['rig']!r}, mode={self.raw['mode']!r}, sets={list(self.sets['lawset'])})"


def compare(
    rig: RigLike = None,
    *,
    lawsets: Optional[Union[LawSetLike, Sequence[LawSetLike]]] = None,
    laws: Sequence[str] = (),
    data: Optional[PathLike] = None,
    validate: Union[None, PathLike, Sequence[PathLike]] = None,
    set: Optional[Union[Mapping[str, Any], Sequence[str]]] = None,
    steady: bool = False,
    no_cv: bool = False,
    no_fit: bool = False,
    starts: int = 4,
    data_for_any_rig: bool = False,
    plugin_paths: Optional[Iterable[PathLike]] = None,
    in_process: bool = False,
    time_limit_s: Optional[float] = None,
    memory_limit_mb: Optional[int] = None,
    call_limit_s: Optional[float] = None,
) -> Comparison:
    """``tribo compare``: law sets (default: the bundled three) against measured data (default:
    the rig's own bundled measurements), each set with free parameters fitted first (``no_fit``
    keeps the file's values, labelled "not fitted"; ``starts`` Latin-hypercube starts besides
    its own values and the corners of its bounds), scored, ranked and judged (``raw["verdict"]``)
    as the CLI does. Data declaring another rig need ``data_for_any_rig=True``.

    ``in_process`` and the limits: as for :func:`run`."""
    job = {
        "rig": _rig_spec(rig, set),
        "lawsets": _lawset_specs(lawsets, laws),
        "data": _data(data),
        "validate": _many(validate),
        "steady": bool(steady),
        "no_cv": bool(no_cv),
        "no_fit": bool(no_fit),
        "starts": int(starts),
        "data_for_any_rig": bool(data_for_any_rig),
        "plugin_paths": _plugin_paths(plugin_paths),
    }
    return Comparison(_native.compare(json.dumps(job), _isolation(in_process, time_limit_s, memory_limit_mb, call_limit_s)))


class MassResponse:
    """A mass response (``tribo mass-response --json``): :attr:`table` one row per law set,
    scale and speed; :attr:`joints` one row per law set, scale, speed and joint."""

    def __init__(self, raw: List[Dict[str, Any]]) -> None:
        self.raw = raw
        rows, joints = [], []
        for m in raw:
            for c in m["changes"]:
                base = {"lawset": m["lawset"], "body": m["body"], "scale": c["scale"], "speed_rpm": c["speed_rpm"]}
                rows.append(
                    {
                        **base,
                        **{k: c[k] for k in ("original_nm", "scaled_nm", "change_nm", "fedem_change_nm")},
                    }
                )
                for j in c["joints"]:
                    joints.append({**base, **j})
        self.table = pd.DataFrame(rows)
        self.joints = pd.DataFrame(joints)

    def __repr__(self) -> str:
        return f"MassResponse(lawsets={[m['lawset'] for m in self.raw]})"


def mass_response(
    rig: RigLike = None,
    *,
    body: str = "rod",
    scales: Union[float, Sequence[float]] = 0.6,
    lawsets: Optional[Union[LawSetLike, Sequence[LawSetLike]]] = None,
    set: Optional[Union[Mapping[str, Any], Sequence[str]]] = None,
    steady: bool = False,
    plugin_paths: Optional[Iterable[PathLike]] = None,
    in_process: bool = False,
    time_limit_s: Optional[float] = None,
    memory_limit_mb: Optional[int] = None,
    call_limit_s: Optional[float] = None,
) -> MassResponse:
    """``tribo mass-response --body BODY --scale S`` (or ``--scales``): torque and per-joint
    friction change when a body's mass (and inertia) is scaled.

    ``in_process`` and the limits: as for :func:`run`."""
    scale_list = [float(scales)] if isinstance(scales, (int, float)) else [float(s) for s in scales]
    job = {
        "rig": _rig_spec(rig, set),
        "lawsets": _lawset_specs(lawsets),
        "body": body,
        "scales": scale_list,
        "steady": bool(steady),
        "plugin_paths": _plugin_paths(plugin_paths),
    }
    return MassResponse(_native.mass_response(json.dumps(job), _isolation(in_process, time_limit_s, memory_limit_mb, call_limit_s)))


class FitResult:
    """A calibration (``tribo fit --json``): :attr:`params` (id, start, value, bounds, 1-sigma,
    bound hit), :attr:`points` (speed, measured, model, residual), :attr:`lawset` the
    calibrated law set, :attr:`lawset_toml` the file ``tribo fit`` writes, :attr:`raw`."""

    def __init__(self, raw: Dict[str, Any], toml_text: str, name: str) -> None:
        self.raw = raw
        self.lawset_toml = toml_text
        self.lawset = LawSet.from_text(toml_text, f"{name}-fitted.toml")
        self.params = pd.DataFrame(
            {
                "id": raw["params"],
                "start": raw["start"],
                "value": raw["values"],
                "lower": [b[0] for b in raw["bounds"]],
                "upper": [b[1] for b in raw["bounds"]],
                "std_dev": raw["std_dev"],
                "at_bound": raw["at_bound"],
            }
        )
        self.points = pd.DataFrame(
            {
                "speed_rpm": raw["speeds_rpm"],
                "measured_nm": raw["measured_nm"],
                "model_nm": raw["model_nm"],
                "residual_nm": raw["residuals_nm"],
            }
        )

    @property
    def rmse_nm(self) -> float:
        """In-sample RMSE, N m."""
        return float(self.raw["rmse_nm"])

    def __repr__(self) -> str:
        return f"FitResult(lawset={self.raw['lawset']!r}, rmse_nm={self.rmse_nm:.4f}, termination={self.raw['termination']!r})"


def fit(
    rig: RigLike = None,
    *,
    lawset: LawSetLike,
    params: Optional[Sequence[str]] = None,
    data: Union[None, PathLike, Sequence[PathLike]] = None,
    validate: Union[None, PathLike, Sequence[PathLike]] = None,
    starts: int = 4,
    no_cv: bool = False,
    data_for_any_rig: bool = False,
    set: Optional[Union[Mapping[str, Any], Sequence[str]]] = None,
    plugin_paths: Optional[Iterable[PathLike]] = None,
    in_process: bool = False,
    time_limit_s: Optional[float] = None,
    memory_limit_mb: Optional[int] = None,
    call_limit_s: Optional[float] = None,
) -> FitResult:
    """``tribo fit --lawset L [--params ...] [--data ...] [--starts N]``: calibrate the law set's
    free parameters (or ``params``, ``JOINT.LAW.PARAM``) on steady-state runs, from its own
    values, the corners of the bounds and ``starts`` Latin-hypercube points, polished from the
    best (as the CLI; 0 to 64).

    ``in_process`` and the limits: as for :func:`run`."""
    spec = _lawset_spec(lawset)
    job = {
        "rig": _rig_spec(rig, set),
        "lawset": spec,
        "params": list(params) if params is not None else None,
        "data": _many(data),
        "validate": _many(validate),
        "starts": int(starts),
        "no_cv": bool(no_cv),
        "data_for_any_rig": bool(data_for_any_rig),
        "plugin_paths": _plugin_paths(plugin_paths),
    }
    raw, toml_text = _native.fit(json.dumps(job), _isolation(in_process, time_limit_s, memory_limit_mb, call_limit_s))
    return FitResult(raw, toml_text, raw["lawset"])


class Sweep:
    """A sweep (``tribo sweep --json``): :attr:`table` one row per law set, temperature and
    speed with each joint's friction torque in a column ``<joint>_nm``; :attr:`raw`."""

    def __init__(self, raw: Dict[str, Any]) -> None:
        self.raw = raw
        rows = []
        for s in raw["sets"]:
            for p in s["points"]:
                row = {
                    "lawset": s["lawset"],
                    "oil_temp_c": p["oil_temp_c"],
                    "speed_rpm": p["speed_rpm"],
                    "viscosity_pa_s": p["viscosity_pa_s"],
                    "torque_nm": p["torque_nm"],
                }
                row.update({f"{j['joint']}_nm": j["friction_torque_nm"] for j in p["joints"]})
                rows.append(row)
        self.table = pd.DataFrame(rows)

    @property
    def oil(self) -> Dict[str, Any]:
        """The oil swept: name, grade, viscosity model, source."""
        return dict(self.raw["oil"])

    def __repr__(self) -> str:
        return f"Sweep(rig={self.raw['rig']!r}, sets={[s['lawset'] for s in self.raw['sets']]}, points={len(self.table)})"


#: The temperatures and speeds of ``tribo sweep`` without ``--temps`` / ``--speeds``.
DEFAULT_TEMPS_C = (40.0, 50.0, 60.0, 70.0, 80.0, 90.0, 100.0, 110.0)
DEFAULT_SPEEDS_RPM = (3000.0, 4000.0, 5000.0, 6000.0, 7000.0, 8000.0, 9000.0)


def sweep(
    rig: RigLike = None,
    *,
    lawsets: Optional[Union[LawSetLike, Sequence[LawSetLike]]] = None,
    laws: Sequence[str] = (),
    temps: Sequence[float] = DEFAULT_TEMPS_C,
    speeds: Sequence[float] = DEFAULT_SPEEDS_RPM,
    oil: Optional[PathLike] = None,
    set: Optional[Union[Mapping[str, Any], Sequence[str]]] = None,
    plugin_paths: Optional[Iterable[PathLike]] = None,
    in_process: bool = False,
    time_limit_s: Optional[float] = None,
    memory_limit_mb: Optional[int] = None,
    call_limit_s: Optional[float] = None,
) -> Sweep:
    """``tribo sweep``: steady-state torque of each law set over oil temperatures and speeds.

    ``in_process`` and the limits: as for :func:`run`."""
    job = {
        "rig": _rig_spec(rig, set, oil),
        "lawsets": _lawset_specs(lawsets, laws),
        "temps_c": [float(t) for t in temps],
        "speeds_rpm": [float(s) for s in speeds],
        "plugin_paths": _plugin_paths(plugin_paths),
    }
    return Sweep(_native.sweep(json.dumps(job), _isolation(in_process, time_limit_s, memory_limit_mb, call_limit_s)))
