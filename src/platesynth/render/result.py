"""What every renderer returns: the image and its exact instance masks."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from platesynth.errors import ParameterError

MIN_SIDE, MAX_SIDE = 16, 16384


@dataclass(frozen=True)
class WellInfo:
    """One well of the plate as drawn in the image.

    ``id`` is its value in the well mask (1..n); ``row``/``col`` its 0-based position in the image grid
    from the top-left; ``label`` the plate's embossed name (e.g. ``"A1"``; mirrored when shot from below);
    ``countable`` whether a person would count its plaques (not where the layer is lysed, emptied or confluent).
    """

    id: int
    row: int
    col: int
    label: str
    countable: bool = True


@dataclass
class RenderResult:
    """A rendered scene.

    Attributes
    ----------
    image : (H, W, 3) uint8 RGB image.
    wells : (H, W) uint8 well instance mask: 0 background, 1..n wells.
    plaques : (H, W) uint16 plaque instance mask: 0 none, 1..m plaques (ids unique, hidden plaques absent).
    well_info : one :class:`WellInfo` per well id present in the plate.
    """

    image: np.ndarray
    wells: np.ndarray
    plaques: np.ndarray
    well_info: list[WellInfo] = field(default_factory=list)

    def plaque_counts(self) -> dict[int, int]:
        """Visible plaques per well id (a plaque belongs to the well holding most of its pixels)."""
        return plaque_counts(self.wells, self.plaques, [w.id for w in self.well_info])

    def well_counts(self, plaques: dict[int, int] | None = None) -> dict[int, int | None]:
        """Plaques per well id as a person reports them: ``None`` (a blank) for a well that is not countable.

        ``plaques``: :meth:`plaque_counts`, where the caller has it already.
        """
        counts = self.plaque_counts() if plaques is None else plaques
        return {w.id: counts[w.id] if w.countable else None for w in self.well_info}


def plaque_wells(wells: np.ndarray, plaques: np.ndarray) -> dict[int, int]:
    """The well each plaque belongs to: the one holding most of its pixels, or 0 where most lie outside every well.

    Parameters
    ----------
    wells, plaques : (H, W) integer instance masks of equal shape.

    Returns
    -------
    dict mapping each plaque id in ``plaques`` to a well id, or to 0 (outside every well, which also wins a tie).
    """
    inside = plaques > 0
    if not inside.any():
        return {}
    pairs = np.stack([plaques[inside].astype(np.int64), wells[inside].astype(np.int64)])
    (plaque_ids, well_of_pixel), n = np.unique(pairs, axis=1, return_counts=True)
    order = np.lexsort((-n, plaque_ids))  # per plaque, the well with the most pixels first (the lower id on a tie)
    plaque_ids, well_of_pixel = plaque_ids[order], well_of_pixel[order]
    first = np.r_[True, plaque_ids[1:] != plaque_ids[:-1]]
    return dict(zip(plaque_ids[first].tolist(), well_of_pixel[first].tolist()))


def plaque_counts(wells: np.ndarray, plaques: np.ndarray, well_ids: list[int] | None = None) -> dict[int, int]:
    """Count plaques per well from the two instance masks.

    Parameters
    ----------
    wells, plaques : (H, W) integer instance masks of equal shape.
    well_ids : wells to report (with 0 where they hold no plaque); default: the ids in ``wells``.

    Returns
    -------
    dict mapping well id to the number of plaque ids whose pixels lie mostly in that well (:func:`plaque_wells`).
    """
    if well_ids is None:
        well_ids = [int(i) for i in np.unique(wells) if i != 0]
    counts = {int(i): 0 for i in well_ids}
    for well in plaque_wells(wells, plaques).values():
        if well in counts:
            counts[well] += 1
    return counts


def check_size(size: tuple[int, int]) -> tuple[int, int]:
    """Validate an image size ``(width, height)`` for any renderer.

    Raises
    ------
    ParameterError
        If it is not two integers, each in [16, 16384] pixels.
    """
    try:
        width, height = (int(s) for s in size)
    except (TypeError, ValueError):
        raise ParameterError(f"size must be (width, height), got {size!r}") from None
    if not (MIN_SIDE <= width <= MAX_SIDE and MIN_SIDE <= height <= MAX_SIDE):
        raise ParameterError(
            f"size {width}x{height} is out of range: each side must be in [{MIN_SIDE}, {MAX_SIDE}] pixels"
        )
    return width, height

