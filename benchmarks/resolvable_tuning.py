"""Threshold tuning with every rendered plaque scored against tuning with the unresolvable ones left out.

For each model, the thresholds are tuned again on its own validation images (the held-out items of its training
data, as its training chose them) with ``min_resolved_cells`` 0 (every plaque) and the given value, and the script
prints the chosen (probability, NMS) pairs and the validation count error at each. With ``--out``, it writes a copy of
the model per setting with those thresholds (``OUT/<model>-c<cells>``), to be scored on the real plates with
``python benchmarks/zero_shot_counts.py --models OUT/...``. The training data must be where the training read it
(``train.json``; for a model without one, such as the shipped ``models/plaque12``, its ``config.json`` recipe and
sources, or ``--data`` in the same order: ``scripts/train_model.sh`` renders them again).

Run: ``python benchmarks/resolvable_tuning.py --models runs/m-s1 --cells 3 --out runs/retuned`` (``--threads T``).
"""

from __future__ import annotations

import argparse
import shutil
from pathlib import Path


def main(argv: list[str] | None = None) -> None:
    """Print both tunings per model; write the re-tuned copies with ``--out``."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--models", required=True, help="comma-separated model folders")
    parser.add_argument("--cells", type=float, default=3.0, help="min_resolved_cells compared with 0")
    parser.add_argument("--data", action="append", default=[], help="the training's datasets, in order (optional)")
    parser.add_argument("--out", type=Path, default=None, help="write a re-tuned copy of each model here")
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args(argv)

    import torch

    from platesynth.io import write_json
    from platesynth.segment.model import CONFIG_NAME, load_model
    from platesynth.segment.train import choose_thresholds, threshold_scores, tuning_items, validation_at

    torch.set_num_threads(args.threads)
    for folder in (Path(f) for f in args.models.split(",")):
        model = load_model(folder)
        items = tuning_items(model, folder, args.data)
        for cells in (0.0, args.cells):
            scores = threshold_scores(model, items, min_resolved_cells=cells)
            thresholds = choose_thresholds(scores)
            at = validation_at(scores, *thresholds["plaques"])
            print(f"{folder.name}  cells {cells:g}: plaques prob/NMS {thresholds['plaques']}, wells "
                  f"{thresholds['wells']}; validation count MAE {at['count_mae']:.2f}, bias {at['count_bias']:+.2f} "
                  f"over {at['countable_wells']} wells of {len(items)} images")
            if args.out is not None:
                copy = args.out / f"{folder.name}-c{cells:g}"
                shutil.rmtree(copy, ignore_errors=True)
                shutil.copytree(folder, copy)
                model.config.set_thresholds(thresholds)
                write_json(copy / CONFIG_NAME, model.config.model_dump(mode="json"))


if __name__ == "__main__":
    main()
