"""Laws called from Python run in a worker process: a law that segfaults, calls ``exit(0)`` or
``_exit(0)``, or hangs inside one call raises ``tribo.SimulationError`` naming the law, and the
interpreter (this test process) goes on. The hostile laws are the fixture of the CLI's tests,
``tests/fixtures/c/foreign_law.c``, built here with the system C compiler; each misbehaves
after 3000 calls. Runs use the default limits, except where a test says otherwise."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

import tribo

ROOT = Path(__file__).resolve().parents[2]
FIXTURE = ROOT / "tests" / "fixtures" / "c" / "foreign_law.c"
INCLUDE = ROOT / "plugin-api" / "include"
SHORT = {
    "cycle.segments": '[{kind="ramp", to_rpm=3000, duration_s=0.3}, {kind="hold", duration_s=0.3}]'
}
FRICTIONLESS = str(ROOT / "rigs" / "reference-frictionless.toml")

# case number of the fixture, law name
CASES = {"segfault": 8, "exit0": 3, "stuck": 5, "thread": 4, "exit": 10}


@pytest.fixture(scope="module")
def hostile(tmp_path_factory):
    """Build each case the tests use; returns {name: library path}."""
    out = tmp_path_factory.mktemp("hostile")
    libs = {}
    for name, case in CASES.items():
        lib = out / f"libtribo_law_hostile_{name}.so"
        cc = os.environ.get("CC", "cc")
        subprocess.run(
            [cc, "-shared", "-fPIC", "-O2", "-std=c99", f"-DCASE={case}", "-I", str(INCLUDE),
             str(FIXTURE), "-o", str(lib), "-lpthread"],
            check=True,
        )
        libs[name] = str(lib)
    return libs


def _run(libs, name, **kw):
    return tribo.run(
        FRICTIONLESS,
        laws=[f"piston=hostile-{name}"],
        set=SHORT,
        plugin_paths=[libs[name]],
        **kw,
    )


@pytest.mark.parametrize(
    "name, words",
    [
        ("segfault", ["signal 11", "SIGSEGV"]),
        ("exit", ["exit()"]),
        ("exit0", ["status 0", "without sending results"]),
    ],
)
def test_a_crashing_or_exiting_law_raises_naming_it_and_the_script_goes_on(hostile, name, words):
    with pytest.raises(tribo.SimulationError) as e:
        _run(hostile, name)
    message = str(e.value)
    for w in [f"law `hostile-{name}`", hostile[name], "at joint `piston`", *words]:
        assert w in message, message
    # Still alive, and a good run after it works.
    assert len(tribo.run(FRICTIONLESS, lawset="fedem-baseline", set=SHORT).plateaus) == 1


def test_a_stuck_law_raises_after_the_default_call_limit_naming_law_joint_and_inputs(hostile):
    start = time.monotonic()
    with pytest.raises(tribo.SimulationError) as e:
        _run(hostile, "stuck")
    elapsed = time.monotonic() - start
    message = str(e.value)
    for w in ["law `hostile-stuck`", "at joint `piston`", "did not return from one call in 10",
              "call_limit_s", "the call's inputs: t = ", "normal load"]:
        assert w in message, message
    assert elapsed < 60, elapsed


def test_a_law_with_a_background_thread_gives_the_same_results_isolated_as_in_process(hostile):
    iso = _run(hostile, "thread")
    inp = _run(hostile, "thread", in_process=True)
    assert iso.raw == inp.raw


def test_limits_out_of_range_are_input_errors(hostile):
    for kw, word in [({"time_limit_s": 1e300}, "time_limit_s"), ({"call_limit_s": -1}, "call_limit_s"),
                     ({"memory_limit_mb": 2**60}, "memory_limit_mb")]:
        with pytest.raises(tribo.InputError) as e:
            _run(hostile, "thread", **kw)
        assert word in str(e.value), str(e.value)


def test_a_crash_in_process_still_ends_the_interpreter_which_is_why_it_is_opt_in(hostile):
    # In a child interpreter, so this test process survives to check it.
    code = (
        "import tribo, sys\n"
        f"tribo.run({FRICTIONLESS!r}, laws=['piston=hostile-segfault'], set={SHORT!r},"
        f" plugin_paths=[{hostile['segfault']!r}], in_process=True)\n"
        "print('survived')\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode != 0
    assert "survived" not in proc.stdout


def test_laws_opens_the_libraries_in_workers_so_an_initialiser_that_exits_crashes_or_hangs_is_a_warning(tmp_path):
    # The fixture of the CLI's mischief tests, tests/fixtures/c/mischief.c: initialisers that
    # call _exit(0), raise SIGSEGV, or never return.
    plugins = tmp_path / "plugins"
    plugins.mkdir()
    cases = {"ctor_exit": (3, "status 0"), "ctor_crash": (11, "SIGSEGV"), "ctor_hang": (4, "did not return")}
    for name, (case, _) in cases.items():
        subprocess.run(
            [os.environ.get("CC", "cc"), "-shared", "-fPIC", "-O2", "-std=c99", f"-DCASE={case}",
             "-I", str(INCLUDE), str(ROOT / "tests" / "fixtures" / "c" / "mischief.c"),
             "-o", str(plugins / f"libtribo_law_mischief_{name}.so"), "-lpthread"],
            check=True,
        )
    start = time.monotonic()
    with pytest.warns(RuntimeWarning) as caught:
        listed = tribo.laws([plugins])
    elapsed = time.monotonic() - start
    # The interpreter is alive, and the good laws (the bundled ones) are listed.
    assert "coulomb" in set(listed["name"]), listed
    broken = {Path(b["file"]).name: b["error"] for b in listed.attrs["broken"]}
    warned = [str(w.message) for w in caught]
    for name, (_, words) in cases.items():
        file = f"libtribo_law_mischief_{name}.so"
        assert file in broken, broken
        assert "while loading it" in broken[file] and words in broken[file], broken[file]
        assert any(file in w for w in warned), warned
    # The hang ends at the default 10 s call limit (the parent's backstop 3 s later), once.
    assert elapsed < 10 + 3 + 10, elapsed
