"""Every CLI study through Python gives the numbers of `tribo ... --json --in-process`, bit
for bit: the whole JSON document (`raw`) and the DataFrames built from it."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

import tribo


def same(a, b, where: str = "$") -> None:
    """Exact equality of two JSON documents: the same types (an ``int`` is not a ``float``), the
    same keys in the same order, every float the same bits (NaN never appears: serde_json writes
    null). ``==`` alone would take 1 for 1.0 and ignore key order, which the native module's
    direct conversion (no JSON text in between) must get right as ``json.loads`` does."""
    assert type(a) is type(b), f"{where}: {type(a).__name__} {a!r} against {type(b).__name__} {b!r}"
    if isinstance(a, dict):
        assert list(a) == list(b), f"{where}: keys {list(a)} against {list(b)}"
        for k in a:
            same(a[k], b[k], f"{where}.{k}")
    elif isinstance(a, list):
        assert len(a) == len(b), f"{where}: {len(a)} items against {len(b)}"
        for i, (x, y) in enumerate(zip(a, b)):
            same(x, y, f"{where}[{i}]")
    elif isinstance(a, float):
        assert a.hex() == b.hex(), f"{where}: {a!r} against {b!r}"
    else:
        assert a == b, f"{where}: {a!r} against {b!r}"


def test_run_steady_matches_cli_and_dataframes_hold_its_numbers(cli):
    want = cli("run", "crf250r-motored", "--lawset", "stribeck-duty", "--steady", "--json")
    got = tribo.run("crf250r-motored", lawset="stribeck-duty", steady=True)
    same(got.raw, want)
    p = got.plateaus
    assert list(p["set_speed_rpm"]) == [q["set_speed_rpm"] for q in want["plateaus"]]
    assert list(p["motoring_torque_nm"]) == [q["motoring_torque_nm"] for q in want["plateaus"]]
    j = got.joints
    flat = [(q["set_speed_rpm"], l["joint"], l["friction_torque_nm"]) for q in want["plateaus"] for l in q["joints"]]
    assert len(j) == len(flat)
    assert list(zip(j["set_speed_rpm"], j["joint"], j["friction_torque_nm"])) == flat
    # The laws' torques at the crank add up to less than the motoring torque (the rest is
    # the drive's inertia work over whole revolutions, zero in steady state): physics, not print.
    for q in want["plateaus"]:
        assert math.isclose(
            sum(l["friction_torque_nm"] for l in q["joints"]), q["motoring_torque_nm"], rel_tol=1e-3
        )


def test_run_cycle_with_sets_laws_and_timeseries_matches_cli(cli, tmp_path):
    args = ["run", "crf250r-motored", "--set", "bodies.rod.mass_scale=0.6", "--law", "piston=coulomb", "--json"]
    want = cli(*args)
    got = tribo.run(
        tribo.Rig("crf250r-motored").set({"bodies.rod.mass_scale": 0.6}),
        laws=["piston=coulomb"],
        timeseries=True,
    )
    same(got.raw, want)
    ts = got.timeseries
    assert ts is not None and len(ts["time_s"]) == want["steps"]
    assert np.all(np.diff(ts["time_s"]) > 0)
    # The series against the CLI's --timeseries CSV (same steps, same values).
    csv = tmp_path / "ts.csv"
    cli(*args[:-1], "--timeseries", str(csv), "--json")
    df = pd.read_csv(csv, comment="#")
    assert len(df) == len(ts["time_s"])
    assert list(df.columns) == list(ts)
    # The CSV holds 4 to 7 decimals; the arrays hold every bit.
    for name in df.columns:
        np.testing.assert_allclose(df[name].to_numpy(), ts[name], rtol=0, atol=6e-4, err_msg=name)


@pytest.mark.parametrize("steady", [True, False])
def test_compare_matches_cli(cli, steady):
    flags = ["--steady"] if steady else []
    want = cli("compare", *flags, "--json", "--in-process", "--out", "cmp")
    got = tribo.compare(steady=steady)
    same(got.raw, want)
    # The table the CLI prints: the model torque of each set at each measured speed.
    for s in want["sets"]:
        assert list(got.table[s["lawset"]]) == [p["motoring_torque_nm"] for p in s["run"]["plateaus"]]
        row = got.sets.set_index("lawset").loc[s["lawset"]]
        assert row["rank"] == s["rank"] and row["rmse_nm"] == s["rmse_nm"]
        cv = s["scores"]["cv_rmse_nm"]
        # A set with no out-of-sample figure (null in JSON) is a missing value in the frame.
        assert pd.isna(row["cv_rmse_nm"]) if cv is None else row["cv_rmse_nm"] == cv
    assert list(got.table["measured_nm"]) == [r["torque_nm"] for r in want["data"]]
    # The errors are model minus measurement.
    for s in want["sets"]:
        np.testing.assert_allclose(got.errors[s["lawset"]], got.table[s["lawset"]] - got.table["measured_nm"], atol=1e-12)


def test_compare_with_lawsets_validate_and_no_cv_matches_cli(cli, tmp_path):
    other = tmp_path / "other-run.csv"
    other.write_text("speed_rpm,torque_nm,oil_temp_c\n3000,0.71,85\n6000,1.12,86\n9000,1.90,88\n")
    want = cli(
        "compare", "--steady", "--no-cv", "--lawset", "fedem-baseline", "--lawset", "physical-bearings",
        "--validate", str(other), "--json", "--in-process", "--out", "cmp",
    )
    assert want["sets"][0]["validation"], "the validation data were scored"
    got = tribo.compare(
        lawsets=[tribo.LawSet("fedem-baseline"), "physical-bearings"],
        validate=other,
        steady=True,
        no_cv=True,
    )
    same(got.raw, want)
    assert list(got.sets["lawset"]) == ["fedem-baseline", "physical-bearings"]


@pytest.mark.parametrize(
    "cli_args, kwargs",
    [
        (["--steady"], {"steady": True}),
        (["--steady", "--scales", "0.5,0.8,1.1", "--body", "piston"], {"steady": True, "scales": [0.5, 0.8, 1.1], "body": "piston"}),
        ([], {}),
    ],
)
def test_mass_response_matches_cli(cli, cli_args, kwargs):
    want = cli("mass-response", *cli_args, "--json", "--in-process", "--out", "mr")
    got = tribo.mass_response(**kwargs)
    same(got.raw, want)
    rows = [(m["lawset"], c["scale"], c["speed_rpm"], c["change_nm"]) for m in want for c in m["changes"]]
    t = got.table
    assert len(t) == len(rows)
    assert list(zip(t["lawset"], t["scale"], t["speed_rpm"], t["change_nm"])) == rows
    # change = scaled - original, as the CLI defines it.
    np.testing.assert_allclose(t["change_nm"], t["scaled_nm"] - t["original_nm"], atol=1e-12)


def test_fit_matches_cli_and_writes_the_same_lawset(cli, tmp_path):
    out = tmp_path / "fitted.toml"
    want = cli("fit", "--lawset", "stribeck-duty", "--starts", "2", "--json", "--in-process", "--out", str(out))
    got = tribo.fit(lawset="stribeck-duty", starts=2)
    same(got.raw, want)
    assert got.lawset_toml == out.read_text()
    assert list(got.params["value"]) == want["values"]
    assert list(got.points["residual_nm"]) == want["residuals_nm"]
    # The calibrated law set runs and reproduces the fitted model torque at the data's speeds.
    assert got.lawset.name == "stribeck-duty"


def test_fit_with_params_and_data_matches_cli(cli, tmp_path):
    want = cli(
        "fit", "--lawset", "mixed-film", "--no-cv", "--data", "crf250r-measured.csv",
        "--json", "--in-process", "--out", str(tmp_path / "f.toml"),
    )
    got = tribo.fit(lawset="mixed-film", no_cv=True, data=["crf250r-measured.csv"])
    same(got.raw, want)


@pytest.mark.parametrize(
    "cli_args, kwargs",
    [
        ([], {}),
        (
            ["--lawset", "mixed-film", "--temps", "40,100", "--speeds", "3000,9000", "--set", "bodies.rod.mass_scale=0.8"],
            {"lawsets": "mixed-film", "temps": [40, 100], "speeds": [3000, 9000], "set": {"bodies.rod.mass_scale": 0.8}},
        ),
    ],
)
def test_sweep_matches_cli(cli, cli_args, kwargs):
    want = cli("sweep", *cli_args, "--json", "--in-process", "--out", "sw")
    got = tribo.sweep(**kwargs)
    same(got.raw, want)
    t = got.table
    pts = [(s["lawset"], p["oil_temp_c"], p["speed_rpm"], p["torque_nm"]) for s in want["sets"] for p in s["points"]]
    assert len(t) == len(pts)
    assert list(zip(t["lawset"], t["oil_temp_c"], t["speed_rpm"], t["torque_nm"])) == pts
    for joint in tribo.JOINTS:
        assert f"{joint}_nm" in t.columns


def test_rig_and_lawset_from_dicts_run_like_their_files(cli, tmp_path):
    rig = tribo.Rig.from_dict({"extends": "crf250r-motored.toml", "bodies": {"rod": {"mass_scale": 0.7}}}, name="light.toml")
    ls = tribo.LawSet("stribeck-duty")
    ls2 = tribo.LawSet.from_dict(ls.file, name="copy.toml")
    a = tribo.run(rig, lawset=ls2, steady=True)
    b = cli("run", "crf250r-motored", "--set", "bodies.rod.mass_scale=0.7", "--lawset", "stribeck-duty", "--steady", "--json")
    assert a.plateaus["motoring_torque_nm"].tolist() == [p["motoring_torque_nm"] for p in b["plateaus"]]
    # A law parameter set from Python changes the torque the way the law says: a larger
    # hydrodynamic scale on the piston gives more torque at every speed.
    mu = ls.file["laws"]
    piston = [e for e in mu if e["joint"] == "piston"][0]
    params = tribo.LawSet("stribeck-duty").free_params()
    c = params[params["param"] == "c"]
    assert len(c) == 1, params
    pid = c["id"].iloc[0]
    bigger = ls.set_params({pid: float(c["upper"].iloc[0])})
    smaller = ls.set_params({pid: float(c["lower"].iloc[0])})
    hi = tribo.run(lawset=bigger, steady=True).plateaus["motoring_torque_nm"]
    lo = tribo.run(lawset=smaller, steady=True).plateaus["motoring_torque_nm"]
    assert len(hi) == len(lo) == 7
    # The piston runs in full film over nearly every revolution under this law
    # (docs/crf250r-study.md): its friction is c sqrt(eta U W L), so a larger c is more
    # torque, never less.
    assert (hi > lo).all(), (list(hi), list(lo))
    assert piston["law"]


def test_an_engine_runs_from_python_like_the_cli(cli, tmp_path):
    # A multi-cylinder engine through the same call: the transient cycle with its time series
    # (one normal-load column per joint of the engine) and the steady state, as the CLI's.
    args = ["run", "vtwin-90-frictionless", "--law", "piston=coulomb", "--json"]
    want = cli(*args)
    got = tribo.run("vtwin-90-frictionless", laws=["piston=coulomb"], timeseries=True)
    same(got.raw, want)
    ts = got.timeseries
    assert ts is not None and len(ts["time_s"]) == want["steps"]
    loads = [n for n in ts if n.endswith("_normal_load_n")]
    assert loads == [
        "main_1_normal_load_n",
        "main_2_normal_load_n",
        "big_end_1_normal_load_n",
        "small_end_1_normal_load_n",
        "piston_1_normal_load_n",
        "big_end_2_normal_load_n",
        "small_end_2_normal_load_n",
        "piston_2_normal_load_n",
    ]
    csv = tmp_path / "ts.csv"
    cli(*args[:-1], "--timeseries", str(csv), "--json")
    assert list(pd.read_csv(csv, comment="#").columns) == list(ts)
    steady = cli(*args, "--steady")
    same(tribo.run("vtwin-90-frictionless", laws=["piston=coulomb"], steady=True).raw, steady)
    # Both pistons carry the law, and the plateau friction is the motoring torque (steady).
    names = {l["joint"] for l in steady["plateaus"][0]["joints"]}
    assert names == {"piston_1", "piston_2"}
    for q in steady["plateaus"]:
        assert math.isclose(
            sum(l["friction_torque_nm"] for l in q["joints"]), q["motoring_torque_nm"], rel_tol=1e-6
        )


def test_modes_and_the_transducer_match_cli(cli):
    want = cli("modes", "crf250r-testbed", "--json")
    same(tribo.modes("crf250r-testbed"), want)
    run = cli("run", "crf250r-testbed", "--lawset", "fedem-baseline", "--steady", "--json")
    got = tribo.run("crf250r-testbed", lawset="fedem-baseline", steady=True)
    same(got.raw, run)
    assert all("instrument" in p for p in got.raw["plateaus"])
    with pytest.raises(tribo.InputError, match="no \\[drivetrain\\]"):
        tribo.modes("crf250r-motored")
