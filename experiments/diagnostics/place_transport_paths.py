"""Where to put transport paths so the held sphere can follow them: floors of candidate planes.

    .venv/bin/python experiments/diagnostics/place_transport_paths.py \
        experiments/variants/td3-sbx-128-3e6-mirror-fast-transport-fine-10ms-long.yaml \
        runs/workspace-study/held.parquet [--torque-scale 7.5] [--sizes 0.1 0.15] \
        [--heights 0.90 0.92 0.94 0.95 0.96 0.97]

Reads the held rest positions that ``softtrack workspace SPEC --out DIR`` wrote
(``DIR/held.parquet``) and prints, for the study's three paths scaled to each size (the
circle's radius; the rectangle and figure-eight keep the study's proportions: 2r × 4r/3,
amplitudes r and r/2) centred on the arms' axis in each horizontal plane, each path's floor
(:func:`softtrack.evaluation.workspace.path_floors`) and the share of it within 0.025 m of a held
position. The reachable transport paths (``variants/...-reachable.yaml``) were placed with it.
Nothing is written.
"""

from __future__ import annotations

import argparse
import dataclasses

import pandas as pd

from softtrack import api
from softtrack.evaluation.workspace import path_floors
from softtrack.spec.env_config import env_config


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("spec", help="the transport spec the held positions were measured with")
    parser.add_argument("held", help="held.parquet of `softtrack workspace --out`")
    parser.add_argument("--torque-scale", type=float, default=None, help="N·m per unit")
    parser.add_argument("--sizes", type=float, nargs="+", default=[0.1, 0.15], help="m")
    parser.add_argument(
        "--heights", type=float, nargs="+", default=[0.90, 0.92, 0.94, 0.95, 0.96, 0.97]
    )
    args = parser.parse_args()
    config = env_config(api.validate_spec(args.spec))
    table = pd.read_parquet(args.held)
    scale = config.sim.torque_scale if args.torque_scale is None else args.torque_scale
    held = table[table["torque_scale"] == scale][["x", "y", "z"]].to_numpy()
    print(f"{len(held)} held positions at {scale:g} N·m per control unit")
    for size in args.sizes:
        for height in args.heights:
            target = dataclasses.replace(
                config.target,
                center=(0.0, height, 0.0),
                circle_radius=size,
                rectangle_size=(2 * size, 4 * size / 3),
                figure8_amplitude=(size, size / 2),
            )
            floors = path_floors(dataclasses.replace(config, target=target), held)
            cells = "  ".join(
                f"{row.path} {row.floor:.4f} m ({row.within:.0%})" for row in floors.itertuples()
            )
            print(f"size {size:g} m, y = {height:.2f} m: {cells}")


if __name__ == "__main__":
    main()
