"""python/README.md as a user meets it: every ``python`` block runs, in order, in one namespace
(later blocks may use names of earlier ones), from a scratch directory; the install block names
paths that exist."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
README = ROOT / "python" / "README.md"


def blocks(lang: str) -> list:
    text = README.read_text()
    return re.findall(rf"^```{lang}\n(.*?)^```", text, flags=re.S | re.M)


def test_readme_starts_with_installing_into_your_own_venv():
    text = README.read_text()
    first = text.index("```")
    assert text[first:].startswith("```sh"), "the first block installs"
    install = blocks("sh")[0]
    assert "python3 -m venv" in install and "pip install './python" in install, install
    # What pip is pointed at is a package maturin can build.
    assert (ROOT / "python" / "pyproject.toml").is_file()
    assert 'build-backend = "maturin"' in (ROOT / "python" / "pyproject.toml").read_text()


def test_every_python_block_of_the_readme_runs(tmp_path, monkeypatch, capsys):
    code = blocks("python")
    assert len(code) >= 2, "a first example and the API tour"
    monkeypatch.chdir(tmp_path)
    namespace: dict = {"__name__": "__readme__"}
    for i, block in enumerate(code):
        exec(compile(block, f"python/README.md block {i + 1}", "exec"), namespace)
    out = capsys.readouterr().out
    # The first example printed its torques (its own assert checks they are not zero).
    assert "motoring_torque_nm" in out
    # The tour's comparison printed its verdict.
    assert namespace["cmp"].verdict in out
    assert namespace["cmp"].verdict == namespace["cmp"].raw["verdict"]["sentence"]
