"""Plaques per well by image column: a preset's scenes against the person's counts of the shared real plates.

For each column of the 12-well image grid (photographed from below: column 3 holds the least diluted wells of the
shared plates) it prints the number of countable wells, the share of uncountable ones (lysed or emptied; blank in
the real table), the mean, median and largest count and the share of wells without plaques, and the share of
plates without any plaque. Scenes are sampled only (no rendering): counts are those of the scene's plaques.

Run: ``python benchmarks/count_distribution.py`` (``--preset P``, ``--plates N``, ``--split fit|check|all``).
"""

from __future__ import annotations

import argparse
import os
import statistics
from collections import defaultdict
from pathlib import Path

from shared_split import in_split

ROOT = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("PLATESYNTH_SHARED", ROOT.parent / "shared"))


def _summary(columns: dict[int, list[int | None]], plates: list[list[int | None]]) -> list[str]:
    lines = []
    for col in sorted(columns):
        values = columns[col]
        counted = [v for v in values if v is not None]
        lines.append(
            f"  col {col}: {len(counted):4d} countable, {100 * (len(values) - len(counted)) / len(values):5.1f} % uncountable, "
            f"mean {statistics.mean(counted):5.1f}, median {statistics.median(counted):4.1f}, max {max(counted):4d}, "
            f"{100 * sum(v == 0 for v in counted) / len(counted):5.1f} % without plaques"
        )
    empty = sum(all((v or 0) == 0 and v is not None for v in plate) for plate in plates)
    lines.append(f"  plates without any plaque: {empty} of {len(plates)} ({100 * empty / len(plates):.0f} %)")
    return lines


def main(argv: list[str] | None = None) -> None:
    """Print the two distributions."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--preset", default="high")
    parser.add_argument("--plates", type=int, default=200, help="sampled scenes")
    parser.add_argument("--split", choices=("all", "fit", "check"), default="all")
    args = parser.parse_args(argv)

    from platesynth.data.layout import read_counts_csv
    from platesynth.scene import load_config, sample_scene

    config = load_config(args.preset)
    columns: dict[int, list[int | None]] = defaultdict(list)
    plates = []
    for seed in range(args.plates):
        scene = sample_scene(config, seed)
        per_well: dict[int, int] = defaultdict(int)
        for plaque in scene.plaques:
            per_well[plaque.well] += 1
        plate = [per_well[w.id] if w.countable else None for w in scene.wells]
        for well, value in zip(scene.wells, plate):
            columns[well.col].append(value)
        plates.append(plate)
    print(f"preset {args.preset}, {args.plates} sampled plates")
    print("\n".join(_summary(columns, plates)))

    table = SHARED / "data" / "plaque12" / "counts.csv"
    if not table.is_file():
        print(f"{table} not found: no real counts to compare with")
        return
    real_columns: dict[int, list[int | None]] = defaultdict(list)
    real_plates: dict[str, list[int | None]] = defaultdict(list)
    for row in read_counts_csv(table):
        if in_split(row.image, args.split):
            real_columns[row.col].append(row.count)
            real_plates[row.image].append(row.count)
    print(f"real plates ({args.split}): {len(real_plates)}")
    print("\n".join(_summary(real_columns, list(real_plates.values()))))


if __name__ == "__main__":
    main()
