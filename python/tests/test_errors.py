"""Each kind of bad input raises a tribo exception carrying the CLI's message, word for word."""

from __future__ import annotations

import pytest

import tribo


def cli_error(stderr: str) -> str:
    """The message of the CLI's one `error:` line."""
    lines = [l for l in stderr.splitlines() if l.startswith("error: ")]
    assert len(lines) == 1, stderr
    return lines[0][len("error: "):]


def test_a_missing_rig_raises_input_error_with_the_cli_message(cli, tmp_path):
    missing = str(tmp_path / "no-such-rig.toml")
    want = cli_error(cli("run", missing, "--steady", "--json", fail=True))
    with pytest.raises(tribo.InputError) as e:
        tribo.Rig(missing)
    assert str(e.value) == want
    with pytest.raises(tribo.InputError) as e:
        tribo.run(missing, steady=True)
    assert str(e.value) == want
    assert "no bundled rig has that name" in want


def test_a_bad_rig_value_names_set_and_field(cli):
    want = cli_error(cli("run", "crf250r-motored", "--set", "geometry.bore_m=-1", "--json", fail=True))
    with pytest.raises(tribo.InputError) as e:
        tribo.Rig("crf250r-motored").set({"geometry.bore_m": -1})
    # The CLI's message word for word, located where a Python user gave the value (issue 27
    # point 8: `set=`, the keyword, where the CLI says `--set`, its flag).
    assert want == "--set: geometry.bore_m: must be a positive number (m), got -1"
    assert str(e.value) == "set=" + want[len("--set"):]


def test_a_rig_file_with_an_unknown_key_gives_file_line_column(cli, tmp_path):
    rig = tmp_path / "rig.toml"
    rig.write_text('extends = "crf250r-motored.toml"\n[bodies.rod]\nmas_kg = 0.3\n')
    want = cli_error(cli("run", str(rig), "--json", fail=True))
    with pytest.raises(tribo.InputError) as e:
        tribo.Rig(rig)
    assert str(e.value) == want
    assert str(rig) in want and "mas_kg" in want


def test_a_bad_law_parameter_raises_input_error_with_the_cli_message(cli, tmp_path):
    params = tmp_path / "bad.toml"
    params.write_text("mu = -3.0\n")
    arg = f"piston=coulomb:{params}"
    want = cli_error(cli("run", "crf250r-motored", "--law", arg, "--steady", "--json", fail=True))
    with pytest.raises(tribo.InputError) as e:
        tribo.run("crf250r-motored", laws=[arg], steady=True)
    assert str(e.value) == want
    assert "mu" in want and str(params) in want


def test_a_bad_parameter_in_a_lawset_dict_fails_its_compare_before_any_run(cli):
    ls = tribo.LawSet("stribeck-duty").file
    ls["name"] = "broken-set"
    ls["laws"][0]["params"]["no_such_param"] = 1.0
    with pytest.raises(tribo.InputError) as e:
        tribo.compare(lawsets=[ls], steady=True)
    assert "no_such_param" in str(e.value) and "broken-set" in str(e.value)


def test_an_unknown_law_lists_the_laws_available(cli):
    want = cli_error(cli("run", "crf250r-motored", "--law", "piston=no-such-law", "--json", fail=True))
    with pytest.raises(tribo.InputError) as e:
        tribo.run("crf250r-motored", laws=["piston=no-such-law"])
    assert str(e.value) == want
    assert "stribeck-duty" in want


def test_a_broken_plugin_raises_plugin_error_with_the_cli_message(cli, tmp_path):
    broken = tmp_path / "libtribo_law_broken.so"
    broken.write_bytes(b"this is not a shared library\n" * 10)
    want = cli_error(cli("--plugin", str(broken), "run", "crf250r-motored", "--steady", "--json", fail=True))
    with pytest.raises(tribo.PluginError) as e:
        tribo.run("crf250r-motored", steady=True, plugin_paths=[broken])
    assert str(e.value) == want
    assert str(broken) in want


def test_set_params_checks_names_and_ranges_when_called_and_messages_say_set():
    ls = tribo.LawSet("stribeck-duty")
    free = ls.free_params()
    mu_b = free[free["param"] == "mu_b"].iloc[0]
    # A value outside the law's own range is refused by set_params itself, before any run.
    with pytest.raises(tribo.InputError, match=r"mu_b") as e:
        ls.set_params({mu_b["id"]: 7.0})
    assert "laws[" in str(e.value), str(e.value)
    # So is a parameter the law does not have.
    with pytest.raises(tribo.InputError, match="no_such_param"):
        ls.set_params({"piston.stribeck-duty.no_such_param": 0.1})
    # An accepted value is in the law set as given.
    ok = ls.set_params({mu_b["id"]: 0.1})
    entry = [e for e in ok.file["laws"] if e["joint"] == "piston"][0]
    assert entry["params"]["mu_b"] == 0.1
    # A rig override is located where a Python user gave it: `set=`, not the CLI's `--set`.
    with pytest.raises(tribo.InputError) as e:
        tribo.run(set={"geometry.bore_m": -1.0}, steady=True)
    assert str(e.value).startswith("set=: geometry.bore_m"), str(e.value)
    assert "--set" not in str(e.value)


def test_a_set_on_a_missing_joint_and_bad_sweep_inputs_are_input_errors():
    with pytest.raises(tribo.InputError, match="JOINT.LAW.PARAM"):
        tribo.LawSet("stribeck-duty").set_params({"mu": 0.1})
    with pytest.raises(tribo.InputError, match="no law `coulomb` on joint `piston`"):
        tribo.LawSet("stribeck-duty").set_params({"piston.coulomb.mu": 0.1})
    with pytest.raises(tribo.InputError):
        tribo.sweep(temps=[], speeds=[3000])
    with pytest.raises(tribo.InputError, match="scale factor must be positive"):
        tribo.mass_response(scales=[-1.0])
    # Every tribo exception is also the builtin a caller would expect.
    assert issubclass(tribo.InputError, ValueError)
    assert issubclass(tribo.SimulationError, RuntimeError)
