"""The reference photos of an optimisation, split by plate into a fit part (the objective sees it) and a check
part (only the final report does).

Every photo is one plate. Photos whose names share the part before the first ``_`` (the virus in
``Brisbane_plate2.jpg``) form a group; each group is shuffled with a generator seeded by the run's seed and its
first ``round(check_fraction * n)`` photos go to the check part, so both parts hold every group in proportion.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from platesynth.errors import EmptyDatasetError, ParameterError
from platesynth.io import list_images

CHECK_FRACTION = 0.5
"""Default share of the photos (of each group) kept for the check part."""


@dataclass(frozen=True)
class Split:
    """The photos of each part, sorted by name."""

    fit: tuple[Path, ...]
    check: tuple[Path, ...]

    def to_dict(self) -> dict[str, list[str]]:
        """The photos' file names of each part (JSON)."""
        return {"fit": [p.name for p in self.fit], "check": [p.name for p in self.check]}


def group_of(path: Path) -> str:
    """The group of a photo: its name up to the first ``_`` (the whole stem without one)."""
    return path.stem.split("_")[0]


def split_reference(directory: str | os.PathLike, seed: int, check_fraction: float = CHECK_FRACTION) -> Split:
    """Split the photos of ``directory`` into fit and check parts, by plate, seeded (see the module docstring).

    Raises
    ------
    EmptyDatasetError
        For a missing folder or one without images.
    ParameterError
        If ``check_fraction`` is not in (0, 1), or a part would hold fewer than 2 photos.
    """
    if not 0 < check_fraction < 1:
        raise ParameterError(f"check fraction must be between 0 and 1, got {check_fraction:g}")
    paths = list_images(directory)
    groups: dict[str, list[Path]] = {}
    for path in sorted(paths, key=lambda p: p.name):
        groups.setdefault(group_of(path), []).append(path)
    rng = np.random.default_rng(seed)
    fit: list[Path] = []
    check: list[Path] = []
    for name in sorted(groups):
        members = groups[name]
        order = rng.permutation(len(members))
        n_check = int(np.floor(check_fraction * len(members) + 0.5))
        check += [members[i] for i in order[:n_check]]
        fit += [members[i] for i in order[n_check:]]
    if len(fit) < 2 or len(check) < 2:
        raise ParameterError(
            f"{directory}: {len(paths)} photos split into {len(fit)} to fit and {len(check)} to check; each part needs "
            "at least 2 (give more photos or another check fraction)"
        )
    return Split(tuple(sorted(fit, key=lambda p: p.name)), tuple(sorted(check, key=lambda p: p.name)))


def read_photos(paths: tuple[Path, ...]) -> list[np.ndarray]:
    """The photos as RGB uint8 arrays (read within the pixel and memory limits of :mod:`platesynth.io`)."""
    from platesynth.io import read_image, to_rgb_uint8

    if not paths:
        raise EmptyDatasetError("no reference photos")
    return [to_rgb_uint8(read_image(path)) for path in paths]
