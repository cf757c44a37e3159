"""Calling overhead of the Python package: a steady 7-speed run of the bundled rig with a law
set, from Python (``tribo.run(..., steady=True)`` and its plateau DataFrame) against the same
work in Rust (``bench/steady_baseline.rs``: load, bind, run, the result serialised as JSON; it
also times the runs without the serialisation).

Rounds alternate Rust and Python so a busy machine slows both alike, and each round of either
side is a fresh process: the speed of one process depends on where its stack, heap and
libraries happened to land (address randomisation), so a single Python process against a
fresh Rust process per round would compare one draw with the best of many. Two measures, each
the best round of each side: the median wall time of a call, and the mean processor time of a call
(this thread's time on a processor, from ``/proc/thread-self/schedstat``: the run is
single-threaded, and this leaves out the time spent waiting for a processor, which dominates the
wall clock's noise on a shared machine). Exits 1 if Python costs more than 10% over Rust on
either measure (against the baseline with its JSON). The calls run in process
(``in_process=True``): this measures the Python layer; the worker process every call gets by
default adds a fixed cost per call (``docs/performance.md``, "Current figures").

    cargo build --release --workspace && cargo build --release -p tribo-python --example steady_baseline
    python bench/overhead.py [REPEATS] [ROUNDS]
    python bench/overhead.py --round REPEATS   # one Python round (what the rounds run)
"""

from __future__ import annotations

import math
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import Optional, Tuple

import tribo

ROOT = Path(__file__).resolve().parents[2]


def cpu_ns() -> Optional[int]:
    """This thread's time on a processor in ns, if the system reports it."""
    try:
        with open("/proc/thread-self/schedstat") as f:
            return int(f.read().split()[0])
    except (OSError, ValueError, IndexError):
        return None


def python_ms(repeats: int, lawset: str, frame: bool) -> Tuple[float, float]:
    """Median wall ms of `tribo.run` (and, with `frame`, building its plateau DataFrame), and
    the mean processor ms per call."""
    times = []
    start = cpu_ns()
    for _ in range(repeats):
        t = time.perf_counter()
        r = tribo.run("crf250r-motored", lawset=lawset, steady=True, in_process=True)
        if frame:
            r.plateaus
        times.append((time.perf_counter() - t) * 1e3)
    end = cpu_ns()
    cpu = math.nan if start is None or end is None else (end - start) * 1e-6 / repeats
    return statistics.median(times), cpu


LAWSET = "stribeck-duty"


def one_round(repeats: int) -> None:
    """A Python round in this (fresh) process: prints the median wall ms, the mean processor ms
    per call, and the median wall ms with the plateau DataFrame."""
    tribo.run("crf250r-motored", lawset=LAWSET, steady=True, in_process=True).plateaus  # plugins opened, pandas warm
    wall, cpu = python_ms(repeats, LAWSET, frame=False)
    frame = python_ms(repeats, LAWSET, frame=True)[0]
    print(f"{wall:.4f} {cpu:.4f} {frame:.4f}")


def main() -> int:
    if len(sys.argv) > 2 and sys.argv[1] == "--round":
        one_round(int(sys.argv[2]))
        return 0
    repeats = int(sys.argv[1]) if len(sys.argv) > 1 else 50
    rounds = int(sys.argv[2]) if len(sys.argv) > 2 else 9
    lawset = LAWSET
    exe = ROOT / "target" / "release" / "examples" / "steady_baseline"
    rust, bare, rust_cpu, py, py_cpu, frame = [], [], [], [], [], []
    for _ in range(rounds):
        out = subprocess.run([str(exe), str(repeats), lawset], check=True, capture_output=True, text=True)
        whole, unserialised, cpu = (float(x) for x in out.stdout.split())
        rust.append(whole)
        bare.append(unserialised)
        rust_cpu.append(cpu)
        out = subprocess.run(
            [sys.executable, __file__, "--round", str(repeats)], check=True, capture_output=True, text=True
        )
        wall, cpu, with_frame = (float(x) for x in out.stdout.split())
        py.append(wall)
        py_cpu.append(cpu)
        frame.append(with_frame)
    r, b, p, f = min(rust), min(bare), min(py), min(frame)
    rc, pc = min(rust_cpu), min(py_cpu)
    print(f"steady 7-speed run, {lawset}, best of {rounds} rounds of {repeats} runs:")
    print(f"  wall (median): Rust {r:.3f} ms (without serialising the result {b:.3f} ms), "
          f"Python tribo.run {p:.3f} ms: x{p / r:.3f} (x{p / b:.3f} over the unserialised run)")
    print(f"  processor time (mean): Rust {rc:.3f} ms, Python tribo.run {pc:.3f} ms: x{pc / rc:.3f}")
    print(f"  with the plateau DataFrame (wall) {f:.3f} ms: x{f / r:.3f}")
    worst = max(p / r, pc / rc if rc == rc and pc == pc else 0.0)
    return 0 if worst <= 1.10 else 1


if __name__ == "__main__":
    sys.exit(main())
