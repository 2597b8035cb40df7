"""Zero-shot plaque counts of a model on the shared real plates, on the fit and check halves and on all of them.

For each model: MAE, RMSE, Pearson r and bias of the plaques per well against the person's counts (countable wells
only), the number of wells, and how well it finds the uncountable wells (precision, recall of the blanks), from
:func:`platesynth.segment.counts.evaluate_counts`; and how large it draws the wells: its wells' mean radius over the
fitted plate grid's (:func:`platesynth.metrics.fit_plate_grid`), photo by photo (10th, 50th and 90th percentiles). The split is by virus (``benchmarks/shared_split.py``): looks
and models are tuned on the fit viruses, the check virus is only measured.

Run: ``python benchmarks/zero_shot_counts.py`` (``--models DIR,DIR``, ``--threads T``, ``--table OUT.csv`` for the
per-well records of the first model, ``--plaque-thresholds PROB,NMS`` in place of the models' own). Each model's
last line is its bias by virus and by the person's count (:func:`bias_by_count`): where a model misses crowded wells
or finds plaques in sparse ones, which one MAE and bias over all wells mix. The line before it is the count error its
training measured on its own held-out renders at its kept thresholds (``training.validation_at_thresholds``):
trainings with a large one counted the photos worse too (``docs/segmentation.md``).
"""

from __future__ import annotations

import argparse
import csv
import hashlib
import os
import tempfile
from pathlib import Path

from shared_split import SPLITS, split_counts, virus

ROOT = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("PLATESYNTH_SHARED", ROOT.parent / "shared"))
COUNT_BINS = ((0, 5), (5, 20), (20, 50), (50, 200))
"""Ranges of the person's count, ``[low, high)``, that :func:`bias_by_count` reports apart."""


def bias_by_count(wells: list[dict]) -> str:
    """Mean predicted minus counted plaques per well by virus (the photo name's prefix) and by the person's count
    (:data:`COUNT_BINS`), from :func:`platesynth.segment.counts.evaluate_counts`'s per-well records of the wells it
    scores (those with a count)."""
    parts = []
    for name in SPLITS["all"]:
        pairs = [(w["count"], w["predicted"]) for w in wells if virus(w["image"]) == name and w["count"] is not None]
        bins = []
        for low, high in COUNT_BINS:
            errors = [found - counted for counted, found in pairs if low <= counted < high]
            bins.append(f"{low}-{high}: {sum(errors) / len(errors):+.1f} ({len(errors)})" if errors else f"{low}-{high}: -")
        parts.append(f"{name} " + ", ".join(bins))
    return "bias by the person's count (wells): " + "; ".join(parts)


def held_out_error(training: dict | None) -> str:
    """The plaque count error a training measured on its held-out renders at the thresholds it kept."""
    at = (training or {}).get("validation_at_thresholds") or {}
    if at.get("count_mae") is None:
        return "held-out renders at the kept thresholds: not recorded"
    return (f"held-out renders at the kept thresholds: count MAE {at['count_mae']:.2f}, bias {at['count_bias']:+.2f} "
            f"({at['countable_wells']} wells)")


def main(argv: list[str] | None = None) -> None:
    """Print the count agreement of each model on each split."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--models", default=str(ROOT / "models" / "plaque12"), help="comma-separated model folders")
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--table", type=Path, default=None, help="write the first model's per-well records here")
    parser.add_argument("--plaque-thresholds", default=None, metavar="PROB,NMS",
                        help="the plaque branch's thresholds in place of those tuned with each model")
    args = parser.parse_args(argv)
    plaque_thresholds = tuple(float(t) for t in args.plaque_thresholds.split(",")) if args.plaque_thresholds else None
    plates = SHARED / "data" / "plaque12" / "plates"
    counts = SHARED / "data" / "plaque12" / "counts.csv"
    if not counts.is_file():
        raise SystemExit(f"{counts} not found: set PLATESYNTH_SHARED to the shared material")

    import numpy as np
    import torch

    from platesynth.metrics import fit_plate_grid
    from platesynth.segment.counts import evaluate_counts
    from platesynth.segment.model import load_model
    from platesynth.segment.predict import predict_image

    torch.set_num_threads(args.threads)
    print(f"{'model':28s} {'split':6s} {'wells':>5s} {'MAE':>6s} {'RMSE':>6s} {'r':>6s} {'bias':>6s} "
          f"{'unc.':>5s} {'prec.':>6s} {'recall':>6s}")
    with tempfile.TemporaryDirectory() as tmp:
        for index, folder in enumerate(args.models.split(",")):
            model = load_model(folder)
            thresholds = model.config.thresholds | ({"plaques": plaque_thresholds} if plaque_thresholds else {})
            cache: dict[bytes, object] = {}
            well_scale: dict[bytes, float] = {}

            def predict(image, model=model, cache=cache, thresholds=thresholds, well_scale=well_scale):
                key = hashlib.sha1(image.tobytes()).digest()
                if key not in cache:
                    cache[key] = result = predict_image(model, image, thresholds=thresholds)
                    radii = [np.sqrt((result.wells == w.id).sum() / np.pi) for w in result.well_info]
                    well_scale[key] = float(np.mean(radii) / np.mean([d.radius for d in fit_plate_grid(image[..., :3])]))
                return cache[key]

            records: list[dict] = []
            for split in ("fit", "check", "all"):
                table = split_counts(counts, split, Path(tmp) / f"{split}.csv")
                report = evaluate_counts(predict, plates, table, 12)
                unc = report["countability"]
                print(f"{Path(folder).name:28s} {split:6s} {report['n_wells']:5d} {report['mae']:6.2f} "
                      f"{report['rmse']:6.2f} {report['pearson_r']:6.3f} {report['bias']:+6.2f} "
                      f"{unc['n_uncountable']:5d} {unc['precision']:6.2f} {unc['recall']:6.2f}")
                if split == "all":
                    records = report["wells"]
                if index == 0 and split == "all" and args.table is not None:
                    with args.table.open("w", newline="") as handle:
                        writer = csv.DictWriter(handle, fieldnames=list(report["wells"][0]))
                        writer.writeheader()
                        writer.writerows(report["wells"])
            low, middle, high = np.percentile(list(well_scale.values()), [10, 50, 90])
            print(f"{Path(folder).name:28s} wells' radius over the fitted grid's, {len(well_scale)} photos: "
                  f"{low:.3f} {middle:.3f} {high:.3f} (10th, 50th, 90th percentiles)")
            print(f"{Path(folder).name:28s} {held_out_error(model.config.training)}")
            print(f"{Path(folder).name:28s} {bias_by_count(records)}")


if __name__ == "__main__":
    main()
