"""The wells' radial profile, inside and around: a preset's renders against the shared real 12-well photos.

Inside: a plain well (no plaque; in the photos a well counted 0) is paler toward its rim, as the stain is denser at
the centre. Its luminance is averaged over rings (medians), relative to the centre's (within 0.3 radii); the photos'
and the renders' wells are compared ring by ring.

Around: seen from below on a light box, each well is ringed by its wall: a band about a tenth of the well's radius
wide with several thin grey outlines (the wall's foot and top edge). For every well, the luminance is sampled along
rays on its four diagonals (where no label or neighbouring well lies), from 0.9 to 1.4 radii, and divided by the
deck's level (the median from 1.3 to 1.4 radii). Prints, per virus of the photos and for the preset: the median
profile's mean over the band (1.0 to 1.15 radii: below 1, the band is darker than the deck), its minimum, and the
line contrast (the median over rays of the band's maximum minus minimum). Wells are found with the fitted plate grid
(:func:`platesynth.metrics.fit_plate_grid`) in photos and renders alike; raster renders at the photos' size.

And the deck's colour there (the light box seen through the plastic): red minus green and blue minus green, per image.

And around each wall's circumference: the band's luminance (1.0 to 1.15 radii) averaged in each of 24 sectors; the
sectors' standard deviation (how uneven the wall is around the well), and the first angular harmonic's amplitude
along the well's outward direction, away from the image's centre (positive: brighter on the outward side), for the
wells far from the image's centre (beyond 0.6 of its half-diagonal) and near it, in 8-bit levels.

And each plate's one-sidedness: over its plain wells, the mean of each well's luminance difference, lower half minus
upper half and right half minus left half of a ring (:data:`SIDED_RING` radii), over the ring's mean; the length of
that mean vector (0 when the wells' darker sides point every way; PR8's photos are darker toward the bottom in every
well, ``stain.pooling``), its median over the images.

And each well's outer band by side: the sRGB-decoded blue (the channel a violet stain passes most of) in the band
:data:`SIDE_BAND` radii wide inside the rim, on each side (top, bottom, left, right: sectors of
:data:`SIDE_SPREAD_DEG` either side), over the well's centre (within :data:`SIDE_CENTRE` radii); the median over
the images of each well position, averaged over each plate row's wells. PR8's photos keep 0.56-0.64 of the
centre's blue at the bottom of the row nearest the light box's edge (``background.panel_shade``).

Run: ``python benchmarks/well_profile.py`` (``--preset P``, ``--images N``, ``--set name=value`` overrides).
"""

from __future__ import annotations

import argparse
import os
from dataclasses import dataclass
from pathlib import Path

from preset_options import add_preset_options, preset_config
from shared_split import SPLITS, virus

ROOT = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("PLATESYNTH_SHARED", ROOT.parent / "shared"))
RADII = (0.9, 1.4, 0.01)
"""Sampled distances from a well's centre, in radii (start, stop, step)."""
DECK = (1.3, 1.4)
BAND = (1.0, 1.15)
DIAGONALS_DEG = (45, 135, 225, 315)
SPREAD_DEG = 12
SECTORS = 24
"""Sectors around a wall's circumference."""
OFF_AXIS = 0.6
"""A well beyond this share of the image's half-diagonal from its centre is an outer one."""
"""Rays every 3 degrees within this angle of each diagonal."""
RINGS = (0.0, 0.3, 0.5, 0.7, 0.8, 0.85, 0.9, 0.93, 0.96)
"""Edges of the rings inside a plain well, in radii (the first ring is the centre the others are relative to)."""
SIDED_RING = (0.7, 0.95)
"""The ring of a plain well whose halves the one-sidedness compares, in radii."""
SIDE_BAND, SIDE_CENTRE, SIDE_SPREAD_DEG = (0.75, 0.92), 0.4, 30
"""The outer band by side: its radii, the centre it is divided by (radii), and each side's half-angle (degrees)."""
SIDES_DEG = {"top": -90, "bottom": 90, "left": 180, "right": 0}
"""The sides' directions in the image (y down), degrees."""


def main(argv: list[str] | None = None) -> None:
    """Print the plain wells' rings and the walls' band level, darkest point and contrast, photos against renders."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_preset_options(parser, images=8, seed=10_000)
    args = parser.parse_args(argv)

    import csv

    import numpy as np
    from scipy.ndimage import map_coordinates

    from platesynth.io import list_images, read_image
    from platesynth.metrics import fit_plate_grid
    from platesynth.render.color import srgb_to_linear
    from platesynth.render.look import LUMINANCE
    from platesynth.render.raster import render_raster
    from platesynth.scene import sample_scene

    radii = np.arange(*RADII)
    deck, band = (radii >= DECK[0]) & (radii < DECK[1]), (radii >= BAND[0]) & (radii <= BAND[1])
    angles = np.deg2rad([d + a for d in DIAGONALS_DEG for a in range(-SPREAD_DEG, SPREAD_DEG + 1, 3)])

    def rays(discs) -> tuple[np.ndarray, np.ndarray]:
        """Pixel rows and columns along the wells' diagonals at ``radii``: each ``(wells * angles, radii)``."""
        ys = np.concatenate([disc.cy + np.sin(angles)[:, None] * radii * disc.radius for disc in discs])
        xs = np.concatenate([disc.cx + np.cos(angles)[:, None] * radii * disc.radius for disc in discs])
        return ys, xs

    def sampled(channel: np.ndarray, ys: np.ndarray, xs: np.ndarray) -> np.ndarray:
        return map_coordinates(channel, [ys.ravel(), xs.ravel()], order=1, mode="nearest").reshape(ys.shape)

    def profiles(luminance: np.ndarray, discs) -> np.ndarray:
        """One row per ray: luminance at ``radii`` relative to the deck's."""
        ray = sampled(luminance, *rays(discs))
        return ray / np.median(ray[:, deck], axis=1, keepdims=True)

    def deck_colour(image: np.ndarray, discs) -> np.ndarray:
        """The image's median (red - green, blue - green) over the deck along the wells' diagonals."""
        ys, xs = (points[:, deck] for points in rays(discs))
        rgb = np.stack([sampled(image[..., c].astype(np.float64), ys, xs).ravel() for c in range(3)], axis=1)
        return np.median(rgb[:, [0, 2]] - rgb[:, [1]], axis=0)

    def rings(luminance: np.ndarray, discs) -> np.ndarray:
        """One row per well of ``discs``: the median luminance of each ring of :data:`RINGS` over the centre's."""
        yy, xx = np.mgrid[: luminance.shape[0], : luminance.shape[1]]
        rows = []
        for disc in discs:
            radius = np.hypot(yy - disc.cy, xx - disc.cx) / disc.radius
            levels = [np.median(luminance[(radius >= a) & (radius < b)]) for a, b in zip(RINGS[:-1], RINGS[1:])]
            rows.append(np.array(levels[1:]) / levels[0])
        return np.array(rows)

    def report_rings(label: str, wells: np.ndarray) -> None:
        print(f"{label:24s} {len(wells):6d}  " + " ".join(f"{v:.3f}" for v in np.median(wells, axis=0)))

    def report(label: str, rays: np.ndarray) -> None:
        median = np.median(rays, axis=0)
        contrast = np.median(rays[:, band].max(axis=1) - rays[:, band].min(axis=1))
        print(f"{label:24s} {len(rays):6d}  band {median[band].mean():.3f}  darkest {median[band].min():.3f}  "
              f"line contrast {contrast:.3f}")

    def report_deck(label: str, offsets: np.ndarray) -> None:
        red, blue = (np.percentile(offsets[:, k], [10, 50, 90]).round().astype(int) for k in (0, 1))
        print(f"{label:24s} {len(offsets):6d}  red - green {red}  blue - green {blue}")

    def around(luminance: np.ndarray, discs) -> np.ndarray:
        """One row per well: its sectors' standard deviation over the band, the outward harmonic's amplitude and
        its distance from the image's centre over the half-diagonal."""
        height, width = luminance.shape
        yy, xx = np.mgrid[:height, :width]
        rows = []
        for disc in discs:
            dy, dx = yy - disc.cy, xx - disc.cx
            in_band = (np.hypot(dy, dx) >= BAND[0] * disc.radius) & (np.hypot(dy, dx) <= BAND[1] * disc.radius)
            angle = np.arctan2(dy[in_band], dx[in_band])
            sector = ((angle + np.pi) / (2 * np.pi) * SECTORS).astype(int) % SECTORS
            levels = np.bincount(sector, luminance[in_band], SECTORS) / np.bincount(sector, minlength=SECTORS)
            centres = np.arange(SECTORS) * 2 * np.pi / SECTORS - np.pi + np.pi / SECTORS
            outward = np.arctan2(disc.cy - height / 2, disc.cx - width / 2)
            harmonic = 2 * np.mean((levels - levels.mean()) * np.cos(centres - outward))
            off_axis = np.hypot(disc.cy - height / 2, disc.cx - width / 2) / np.hypot(height / 2, width / 2)
            rows.append((levels.std(), harmonic, off_axis))
        return np.array(rows)

    def one_sidedness(luminance: np.ndarray, discs) -> float:
        """The length of the mean over ``discs`` of (lower - upper, right - left) halves of their rings, relative."""
        yy, xx = np.mgrid[: luminance.shape[0], : luminance.shape[1]]
        sides = []
        for disc in discs:
            dy, dx = yy - disc.cy, xx - disc.cx
            radius = np.hypot(dy, dx) / disc.radius
            ring = (radius >= SIDED_RING[0]) & (radius < SIDED_RING[1])
            level = luminance[ring].mean()
            sides.append(((luminance[ring & (dy > 0)].mean() - luminance[ring & (dy < 0)].mean()) / level,
                          (luminance[ring & (dx > 0)].mean() - luminance[ring & (dx < 0)].mean()) / level))
        return float(np.hypot(*np.mean(sides, axis=0)))

    def sides(image: np.ndarray, discs) -> np.ndarray:
        """One row per well of ``discs``: the linear blue of its outer band on each of :data:`SIDES_DEG` over its
        centre's."""
        blue = np.asarray(srgb_to_linear(image[..., 2] / 255.0))
        yy, xx = np.mgrid[: blue.shape[0], : blue.shape[1]]
        rows = []
        for disc in discs:
            dy, dx = yy - disc.cy, xx - disc.cx
            radius = np.hypot(dy, dx) / disc.radius
            band = (radius > SIDE_BAND[0]) & (radius < SIDE_BAND[1])
            angle = np.degrees(np.arctan2(dy, dx))
            centre = np.median(blue[radius < SIDE_CENTRE])
            rows.append([np.median(blue[band & (np.abs((angle - side + 180) % 360 - 180) < SIDE_SPREAD_DEG)]) / centre
                         for side in SIDES_DEG.values()])
        return np.array(rows)

    def report_sides(label: str, measured: list, rows: int, cols: int) -> None:
        per_position = np.median([sides(m.image, m.discs) for m in measured], axis=0).reshape(rows, cols, -1)
        for row, levels in enumerate(per_position.mean(axis=1)):
            print(f"{label if row == 0 else '':24s} {len(measured):6d}  row {row}  "
                  + "  ".join(f"{side} {level:.2f}" for side, level in zip(SIDES_DEG, levels)))

    def report_around(label: str, wells: np.ndarray) -> None:
        outer, inner = wells[:, 2] > OFF_AXIS, wells[:, 2] <= OFF_AXIS
        print(f"{label:24s} {len(wells):6d}  unevenness {np.median(wells[:, 0]):5.2f}  outward harmonic: outer wells "
              f"{np.median(wells[outer, 1]):+5.2f}, inner {np.median(wells[inner, 1]):+5.2f}")

    @dataclass
    class Measured:
        """An image read or rendered once, and its wells found once (the plate grid fitted to it)."""

        image: np.ndarray
        discs: list
        plain: list  # indices of the plain wells among ``discs``

        @property
        def luminance(self) -> np.ndarray:
            return self.image.astype(np.float64) @ np.array(LUMINANCE)

    paths = list_images(SHARED / "data" / "plaque12" / "plates")
    if not paths:
        raise SystemExit(f"no real photos under {SHARED}: set PLATESYNTH_SHARED to the shared material")
    plain_counts = {}
    with open(SHARED / "data" / "plaque12" / "counts.csv", newline="") as table:
        for row in csv.DictReader(table):
            if row["count"] == "0":
                plain_counts.setdefault(row["image"], []).append(int(row["row"]) * 4 + int(row["col"]))
    photos = {name: [] for name in SPLITS["all"]}
    for path in paths:
        image = read_image(path)
        photos[virus(path.name)].append(
            Measured(image, fit_plate_grid(image), plain_counts.get(path.name, [])))
    config, label = preset_config(args)
    renders = []
    for scene in (sample_scene(config, args.seed + index) for index in range(args.images)):
        image = render_raster(scene, (1216, 944)).image
        with_plaques = {plaque.well for plaque in scene.plaques}
        plain = [i for i, well in enumerate(scene.wells) if not (well.lysed or well.emptied or well.id in with_plaques)]
        renders.append(Measured(image, fit_plate_grid(image, (scene.plate.rows, scene.plate.cols)), plain))
    sets = [(f"real, {name}", measured) for name, measured in photos.items()] + [(label, renders)]

    print(f"{'plain wells of':24s} {'wells':>6s}  luminance of the rings "
          + ", ".join(f"{a}-{b}" for a, b in zip(RINGS[1:-1], RINGS[2:])) + " radii over the centre's")
    for name, measured in sets:
        plain = [rings(m.luminance, [m.discs[i] for i in m.plain]) for m in measured if m.plain]
        report_rings(name, np.concatenate(plain))

    print(f"\n{'walls of':24s} {'rays':>6s}  relative to the deck at {DECK[0]}-{DECK[1]} radii; "
          f"band {BAND[0]}-{BAND[1]}")
    for name, measured in sets:
        report(name, np.concatenate([profiles(m.luminance, m.discs) for m in measured]))

    print(f"\n{'deck colour of':24s} {'images':>6s}  8-bit red minus green, blue minus green at {DECK[0]}-{DECK[1]} "
          "radii: 10th, 50th, 90th percentiles")
    for name, measured in sets:
        report_deck(name, np.array([deck_colour(m.image, m.discs) for m in measured]))

    print(f"\n{'walls around, of':24s} {'wells':>6s}  the band's {SECTORS} sectors: standard deviation, first harmonic "
          f"along the outward direction (8-bit levels; outer wells beyond {OFF_AXIS} of the half-diagonal)")
    for name, measured in sets:
        report_around(name, np.concatenate([around(m.luminance, m.discs) for m in measured]))

    print(f"\n{'one-sidedness of':24s} {'images':>6s}  the length of the mean (lower - upper, right - left) of the "
          f"plain wells' {SIDED_RING[0]}-{SIDED_RING[1]} radii rings, relative: median, 25th and 75th percentiles")
    for name, measured in sets:
        values = np.array([one_sidedness(m.luminance, [m.discs[i] for i in m.plain]) for m in measured
                           if len(m.plain) >= 2])
        if not len(values):
            print(f"{name:24s} {0:6d}  (no image with two plain wells)")
            continue
        print(f"{name:24s} {len(values):6d}  {np.median(values):.3f} ({np.percentile(values, 25):.3f}-"
              f"{np.percentile(values, 75):.3f})")

    print(f"\n{'outer band by side, of':24s} {'images':>6s}  linear blue at {SIDE_BAND[0]}-{SIDE_BAND[1]} radii on each "
          f"side over the centre's (within {SIDE_CENTRE}), median per well, mean per plate row")
    for name, measured in sets:
        report_sides(name, measured, 3, 4)


if __name__ == "__main__":
    main()
