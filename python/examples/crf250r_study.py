"""A worked, notebook-style study of the CRF 250 R rig from Python.

1. The CLI's comparison table (`tribo compare --steady`): the bundled law sets against the
   thesis's measured torque, ranked by leave-one-out error.
2. A 2-parameter sweep: connecting-rod mass scale x oil temperature (a full-factorial design
   through tribo.study), the torque at 9000 rpm drawn as a heat map.

Run it as a script (CI does): `python examples/crf250r_study.py`; the plot goes into
$TRIBO_EXAMPLE_OUT (default: the current directory).
"""

from __future__ import annotations

import os
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import tribo  # noqa: E402
from tribo import study  # noqa: E402


def main() -> None:
    out = Path(os.environ.get("TRIBO_EXAMPLE_OUT", "."))
    out.mkdir(parents=True, exist_ok=True)

    # %% 1. The comparison table, as `tribo compare --steady` prints it.
    cmp = tribo.compare(steady=True)
    print(f"rig {cmp.raw['rig']}, data {cmp.raw['data_file']}, mode {cmp.raw['mode']}")
    print(cmp.sets[["lawset", "rank", "rmse_nm", "cv_rmse_nm", "aicc", "bic"]].sort_values("rank").to_string(index=False))
    print()
    print(cmp.table.to_string(index=False, float_format=lambda v: f"{v:.4f}"))
    best = cmp.sets.sort_values("rank").iloc[0]["lawset"]

    # %% 2. Rod mass x oil temperature, the best-ranked law set, steady state.
    design = study.full_factorial(
        {"rig:bodies.rod.mass_scale": [0.6, 0.8, 1.0, 1.2], "oil_temp_c": [40.0, 60.0, 80.0, 100.0, 120.0]}
    )
    res = study.run_design(design, lawset=best, speeds=[3000.0, 6000.0, 9000.0])
    top = res[res["speed_rpm"] == 9000.0].pivot(
        index="rig:bodies.rod.mass_scale", columns="oil_temp_c", values="torque_nm"
    )
    print(f"\nmotoring torque at 9000 rpm, N m ({best}): rod mass scale (rows) x oil temperature, C (columns)")
    print(top.to_string(float_format=lambda v: f"{v:.4f}"))

    fig, ax = plt.subplots(figsize=(6, 4))
    im = ax.imshow(top.to_numpy(), origin="lower", aspect="auto", cmap="viridis")
    ax.set_xticks(range(len(top.columns)), [f"{c:g}" for c in top.columns])
    ax.set_yticks(range(len(top.index)), [f"{i:g}" for i in top.index])
    ax.set_xlabel("oil temperature, C")
    ax.set_ylabel("connecting-rod mass scale")
    ax.set_title(f"CRF 250 R motoring torque at 9000 rpm ({best})")
    fig.colorbar(im, ax=ax, label="N m")
    fig.tight_layout()
    path = out / "rod_mass_x_oil_temp.png"
    fig.savefig(path, dpi=100)
    print(f"\nwrote {path}")


if __name__ == "__main__":
    main()
