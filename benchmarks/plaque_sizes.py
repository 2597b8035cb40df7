"""Plaque sizes as a segmentation model sees them: the shared real 12-well photos against presets' renders.

Every image, real or rendered, is measured alike: the model's predicted wells and plaques
(:func:`platesynth.optimise.objective.plaque_area_fractions`), each plaque's area as a share of its well's. The
renders' true masks would hold plaques too small or faint for anyone to see, so they are not used. Prints the 10th,
25th, 50th, 75th and 90th percentiles of the area fractions (per mille of the well), the plaques found per image
(and, for renders, the plaques their true masks hold per image: how many the model can see), and the
``plaque_sizes`` term of ``platesynth optimise`` (:func:`platesynth.metrics.wells.plaque_area_distance`, decades) of
each preset against each half of the photos (fit: Brisbane and IBV; check: PR8).

Run: ``python benchmarks/plaque_sizes.py`` (``--presets high,low,runs/opt/best.yaml``, ``--images N``,
``--model DIR``).
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from shared_split import in_split

ROOT = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("PLATESYNTH_SHARED", ROOT.parent / "shared"))
SIZE = (608, 472)
"""Both sets are measured at the optimiser's default size (the photos resized, Lanczos)."""
PERCENTILES = (10, 25, 50, 75, 90)


def main(argv: list[str] | None = None) -> None:
    """Print the percentiles of plaque area fractions of the photos' halves and of each preset's renders."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--presets", default="low,high", help="comma-separated presets or configuration files")
    parser.add_argument("--images", type=int, default=16, help="renders per preset")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--model", default=str(ROOT / "models" / "plaque12"))
    args = parser.parse_args(argv)

    import numpy as np
    import torch

    from platesynth.io import list_images, read_image, to_rgb_uint8
    from platesynth.metrics.wells import plaque_area_distance
    from platesynth.optimise.objective import plaque_area_fractions, resized
    from platesynth.render import render
    from platesynth.scene import load_config, sample_scene

    torch.set_num_threads(max(1, os.cpu_count() or 1))
    photos = list_images(SHARED / "data" / "plaque12" / "plates")
    if not photos:
        raise SystemExit(f"no real photos under {SHARED}: set PLATESYNTH_SHARED to the shared material")

    def report(label: str, fractions: np.ndarray, n_images: int, halves: dict[str, np.ndarray],
               n_true: int | None = None) -> None:
        per_mille = np.round(np.percentile(fractions, PERCENTILES) * 1e3, 2)
        distances = "  ".join(f"{half} {plaque_area_distance(fractions, values):.3f}" for half, values in halves.items())
        true = f"{n_true / n_images:6.1f}" if n_true is not None else "     -"
        print(f"{label:28s} {per_mille}  {len(fractions) / n_images:6.1f}  {true}  {distances}")

    halves = {}
    for half in ("fit", "check"):
        images = [resized(to_rgb_uint8(read_image(p)), SIZE) for p in photos if in_split(p.name, half)]
        halves[half] = (plaque_area_fractions(images, args.model), len(images))
    print(f"{'plaques of':28s} area per mille of the well, percentiles {PERCENTILES}; found and true per image; "
          "plaque_sizes to")
    reference = {half: values for half, (values, _) in halves.items()}
    for half, (values, n_images) in halves.items():
        report(f"photos, {half}", values, n_images, reference)
    for name in args.presets.split(","):
        config = load_config(path=name) if name.endswith((".yaml", ".yml")) else load_config(name)
        results = [render(sample_scene(config, args.seed + i), SIZE) for i in range(args.images)]
        n_true = sum(np.unique(result.plaques).size - 1 for result in results)
        report(name, plaque_area_fractions([r.image for r in results], args.model), len(results), reference, n_true)


if __name__ == "__main__":
    main()
