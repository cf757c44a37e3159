"""The FMU's dynamics, imported by FMPy: the torque-input FMU (`tribo fmu export --input
drive-torque`) against the same run from the command line (`tribo run --drive-torque`, no FMU,
no worker, no FMPy, its communication points ten times coarser), the energy balance of a
coast-down, and the FMU state through its byte serialisation."""

from __future__ import annotations

import math

import fmpy
import pytest
from fmpy.fmi1 import FMICallException
from fmpy.validation import validate_fmu

from conftest import Fmu, run_json

RIG = "crf250r-motored"
LAWSET = "fedem-baseline"
START_RPM = 3000.0
DURATION_S = 0.2
CLI_EVERY_S = 0.02
FMU_STEP_S = 0.002
OUT = ("crank_speed", "crank_angle", "friction_energy", "friction_torque", "drive_torque_cycle_mean")


def rad_s(rpm: float) -> float:
    return rpm * math.pi / 30.0


@pytest.fixture(scope="module")
def torque_fmu(exported):
    return exported(RIG, "--lawset", LAWSET, "--input", "drive-torque")


@pytest.fixture(scope="module")
def coast_cli(tribo_bin):
    """`tribo run --drive-torque 0` from 3000 rpm: a sample every 20 ms."""
    return run_json(
        tribo_bin, "run", RIG, "--lawset", LAWSET, "--drive-torque", "0",
        "--start-rpm", str(START_RPM), "--duration", str(DURATION_S), "--every", str(CLI_EVERY_S),
    )["samples"]


def test_fmpy_validates_the_torque_fmu_whose_input_is_drive_torque_and_output_crank_speed(torque_fmu):
    fmu, _ = torque_fmu
    assert validate_fmu(str(fmu)) == []
    v = {x.name: x for x in fmpy.read_model_description(str(fmu), validate=True).modelVariables}
    assert (v["drive_torque"].causality, v["drive_torque"].unit) == ("input", "N.m")
    assert (v["crank_speed"].causality, v["crank_speed"].unit) == ("output", "rad/s")
    assert (v["crank_speed_start"].causality, v["crank_speed_start"].variability) == ("parameter", "fixed")
    assert v["crank_speed_start"].unit == "rad/s"


def test_with_zero_drive_torque_from_3000_rpm_the_crank_slows_as_tribo_run_says(torque_fmu, coast_cli):
    _, unzipdir = torque_fmu
    f = Fmu(unzipdir, start={"crank_speed_start": rad_s(START_RPM), "drive_torque": 0.0})
    try:
        rows = [f.get(*OUT)]
        per_sample = round(CLI_EVERY_S / FMU_STEP_S)
        for k in range(round(DURATION_S / FMU_STEP_S)):
            f.step(FMU_STEP_S)
            if (k + 1) % per_sample == 0:
                rows.append(f.get(*OUT))
    finally:
        f.free()
    assert len(rows) == len(coast_cli) == 11
    for row, cli in zip(rows, coast_cli):
        speed, angle, energy = row[0], row[1], row[2]
        assert speed == pytest.approx(cli["crank_speed_rad_s"], rel=1e-6, abs=0.0), cli["time_s"]
        assert angle == pytest.approx(cli["crank_angle_rad"], rel=1e-6, abs=1e-12), cli["time_s"]
        # The friction energy is the integral of a power with kinks (friction reversals): its
        # error at the 1-degree step is a few 1e-6, and the FMU's communication points (ten
        # times finer) cut the steps elsewhere than the command line's, so 1e-5.
        assert energy == pytest.approx(cli["friction_energy_j"], rel=1e-5, abs=1e-12), cli["time_s"]
        # No drive torque, no drive work (to rounding: the torque is the reactions' balance).
        assert abs(cli["drive_work_j"]) < 1e-9
    # It slows under friction: every cycle (4 pi, about 42 ms at 3000 rpm) ends slower than the
    # one before at the same phase, and the friction has dissipated energy throughout.
    speeds = [r[0] for r in rows]
    assert speeds[0] == rad_s(START_RPM)
    assert speeds[-1] < 0.95 * speeds[0]
    energies = [r[2] for r in rows]
    assert all(b > a for a, b in zip(energies, energies[1:]))


def test_the_coast_down_s_energy_balance_closes(torque_fmu, tribo_bin):
    """Over whole revolutions at the same crank angle the mechanism's kinetic energy differs only
    by the crank speed (its inertia repeats with the angle) and the gas spring returns its work:
    from one top dead centre to a later one, the friction energy dissipated equals the crank's
    loss of kinetic energy at a constant reduced inertia, which two such intervals determine.
    Here: the drop in speed squared per joule dissipated is the same over the first and the
    second such interval (within 1e-3), as a constant inertia requires."""
    _, unzipdir = torque_fmu
    f = Fmu(unzipdir, start={"crank_speed_start": rad_s(START_RPM), "drive_torque": 0.0})
    cycle = 4 * math.pi
    marks = []
    try:
        prev = f.get("crank_angle", "crank_speed", "friction_energy")
        marks.append(prev)
        h = 2e-5
        while len(marks) < 3:
            f.step(h)
            now = f.get("crank_angle", "crank_speed", "friction_energy")
            k = len(marks)
            if now[0] >= k * cycle:
                # Linear between the two communication points to the cycle's end.
                w = (k * cycle - prev[0]) / (now[0] - prev[0])
                marks.append([p + w * (n - p) for p, n in zip(prev, now)])
            prev = now
    finally:
        f.free()
    ratios = []
    for a, b in zip(marks, marks[1:]):
        ratios.append((a[1] ** 2 - b[1] ** 2) / (b[2] - a[2]))
    assert ratios[0] > 0
    assert ratios[1] == pytest.approx(ratios[0], rel=1e-3)


def test_a_serialised_state_restored_continues_bit_for_bit(torque_fmu):
    _, unzipdir = torque_fmu
    start = {"crank_speed_start": rad_s(START_RPM), "drive_torque": 0.0}
    f = Fmu(unzipdir, start=start)
    g = Fmu(unzipdir, name="second", start=start)
    try:
        for _ in range(25):
            f.step(FMU_STEP_S)
        state = f.slave.getFMUstate()
        blob = f.slave.serializeFMUstate(state)
        t_saved = f.t

        def run_on(x):
            rows = []
            for k in range(20):
                x.set("drive_torque", 2.0 if k < 10 else -1.0)
                x.step(FMU_STEP_S)
                rows.append(x.get(*OUT))
            return rows

        first = run_on(f)
        # The same instance, back to the state, and the same way again.
        f.slave.setFMUstate(state)
        f.t = t_saved
        second = run_on(f)
        # Another instance, from the bytes.
        restored = g.slave.deSerializeFMUstate(blob)
        g.slave.setFMUstate(restored)
        g.t = t_saved
        third = run_on(g)
        assert first == second == third
        # The torque did act: the crank sped up, then slowed.
        assert first[9][0] > first[0][0] and first[-1][0] < first[9][0]
        f.slave.freeFMUstate(state)
        g.slave.freeFMUstate(restored)
    finally:
        f.free()
        g.free()


def test_bytes_that_are_not_a_state_are_an_error_and_the_fmu_steps_on(torque_fmu, exported):
    _, unzipdir = torque_fmu
    f = Fmu(unzipdir, start={"crank_speed_start": rad_s(START_RPM), "drive_torque": 0.0})
    try:
        f.step(FMU_STEP_S)
        blob = bytes(f.slave.serializeFMUstate(f.slave.getFMUstate()))
        before = f.get(*OUT)
        bad = [b"", b"garbage", blob[:10], blob[:-7], b"TRIBOFMU" + (99).to_bytes(4, "little") + blob[12:]]
        # The worker's own record damaged inside an intact outer one: its magic bytes.
        at = blob.find(b"TRIBORUN")
        assert at > 0
        bad.append(blob[:at] + b"X" + blob[at + 1:])
        for b in bad:
            with pytest.raises(FMICallException):
                s = f.slave.deSerializeFMUstate(b)
                f.slave.setFMUstate(s)
        assert f.get(*OUT) == before
        f.step(FMU_STEP_S)
        assert f.get("crank_angle")[0] > before[1]
    finally:
        f.free()
    # A state of the speed-input FMU is not one of the torque-input FMU.
    _, speed_dir = exported(RIG, "--lawset", LAWSET)
    s = Fmu(speed_dir, start={"crank_speed": rad_s(START_RPM)})
    t = Fmu(unzipdir, name="torque", start={"crank_speed_start": rad_s(START_RPM)})
    try:
        s.step(FMU_STEP_S)
        blob = s.slave.serializeFMUstate(s.slave.getFMUstate())
        with pytest.raises(FMICallException):
            t.slave.setFMUstate(t.slave.deSerializeFMUstate(blob))
    finally:
        s.free()
        t.free()
