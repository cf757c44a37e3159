"""The test bed's drivetrain against an independent multibody code: Exudyn (PyPI, installed by
python/build-and-test.sh) runs the rig's slider-crank on the chain `tribo modes` reflects to
crank speed (tests/peers/exudyn_testbed.py); Tribo's steady drivetrain must agree with it
within 1% at three plateaus.

The chain's two rubbery elements are damped at the top of their stated ranges (belt 0.05, socket
on the taped bolt 0.2 N m s/rad; rigs/crf250r-testbed.toml) in both codes, so that Exudyn's plain
time integration settles in seconds; the friction is the Coulomb part of the FEDEM baseline
(tests/peers/fedem-coulomb.toml), the friction Exudyn models. Both codes get the same numbers:
the script reads them from the rig, the law set and `tribo modes --json`, and passes its
damping to every Tribo command it runs."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "tests" / "peers" / "exudyn_testbed.py"
DAMPING = {"belt": 0.05, "socket on taped bolt": 0.2}  # the top of each stated range
PLATEAUS_RPM = (3000.0, 6000.0, 9000.0)
TOLERANCE = 0.01


@pytest.fixture(scope="module")
def comparison(tribo_bin):
    args = [sys.executable, str(SCRIPT), "--tribo", str(tribo_bin), "--rpm", *map(str, PLATEAUS_RPM)]
    for name, value in DAMPING.items():
        args += ["--damping", f"{name}={value}"]
    proc = subprocess.run(args, capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr[-4000:]
    return json.loads(proc.stdout)


def test_the_friction_is_the_same_on_the_rigid_crank(comparison):
    """Before the chain: the rigid crank's mean motoring torque, Exudyn's Coulomb on its joint
    reactions against Tribo's fedem-friction laws (the comparison rests on this)."""
    for p in comparison["plateaus"]:
        rel = p["relative_difference"]["rigid_mean_torque_nm"]
        assert abs(rel) < 2e-3, (p["rpm"], p["exudyn"]["rigid_mean_torque_nm"], p["tribo"]["rigid_mean_torque_nm"])


def test_exudyn_settled_far_below_the_tolerance(comparison):
    """Exudyn integrates from a constant speed: its last cycle must have stopped moving, each
    figure changing by far less than the tolerance over the last half second."""
    for p in comparison["plateaus"]:
        assert p["exudyn"]["drift_gap_s"] >= 0.4
        for name, drift in p["exudyn"]["drift"].items():
            assert drift < TOLERANCE / 20, (p["rpm"], name, drift)


@pytest.mark.parametrize(
    "figure", ["transducer_mean_torque_nm", "transducer_peak_to_peak_nm", "crank_speed_fluctuation"]
)
def test_the_transducer_and_the_crank_speed_agree_with_exudyn_within_one_percent(comparison, figure):
    got = [(p["rpm"], p["tribo"][figure], p["exudyn"][figure]) for p in comparison["plateaus"]]
    assert [rpm for rpm, *_ in got] == list(PLATEAUS_RPM)
    for rpm, tribo, exudyn in got:
        assert abs(tribo - exudyn) <= TOLERANCE * abs(exudyn), (rpm, figure, tribo, exudyn)
