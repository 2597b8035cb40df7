"""Where a trained model's false plaques lie: on its held-out renders' scratches, or at the rim of the photos' wells.

A scrape, a stray scratch or a tear at the rim is a pale lesion in the stain, as a plaque is. This predicts every
held-out render of a training (the images its thresholds were tuned on) at a few probability thresholds (the NMS
threshold kept with the model) and sorts each predicted plaque: found (at least ``--overlap`` of its pixels on rendered
plaques) or false, and a false one on a scratch (at least ``--overlap`` of its pixels where a scratch took the stain
off, :func:`platesynth.render.raster.scratch_map`) or elsewhere. The last line says how much of the wells' area the
scratches cover, for scale.

With ``--photos`` it looks at the shared real plates instead (``../shared/data/plaque12``, or ``PLATESYNTH_SHARED``):
every plaque it predicts in a well a person counted 0 is false, and it is sorted by where it lies in its well
(:func:`place_in_well`): inside, or at the rim (beyond ``RIM`` of the well's radius) at the top of the image, at the
bottom (apart for the plate's last row, whose wells are seen past the plate's lower wall) or at a side. These are the
plaques a lower threshold adds on the photos; the renders teach what to leave out.

Run: ``python benchmarks/false_plaques.py --models DIR[,DIR...]`` (``--probs 0.15,0.3``: the kept probability is
always added; ``--nms N`` for every model instead of its kept one, to compare models at the same pair; ``--data D
--data D ...`` as in ``threshold_grid.py``; ``--renders DIR``: every render of a dataset instead, such as plaque-free
ones with smears; ``--photos``; ``--threads T``).
"""

from __future__ import annotations

import argparse
import os
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy import ndimage

from platesynth.render.result import plaque_wells

ROOT = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("PLATESYNTH_SHARED", ROOT.parent / "shared"))
SCRAPED = 0.05
"""A pixel is on a scratch where the scratch took off more than this share of the stain."""
RIM = 0.85
"""A plaque whose centre lies beyond this share of its well's radius from the well's centre is at the rim."""
PLACES = ("inside", "rim, top", "rim, bottom, last row", "rim, bottom, other rows", "rim, side")
"""Where :func:`place_in_well` puts a plaque: the top and the bottom are the image's, within 45 degrees."""


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


def place_in_well(wells: np.ndarray, plaques: np.ndarray, last_row: set[int] = frozenset()) -> list[str]:
    """Where each plaque lies in its well (one of :data:`PLACES`).

    Parameters
    ----------
    wells, plaques : (H, W) integer instance masks of the same image; a plaque's well is the one
        :func:`platesynth.render.result.plaque_wells` gives it, as the counts do, and plaques mostly outside every
        well are left out.
    last_row : ids of the wells in the plate's last row of the image (the bottom one).

    Returns
    -------
    list of str
        One place per plaque lying in a well, in the order of the plaque ids. The well's centre and radius are its
        mask's centroid and the radius of a disc of its area; a plaque's centre is its centroid.
    """
    places = []
    discs: dict[int, tuple[float, float, float]] = {}  # well id: centre row, centre column, radius
    well_of = plaque_wells(wells, plaques)
    for plaque, box in enumerate(ndimage.find_objects(plaques), start=1):
        well = well_of.get(plaque, 0)
        if well == 0:
            continue
        inside = plaques[box] == plaque
        if well not in discs:
            well_y, well_x = np.nonzero(wells == well)
            discs[well] = well_y.mean(), well_x.mean(), np.sqrt(well_y.size / np.pi)
        centre_y, centre_x, radius = discs[well]
        y, x = np.nonzero(inside)
        dy, dx = (y + box[0].start).mean() - centre_y, (x + box[1].start).mean() - centre_x
        if np.hypot(dy, dx) <= RIM * radius:
            places.append("inside")
        elif -dy >= abs(dx):
            places.append("rim, top")
        elif dy >= abs(dx):
            places.append("rim, bottom, last row" if well in last_row else "rim, bottom, other rows")
        else:
            places.append("rim, side")
    return places


def models_to_tally(args: argparse.Namespace) -> Iterator[tuple[Path, Any, float, list[float], float]]:
    """Each model of ``--models`` with what to tally it at: its folder, the model, its kept probability threshold, the
    probability thresholds (``--probs`` and the kept one) and the NMS threshold (``--nms``, else its kept one)."""
    import torch

    from platesynth.segment.model import load_model

    torch.set_num_threads(args.threads)
    for model_dir in (Path(m) for m in args.models.split(",")):
        model = load_model(model_dir)
        kept_prob, kept_nms = model.config.thresholds["plaques"]
        probs = sorted({*(float(p) for p in args.probs.split(",")), float(kept_prob)})
        yield model_dir, model, float(kept_prob), probs, kept_nms if args.nms is None else args.nms


def tally_photos(args: argparse.Namespace) -> None:
    """Print, per model and probability threshold, the plaques found in the photos' wells a person counted 0."""
    from platesynth.data.layout import read_counts_csv
    from platesynth.io import read_image
    from platesynth.segment.predict import predict_image

    plates, table = SHARED / "data" / "plaque12" / "plates", SHARED / "data" / "plaque12" / "counts.csv"
    if not table.is_file():
        raise SystemExit(f"{table} not found: set PLATESYNTH_SHARED to the shared material")
    empty: dict[str, set[tuple[int, int]]] = {}
    for record in read_counts_csv(table):
        if record.count == 0:
            empty.setdefault(record.image, set()).add((record.row, record.col))
    for model_dir, model, kept_prob, probs, kept_nms in models_to_tally(args):
        tallies = {p: Counter() for p in probs}
        n_wells = 0
        for name, cells in sorted(empty.items()):
            image = read_image(plates / name)
            for p in probs:
                result = predict_image(model, image, thresholds={"plaques": (p, kept_nms)})
                last = max(w.row for w in result.well_info)
                keep = [w.id for w in result.well_info if (w.row, w.col) in cells]
                wells = np.where(np.isin(result.wells, keep), result.wells, 0)
                tallies[p].update(place_in_well(wells, result.plaques, {w.id for w in result.well_info if w.row == last}))
            n_wells += len(keep)
        print(f"{model_dir} ({n_wells} photo wells counted 0, NMS {kept_nms}): false plaques per 100 wells")
        for p in probs:
            total = sum(tallies[p].values())
            mark = " (kept)" if p == kept_prob else ""
            where = ", ".join(f"{place} {100 * tallies[p][place] / max(n_wells, 1):.0f}" for place in PLACES)
            print(f"  prob {p:.2f}{mark}: {100 * total / max(n_wells, 1):.0f} ({where})")


def main(argv: list[str] | None = None) -> None:
    """Print each model's tally per probability threshold."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--models", required=True, help="finished trainings' folders, comma-separated")
    parser.add_argument("--data", action="append", default=[], help="the trainings' datasets, in order (optional)")
    parser.add_argument("--probs", default="0.15,0.3", help="probability thresholds besides the kept one")
    parser.add_argument("--nms", type=float, default=None, help="NMS threshold (default: each model's kept one)")
    parser.add_argument("--overlap", type=float, default=0.3)
    parser.add_argument("--photos", action="store_true", help="the shared photos' wells counted 0, not the renders")
    parser.add_argument("--renders", default=None, help="every render of this dataset instead of the held-out ones")
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args(argv)
    if args.photos:
        tally_photos(args)
        return

    from platesynth.data.layout import list_items, load_item
    from platesynth.segment.data import item_scratches
    from platesynth.segment.predict import predict_image
    from platesynth.segment.train import tuning_items

    for model_dir, model, kept_prob, probs, kept_nms in models_to_tally(args):
        tallies = {p: PlaqueTally() for p in probs}
        scratched_area = well_area = 0
        items = list_items(args.renders) if args.renders else tuning_items(model, model_dir, args.data)
        for item in items:
            image, wells, plaques = load_item(item)
            scraped = item_scratches(item, image.shape[:2]) > SCRAPED
            scratched_area += int((scraped & (wells > 0)).sum())
            well_area += int((wells > 0).sum())
            for p in probs:
                predicted = predict_image(model, image, thresholds={"plaques": (p, kept_nms)}).plaques
                tallies[p].add(sort_predicted(predicted, plaques, scraped, args.overlap))
        print(f"{model_dir} ({len(items)} {'renders of ' + args.renders if args.renders else 'held-out renders'}, "
              f"NMS {kept_nms}):")
        for p in probs:
            t = tallies[p]
            share = t.false_on_scratches / t.false if t.false else float("nan")
            mark = " (kept)" if p == kept_prob else ""
            print(f"  prob {p:.2f}{mark}: found {t.found}, false {t.false}, on scratches {t.false_on_scratches} "
                  f"({share:.0%})")
        print(f"  scratches cover {scratched_area / max(well_area, 1):.2%} of the wells' area")


if __name__ == "__main__":
    main()
