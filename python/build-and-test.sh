#!/usr/bin/env bash
# The Python half of the test command (README): a virtual environment in target/pyenv with
# maturin, pytest, pandas, numpy, dask[distributed], matplotlib, fmpy and exudyn (the multibody
# peer of tests/peers/exudyn_testbed.py) from PyPI, the `tribo` wheel built with maturin and
# installed into it, then the Python tests and the worked example, and the FMU's tests with FMPy
# as the importer (host/fmu/tests).
# Needs `cargo build --release --workspace` first (the tests compare against target/release/tribo
# and load the law plugins from target/release).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(dirname "$here")"
target="${CARGO_TARGET_DIR:-$root/target}"
venv="$target/pyenv"
python="${PYTHON:-python3}"
if [ ! -x "$venv/bin/python" ]; then
  "$python" -m venv "$venv"
fi
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check \
  "maturin>=1.5,<2" pytest pandas numpy "dask[distributed]" matplotlib fmpy "exudyn==1.13.6"
rm -rf "$target/wheels"
(cd "$here" && "$venv/bin/maturin" build --release --quiet -o "$target/wheels")
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check --force-reinstall --no-deps "$target"/wheels/tribo-*.whl
cd "$here"
# The example writes its plot into a scratch directory; MPLBACKEND keeps matplotlib off any display.
MPLBACKEND=Agg TRIBO_EXAMPLE_OUT="$target/python-example" "$venv/bin/python" examples/crf250r_study.py
"$venv/bin/python" "$venv/bin/pytest" -q -p no:cacheprovider tests
# A separate run: its conftest is the FMU's own.
"$venv/bin/python" "$venv/bin/pytest" -q -p no:cacheprovider "$root/host/fmu/tests"
