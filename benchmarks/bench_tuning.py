"""Threshold tuning at the end of a training: one drawing per NMS threshold against drawing every pair.

:func:`platesynth.segment.train.threshold_scores` runs NMS and draws the polygons once per NMS threshold and reads
every probability threshold off that drawing. The reference here is the direct way it replaced: NMS, drawing and
matching for every (probability, NMS) pair. Both score the same rendered validation images (``high`` at the
training size, 512x384) with the shipped model on the CPU; the script prints each one's time, their ratio and how
far the scores differ. They can differ slightly: stardist's NMS orders polygons of equal score, and searches for
overlapping neighbours, among the candidates above the threshold it is given, so running it at a higher threshold
now and then keeps another polygon (on 16 images: one well of one image, at two of the 54 pairs, by one plaque).
Exits 1 if more than 1 % of the count errors or a mean AP by more than 0.001 differ.

Run: ``python benchmarks/bench_tuning.py`` (``--images N``, default 16; ``--quick`` for 4; ``--threads T``).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def reference_scores(model, items, prob_thresholds, nms_thresholds, tau=0.5):
    """Mean AP per branch and count errors per pair, drawing each pair's polygons alone."""
    from platesynth.data.layout import load_item
    from platesynth.render.result import plaque_counts
    from platesynth.segment.countability import rendered_countable
    from platesynth.segment.matching import match_instances
    from platesynth.segment.predict import nms_polygons, polygons_to_mask, predict_maps

    shape = (len(prob_thresholds), len(nms_thresholds))
    mean_ap = {"wells": np.zeros(shape), "plaques": np.zeros(shape)}
    errors = [[[] for _ in nms_thresholds] for _ in prob_thresholds]
    for item in items:
        image, wells, plaques = load_item(item)
        counted = [w for w, ok in rendered_countable(item).items() if ok]
        true_counts = plaque_counts(wells, plaques, counted)
        maps, working_shape = predict_maps(model, image)
        for name, truth in (("wells", wells), ("plaques", plaques)):
            for i, prob in enumerate(prob_thresholds):
                for j, nms in enumerate(nms_thresholds):
                    predicted = polygons_to_mask(nms_polygons(maps[name], prob, nms), working_shape, truth.shape)
                    mean_ap[name][i, j] += match_instances(truth, predicted, tau).ap / len(items)
                    if name == "plaques":
                        found = plaque_counts(wells, predicted, counted)
                        errors[i][j] += [found[w] - true_counts[w] for w in counted]
    return mean_ap, np.array(errors, dtype=float).reshape(*shape, -1)


def main(argv: list[str] | None = None) -> None:
    """Print both times, their ratio and whether the scores agree."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--images", type=int, default=16)
    parser.add_argument("--quick", action="store_true", help="4 images")
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args(argv)
    count = 4 if args.quick else args.images

    import torch

    from platesynth.data.batch import build_manifest, render_dataset
    from platesynth.data.layout import list_items
    from platesynth.segment.model import load_model
    from platesynth.segment.train import NMS_THRESHOLDS, PROB_THRESHOLDS, threshold_scores

    torch.set_num_threads(args.threads)
    model = load_model(ROOT / "models" / "plaque12")
    with tempfile.TemporaryDirectory() as tmp:
        render_dataset(Path(tmp), build_manifest(count=count, preset="high", seed=7, size=(512, 384)))
        items = list_items(tmp)
        start = time.perf_counter()
        ours = threshold_scores(model, items)
        ours_seconds = time.perf_counter() - start
        start = time.perf_counter()
        mean_ap, errors = reference_scores(model, items, PROB_THRESHOLDS, NMS_THRESHOLDS)
        reference_seconds = time.perf_counter() - start
    differing = float(np.mean(ours.count_errors != errors)) if errors.size else 0.0
    ap_gap = max(float(np.abs(ours.mean_ap[name] - mean_ap[name]).max()) for name in mean_ap)
    pairs = len(PROB_THRESHOLDS) * len(NMS_THRESHOLDS)
    print(f"{count} images of high at 512x384, {pairs} threshold pairs per branch, {args.threads} torch threads")
    print(f"one drawing per NMS threshold: {ours_seconds:7.2f} s")
    print(f"every pair drawn (reference):  {reference_seconds:7.2f} s")
    print(f"ratio reference / ours: {reference_seconds / ours_seconds:.1f}x")
    print(f"count errors differing: {100 * differing:.3f} % of {errors.size}; largest mean-AP difference {ap_gap:.2e}")
    if differing > 0.01 or ap_gap > 1e-3:
        sys.exit(1)


if __name__ == "__main__":
    main()
