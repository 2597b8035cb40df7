"""Speed of the segmentation model: seconds per plate photo (prediction of wells, plaques and counts) on the CPU.

The target is 1.5 s per plate photo on 2 CPU cores; the script prints each model's median and slowest time per image
and their ratios to that target (below 1: faster than the target; the slowest is a photo whose wells are rescaled
to the training size, which runs the network twice), the model file's size, and the machine's load average (the
CPUs are shared). Images are the real 12-well plate photos of ``../shared/data/plaque12/plates`` (or
``PLATESYNTH_SHARED``); where they are absent, raster renders of the ``high`` preset at 1216x944. The first image
of each model is a warm-up and is not timed.

Run: ``python benchmarks/bench_predict.py`` (``--models DIR,DIR``, ``--count N``, ``--threads T``); by default every
shared photo but the warm-up is timed.
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("PLATESYNTH_SHARED", ROOT.parent / "shared"))
TARGET_SECONDS = 1.5


def _images(count: int) -> list:
    from platesynth.io import list_images, read_image

    plates = SHARED / "data" / "plaque12" / "plates"
    if plates.is_dir():
        return [read_image(p) for p in list_images(plates)[: count + 1]]
    print(f"{plates} not found: timing on raster renders of the high preset instead")
    from platesynth.render.raster import render_raster
    from platesynth.scene import load_config, sample_scene

    return [render_raster(sample_scene(load_config("high"), seed), (1216, 944)).image for seed in range(count + 1)]


def main(argv: list[str] | None = None) -> None:
    """Print seconds per plate photo per model."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--models", default=str(ROOT / "models" / "plaque12"), help="comma-separated model folders")
    parser.add_argument("--count", type=int, default=38, help="timed images per model (the photos after the first)")
    parser.add_argument("--threads", type=int, default=2, help="torch CPU threads")
    args = parser.parse_args(argv)

    import numpy as np
    import torch

    from platesynth.segment.model import load_model
    from platesynth.segment.predict import predict_image

    torch.set_num_threads(args.threads)
    images = _images(args.count)
    print(f"prediction on the CPU, {args.threads} torch threads, {len(images) - 1} timed images, "
          f"load average {os.getloadavg()[0]:.2f} at start")
    print(f"{'model':40s} {'MB':>6s} {'median s':>9s} {'x target':>9s} {'slowest s':>10s} {'x target':>9s}")
    for folder in args.models.split(","):
        model = load_model(folder)
        predict_image(model, images[0])
        seconds = []
        for image in images[1:]:
            start = time.perf_counter()
            predict_image(model, image)
            seconds.append(time.perf_counter() - start)
        size_mb = sum(p.stat().st_size for p in Path(folder).iterdir() if p.is_file()) / 1e6
        median, slowest = float(np.median(seconds)), float(np.max(seconds))
        print(f"{Path(folder).name:40s} {size_mb:6.1f} {median:9.2f} {median / TARGET_SECONDS:9.2f} "
              f"{slowest:10.2f} {slowest / TARGET_SECONDS:9.2f}")
    print(f"target {TARGET_SECONDS} s per plate photo; load average {os.getloadavg()[0]:.2f} at end")


if __name__ == "__main__":
    main()
