"""Object-level realism metrics on well crops: whole-image Fréchet distances barely see plaques.

Every well of a plate image is cut out as a square around its disc, resized to one size (128x128 by default) and
measured, so that a synthetic and a real set of wells can be compared well by well instead of plate by plate:

* deep features of the crops: Fréchet distance and KID of AlexNet features (``fd_wells``, ``kid_wells``, with
  :mod:`platesynth.metrics.frechet`), and how often a crop's nearest neighbour in that space is of its own set
  (``nn_accuracy_wells``: 0.5 when real and synthetic wells cannot be told apart);
* naturalness of the crops: mean Nf and ``dnf_wells`` (:func:`platesynth.metrics.naturalness.naturalness_factor`);
* texture of the monolayer: the radially averaged power spectrum inside the well disc, plaques left out where a
  plaque mask exists, and the RMS difference of the two sets' mean log-spectra (``spectrum_distance_wells``); the
  same with plaques kept in both sets (``spectrum_distance_wells_with_plaques``), like for like against photos
  without masks;
* plaques: their areas (share of the well's area, and mm² where the well's radius is known) and contrasts (Weber
  contrast of the plaque against the monolayer around it), measured from plaque masks only. A set of photos without
  masks has no plaque figures (``None``): they are not guessed.

Where the wells are
-------------------
* Datasets written by platesynth (``images/``, ``masks/wells/``, ``masks/plaques/``, ``params/``): from the true
  well mask. Each well's crop is the square bounding box of its mask (centre and side of the bounding box, side
  = the larger of its height and width). Wells cut by the image border are left out.
* Photos without masks: :func:`fit_plate_grid` fits a regular grid of discs (3 rows x 4 columns by default, the
  12-well plate) to the stained wells; each crop is the square around a fitted disc.
* Photos with a trained model: the model's predicted well masks, handled like true masks (optional).

The crop keeps every pixel of the square: the corners show the well's wall and the plate around it, in both sets.

Public API
----------
WellDisc(cy, cx, radius, id)
    One well disc in image pixels.
wells_from_mask(wells) -> list of WellDisc
fit_plate_grid(image, grid=(3, 4)) -> list of WellDisc
crop_well(image, disc, size=128) -> (size, size, 3) uint8
crop_mask(mask, disc, size=128) -> (size, size) bool
radial_power_spectrum(image, exclude=None, radius=0.9, taper=0.25) -> (frequencies, power)
plaque_measurements(image, wells, plaques) -> dict of arrays
WellCrops(size=128, extractor=None, grid=(3, 4))
    Streaming state of one set of wells: ``update(image, wells=None, plaques=None)``, ``compute()``.
compare_well_crops(synthetic, reference) -> dict
collect_well_crops(path, ...) -> WellCrops
well_metrics(directory, reference, ...) -> dict
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from PIL import Image
from scipy import ndimage
from scipy.signal import fftconvolve
from scipy.stats import wasserstein_distance

from platesynth.errors import DatasetError, MetricUndefinedError, ParameterError, PlatesynthError, ShapeMismatchError
from platesynth.io import list_images, read_image, to_rgb_uint8
from platesynth.limits import check_well_crops
from platesynth.metrics.diversity import grayscale
from platesynth.metrics.naturalness import naturalness_factor
from platesynth.metrics.pair import ProgressCallback

__all__ = [
    "WellCrops",
    "WellDisc",
    "collect_well_crops",
    "compare_well_crops",
    "crop_mask",
    "crop_well",
    "find_dataset_root",
    "fit_plate_grid",
    "plaque_measurements",
    "radial_power_spectrum",
    "well_metrics",
    "wells_from_mask",
]

CROP_SIZE = 128
"""Side of the resized well crops, pixels."""
SPECTRUM_RADIUS = 0.9
"""Radius of the disc whose power spectrum is taken, as a fraction of the crop's half side (the well's radius)."""
SPECTRUM_TAPER = 0.25
"""Outer fraction of that radius over which the spectrum's window falls from 1 to 0 (raised cosine)."""
SPECTRUM_FLOOR = 1.0 / 12.0
"""Power (gray levels²) below the 8-bit quantisation noise, the power of rounding to integers, is raised to it before
the logarithm: a perfectly flat crop counts as quantisation noise instead of minus infinity."""
_GRID_LONG_SIDE = 200
"""Long side (pixels) of the image the grid is searched on; the search is then refined at 3x this size."""
_GRID_RATIOS = (0.33, 0.475)
"""Well radius / well pitch ratios tried (the 12-well plate's is 11.05 / 26.01 = 0.425; 6-well 0.45, 96-well 0.35)."""
_GRID_SMALLEST = 0.3
"""Smallest pitch tried, as a fraction of the largest grid that fits the image."""
_RING = 1.25
"""The grid's disc detector compares a disc with the ring from its radius out to this many radii."""


class WellDisc(NamedTuple):
    """One well in image pixel coordinates: centre ``(cy, cx)``, ``radius``, and its id (mask value, or grid order)."""

    cy: float
    cx: float
    radius: float
    id: int = 0


# --------------------------------------------------------------------------------------------- where the wells are


def wells_from_mask(wells: np.ndarray, *, keep_cut: bool = False) -> list[WellDisc]:
    """The well discs of a well instance mask, from each id's bounding box.

    Parameters
    ----------
    wells : numpy.ndarray
        ``(H, W)`` integer instance mask, 0 background.
    keep_cut : bool
        Keep wells whose bounding box touches the image border (cut by the frame); left out by default.

    Returns
    -------
    list of WellDisc
        In id order: centre of the bounding box, ``radius`` = half the larger side of the box.
    """
    wells = np.asarray(wells)
    if wells.ndim != 2 or not np.issubdtype(wells.dtype, np.integer):
        raise ShapeMismatchError(f"expected a 2-D integer well mask, got {wells.dtype} {wells.shape}")
    height, width = wells.shape
    discs = []
    for index, box in enumerate(ndimage.find_objects(wells), start=1):
        if box is None:
            continue
        rows, cols = box
        cut = rows.start == 0 or cols.start == 0 or rows.stop == height or cols.stop == width
        if cut and not keep_cut:
            continue
        side = max(rows.stop - rows.start, cols.stop - cols.start)
        discs.append(WellDisc((rows.start + rows.stop - 1) / 2, (cols.start + cols.stop - 1) / 2, side / 2, index))
    return discs


def _stain_map(image: np.ndarray) -> np.ndarray:
    """Where the stain is: chroma ``max(R, G, B) - min(R, G, B)``; darkness ``255 - gray`` for gray images.

    Chroma is high on stained (coloured) monolayers and low on white plastic, a light box, and black or gray
    surroundings (rulers, desks), so it picks the wells out better than brightness.
    """
    rgb = to_rgb_uint8(np.asarray(image)).astype(np.float32)
    chroma = rgb.max(axis=-1) - rgb.min(axis=-1)
    if np.percentile(chroma, 99) < 10:  # no colour: a grayscale photo
        return 255.0 - rgb.mean(axis=-1)
    return chroma


def _disc_detector(radius: float) -> np.ndarray:
    """Kernel: mean over a disc minus mean over the ring around it (zero sum)."""
    half = int(np.ceil(radius * _RING)) + 1
    y, x = np.mgrid[-half : half + 1, -half : half + 1]
    distance = np.hypot(y, x)
    inner, ring = distance <= radius, (distance > radius) & (distance <= radius * _RING)
    return inner / inner.sum() - ring / ring.sum()


def _lattice(grid: tuple[int, int], pitch: tuple[float, float], angle: float = 0.0) -> np.ndarray:
    """``(rows * cols, 2)`` offsets (dy, dx) of each well's centre from the first one's, row by row."""
    rows, cols = grid
    i, j = np.divmod(np.arange(rows * cols), cols)
    cos, sin = np.cos(angle), np.sin(angle)
    dy, dx = i * pitch[0], j * pitch[1]
    return np.stack([cos * dy + sin * dx, cos * dx - sin * dy], axis=1)


def _best_origin(
    response: np.ndarray, offsets: np.ndarray, window: tuple[int, int, int, int] | None = None
) -> tuple[float, int, int]:
    """Best summed response of discs at ``origin + offsets``: ``(score, y0, x0)`` of the first well's centre.

    ``window`` = ``(y_min, y_max, x_min, x_max)`` (inclusive) limits the origins tried; offsets are rounded to pixels.
    """
    height, width = response.shape
    shifts = np.rint(offsets).astype(int)
    y_min, x_min = -shifts[:, 0].min(), -shifts[:, 1].min()  # origins keeping every centre inside the image
    y_max, x_max = height - 1 - shifts[:, 0].max(), width - 1 - shifts[:, 1].max()
    if window is not None:
        y_min, y_max = max(y_min, window[0]), min(y_max, window[1])
        x_min, x_max = max(x_min, window[2]), min(x_max, window[3])
    if y_min > y_max or x_min > x_max:
        return -np.inf, 0, 0
    total = np.zeros((y_max - y_min + 1, x_max - x_min + 1))
    for dy, dx in shifts:
        total += response[y_min + dy : y_max + dy + 1, x_min + dx : x_max + dx + 1]
    y, x = np.unravel_index(int(np.argmax(total)), total.shape)
    return float(total[y, x]), int(y + y_min), int(x + x_min)


def _downsized(stain: np.ndarray, long_side: int) -> tuple[np.ndarray, float]:
    scale = min(1.0, long_side / max(stain.shape))
    size = (max(1, round(stain.shape[1] * scale)), max(1, round(stain.shape[0] * scale)))
    small = np.asarray(Image.fromarray(stain.astype(np.float32)).resize(size, Image.Resampling.BOX))
    return small, scale


def _coarse_grid(stain: np.ndarray, grid: tuple[int, int]) -> tuple[float, float, int, int]:
    """Every pitch (1.5% steps), radius/pitch ratio and origin, no rotation: ``(pitch, radius, y0, x0)``."""
    rows, cols = grid
    largest = min(stain.shape[1] / cols, stain.shape[0] / rows)
    pitches = largest * np.exp(np.arange(np.log(_GRID_SMALLEST), 0.0, 0.015))
    radii = np.exp(np.arange(np.log(_GRID_RATIOS[0] * pitches[0]), np.log(_GRID_RATIOS[-1] * largest), 0.03))
    radii = radii[radii >= 1.5]
    best = (-np.inf, 0.0, 0.0, 0, 0)
    for radius in radii:
        response = fftconvolve(stain, _disc_detector(radius), mode="same")
        for pitch in pitches[(radius >= _GRID_RATIOS[0] * pitches) & (radius <= _GRID_RATIOS[-1] * pitches)]:
            score, y0, x0 = _best_origin(response, _lattice(grid, (pitch, pitch)))
            if score > best[0]:
                best = (score, pitch, radius, y0, x0)
    if best[1] == 0.0:
        raise MetricUndefinedError(
            f"image of {stain.shape[1]}x{stain.shape[0]} px (shrunk) is too small for a {rows}x{cols} grid"
        )
    return best[1:]


def fit_plate_grid(image: np.ndarray, grid: tuple[int, int] = (3, 4)) -> list[WellDisc]:
    """Find the wells of a photo of a plate without masks by fitting a regular grid of discs to its stain.

    The stained wells are the most coloured discs of a plate photo (chroma ``max(R, G, B) - min(R, G, B)``, or
    darkness for a gray photo: high on stain, low on white plastic, a light box, and black or gray surroundings). A
    disc detector (mean stain inside a disc minus the mean in the ring out to 1.25 radii) is correlated with that
    map; the grid is the ``rows x cols`` lattice of equal discs with the largest summed response. Because all wells
    are scored together, pale wells (lysed or clear) are placed by their neighbours.

    The search runs on the image shrunk to a long side of 200 px over pitches from 30% to 100% of the largest
    that fits (1.5% steps), radius/pitch ratios from 0.33 to 0.475 and every origin, then is refined at 600 px:
    row and column pitch separately (within 2%), the radius (within 6%), a rotation (within 2 degrees) and the
    origin (within 2 coarse pixels).

    Parameters
    ----------
    image : numpy.ndarray
        ``(H, W)`` or ``(H, W, 3|4)`` uint8 or uint16 photo of a plate, which should fill at least a third of the
        frame's width or height.
    grid : (int, int)
        ``(rows, cols)`` of the plate as seen in the image; swapped for a portrait image when ``rows < cols``.

    Returns
    -------
    list of WellDisc
        Row by row from the top left, ids 1..rows*cols. A disc may reach past the image border by the fit's error;
        :func:`crop_well` pads it.

    Raises
    ------
    MetricUndefinedError
        If the image is too small for the grid.
    """
    rows, cols = grid
    if rows < 1 or cols < 1:
        raise ParameterError(f"grid must have at least one row and column, got {grid}")
    stain = _stain_map(image)
    if stain.shape[0] > stain.shape[1] and rows < cols:
        rows, cols = cols, rows
    small, scale = _downsized(stain, _GRID_LONG_SIDE)
    pitch, radius, y0, x0 = _coarse_grid(small, (rows, cols))
    fine, fine_scale = _downsized(stain, 3 * _GRID_LONG_SIDE)
    factor = fine_scale / scale
    pitch, radius, y0, x0 = pitch * factor, radius * factor, round(y0 * factor), round(x0 * factor)
    reach = int(np.ceil(2 * factor))
    window = (y0 - reach, y0 + reach, x0 - reach, x0 + reach)
    best = (-np.inf, (pitch, pitch), 0.0, radius, y0, x0)
    steps = np.linspace(-1.0, 1.0, 5)
    for fine_radius in radius * (1 + 0.06 * steps):
        response = fftconvolve(fine, _disc_detector(fine_radius), mode="same")
        for angle in np.deg2rad(2.0 * np.linspace(-1.0, 1.0, 9)):
            for pitch_y in pitch * (1 + 0.02 * steps):
                for pitch_x in pitch * (1 + 0.02 * steps):
                    offsets = _lattice((rows, cols), (pitch_y, pitch_x), angle)
                    score, oy, ox = _best_origin(response, offsets, window)
                    if score > best[0]:
                        best = (score, (pitch_y, pitch_x), angle, fine_radius, oy, ox)
    _, pitches, angle, radius, oy, ox = best
    centres = np.array([oy, ox]) + _lattice((rows, cols), pitches, angle)
    centres = (centres + 0.5) / fine_scale - 0.5  # fine-image pixel centres -> image pixel centres
    return [WellDisc(float(cy), float(cx), radius / fine_scale, index) for index, (cy, cx) in enumerate(centres, 1)]


# ------------------------------------------------------------------------------------------------------- cropping


def _square(array: np.ndarray, disc: WellDisc, mode: str) -> np.ndarray:
    """The square of side ``round(2 * radius)`` centred on the disc; parts outside the image padded (``mode``)."""
    side = max(1, round(2 * disc.radius))
    top, left = math.ceil(disc.cy - side / 2), math.ceil(disc.cx - side / 2)  # a bounding box's own start
    height, width = array.shape[:2]
    pads = (max(0, -top), max(0, top + side - height)), (max(0, -left), max(0, left + side - width))
    window = array[max(0, top) : top + side, max(0, left) : left + side]
    if window.size == 0:
        raise ParameterError(f"well at ({disc.cy:.0f}, {disc.cx:.0f}) lies outside the {width}x{height} image")
    if any(any(pad) for pad in pads):
        window = np.pad(window, pads + ((0, 0),) * (array.ndim - 2), mode=mode)
    return window


def crop_well(image: np.ndarray, disc: WellDisc, size: int = CROP_SIZE) -> np.ndarray:
    """The square around a well disc, resized to ``size`` x ``size``.

    Parameters
    ----------
    image : numpy.ndarray
        ``(H, W)`` or ``(H, W, 3|4)`` uint8 or uint16 image (brought to RGB uint8 first).
    disc : WellDisc
        The well: the crop is the square of side ``round(2 * radius)`` centred on it (for a disc from
        :func:`wells_from_mask`, the square bounding box of the well). Parts outside the image repeat the edge.
    size : int
        Side of the result (Pillow Lanczos).

    Returns
    -------
    numpy.ndarray
        ``(size, size, 3)`` uint8.
    """
    square = _square(to_rgb_uint8(np.asarray(image)), disc, "edge")
    return np.asarray(Image.fromarray(np.ascontiguousarray(square)).resize((size, size), Image.Resampling.LANCZOS))


def crop_mask(mask: np.ndarray, disc: WellDisc, size: int = CROP_SIZE) -> np.ndarray:
    """Where ``mask`` is non-zero in the same square as :func:`crop_well` (nearest neighbour), ``(size, size)`` bool."""
    square = _square((np.asarray(mask) != 0).astype(np.uint8), disc, "constant")
    return np.asarray(Image.fromarray(square).resize((size, size), Image.Resampling.NEAREST)) != 0


# ----------------------------------------------------------------------------------------------- power spectrum


def spectrum_window(size: int, radius: float = SPECTRUM_RADIUS, taper: float = SPECTRUM_TAPER) -> np.ndarray:
    """Centred disc window of a ``size`` x ``size`` crop: 1 inside, raised-cosine fall-off over its outer ``taper``.

    The disc's radius is ``radius * size / 2`` (a fraction of the well's radius for a well crop).
    """
    if not 0 < radius <= 1.5 or not 0 <= taper < 1:
        raise ParameterError(f"spectrum window needs 0 < radius <= 1.5 and 0 <= taper < 1, got {radius}, {taper}")
    centre = (size - 1) / 2
    y, x = np.mgrid[0:size, 0:size]
    rho = np.hypot(y - centre, x - centre) / (radius * size / 2)  # 1 at the disc's edge
    start = 1.0 - taper
    fall = np.clip((rho - start) / max(taper, 1e-12), 0.0, 1.0)
    return np.where(rho <= 1.0, 0.5 * (1 + np.cos(np.pi * fall)), 0.0)


def radial_power_spectrum(
    image: np.ndarray,
    exclude: np.ndarray | None = None,
    *,
    radius: float = SPECTRUM_RADIUS,
    taper: float = SPECTRUM_TAPER,
) -> tuple[np.ndarray, np.ndarray]:
    """Radially averaged power spectrum of a square image inside a centred disc.

    The gray values (float input as is; uint8/uint16 and colour images through :func:`~platesynth.metrics.grayscale`)
    are weighted by :func:`spectrum_window` times ``~exclude``, their weighted mean is removed inside the window,
    and the 2-D periodogram ``|FFT(w (g - mean))|^2 / sum(w^2)`` is averaged over rings of integer frequency.
    With this normalisation white noise of variance s² has the flat spectrum s² whatever the window.

    Parameters
    ----------
    image : numpy.ndarray
        ``(N, N)`` gray (any real dtype) or ``(N, N, 3|4)`` uint8/uint16 image.
    exclude : numpy.ndarray, optional
        ``(N, N)`` bool: pixels left out (e.g. plaques).
    radius, taper : float
        The window's disc radius (fraction of ``N / 2``) and the outer fraction over which it falls to 0.

    Returns
    -------
    frequencies : numpy.ndarray
        ``1 .. N // 2``: cycles per image side (per well diameter for a well crop); ring ``k`` holds the
        frequencies ``k - 0.5 <= |f| < k + 0.5``.
    power : numpy.ndarray
        Mean power in each ring, in (gray level)² (gray levels 0..255 for 8-bit images).

    Raises
    ------
    ShapeMismatchError
        If the image is not square or ``exclude`` does not match it.
    MetricUndefinedError
        If nothing is left inside the window.
    """
    image = np.asarray(image)
    if image.ndim == 3 or image.dtype in (np.uint8, np.uint16):
        gray = grayscale(image).astype(np.float64)
    else:
        gray = image.astype(np.float64)
    if gray.ndim != 2 or gray.shape[0] != gray.shape[1]:
        raise ShapeMismatchError(f"power spectrum needs a square (N, N) image, got shape {image.shape}")
    size = gray.shape[0]
    window = spectrum_window(size, radius, taper)
    if exclude is not None:
        exclude = np.asarray(exclude, dtype=bool)
        if exclude.shape != gray.shape:
            raise ShapeMismatchError(f"exclude mask has shape {exclude.shape}, image {gray.shape}")
        window = window * ~exclude
    weight = float(np.sum(window**2))
    if weight == 0.0:
        raise MetricUndefinedError("power spectrum undefined: no pixel left inside the window")
    mean = float(np.sum(window * gray) / np.sum(window))
    periodogram = np.abs(np.fft.fft2(window * (gray - mean))) ** 2 / weight
    frequency = np.fft.fftfreq(size) * size
    ring = np.rint(np.hypot(*np.meshgrid(frequency, frequency, indexing="ij"))).astype(int)
    n_rings = size // 2
    inside = (ring >= 1) & (ring <= n_rings)
    sums = np.bincount(ring[inside], weights=periodogram[inside], minlength=n_rings + 1)[1:]
    counts = np.bincount(ring[inside], minlength=n_rings + 1)[1:]
    return np.arange(1, n_rings + 1, dtype=np.float64), sums / counts


# ------------------------------------------------------------------------------------------------------- plaques


def plaque_measurements(
    image: np.ndarray, wells: np.ndarray, plaques: np.ndarray, well_radius_mm: float | None = None
) -> dict[str, np.ndarray]:
    """Area and contrast of every plaque of an image, from its well and plaque instance masks.

    A plaque belongs to the well holding most of its pixels (plaques mostly outside every well are left out).
    Its **area** is its pixel count; its **area fraction** that count over its well's pixel count. Its
    **contrast** is the Weber contrast ``(I_plaque - I_ring) / I_ring`` of the mean gray level
    (:func:`~platesynth.metrics.grayscale`) of its pixels against the monolayer around it: the pixels of the same
    well within ``max(2, r / 2)`` px of the plaque (``r = sqrt(area / pi)``, its equivalent radius) that belong to no
    plaque. Plaques are lighter than the stained monolayer, so contrasts are positive, up to about 1 or more on
    dark stain. A plaque with no monolayer around it (e.g. inside a cluster) has no contrast (NaN).

    Parameters
    ----------
    image : numpy.ndarray
        ``(H, W)`` or ``(H, W, 3|4)`` uint8 or uint16 image.
    wells, plaques : numpy.ndarray
        ``(H, W)`` integer instance masks (0 background).
    well_radius_mm : float, optional
        Radius of a well's bottom in mm (platesynth's ``plate.well_radius_mm``); gives ``area_mm2``.

    Returns
    -------
    dict of numpy.ndarray
        One entry per plaque, in plaque-id order: ``well`` (id), ``area_px``, ``area_fraction``, ``contrast``
        (NaN where undefined) and, with ``well_radius_mm``, ``area_mm2 = area_fraction * pi * well_radius_mm**2``.
    """
    gray = grayscale(np.asarray(image)).astype(np.float64)
    wells, plaques = np.asarray(wells), np.asarray(plaques)
    if wells.shape != gray.shape or plaques.shape != gray.shape:
        raise ShapeMismatchError(f"image {gray.shape}, well mask {wells.shape} and plaque mask {plaques.shape} differ")
    well_area = np.bincount(wells.ravel().astype(np.int64))
    records: dict[str, list[float]] = {"well": [], "area_px": [], "area_fraction": [], "contrast": []}
    height, width = gray.shape
    for index, box in enumerate(ndimage.find_objects(plaques), start=1):
        if box is None:
            continue
        inside_box = plaques[box] == index
        well_ids, counts = np.unique(wells[box][inside_box], return_counts=True)
        well = int(well_ids[np.argmax(counts)])
        if well == 0:
            continue
        area = int(inside_box.sum())
        reach = max(2.0, 0.5 * np.sqrt(area / np.pi))
        pad = int(np.ceil(reach)) + 1
        rows = slice(max(0, box[0].start - pad), min(height, box[0].stop + pad))
        cols = slice(max(0, box[1].start - pad), min(width, box[1].stop + pad))
        plaque = plaques[rows, cols] == index
        distance = ndimage.distance_transform_edt(~plaque)
        ring = (distance > 0) & (distance <= reach) & (plaques[rows, cols] == 0) & (wells[rows, cols] == well)
        patch = gray[rows, cols]
        surround = float(patch[ring].mean()) if ring.any() else 0.0
        contrast = (float(patch[plaque].mean()) - surround) / surround if surround > 0 else np.nan
        records["well"].append(well)
        records["area_px"].append(area)
        records["area_fraction"].append(area / well_area[well])
        records["contrast"].append(contrast)
    result = {
        "well": np.asarray(records["well"], dtype=np.int64),
        "area_px": np.asarray(records["area_px"], dtype=np.int64),
        "area_fraction": np.asarray(records["area_fraction"], dtype=np.float64),
        "contrast": np.asarray(records["contrast"], dtype=np.float64),
    }
    if well_radius_mm is not None:
        result["area_mm2"] = result["area_fraction"] * np.pi * float(well_radius_mm) ** 2
    return result


# ------------------------------------------------------------------------------------------------ a set of wells


def _summary(values: list[np.ndarray] | None) -> tuple[np.ndarray | None, float | None, float | None]:
    """All values (finite only), their median and mean; None where not measured or empty."""
    if values is None:
        return None, None, None
    joined = np.concatenate(values) if values else np.empty(0)
    joined = joined[np.isfinite(joined)]
    if joined.size == 0:
        return joined, None, None
    return joined, float(np.median(joined)), float(np.mean(joined))


class WellCrops:
    """Streaming state of one set of well crops: features, naturalness, log power spectra, plaque measurements.

    Parameters
    ----------
    size : int
        Side of the crops, pixels.
    extractor : FeatureExtractor, optional
        For ``fd_wells`` / ``kid_wells`` (e.g. ``get_feature_extractor("alexnet")``); None: no deep features.
    grid : (int, int)
        ``(rows, cols)`` fitted by :func:`fit_plate_grid` to images given without a well mask.

    Examples
    --------
    >>> crops = WellCrops(extractor=get_feature_extractor("alexnet"))  # doctest: +SKIP
    >>> crops.update(image, wells, plaques)  # a synthetic plate: true masks  # doctest: +SKIP
    >>> crops.update(photo)                  # a photo: grid-fitted wells, no plaque figures  # doctest: +SKIP
    >>> crops.compute()["nf_wells"]  # doctest: +SKIP
    """

    def __init__(
        self,
        size: int = CROP_SIZE,
        extractor: Any | None = None,
        grid: tuple[int, int] = (3, 4),
    ) -> None:
        if size < 31 and extractor is not None:
            raise ParameterError(f"well crops of {size} px are too small for deep features (at least 31)")
        check_well_crops(size, grid[0] * grid[1])
        self.size = size
        self.extractor = extractor
        self.grid = grid
        self.reset()

    def reset(self) -> None:
        """Forget every crop seen."""
        self.statistics = None
        if self.extractor is not None:
            from platesynth.metrics.frechet import FeatureStatistics

            self.statistics = FeatureStatistics(self.extractor)
        self.count = 0
        self.plates: list[int] = []  # per crop: which update (plate image) it came from
        self.nf: list[float] = []
        self.log_spectra: list[np.ndarray] = []  # per crop: plaques left out where a plaque mask is given
        self.log_spectra_with_plaques: list[np.ndarray] = []  # per crop: every pixel of the window
        self.plaques: dict[str, list[np.ndarray]] | None = None  # None until an image with a plaque mask is seen
        self.sources: set[str] = set()

    def update(
        self,
        image: np.ndarray,
        wells: np.ndarray | None = None,
        plaques: np.ndarray | None = None,
        *,
        well_radius_mm: float | None = None,
        source: str | None = None,
    ) -> list[WellDisc]:
        """Add the wells of one plate image.

        Parameters
        ----------
        image : numpy.ndarray
            ``(H, W)`` or ``(H, W, 3|4)`` uint8 or uint16 image.
        wells : numpy.ndarray, optional
            Well instance mask; without it the wells come from :func:`fit_plate_grid`.
        plaques : numpy.ndarray, optional
            Plaque instance mask (needs ``wells``): plaque areas and contrasts, and plaques left out of the spectrum.
        well_radius_mm : float, optional
            The well's radius in mm, for plaque areas in mm².
        source : str, optional
            Where the wells came from (``"masks"``, ``"model"``, ``"grid"``); by default ``"masks"`` with a well
            mask and ``"grid"`` without.

        Returns
        -------
        list of WellDisc
            The wells added.
        """
        image = to_rgb_uint8(np.asarray(image))
        if plaques is not None and wells is None:
            raise ParameterError("a plaque mask needs the well mask too (plaques are measured against their well)")
        discs = wells_from_mask(wells) if wells is not None else fit_plate_grid(image, self.grid)
        self.sources.add(source or ("masks" if wells is not None else "grid"))
        crops = []
        for disc in discs:
            crop = crop_well(image, disc, self.size)
            _, power_all = radial_power_spectrum(crop)
            power = power_all
            if plaques is not None:  # plaques (dilated by 1 px) out of the window
                _, power = radial_power_spectrum(crop, ndimage.binary_dilation(crop_mask(plaques, disc, self.size)))
            self.log_spectra.append(np.log10(np.maximum(power, SPECTRUM_FLOOR)))
            self.log_spectra_with_plaques.append(np.log10(np.maximum(power_all, SPECTRUM_FLOOR)))
            self.nf.append(naturalness_factor(crop))
            crops.append(crop)
        if self.statistics is not None and crops:
            self.statistics.update(crops)
        self.plates.extend([self.plates[-1] + 1 if self.plates else 0] * len(crops))
        self.count += len(crops)
        if plaques is not None:
            measured = plaque_measurements(image, wells, plaques, well_radius_mm)
            kept = np.isin(measured["well"], [disc.id for disc in discs])  # plaques of the wells cropped
            if self.plaques is None:
                self.plaques = {"area_fraction": [], "area_mm2": [], "contrast": []}
            for key in self.plaques:
                if key in measured:
                    self.plaques[key].append(measured[key][kept])
        return discs

    def compute(self) -> dict[str, Any]:
        """The set's own figures.

        Returns
        -------
        dict
            ``n_wells``, ``nf_wells`` (mean Nf of the crops), ``spectrum_frequencies`` (cycles per well diameter),
            ``spectrum_wells`` (mean over crops of log10 power, each crop's power raised to at least
            :data:`SPECTRUM_FLOOR`; plaques left out where a plaque mask was given), ``spectrum_wells_with_plaques``
            (the same with plaques kept), ``wells_from`` (how wells were found), and the
            plaque figures ``n_plaques``, ``plaque_area_fraction_median``, ``plaque_area_fraction_mean``,
            ``plaque_area_mm2_median``, ``plaque_contrast_median``, ``plaque_contrast_mean``: None where no plaque
            mask was given (or no plaque / no well radius was found).

        Raises
        ------
        MetricUndefinedError
            If no well was added.
        """
        if self.count == 0:
            raise MetricUndefinedError("no well crops")
        plaques = self.plaques or {}
        fractions, fraction_median, fraction_mean = _summary(plaques.get("area_fraction"))
        _, mm2_median, _ = _summary(plaques.get("area_mm2"))
        _, contrast_median, contrast_mean = _summary(plaques.get("contrast"))
        return {
            "n_wells": self.count,
            "nf_wells": float(np.mean(self.nf)),
            "spectrum_frequencies": np.arange(1, self.size // 2 + 1, dtype=np.float64).tolist(),
            "spectrum_wells": np.mean(self.log_spectra, axis=0).tolist(),
            "spectrum_wells_with_plaques": np.mean(self.log_spectra_with_plaques, axis=0).tolist(),
            "wells_from": ",".join(sorted(self.sources)),
            "n_plaques": None if fractions is None else int(fractions.size),
            "plaque_area_fraction_median": fraction_median,
            "plaque_area_fraction_mean": fraction_mean,
            "plaque_area_mm2_median": mm2_median,
            "plaque_contrast_median": contrast_median,
            "plaque_contrast_mean": contrast_mean,
        }

    def plaque_values(self, key: str) -> np.ndarray | None:
        """All finite plaque values of ``"area_fraction"``, ``"area_mm2"`` or ``"contrast"``; None if not measured."""
        if self.plaques is None:
            return None
        return _summary(self.plaques[key])[0]


def spectrum_distance(log_spectrum_a: np.ndarray, log_spectrum_b: np.ndarray) -> float:
    """RMS over frequency rings of the difference of two mean log10 power spectra (decades; 0 = same texture)."""
    a, b = np.asarray(log_spectrum_a, dtype=np.float64), np.asarray(log_spectrum_b, dtype=np.float64)
    if a.shape != b.shape:
        raise ShapeMismatchError(f"spectra have {a.shape} and {b.shape} rings (crops of different sizes?)")
    return float(np.sqrt(np.mean((a - b) ** 2)))


def plaque_area_distance(area_fractions_a: np.ndarray, area_fractions_b: np.ndarray) -> float:
    """Wasserstein-1 distance between two samples of plaque area fractions, on a log10 scale (decades).

    0 for the same distribution; 0.3 where one set's plaques are (all) twice the other's area. Sizes span decades,
    so the log scale weighs a small plaque's misfit like a large one's.

    Raises
    ------
    MetricUndefinedError
        If either sample is empty, or holds a fraction that is not positive and finite.
    """
    samples = [np.asarray(values, dtype=np.float64).ravel() for values in (area_fractions_a, area_fractions_b)]
    for sample in samples:
        if sample.size == 0:
            raise MetricUndefinedError("no plaques in one of the sets: their sizes cannot be compared")
        if not np.all(np.isfinite(sample) & (sample > 0)):
            raise MetricUndefinedError("plaque area fractions must be positive and finite")
    return float(wasserstein_distance(np.log10(samples[0]), np.log10(samples[1])))


def compare_well_crops(synthetic: WellCrops, reference: WellCrops) -> dict[str, Any]:
    """Compare a synthetic set of well crops with a reference (real) one.

    Parameters
    ----------
    synthetic, reference : WellCrops
        Two sets of crops of the same size; for ``fd_wells`` / ``kid_wells`` both need an extractor.

    Returns
    -------
    dict
        Every key of :meth:`WellCrops.compute` for the synthetic set, the same with ``_reference`` appended for the
        reference set, and the distances:

        - ``fd_wells``, ``kid_wells``, ``kid_wells_std``, ``nn_accuracy_wells`` (when both sets have deep features
          and at least 2 crops): :func:`~platesynth.metrics.frechet.frechet_distance`,
          :func:`~platesynth.metrics.frechet.kernel_distance` and
          :func:`~platesynth.metrics.frechet.nearest_neighbour_accuracy` of the crops' features (the last: how
          well they tell the two sets apart, 0.5 not at all, 1 always; a crop's neighbours are sought in the
          other plates only, as the wells of one plate share its light and stain);
        - ``dnf_wells = |nf_wells_reference - nf_wells|``;
        - ``spectrum_distance_wells``: :func:`spectrum_distance` of the two mean log10 spectra (decades), plaques
          left out where a set has plaque masks; ``spectrum_distance_wells_with_plaques``: of the spectra with
          plaques kept in both sets (like for like when only one set has masks);
        - ``plaque_area_distance``: Wasserstein-1 distance between the two sets' log10 plaque area fractions
          (decades), ``plaque_contrast_distance``: between their plaque contrasts; None unless both sets have
          measured plaques.
    """
    if synthetic.size != reference.size:
        raise ShapeMismatchError(f"crop sizes differ: {synthetic.size} and {reference.size}")
    mine, theirs = synthetic.compute(), reference.compute()

    def both(*keys: str) -> dict[str, Any]:
        return {name: value for key in keys for name, value in ((key, mine[key]), (f"{key}_reference", theirs[key]))}

    result: dict[str, Any] = both("n_wells", "wells_from")
    if synthetic.statistics is not None and reference.statistics is not None:
        from platesynth.metrics.frechet import frechet_distance, kernel_distance, nearest_neighbour_accuracy

        if synthetic.count >= 2 and reference.count >= 2:
            features, reference_features = synthetic.statistics.features, reference.statistics.features
            result["fd_wells"] = frechet_distance(features, reference_features)
            result["kid_wells"], result["kid_wells_std"] = kernel_distance(features, reference_features)
            result["nn_accuracy_wells"] = nearest_neighbour_accuracy(
                features, reference_features, groups_a=synthetic.plates, groups_b=reference.plates)
    result.update(both("nf_wells"))
    result["dnf_wells"] = abs(theirs["nf_wells"] - mine["nf_wells"])
    for key in ("spectrum_wells", "spectrum_wells_with_plaques"):
        result[key.replace("spectrum_", "spectrum_distance_")] = spectrum_distance(mine[key], theirs[key])
    result.update(both(*(key for key in mine if key.startswith(("n_plaques", "plaque_")))))
    for key, name, distance in (
        ("area_fraction", "plaque_area_distance", plaque_area_distance),
        ("contrast", "plaque_contrast_distance", wasserstein_distance),
    ):
        a, b = synthetic.plaque_values(key), reference.plaque_values(key)
        result[name] = None if a is None or b is None or a.size == 0 or b.size == 0 else float(distance(a, b))
    result["spectrum_frequencies"] = mine["spectrum_frequencies"]
    result.update(both("spectrum_wells", "spectrum_wells_with_plaques"))
    return result


# -------------------------------------------------------------------------------------------------- from folders


def find_dataset_root(path: str | os.PathLike) -> Path | None:
    """The platesynth dataset ``path`` is, or whose ``images/`` folder it is; None for a plain folder of images."""
    path = Path(path)
    from platesynth.data.layout import IMAGES_DIR, WELLS_DIR

    if (path / IMAGES_DIR).is_dir() and (path / WELLS_DIR).is_dir():
        return path
    if path.name == IMAGES_DIR and (path.parent / WELLS_DIR).is_dir():
        return path.parent
    return None


class _Plate(NamedTuple):
    name: str
    image: np.ndarray
    wells: np.ndarray | None
    plaques: np.ndarray | None
    well_radius_mm: float | None


def _plates(path: Path) -> tuple[int, Iterator[_Plate]]:
    """The plates of a dataset (with masks) or of a folder of images (without): count and a lazy iterator."""
    from platesynth.data.layout import list_items, load_item, read_params

    root = find_dataset_root(path)
    if root is None:
        paths = list_images(path)
        return len(paths), (_Plate(str(p), read_image(p), None, None, None) for p in paths)
    items = list_items(root)

    def radius_of(item: Any) -> float | None:
        if item.params_path is None:
            return None
        try:
            return float(read_params(item)["scene"]["plate"]["well_radius_mm"])
        except (DatasetError, KeyError, TypeError, ValueError):  # no scene in the params: no mm²
            return None

    def read() -> Iterator[_Plate]:
        for item in items:
            image, wells, plaques = load_item(item)
            yield _Plate(str(item.image_path), image, wells, plaques, radius_of(item))

    return len(items), read()


def collect_well_crops(
    path: str | os.PathLike,
    *,
    size: int = CROP_SIZE,
    extractor: Any | None = None,
    grid: tuple[int, int] = (3, 4),
    model: Any | None = None,
    progress: ProgressCallback | None = None,
) -> WellCrops:
    """Crop and measure every well of a dataset or a folder of plate photos.

    Parameters
    ----------
    path : str or path-like
        A platesynth dataset (its root or its ``images/`` folder: wells and plaques from the masks) or a folder of
        images (wells from :func:`fit_plate_grid`, or from ``model``; no plaque figures without a model).
    size, extractor, grid
        As for :class:`WellCrops`.
    model : StarDistTwoBranch or path-like, optional
        A trained segmentation model (or its folder) whose predicted well and plaque masks are used for images
        without masks (plaque figures then come from predicted masks: ``wells_from`` says ``"model"``).
    progress : callable, optional
        ``progress(description, done, total)`` before the first image and after each.

    Raises
    ------
    EmptyDatasetError, ImageReadError, DatasetError
        For a missing or empty folder, or an unreadable file (named).
    MetricUndefinedError
        If a crop's Nf is undefined (the message names the file).
    """
    path = Path(path)
    total, plates = _plates(path)
    if model is not None and not hasattr(model, "config"):
        from platesynth.segment.model import load_model

        model = load_model(model)
    crops = WellCrops(size, extractor, grid)
    if progress:
        progress(f"{path} (wells)", 0, total)
    for done, plate in enumerate(plates, start=1):
        wells, plaques, source = plate.wells, plate.plaques, None
        try:
            if wells is None and model is not None:
                from platesynth.segment.predict import predict_image

                predicted = predict_image(model, plate.image)
                wells, plaques, source = predicted.wells, predicted.plaques, "model"
            crops.update(plate.image, wells, plaques, well_radius_mm=plate.well_radius_mm, source=source)
        except PlatesynthError as exc:
            raise type(exc)(f"{plate.name}: {exc}") from None
        if progress:
            progress(f"{path} (wells)", done, total)
    if crops.count == 0:
        raise DatasetError(f"{path}: no whole well found")
    return crops


def well_metrics(
    directory: str | os.PathLike,
    reference: str | os.PathLike,
    *,
    size: int = CROP_SIZE,
    grid: tuple[int, int] = (3, 4),
    model: Any | None = None,
    frechet: bool = True,
    progress: ProgressCallback | None = None,
) -> dict[str, Any]:
    """Well-crop realism metrics of a (synthetic) dataset against a reference set of plates.

    Parameters
    ----------
    directory : str or path-like
        Typically a synthetic platesynth dataset (root or ``images/`` folder): wells from the true masks. A plain
        folder of images works too (wells fitted as for the reference).
    reference : str or path-like
        Typically a folder of real plate photos (wells from :func:`fit_plate_grid`, or ``model``), or a dataset
        with masks.
    size : int
        Side of the well crops (default 128).
    grid : (int, int)
        ``(rows, cols)`` of the plates photographed without masks (default the 12-well plate's 3 x 4).
    model : optional
        Segmentation model (or its folder) for folders without masks; see :func:`collect_well_crops`.
    frechet : bool
        Compute ``fd_wells`` and ``kid_wells`` (AlexNet features; needs its weights).
    progress : callable, optional
        ``progress(description, done, total)``.

    Returns
    -------
    dict
        :func:`compare_well_crops` of the two sets: plain numbers, lists of numbers, strings and None (JSON-able).
    """
    for path in (directory, reference):
        if find_dataset_root(path) is None:
            list_images(path)  # refuse a missing or empty folder before loading any network
    extractor = None
    if frechet:
        from platesynth.metrics.frechet import get_feature_extractor

        extractor = get_feature_extractor("alexnet")
    options = {"size": size, "extractor": extractor, "grid": grid, "model": model, "progress": progress}
    synthetic = collect_well_crops(directory, **options)
    real = collect_well_crops(reference, **options)
    return compare_well_crops(synthetic, real)
