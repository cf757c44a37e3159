"""tribo.study: designs, and a 16-point sweep on a Dask LocalCluster of 2 worker processes
equal to the serial run."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

import tribo
from tribo import study


def design16() -> pd.DataFrame:
    return study.full_factorial(
        {"rig:bodies.rod.mass_scale": [0.6, 0.8, 1.0, 1.2], "oil_temp_c": [40.0, 60.0, 80.0, 100.0]}
    )


def test_full_factorial_and_latin_hypercube_cover_their_ranges():
    d = design16()
    assert len(d) == 16 and len(d.drop_duplicates()) == 16
    lhs = study.latin_hypercube({"a": (0.0, 1.0), "b": (10.0, 20.0)}, n=8, seed=3)
    # One point in each of the 8 strata of every factor.
    assert sorted(np.floor(lhs["a"] * 8).astype(int)) == list(range(8))
    assert sorted(np.floor((lhs["b"] - 10.0) / 10.0 * 8).astype(int)) == list(range(8))
    assert lhs.equals(study.latin_hypercube({"a": (0.0, 1.0), "b": (10.0, 20.0)}, n=8, seed=3))


def test_a_point_equals_the_cli_sweep_of_that_rig_and_temperature(cli):
    serial = study.run_design(design16().iloc[[5]], speeds=[3000, 6000, 9000])
    want = cli(
        "sweep", "--lawset", "stribeck-duty", "--temps", "60", "--speeds", "3000,6000,9000",
        "--set", "bodies.rod.mass_scale=0.8", "--json", "--in-process", "--out", "sw",
    )
    assert list(serial["torque_nm"]) == [p["torque_nm"] for p in want["sets"][0]["points"]]
    assert (serial["rig:bodies.rod.mass_scale"] == 0.8).all() and (serial["oil_temp_c"] == 60.0).all()


def test_law_factors_move_the_torque_the_way_the_law_does():
    ls = tribo.LawSet("stribeck-duty")
    free = ls.free_params()
    p = free[free["param"] == "mu_b"].iloc[0]
    d = study.full_factorial({f"law:{p['id']}": [float(p["lower"]), float(p["upper"])]})
    out = study.run_design(d, lawset=ls, speeds=[3000, 9000])
    lo = out[out["point"] == 0]["torque_nm"].to_numpy()
    hi = out[out["point"] == 1]["torque_nm"].to_numpy()
    assert len(lo) == len(hi) == 2
    # The boundary coefficient at its upper bound: more friction wherever the piston touches.
    assert np.all(hi > lo), (lo, hi)


def test_a_bad_factor_fails_before_anything_runs():
    with pytest.raises(tribo.InputError, match="design column `mass`"):
        study.run_design(pd.DataFrame({"mass": [1.0]}))
    with pytest.raises(tribo.InputError, match="no law"):
        study.run_design(pd.DataFrame({"law:piston.coulomb.mu": [0.1]}), dask=True)


def test_a_16_point_sweep_on_a_local_cluster_of_2_processes_equals_the_serial_run():
    # Imported, not skipped when missing: the Python half of the test command installs
    # dask[distributed], and a silent skip would leave the only Dask test unrun.
    import dask.distributed  # noqa: F401
    d = design16()
    serial = study.run_design(d)
    distributed = study.run_design(d, dask=True, n_workers=2)
    assert len(serial) == 16 * len(tribo.DEFAULT_SPEEDS_RPM)
    pd.testing.assert_frame_equal(serial, distributed, check_exact=True)
    # Physics, not print: at the highest speed, cold oil (40 C, several times the viscosity)
    # needs more torque than warm oil (80 C) for the same rod.
    top = serial[(serial["speed_rpm"] == 9000.0) & (serial["rig:bodies.rod.mass_scale"] == 1.0)]
    by_temp = top.set_index("oil_temp_c")["torque_nm"]
    assert by_temp[40.0] > by_temp[80.0]
    assert len(set(distributed["point"])) == 16
