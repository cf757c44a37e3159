"""Shared fixtures: the `tribo` binary of this checkout and a helper that runs it for JSON."""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
RELEASE = Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target")) / "release"
TRIBO = RELEASE / "tribo"


@pytest.fixture(scope="session")
def tribo_bin() -> Path:
    """`target/release/tribo`, built by `cargo build --release` before the Python tests."""
    if not TRIBO.is_file():
        pytest.fail(f"{TRIBO} is missing: run `cargo build --release --workspace` first")
    return TRIBO


@pytest.fixture
def cli(tribo_bin, tmp_path):
    """Run `tribo ARGS` and return its JSON (asserting exit 0), or with `fail=True` its
    standard error (asserting exit 1)."""

    def call(*args: str, fail: bool = False):
        proc = subprocess.run(
            [str(tribo_bin), "--quiet", *args],
            cwd=tmp_path,
            capture_output=True,
            text=True,
            timeout=300,
        )
        if fail:
            assert proc.returncode == 1, proc.stdout + proc.stderr
            return proc.stderr
        assert proc.returncode == 0, proc.stderr
        return json.loads(proc.stdout)

    return call



def pytest_sessionfinish(session, exitstatus):
    """A skipped test is a failed run: every test here has what it needs in the environment
    `python/build-and-test.sh` makes, so a skip means a check silently did not happen."""
    reporter = session.config.pluginmanager.get_plugin("terminalreporter")
    skipped = reporter.stats.get("skipped", []) if reporter is not None else []
    if skipped and session.exitstatus == 0:
        names = ", ".join(getattr(r, "nodeid", "?") for r in skipped)
        print(f"\nerror: {len(skipped)} test(s) skipped, which counts as a failure: {names}")
        session.exitstatus = 1
