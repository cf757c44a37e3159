"""The FMU of a rig with a drivetrain (`crf250r-testbed`): the transducer's figures over the
periodic cycle at the current inputs and the chain's natural frequencies, read through FMPy,
against the command line (`tribo run --steady --json`'s `instrument`, `tribo modes --json`),
which computes them without the FMU, its worker or FMPy."""

from __future__ import annotations

import math

import fmpy
import pytest
from fmpy.validation import validate_fmu

from conftest import Fmu, run_json, text

RIG = "crf250r-testbed"
LAWSET = "fedem-baseline"
REL = 1e-9
FIGURES = {
    "transducer.mean_torque": "mean_torque_nm",
    "transducer.min_torque": "min_torque_nm",
    "transducer.max_torque": "max_torque_nm",
    "transducer.peak_to_peak": "peak_to_peak_nm",
    "transducer.acquired_mean_torque": "acquired_mean_torque_nm",
    "transducer.acquired_peak_to_peak": "acquired_peak_to_peak_nm",
    "crank_speed_fluctuation": "crank_speed_fluctuation",
}


@pytest.fixture(scope="module")
def testbed(exported):
    return exported(RIG, "--lawset", LAWSET)


def test_the_testbed_fmu_declares_the_transducer_outputs_and_the_modes_of_tribo_modes(testbed, tribo_bin):
    fmu, _ = testbed
    assert validate_fmu(str(fmu)) == []
    v = {x.name: x for x in fmpy.read_model_description(str(fmu), validate=True).modelVariables}
    for name in FIGURES:
        assert (v[name].causality, v[name].variability) == ("output", "continuous"), name
    assert v["transducer.peak_to_peak"].unit == "N.m"
    assert v["crank_speed_fluctuation"].unit == "1"
    modes = run_json(tribo_bin, "modes", RIG)["modes"]
    declared = sorted((n for n in v if n.startswith("drivetrain.mode_")), key=lambda n: int(n.split("_")[1].split(".")[0]))
    assert declared == [f"drivetrain.mode_{k + 1}.frequency" for k in range(len(modes))]
    for name, mode in zip(declared, modes):
        assert (v[name].causality, v[name].variability, v[name].unit) == ("output", "constant", "Hz")
        assert float(v[name].start) == pytest.approx(mode["frequency_hz"], rel=1e-15)


def test_a_rig_without_a_drivetrain_has_no_transducer_outputs(exported):
    fmu, _ = exported("crf250r-motored", "--lawset", LAWSET)
    names = {x.name for x in fmpy.read_model_description(str(fmu)).modelVariables}
    assert not {n for n in names if n.startswith(("transducer.", "drivetrain.", "crank_speed_fluct"))}


def test_every_plateau_gives_the_transducer_figures_of_run_steady(testbed, tribo_bin):
    """One instance through the seven thesis plateaus at each one's oil temperature: the
    transducer's figures equal `tribo run --steady`'s, the modes are served as declared, and
    where the run warns that the transducer left its rating the FMU logs it too."""
    _, unzipdir = testbed
    run = run_json(tribo_bin, "run", RIG, "--lawset", LAWSET, "--steady")
    modes = run_json(tribo_bin, "modes", RIG)["modes"]
    plateaus = run["plateaus"]
    first = plateaus[0]
    f = Fmu(unzipdir, start={"crank_speed": first["set_speed_rpm"] * math.pi / 30.0, "oil_temperature": first["oil_temp_c"]})
    try:
        assert f.get("drivetrain.mode_1.frequency")[0] == pytest.approx(modes[0]["frequency_hz"], rel=1e-15)
        for p in plateaus:
            f.set("crank_speed", p["set_speed_rpm"] * math.pi / 30.0)
            f.set("oil_temperature", p["oil_temp_c"])
            f.step(0.01)
            got = dict(zip(FIGURES, f.get(*FIGURES)))
            for name, key in FIGURES.items():
                want = p["instrument"][key]
                assert abs(got[name] - want) <= REL * abs(want), (p["set_speed_rpm"], name, got[name], want)
    finally:
        f.free()
    logged = text(f.log)
    for warning in run["warnings"]:
        if "outside its rating" in warning:
            rpm = warning.split(" rpm")[0]
            assert f"{rpm} rpm: the transducer" in logged, (warning, logged)
