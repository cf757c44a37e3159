"""A rig with a drivetrain (`crf250r-testbed`): the FMU integrates the crank train alone, not
the chain's degrees of freedom, so the export refuses it, saying so and what to do instead."""

from __future__ import annotations

import subprocess


def test_the_export_of_a_rig_with_a_drivetrain_is_refused_naming_it(tribo_bin, tmp_path):
    out = tmp_path / "testbed.fmu"
    for extra in ([], ["--input", "drive-torque"]):
        proc = subprocess.run(
            [str(tribo_bin), "fmu", "export", "crf250r-testbed", "--lawset", "fedem-baseline",
             *extra, "--out", str(out)],
            capture_output=True,
            text=True,
            timeout=600,
        )
        assert proc.returncode == 1, proc.stderr
        assert "[drivetrain]" in proc.stderr and "tribo run" in proc.stderr, proc.stderr
        assert "panicked" not in proc.stderr
        assert not out.exists()
