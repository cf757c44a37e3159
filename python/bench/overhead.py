"""Calling overhead of the Python package: a steady 7-speed run of the bundled rig with a law
set, from Python (``tribo.run(..., steady=True)`` and its plateau DataFrame) against the same
work in Rust (``bench/steady_baseline.rs``). Prints both medians and the ratio; exits 1 if
Python costs more than 10% over Rust.

    cargo build --release --workspace && cargo build --release -p tribo-python --example steady_baseline
    python bench/overhead.py [REPEATS]
"""

from __future__ import annotations

import statistics
import subprocess
import sys
import time
from pathlib import Path

import tribo

ROOT = Path(__file__).resolve().parents[2]


def python_ms(repeats: int, lawset: str, frame: bool) -> float:
    """Median ms of `tribo.run` (and, with `frame`, building its plateau DataFrame)."""
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        r = tribo.run("crf250r-motored", lawset=lawset, steady=True)
        if frame:
            r.plateaus
        times.append((time.perf_counter() - t) * 1e3)
    return statistics.median(times)


def main() -> int:
    repeats = int(sys.argv[1]) if len(sys.argv) > 1 else 50
    rounds = 5
    lawset = "stribeck-duty"
    exe = ROOT / "target" / "release" / "examples" / "steady_baseline"
    tribo.run("crf250r-motored", lawset=lawset, steady=True)  # plugins found and opened once
    # Rounds alternate Rust and Python so a busy machine slows both alike; the best round of
    # each is compared.
    rust, py, py_frame = [], [], []
    for _ in range(rounds):
        out = subprocess.run([str(exe), str(repeats), lawset], check=True, capture_output=True, text=True)
        rust.append(float(out.stdout))
        py.append(python_ms(repeats, lawset, frame=False))
        py_frame.append(python_ms(repeats, lawset, frame=True))
    r, p, f = min(rust), min(py), min(py_frame)
    print(f"steady 7-speed run, {lawset}, best of {rounds} medians of {repeats} runs:")
    print(f"  Rust {r:.3f} ms, Python tribo.run {p:.3f} ms (x{p / r:.3f}), with the plateau DataFrame {f:.3f} ms (x{f / r:.3f})")
    return 0 if p / r <= 1.10 else 1


if __name__ == "__main__":
    sys.exit(main())
