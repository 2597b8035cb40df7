"""A trained model's count error on its own held-out renders over every plaque threshold pair.

A training tunes its thresholds on its held-out renders (:func:`platesynth.segment.train.choose_thresholds`). This
prints, for every probability x NMS pair of the plaque branch, the mean absolute error and the bias of plaques per
countable well on those renders, and the pair the rule keeps beside the pair with the smallest error; then, at a pair
(``--at``, default the kept one and the smallest-error one), the bias by the rendered count. That shows what the
choice trades: plaques found in sparse wells (a scrape, a tear at the rim) against plaques missed in crowded ones.

Run: ``python benchmarks/threshold_grid.py --model DIR`` (``--data D --data D ...``: the training's datasets in order,
where they are no longer where it read them, e.g. the shipped model's, rendered again by ``scripts/train_model.sh``;
``--at PROB,NMS``; ``--threads T``).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

RENDERED_COUNT_BINS = ((0, 1), (1, 5), (5, 20), (20, 50), (50, 10**6))
"""Ranges of the rendered count, ``[low, high)``, whose bias is printed apart."""


def grid_table(title: str, values: np.ndarray, probs: tuple[float, ...], nms: tuple[float, ...], fmt: str) -> str:
    """``values[i, j]`` as a table with one row per probability threshold and one column per NMS threshold."""
    lines = [f"{title}: rows probability, columns NMS", "prob " + "".join(f"{n:>8.2f}" for n in nms)]
    lines += [f"{p:4.2f} " + "".join(f"{v:{fmt}}" for v in row) for p, row in zip(probs, values, strict=True)]
    return "\n".join(lines)


def bias_by_rendered_count(errors: np.ndarray, true_counts: np.ndarray) -> str:
    """Mean predicted minus rendered plaques per well by the rendered count (:data:`RENDERED_COUNT_BINS`)."""
    parts = []
    for low, high in RENDERED_COUNT_BINS:
        inside = (true_counts >= low) & (true_counts < high)
        label = f"{low}+" if high == 10**6 else f"{low}-{high}"
        parts.append(f"{label}: {errors[inside].mean():+.2f} ({inside.sum()})" if inside.any() else f"{label}: -")
    return ", ".join(parts)


def main(argv: list[str] | None = None) -> None:
    """Print the grids and the bias by count at the chosen pairs."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", type=Path, required=True, help="a finished training's folder")
    parser.add_argument("--data", action="append", default=[], help="the training's datasets, in order (optional)")
    parser.add_argument("--at", default=None, metavar="PROB,NMS", help="also the bias by count at this pair")
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args(argv)

    import torch

    from platesynth.segment.model import load_model
    from platesynth.segment.train import choose_thresholds, threshold_scores, tuning_items

    torch.set_num_threads(args.threads)
    model = load_model(args.model)
    items = tuning_items(model, args.model, args.data)
    scores = threshold_scores(model, items)
    if not scores.count_errors.size:
        raise SystemExit(f"{args.model}: no countable well among its {len(items)} held-out renders")
    probs, nms = scores.prob_thresholds, scores.nms_thresholds
    mae, bias = np.abs(scores.count_errors).mean(axis=2), scores.count_errors.mean(axis=2)
    print(f"{args.model}: {scores.count_errors.shape[2]} countable wells of {len(items)} held-out renders")
    print(grid_table("mean absolute count error", mae, probs, nms, "8.2f"))
    print(grid_table("bias", bias, probs, nms, "+8.2f"))
    kept = choose_thresholds(scores)["plaques"]
    i, j = np.unravel_index(int(np.argmin(mae)), mae.shape)
    pairs = {"kept by the training's rule": kept, "smallest error": (probs[i], nms[j])}
    if args.at:
        pairs["asked for"] = tuple(float(t) for t in args.at.split(","))
    for name, (prob, nms_thresh) in pairs.items():
        if prob not in probs or nms_thresh not in nms:
            raise SystemExit(f"--at {prob},{nms_thresh}: not a candidate pair ({probs}; {nms})")
        a, b = probs.index(prob), nms.index(nms_thresh)
        print(f"{name} {prob:g}/{nms_thresh:g}: MAE {mae[a, b]:.2f}, bias {bias[a, b]:+.2f}; by the rendered count: "
              f"{bias_by_rendered_count(scores.count_errors[a, b], scores.true_counts)}")


if __name__ == "__main__":
    main()
