"""The split of the shared real 12-well plates into a fit half and a check half, by virus.

The 39 photos of ``../shared/data/plaque12`` are the project's only real plates, so they are both the tuning set and
the test set. Looks and models are tuned on the **fit** viruses only (Brisbane, IBV: 16 plates); the **check**
virus (PR8: 23 plates) is only ever measured, as a stand-in for plates of other viruses and days.
"""

from __future__ import annotations

import shutil
from pathlib import Path

FIT_VIRUSES = ("Brisbane", "IBV")
CHECK_VIRUSES = ("PR8",)
SPLITS = {"fit": FIT_VIRUSES, "check": CHECK_VIRUSES, "all": FIT_VIRUSES + CHECK_VIRUSES}


def virus(name: str) -> str:
    """The virus of the photo ``name`` (e.g. ``PR8_plate3.jpg`` -> ``PR8``): its name up to the first ``_``."""
    return name.split("_")[0]


def in_split(name: str, split: str) -> bool:
    """Whether the photo ``name`` (e.g. ``PR8_plate3.jpg``) belongs to ``split`` ("fit", "check" or "all")."""
    return virus(name) in SPLITS[split]


def split_folder(source: Path, split: str, target: Path) -> Path:
    """Copy the photos of ``split`` from ``source`` into ``target`` (created); return ``target``."""
    target.mkdir(parents=True, exist_ok=True)
    for path in sorted(source.iterdir()):
        if path.is_file() and in_split(path.name, split):
            shutil.copy2(path, target / path.name)
    return target


def split_counts(source: Path, split: str, target: Path) -> Path:
    """Write the rows of the counts table ``source`` whose image belongs to ``split`` into ``target``."""
    lines = source.read_text().splitlines()
    kept = [lines[0]] + [line for line in lines[1:] if in_split(line.split(",")[0], split)]
    target.write_text("\n".join(kept) + "\n")
    return target
