"""The FMU that `tribo fmu export` writes, imported by a real FMI importer: FMPy from PyPI.

Reference values come from the command line (`tribo run --steady`, a separate path through the
solver: its own periodic steady state on a fixed 1-degree grid, no FMU, no worker, no FMPy) and
from the energy balance (at a steady speed the drive's work per revolution is the friction's).

The FMU integrates in time (Simpson's rule at the input speed, steps of at most 1 degree cut at
every communication point), the steady run on a grid whose points fall on the dead centres,
where the piston's friction reverses: a kink in the friction power that Simpson's rule across it
integrates to a few 1e-5 (`STEADY_REL`), the price of communication points anywhere.
"""

from __future__ import annotations

import math
import shutil
import time
from pathlib import Path

import fmpy
import numpy as np
import pytest
from fmpy.fmi1 import FMICallException
from fmpy.validation import validate_fmu

from conftest import Fmu, run_json, text

RIG = "crf250r-motored"
LAWSET = "fedem-baseline"
REL = 1e-6
# The FMU's time integration against the steady run's periodic grid (see the module doc).
STEADY_REL = 1e-4


def rad_s(rpm: float) -> float:
    return rpm * math.pi / 30.0


@pytest.fixture(scope="module")
def baseline(exported):
    return exported(RIG, "--lawset", LAWSET)


@pytest.fixture(scope="module")
def steady(tribo_bin):
    """`tribo run crf250r-motored --lawset fedem-baseline --steady`, per plateau: speed, oil
    temperature, motoring torque and each joint's friction torque (its laws summed)."""
    out = run_json(tribo_bin, "run", RIG, "--lawset", LAWSET, "--steady")
    plateaus = []
    for p in out["plateaus"]:
        joints: dict[str, float] = {}
        for j in p["joints"]:
            joints[j["joint"]] = joints.get(j["joint"], 0.0) + j["friction_torque_nm"]
        plateaus.append(
            {
                "rpm": p["set_speed_rpm"],
                "oil_c": p["oil_temp_c"],
                "motoring": p["motoring_torque_nm"],
                "joints": joints,
                "total": sum(joints.values()),
            }
        )
    return plateaus


def close(a: float, b: float, rel: float = REL) -> bool:
    return abs(a - b) <= rel * max(abs(a), abs(b))


def test_fmpy_validates_the_fmu_and_its_interface_carries_units_and_the_law_set(baseline):
    fmu, unzipdir = baseline
    assert validate_fmu(str(fmu)) == []
    md = fmpy.read_model_description(str(fmu), validate=True)
    assert md.fmiVersion == "2.0" and md.coSimulation is not None
    assert md.coSimulation.canGetAndSetFMUstate and md.coSimulation.canSerializeFMUstate
    v = {x.name: x for x in md.modelVariables}
    units = {u.name: u for u in md.unitDefinitions}
    # Inputs with their units; rpm offered as the display unit of rad/s (30/pi).
    assert (v["crank_speed"].causality, v["crank_speed"].unit) == ("input", "rad/s")
    assert v["crank_speed"].displayUnit == "rpm"
    rpm = next(d for d in units["rad/s"].displayUnits if d.name == "rpm")
    assert close(rpm.factor, 30.0 / math.pi, 1e-15)
    assert (v["oil_temperature"].causality, v["oil_temperature"].unit) == ("input", "degC")
    assert units["degC"].baseUnit.K == 1 and units["degC"].baseUnit.offset == 273.15
    # N m is kg m^2 s^-2.
    nm = units["N.m"].baseUnit
    assert (nm.kg, nm.m, nm.s) == (1, 2, -2)
    # Outputs: totals and each joint with laws (the small end has none in this set).
    for name in ["friction_torque", "friction_power", "friction_energy", "crank_angle",
                 "drive_torque", "friction_torque_cycle_mean", "drive_torque_cycle_mean"]:
        assert v[name].causality == "output", name
    for joint in ["main_a", "main_b", "big_end", "piston"]:
        assert v[f"{joint}.friction_torque"].unit == "N.m"
        assert v[f"{joint}.friction_power"].unit == "W"
    assert "small_end.friction_torque" not in v
    # Law parameters are tunable, start at the law set's values (thesis table 9.5), and
    # keep the law's declared range.
    mu = v["piston.fedem_friction.mu"]
    assert (mu.causality, mu.variability) == ("parameter", "tunable")
    assert float(mu.start) == 0.08
    assert float(v["main_a.fedem_friction.mu"].start) == 0.00245
    assert float(v["big_end.polyline_damper.factors[1]"].start) == 0.655
    assert v["big_end.polyline_damper.per_engine_speed"].type == "Boolean"
    # Resources: the rig, the interface, the two law libraries and the worker travel inside.
    res = unzipdir / "resources"
    assert (res / "model.toml").is_file() and (res / "interface.toml").is_file()
    assert sorted(p.name for p in (res / "plugins").iterdir()) == [
        "libtribo_law_fedem_friction.so",
        "libtribo_law_polyline_damper.so",
    ]
    assert (unzipdir / "binaries" / "linux64" / "tribo_fmu.so").is_file()


def test_one_second_at_6000_rpm_in_fmpy_gives_the_cli_mean_torque_every_revolution(baseline, steady):
    fmu, _ = baseline
    p = next(p for p in steady if p["rpm"] == 6000.0)
    joints = list(p["joints"])
    out = ["crank_angle", "friction_energy", "friction_torque_cycle_mean", "drive_torque_cycle_mean"]
    out += [f"{j}.friction_energy" for j in joints]
    res = fmpy.simulate_fmu(
        str(fmu),
        start_time=0.0,
        stop_time=1.0,
        step_size=1e-4,
        output_interval=1e-4,
        start_values={"crank_speed": rad_s(6000.0), "oil_temperature": p["oil_c"]},
        output=out,
    )
    assert math.isclose(res["time"][-1], 1.0)
    theta = res["crank_angle"]
    # 6000 rpm is 100 revolutions per second: one revolution every 100 steps of 0.1 ms.
    assert close(theta[-1], 100 * 2 * math.pi, 1e-12)
    k = np.arange(0, len(theta) - 100, 100)
    dtheta = theta[k + 100] - theta[k]
    per_rev = (res["friction_energy"][k + 100] - res["friction_energy"][k]) / dtheta
    assert len(per_rev) == 100
    for m in per_rev:
        assert close(m, p["total"], STEADY_REL), (m, p["total"])
    for j in joints:
        e = res[f"{j}.friction_energy"]
        mj = (e[-1] - e[-101]) / (theta[-1] - theta[-101])
        assert close(mj, p["joints"][j], STEADY_REL), (j, mj, p["joints"][j])
    assert close(res["friction_torque_cycle_mean"][-1], p["total"], STEADY_REL)
    # Energy balance at a steady speed: the drive's work per revolution is the friction's (the
    # gas's work over a whole 4-stroke cycle is zero: two revolutions).
    assert close(res["drive_torque_cycle_mean"][-1], p["motoring"], STEADY_REL)
    assert close(res["drive_torque_cycle_mean"][-1], res["friction_torque_cycle_mean"][-1], STEADY_REL)


def test_every_thesis_plateau_gives_the_mean_torque_of_run_steady(baseline, steady):
    _, unzipdir = baseline
    fmu = Fmu(unzipdir)
    try:
        for p in steady:
            w = rad_s(p["rpm"])
            fmu.set("crank_speed", w)
            fmu.set("oil_temperature", p["oil_c"])
            # One revolution at the new speed, then a measured one, 37 uneven steps each.
            rev = 2 * math.pi / w
            steps = np.diff(rev * np.linspace(0.0, 1.0, 38) ** 2)
            for h in steps:
                fmu.step(float(h))
            before = fmu.get("crank_angle", "friction_energy", *[f"{j}.friction_energy" for j in p["joints"]])
            for h in steps[::-1]:
                fmu.step(float(h))
            after = fmu.get("crank_angle", "friction_energy", *[f"{j}.friction_energy" for j in p["joints"]])
            dtheta = after[0] - before[0]
            assert close(dtheta, 2 * math.pi, 1e-12)
            assert close((after[1] - before[1]) / dtheta, p["total"], STEADY_REL), p["rpm"]
            for i, j in enumerate(p["joints"]):
                assert close((after[2 + i] - before[2 + i]) / dtheta, p["joints"][j], STEADY_REL), (p["rpm"], j)
            (mean,) = fmu.get("friction_torque_cycle_mean")
            assert close(mean, p["total"], STEADY_REL), p["rpm"]
    finally:
        fmu.free()


def test_two_instances_in_one_process_share_nothing(baseline):
    _, unzipdir = baseline
    a_in = {"crank_speed": rad_s(3000.0), "oil_temperature": 80.0}
    b_in = {"crank_speed": rad_s(9000.0), "oil_temperature": 110.0, "piston.fedem_friction.mu": 0.16}
    names = ("crank_angle", "friction_torque", "friction_energy", "piston.friction_power")

    def alone(start, n):
        f = Fmu(unzipdir, start=start)
        rows = []
        for _ in range(n):
            f.step(2.5e-4)
            rows.append(f.get(*names))
        f.free()
        return rows

    solo_a = alone(a_in, 40)
    solo_b = alone(b_in, 40)
    a = Fmu(unzipdir, name="a", start=a_in)
    b = Fmu(unzipdir, name="b", start=b_in)
    rows_a, rows_b = [], []
    for _ in range(40):
        a.step(2.5e-4)
        b.step(2.5e-4)
        rows_b.append(b.get(*names))
        rows_a.append(a.get(*names))
    a.free()
    b.free()
    # Interleaved, each is exactly what it is alone, and the two differ.
    assert rows_a == solo_a
    assert rows_b == solo_b
    assert rows_a[-1][3] != rows_b[-1][3]


def test_fmu_state_saved_serialised_and_restored_repeats_the_steps_exactly(baseline):
    _, unzipdir = baseline
    f = Fmu(unzipdir, start={"crank_speed": rad_s(4000.0), "oil_temperature": 81.0})
    names = ("crank_angle", "friction_energy", "friction_torque", "drive_torque_cycle_mean")
    try:
        for _ in range(30):
            f.step(3e-4)
        state = f.slave.getFMUstate()
        blob = f.slave.serializeFMUstate(state)
        t_saved = f.t

        def run_on():
            rows = []
            f.set("crank_speed", rad_s(5000.0))
            for _ in range(25):
                f.step(4e-4)
                rows.append(f.get(*names))
            return rows

        first = run_on()
        f.slave.setFMUstate(state)
        f.t = t_saved
        assert f.get(*names)[0] < first[0][0]
        second = run_on()
        restored = f.slave.deSerializeFMUstate(blob)
        f.slave.setFMUstate(restored)
        f.t = t_saved
        third = run_on()
        assert first == second == third
        f.slave.freeFMUstate(state)
        f.slave.freeFMUstate(restored)
    finally:
        f.free()


def test_a_law_parameter_tuned_between_steps_acts_from_then_on(baseline):
    _, unzipdir = baseline
    start = {"crank_speed": rad_s(7000.0), "oil_temperature": 81.0}
    rev = 2 * math.pi / rad_s(7000.0)
    tuned = Fmu(unzipdir, start=start)
    fresh = Fmu(unzipdir, start={**start, "piston.fedem_friction.mu": 0.12})
    try:
        for f in (tuned, fresh):
            for _ in range(10):
                f.step(rev / 10)
        (one_rev,) = tuned.get("piston.friction_energy")
        tuned.set("piston.fedem_friction.mu", 0.12)
        for f in (tuned, fresh):
            for _ in range(10):
                f.step(rev / 10)
        names = ("piston.friction_power", "piston.friction_torque", "crank_angle")
        # After a whole revolution with the new coefficient the tuned instance is the one that
        # started with it (the energies differ by the first revolution's).
        assert tuned.get(*names) == fresh.get(*names)
        means = [f.get("friction_torque_cycle_mean")[0] for f in (tuned, fresh)]
        assert close(means[0], means[1], 1e-12), means
        (two_revs,) = tuned.get("piston.friction_energy")
        # The piston dissipated more in the second revolution, by about the coefficient's 1.5
        # (the side thrust answers the larger friction force a little).
        ratio = (two_revs - one_rev) / one_rev
        assert 1.4 < ratio < 1.6, ratio
    finally:
        tuned.free()
        fresh.free()


CORRUPTIONS = {
    "a law library missing": (
        lambda r: (r / "plugins" / "libtribo_law_fedem_friction.so").unlink(),
        ["libtribo_law_fedem_friction.so", "missing", "fedem-friction"],
    ),
    "a law library that is not a library": (
        lambda r: (r / "plugins" / "libtribo_law_polyline_damper.so").write_bytes(b"not an ELF file"),
        ["libtribo_law_polyline_damper.so", "not a loadable shared library"],
    ),
    "the interface garbled": (
        lambda r: (r / "interface.toml").write_text((r / "interface.toml").read_text()[:-300] + "\n[[["),
        ["interface.toml", "TOML parse error"],
    ),
    "the rig with a negative mass": (
        lambda r: (r / "model.toml").write_text(
            (r / "model.toml").read_text().replace("mass_kg = ", "mass_kg = -", 1)
        ),
        ["model.toml:", "bodies.crank.mass_kg", "must be a positive number"],
    ),
    "the worker executable missing": (
        lambda r: (r / "bin" / "tribo").unlink(),
        ["bin/tribo", "cannot be read"],
    ),
    "the worker executable truncated": (
        lambda r: (r / "bin" / "tribo").write_bytes((r / "bin" / "tribo").read_bytes()[:4096]),
        ["worker process", "ended before answering"],
    ),
}


@pytest.mark.parametrize("case", list(CORRUPTIONS))
def test_a_missing_or_corrupt_resource_is_an_error_status_and_a_logged_message(baseline, tmp_path, case):
    _, unzipdir = baseline
    damaged = tmp_path / "fmu"
    shutil.copytree(unzipdir, damaged)
    corrupt, words = CORRUPTIONS[case]
    corrupt(damaged / "resources")
    log: list[tuple[int, str]] = []
    with pytest.raises(Exception, match="Failed to instantiate"):
        Fmu(damaged, log=log)
    assert log and all(status == 3 for status, _ in log), log
    message = text(log)
    for w in words:
        assert w in message, (w, message)
    # The importer carries on: the intact FMU still runs in this process.
    ok = Fmu(unzipdir, start={"crank_speed": rad_s(3000.0)})
    ok.step(1e-3)
    assert ok.get("friction_energy")[0] > 0.0
    ok.free()


def test_a_worker_executable_without_execute_permission_still_runs(baseline, tmp_path):
    # Python's zipfile, which FMPy extracts with, drops the permission bits.
    _, unzipdir = baseline
    copy = tmp_path / "fmu"
    shutil.copytree(unzipdir, copy)
    exe = copy / "resources" / "bin" / "tribo"
    exe.chmod(0o644)
    f = Fmu(copy, start={"crank_speed": rad_s(3000.0)})
    f.step(1e-3)
    assert f.get("friction_energy")[0] > 0.0
    f.free()


HOSTILE = {
    1: ["killed by signal 11", "SIGSEGV", "fixture-hostile"],
    2: ["killed by signal 6", "SIGABRT", "fixture-hostile"],
    3: ["worker.call_timeout = 2 s", "fixture-hostile"],
    5: ["exit()", "fixture-hostile"],
    # No word from the worker: the FMU names the law call it died in (from the worker's
    # in-flight page), with its library file and joint.
    9: ["exit status 0", "died in a call of law `fixture-hostile`", "libtribo_law_fixture_hostile.so) at joint `piston`"],
    10: ["killed by signal 9", "died in a call of law `fixture-hostile`", "libtribo_law_fixture_hostile.so) at joint `piston`"],
}


@pytest.mark.parametrize("mode", list(HOSTILE))
def test_a_law_that_crashes_hangs_or_exits_is_an_fmi_error_not_the_importers_end(exported, hostile_lib, mode):
    _, unzipdir = exported(RIG, "--lawset", str(hostile_lib.parent / "hostile.toml"), plugin=hostile_lib)
    log: list[tuple[int, str]] = []
    f = Fmu(unzipdir, log=log, start={"crank_speed": rad_s(3000.0), "worker.call_timeout": 2.0})
    f.step(1e-3)
    assert f.get("piston.friction_power")[0] > 0.0
    # The law turns hostile in the middle of the run: the next step fails, with a message.
    f.set("piston.fixture_hostile.mode", float(mode))
    started = time.monotonic()
    with pytest.raises(FMICallException) as e:
        f.step(1e-3)
    assert e.value.status == 3
    assert time.monotonic() - started < 30.0
    message = text(log)
    for w in HOSTILE[mode]:
        assert w in message, (w, message)
    # The instance refuses further steps; a new one in the same process runs.
    with pytest.raises(FMICallException):
        f.step(1e-3)
    f.slave.freeInstance()
    g = Fmu(unzipdir, start={"crank_speed": rad_s(3000.0)})
    g.step(1e-3)
    assert g.get("piston.friction_power")[0] > 0.0
    g.free()


def test_a_stateful_law_carries_its_history_across_a_change_of_speed(exported, creeping_lib):
    """The creeping fixture law's viscous coefficient is c0 (1 + s), s the time it has been
    committed over. After 0.12 s at 3000 rpm (three whole 4-stroke cycles) the speed goes to
    4000 rpm; 1 ms later the crank is where a fresh run at 4000 rpm is after 1 ms (the same
    angle in the cycle, the same piston speed), so the piston's friction powers stand as
    (1 + 0.121) to (1 + 0.001): the history was carried over the change, not restarted."""
    lawset = str(creeping_lib.parent / "creeping.toml")
    _, unzipdir = exported(RIG, "--lawset", lawset, plugin=creeping_lib)
    a = Fmu(unzipdir, start={"crank_speed": rad_s(3000.0), "oil_temperature": 60.0})
    b = Fmu(unzipdir, name="fresh", start={"crank_speed": rad_s(4000.0), "oil_temperature": 60.0})
    try:
        for _ in range(120):
            a.step(1e-3)
        assert close(a.get("crank_angle")[0], 12 * math.pi, 1e-12)
        a.set("crank_speed", rad_s(4000.0))
        a.step(1e-3)
        b.step(1e-3)
        angle_a, power_a = a.get("crank_angle", "piston.friction_power")
        angle_b, power_b = b.get("crank_angle", "piston.friction_power")
        assert close(angle_a - 12 * math.pi, angle_b, 1e-9)
        # The state lags the output time by at most one step of the law (< 0.1 ms here).
        assert power_a / power_b == pytest.approx(1.121 / 1.001, rel=1e-4)
    finally:
        a.free()
        b.free()


def test_a_law_on_a_bearing_it_is_not_made_for_is_a_logged_warning_at_the_start(exported):
    """The rig's own notes, which `tribo run` prints first with every result, reach the
    importer too: the 4B11's plain-journal law on the CRF 250 R's rolling-element mains is
    logged with status fmi2Warning once, when the run starts, naming the joint and the law."""
    _, unzipdir = exported(RIG, "--lawset", "4b11-physical")
    log: list[tuple[int, str]] = []
    f = Fmu(unzipdir, log=log, start={"crank_speed": rad_s(3000.0)})
    f.step(1e-3)
    f.set("crank_speed", rad_s(4000.0))
    f.step(1e-3)
    warnings = [m for status, m in log if status == 1]
    for joint in ("main_a", "main_b"):
        note = f"joint `{joint}`: law `plain-journal` is made for plain bearings"
        notes = [m for m in warnings if note in m]
        assert len(notes) == 1, (joint, warnings)
    assert all(status == 1 for status, _ in log), log
    f.free()


def test_a_law_printing_to_standard_output_cannot_garble_the_fmu_s_channel(exported, hostile_lib):
    _, unzipdir = exported(RIG, "--lawset", str(hostile_lib.parent / "hostile.toml"), plugin=hostile_lib)
    quiet = Fmu(unzipdir, start={"crank_speed": rad_s(5000.0)})
    loud = Fmu(unzipdir, start={"crank_speed": rad_s(5000.0), "piston.fixture_hostile.mode": 6.0})
    for f in (quiet, loud):
        for _ in range(20):
            f.step(5e-4)
    assert quiet.get("friction_energy", "crank_angle") == loud.get("friction_energy", "crank_angle")
    quiet.free()
    loud.free()


def test_a_parameter_or_input_out_of_range_is_an_error_naming_it(baseline):
    _, unzipdir = baseline
    log: list[tuple[int, str]] = []
    f = Fmu(unzipdir, log=log, start={"crank_speed": rad_s(3000.0)})
    f.step(1e-3)
    # fedem-friction declares mu in [0, 10].
    f.set("piston.fedem_friction.mu", 42.0)
    with pytest.raises(FMICallException):
        f.step(1e-3)
    for w in ["mu", "42", "10"]:
        assert w in text(log), (w, text(log))
    f.slave.freeInstance()
    log.clear()
    g = Fmu(unzipdir, log=log, start={"crank_speed": rad_s(3000.0)})
    g.set("crank_speed", -5.0)
    with pytest.raises(FMICallException):
        g.step(1e-3)
    assert "crank_speed" in text(log) and "-5" in text(log), text(log)
    g.slave.freeInstance()


IMPORTER_WITHOUT_SIGPIPE_GUARD = r"""
import os, signal, sys, math
sys.path.insert(0, sys.argv[2])
from conftest import Fmu
from fmpy.fmi1 import FMICallException

# A C importer does not ignore SIGPIPE as Python does: writing to a dead pipe would end it.
signal.signal(signal.SIGPIPE, signal.SIG_DFL)
f = Fmu(sys.argv[1], start={"crank_speed": 3000 * math.pi / 30})
f.step(1e-3)
children = set()
for tid in os.listdir(f"/proc/{os.getpid()}/task"):
    with open(f"/proc/{os.getpid()}/task/{tid}/children") as c:
        children.update(int(p) for p in c.read().split())
assert len(children) == 1, children
# The worker dies between two calls (killed from outside: the OOM killer, a user).
os.kill(children.pop(), signal.SIGKILL)
try:
    f.step(1e-3)
    print("the step succeeded")
except FMICallException as e:
    print("error status", e.status)
print("the importer is alive")
print("\n".join(m for _, m in f.log))
"""


def test_a_worker_killed_between_steps_is_an_error_not_a_sigpipe_for_the_importer(baseline, tmp_path):
    import subprocess
    import sys

    _, unzipdir = baseline
    script = tmp_path / "importer.py"
    script.write_text(IMPORTER_WITHOUT_SIGPIPE_GUARD)
    proc = subprocess.run(
        [sys.executable, str(script), str(unzipdir), str(Path(__file__).parent)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, (proc.returncode, proc.stdout, proc.stderr)
    assert "error status 3" in proc.stdout and "the importer is alive" in proc.stdout, proc.stdout
    assert "killed by signal 9" in proc.stdout + proc.stderr, proc.stdout
