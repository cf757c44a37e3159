"""Fixtures of the FMU tests: the `tribo` binary of this checkout, FMUs it exports (each once
per session), and an FMI 2.0 Co-Simulation driver over FMPy's `FMU2Slave` that records what
the FMU logs."""

from __future__ import annotations

import ctypes
import json
import os
import subprocess
from pathlib import Path

import fmpy
import pytest
from fmpy.fmi2 import FMU2Slave, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE

ROOT = Path(__file__).resolve().parents[3]
RELEASE = Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target")) / "release"
TRIBO = RELEASE / "tribo"


@pytest.fixture(scope="session")
def tribo_bin() -> Path:
    """`target/release/tribo` and the FMU library beside it, built by the test command's cargo
    steps (`cargo build --release` builds both)."""
    for f in (TRIBO, RELEASE / "libtribo_fmu.so"):
        if not f.is_file():
            pytest.fail(f"{f} is missing: run `cargo build --release` first")
    return TRIBO


def run_json(tribo: Path, *args: str, cwd: Path | None = None) -> dict:
    """`tribo ARGS --json`, parsed."""
    proc = subprocess.run(
        [str(tribo), "--quiet", *args, "--json"],
        capture_output=True,
        text=True,
        cwd=cwd,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)


@pytest.fixture(scope="session")
def exported(tribo_bin, tmp_path_factory):
    """`export(*args)`: the FMU `tribo fmu export ARGS` writes (cached per argument list) and
    its directory unpacked by FMPy."""
    cache: dict[tuple[str, ...], tuple[Path, Path]] = {}

    def export(*args: str, plugin: Path | None = None) -> tuple[Path, Path]:
        key = (*args, str(plugin))
        if key not in cache:
            d = tmp_path_factory.mktemp("fmu")
            fmu = d / "engine-friction.fmu"
            pre = ["--plugin", str(plugin)] if plugin else []
            proc = subprocess.run(
                [str(tribo_bin), *pre, "fmu", "export", *args, "--out", str(fmu)],
                capture_output=True,
                text=True,
                cwd=d,
                timeout=600,
            )
            assert proc.returncode == 0, proc.stderr
            cache[key] = (fmu, Path(fmpy.extract(str(fmu))))
        return cache[key]

    return export


def build_fixture_law(tmp_path_factory, source: str, law: str, extra: str) -> Path:
    """The C fixture law `tests/fixtures/c/SOURCE.c` built with the system C compiler as
    `libtribo_law_fixture_SOURCE.so`, and beside it `SOURCE.toml`, a law set putting `law` on
    the piston (`extra`: its law table's further lines)."""
    d = tmp_path_factory.mktemp(source)
    lib = d / f"libtribo_law_fixture_{source}.so"
    cc = os.environ.get("CC", "cc")
    subprocess.run(
        [cc, "-shared", "-fPIC", "-O1", "-I", str(ROOT / "plugin-api" / "include"),
         str(ROOT / "tests" / "fixtures" / "c" / f"{source}.c"), "-o", str(lib)],
        check=True,
    )
    text = f'name = "{source}"\n\n[[laws]]\njoint = "piston"\nlaw = "{law}"\n{extra}'
    (d / f"{source}.toml").write_text(text)
    return lib


@pytest.fixture(scope="session")
def hostile_lib(tmp_path_factory) -> Path:
    """The hostile test law (tests/fixtures/c/hostile.c: parameter `mode` 0 behaves, 1
    segfaults, 2 aborts, 3 hangs, 5 calls exit(0), 6 prints on standard output, 9 calls _exit(0),
    10 kills its process group)."""
    params = "params = { mode = 0 }\n"
    return build_fixture_law(tmp_path_factory, "hostile", "fixture-hostile", params)


@pytest.fixture(scope="session")
def creeping_lib(tmp_path_factory) -> Path:
    """A stateful law whose cycle never repeats (tests/fixtures/c/creeping.c: viscous friction
    growing with the time committed over) on the piston."""
    return build_fixture_law(tmp_path_factory, "creeping", "fixture-creeping", "")


class Fmu:
    """One FMU instance driven through FMPy's FMU2Slave (the FMI 2.0 C calls), with its log."""

    def __init__(
        self,
        unzipdir: Path,
        name: str = "instance",
        start: dict[str, float] | None = None,
        log: list[tuple[int, str]] | None = None,
    ):
        self.md = fmpy.read_model_description(str(unzipdir))
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        # (status, message) of every log call; given by the caller to read it also when the
        # instantiation fails.
        self.log = [] if log is None else log
        self.callbacks = fmi2CallbackFunctions()
        # Keep the ctypes callback alive as long as the instance.
        self._logger = fmi2CallbackLoggerTYPE(self._record)
        self.callbacks.logger = self._logger
        self.callbacks.allocateMemory = fmpy.fmi2.defaultCallbacks.allocateMemory
        self.callbacks.freeMemory = fmpy.fmi2.defaultCallbacks.freeMemory
        # FMPy's proxy formats the printf-style message before it reaches Python.
        from fmpy.logging import addLoggerProxy

        addLoggerProxy(ctypes.byref(self.callbacks))
        self.slave = FMU2Slave(
            guid=self.md.guid,
            unzipDirectory=str(unzipdir),
            modelIdentifier=self.md.coSimulation.modelIdentifier,
            instanceName=name,
        )
        self.slave.instantiate(callbacks=self.callbacks)
        self.t = 0.0
        self.slave.setupExperiment(startTime=0.0)
        self.slave.enterInitializationMode()
        for k, v in (start or {}).items():
            self.set(k, v)
        self.slave.exitInitializationMode()

    def _record(self, env, instance, status, category, message):
        self.log.append((status, message.decode("utf-8", "replace")))

    def set(self, name: str, value: float) -> None:
        self.slave.setReal([self.vr[name]], [value])

    def get(self, *names: str) -> list[float]:
        return self.slave.getReal([self.vr[n] for n in names])

    def step(self, h: float) -> None:
        self.slave.doStep(currentCommunicationPoint=self.t, communicationStepSize=h)
        self.t += h

    def free(self) -> None:
        self.slave.terminate()
        self.slave.freeInstance()


def text(log: list[tuple[int, str]]) -> str:
    """The logged messages, one per line."""
    return "\n".join(m for _, m in log)
