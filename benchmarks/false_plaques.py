"""Where a trained model's false plaques lie on its own held-out renders: on the scenes' scratches, or elsewhere.

A scrape, a stray scratch or a tear at the rim is a pale lesion in the stain, as a plaque is. This predicts every
held-out render of a training (the images its thresholds were tuned on) at a few probability thresholds (the NMS
threshold kept with the model) and sorts each predicted plaque: found (at least ``--overlap`` of its pixels on rendered
plaques) or false, and a false one on a scratch (at least ``--overlap`` of its pixels where a scratch took the stain
off, :func:`platesynth.render.raster.scratch_map`) or elsewhere. The last line says how much of the wells' area the
scratches cover, for scale.

Run: ``python benchmarks/false_plaques.py --models DIR[,DIR...]`` (``--probs 0.15,0.3``: the kept probability is
always added; ``--nms N`` for every model instead of its kept one, to compare models at the same pair; ``--data D
--data D ...`` as in ``threshold_grid.py``; ``--threads T``).
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from pathlib import Path

import numpy as np

SCRAPED = 0.05
"""A pixel is on a scratch where the scratch took off more than this share of the stain."""


@dataclass
class PlaqueTally:
    """Predicted plaques sorted by what lies under them."""

    found: int = 0
    false_on_scratches: int = 0
    false_elsewhere: int = 0

    def add(self, other: PlaqueTally) -> None:
        """Add another image's tally to this one."""
        self.found += other.found
        self.false_on_scratches += other.false_on_scratches
        self.false_elsewhere += other.false_elsewhere

    @property
    def false(self) -> int:
        """All false plaques."""
        return self.false_on_scratches + self.false_elsewhere


def sort_predicted(predicted: np.ndarray, true: np.ndarray, scraped: np.ndarray, overlap: float = 0.3) -> PlaqueTally:
    """Sort the plaques of a predicted instance mask by the rendered plaques and the scratch map under them.

    Parameters
    ----------
    predicted, true : (H, W) integer instance masks of the same image.
    scraped : (H, W) bool, where a scratch took the stain off.
    overlap : share of a predicted plaque's pixels on rendered plaques that makes it found (and on scratches that
        puts a false one on them).
    """
    tally = PlaqueTally()
    ids = predicted.ravel()
    n = int(ids.max()) + 1 if ids.size else 1
    area = np.bincount(ids, minlength=n)
    on_true = np.bincount(ids, weights=(true.ravel() > 0), minlength=n)
    on_scratch = np.bincount(ids, weights=scraped.ravel(), minlength=n)
    for i in np.flatnonzero(area[1:]) + 1:
        if on_true[i] >= overlap * area[i]:
            tally.found += 1
        elif on_scratch[i] >= overlap * area[i]:
            tally.false_on_scratches += 1
        else:
            tally.false_elsewhere += 1
    return tally


def main(argv: list[str] | None = None) -> None:
    """Print each model's tally per probability threshold."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--models", required=True, help="finished trainings' folders, comma-separated")
    parser.add_argument("--data", action="append", default=[], help="the trainings' datasets, in order (optional)")
    parser.add_argument("--probs", default="0.15,0.3", help="probability thresholds besides the kept one")
    parser.add_argument("--nms", type=float, default=None, help="NMS threshold (default: each model's kept one)")
    parser.add_argument("--overlap", type=float, default=0.3)
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args(argv)

    import torch

    from platesynth.data.layout import load_item
    from platesynth.segment.data import item_scratches
    from platesynth.segment.model import load_model
    from platesynth.segment.predict import predict_image
    from platesynth.segment.train import tuning_items

    torch.set_num_threads(args.threads)
    for model_dir in (Path(m) for m in args.models.split(",")):
        model = load_model(model_dir)
        kept_prob, kept_nms = model.config.thresholds["plaques"]
        kept_nms = kept_nms if args.nms is None else args.nms
        probs = sorted({*(float(p) for p in args.probs.split(",")), float(kept_prob)})
        tallies = {p: PlaqueTally() for p in probs}
        scratched_area = well_area = 0
        items = tuning_items(model, model_dir, args.data)
        for item in items:
            image, wells, plaques = load_item(item)
            scraped = item_scratches(item, image.shape[:2]) > SCRAPED
            scratched_area += int((scraped & (wells > 0)).sum())
            well_area += int((wells > 0).sum())
            for p in probs:
                predicted = predict_image(model, image, thresholds={"plaques": (p, kept_nms)}).plaques
                tallies[p].add(sort_predicted(predicted, plaques, scraped, args.overlap))
        print(f"{model_dir} ({len(items)} held-out renders, NMS {kept_nms}):")
        for p in probs:
            t = tallies[p]
            share = t.false_on_scratches / t.false if t.false else float("nan")
            mark = " (kept)" if p == kept_prob else ""
            print(f"  prob {p:.2f}{mark}: found {t.found}, false {t.false}, on scratches {t.false_on_scratches} "
                  f"({share:.0%})")
        print(f"  scratches cover {scratched_area / max(well_area, 1):.2%} of the wells' area")


if __name__ == "__main__":
    main()
