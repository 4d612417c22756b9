"""Benchmark focus's channel check: how far an image's brightest point sums its channels under their coherent gain.

Usage: python benches/bench_channel_loss.py --keep DIR [--scenarios test1,test2,test3,urban] [--seeds 0,1]
       [--variants clean,txswap,phase20] [--output benches/results/channel_loss.json]

Per drive (``simulate --dynamics full``, kept under DIR; ``ingest``, SAR-MIN, the product's 8-channel image) and per
variant: ``clean`` (the config the drive was made with), ``txswap`` (processed with Tx0's and Tx2's rows of
``radar.tx_positions_wavelengths`` swapped: a board's antennas misnumbered), ``phaseN`` (the simulator's channels
with N degrees RMS of phase error each, the processor told none, as an uncalibrated front end): the loss
``sar/focus.py::channel_sum_loss_db`` measures, which focus warns of over ``MAX_CHANNEL_LOSS_DB``. Beside the rows: each
variant's smallest and largest loss. The committed file: the defaults (~15 min on 2 cores).
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

RESULTS = Path(__file__).resolve().parent / "results"


def variant_configs(base: Any, variant: str) -> tuple[Any, Any]:
    """(the simulator's config, the processor's) for ``variant``."""
    if variant.startswith("phase"):
        return replace(base, simulation=replace(base.simulation, channel_phase_std_deg=float(variant[5:]))), base
    if variant == "txswap":
        tx = list(base.radar.tx_positions_wavelengths)
        tx[0], tx[2] = tx[2], tx[0]
        return base, replace(base, radar=replace(base.radar, tx_positions_wavelengths=type(
            base.radar.tx_positions_wavelengths)(tx)))
    if variant != "clean":
        raise SystemExit(f"--variants: {variant!r} is not clean, txswap or phaseN")
    return base, base


def measure(scenario: str, seed: int, variant: str, keep: Path) -> dict[str, Any]:
    from autosar_cli.config import load_config
    from autosar_cli.ingest.pipeline import ingest
    from autosar_cli.nav.navigate import navigate
    from autosar_cli.sar.focus import FocusOptions, channel_sum_loss_db, drive_radar_config, focus_images
    from autosar_cli.sim.simulate import simulate

    sim_config, config = variant_configs(load_config(), variant)
    made = f"{scenario}{seed}" + (f"_{variant}" if variant.startswith("phase") else "")
    log = keep / f"{made}.mcap"
    t0 = time.perf_counter()
    if not log.exists():
        simulate(scenario, log, seed=seed, config=sim_config, dynamics="full")
    drive = keep / f"{made}_{variant}.h5"
    if not drive.exists():
        ingest([log], drive, config=config)
    trajectory = navigate(drive, "sar-min", config)
    config = drive_radar_config(config, drive, None)
    options = FocusOptions()
    image = focus_images(drive, trajectory, config, options).images[0]
    loss = channel_sum_loss_db(drive, trajectory, config, options, image)
    return {"scenario": scenario, "seed": seed, "variant": variant, "loss_db": loss,
            "seconds": round(time.perf_counter() - t0, 1)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--keep", type=Path, required=True, help="folder for the simulated drives and their drive.h5")
    ap.add_argument("--scenarios", default="test1,test2,test3,urban")
    ap.add_argument("--seeds", default="0,1")
    ap.add_argument("--variants", default="clean,txswap,phase20")
    ap.add_argument("--output", type=Path, default=RESULTS / "channel_loss.json")
    args = ap.parse_args()
    args.keep.mkdir(parents=True, exist_ok=True)
    rows = []
    for scenario in args.scenarios.split(","):
        for seed in (int(s) for s in args.seeds.split(",")):
            for variant in args.variants.split(","):
                rows.append(measure(scenario, seed, variant, args.keep))
                print(rows[-1], flush=True)
    # each variant's range, as scalars beside the rows (BENCHMARKS.md shows them inline)
    ranges = {f"{v}_loss_db": [round(f(r["loss_db"] for r in rows if r["variant"] == v), 2) for f in (min, max)]
              for v in dict.fromkeys(r["variant"] for r in rows)}
    out = {"summary": {"drives": len(rows) // len(ranges), **ranges}, "rows": rows,
           "note": "the loss of the image's brightest point (dB under 20 log10 of the channel count); focus warns "
                   "over 6 dB: a Tx row swap and 20 deg channel phases overlap the clean drives, so neither is told"}
    args.output.write_text(json.dumps(out, indent=1))
    for name, (low, high) in ranges.items():
        print(f"{name}: {low:.2f} .. {high:.2f} dB over {len(rows) // len(ranges)} drives")


if __name__ == "__main__":
    main()
