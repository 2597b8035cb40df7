"""The pipette's scrape at the top of each well: a preset's renders against the shared real 12-well photos.

Every well is cropped as the contact sheet crops it (:func:`platesynth.metrics.fit_plate_grid` and
:func:`platesynth.metrics.crop_well`, a square of :data:`TILE` pixels, the stain's edge at about 0.97 of its
half-side), photos and raster renders at the photos' size alike. Only the wells of saturated plates are measured
(the median green of the tile's middle at most :data:`SATURATED_GREEN`: the scrape is a pale strip on a violet whose
green is crushed), and in each the scrape is the largest connected set of pale pixels (green above
:data:`PALE_GREEN`) in the upper :data:`TOP_SHARE` of the tile, inside the stain, that starts at the rim (a pixel
beyond :data:`RIM_START` of the stain's radius) and stays near the tile's vertical midline (a plaque near the top
does not). Per well: the scrape's length (its longest extent) and mean width (its area over its length), in tile
pixels, how its width varies along it (the coefficient of variation of its rows' widths: a torn strip varies, an
even stroke does not), its solidity (area over
convex hull: ragged edges and a blunt end lower it) and the mean 8-bit colour of its brightest quarter. Prints the
share of wells with a scrape and the 10th, 50th and 90th percentiles per split and for the preset.

Run: ``python benchmarks/scrape_look.py`` (``--preset P``, ``--config C``, ``--images N``, ``--set name=value``).
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from preset_options import add_preset_options, preset_config
from shared_split import in_split
from well_contact_sheet import tile_radius

ROOT = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("PLATESYNTH_SHARED", ROOT.parent / "shared"))
TILE = 200
"""Side of a well's crop in pixels, as on the contact sheets the glance judges see."""
SATURATED_GREEN = 20
"""A well is of a saturated plate where the median 8-bit green of its middle is at most this."""
PALE_GREEN = 80
"""A pixel is scraped (pale) where its 8-bit green exceeds this."""
TOP_SHARE = 0.3
"""The scrape is looked for in this upper share of the tile..."""
RIM_START = 0.88
"""...starting beyond this share of the stain's radius from the centre..."""
MIDLINE_SHARE = 0.5
"""...with its top within this share of the half-side from the tile's vertical midline."""
STAIN_EDGE = 0.96
"""Pixels beyond this share of the tile's half-side are the wall, not the stain."""
MIN_AREA = 15
"""A scrape covers at least this many pixels."""
MIDDLE = 0.6
"""A tile's middle, whose green tells a saturated plate, lies within this share of its half-side."""
COLUMNS = ("length", "width", "width cv", "solidity", "R", "G", "B")


def scrape_measures(tile) -> tuple[float, ...] | None:
    """The scrape's measures in one square RGB tile of :data:`TILE` pixels (``COLUMNS``: length and mean width in
    pixels, the coefficient of variation of its rows' widths, its solidity, and the mean R, G, B of its brightest
    quarter), or ``None`` where it holds none (see the module docstring)."""
    import numpy as np
    from skimage.measure import label, regionprops

    yy = np.mgrid[:TILE, :TILE][0]
    half = TILE / 2
    radius = tile_radius(TILE)
    rgb = tile[..., :3].astype(np.float64)
    pale = (rgb[..., 1] > PALE_GREEN) & (radius < STAIN_EDGE) & (yy < TOP_SHARE * TILE)
    candidates = []
    for region in regionprops(label(pale)):
        rows, cols = region.coords[:, 0], region.coords[:, 1]
        top = np.argmin(rows)
        at_rim = radius[rows, cols].max() > RIM_START * STAIN_EDGE
        near_midline = abs(cols[top] + 0.5 - half) < MIDLINE_SHARE * half
        if at_rim and near_midline and region.area >= MIN_AREA:
            candidates.append(region)
    if not candidates:
        return None
    region = max(candidates, key=lambda r: r.area)
    widths = np.bincount(region.coords[:, 0])
    widths = widths[widths > 0]
    pixels = rgb[region.coords[:, 0], region.coords[:, 1]]
    brightness = pixels.mean(axis=1)
    brightest = pixels[brightness >= np.percentile(brightness, 75)].mean(axis=0)
    length = max(region.feret_diameter_max, 1.0)
    return (length, region.area / length, widths.std() / widths.mean(), region.solidity, *brightest)


def is_saturated(tile) -> bool:
    """Whether a tile is a well of a saturated plate: the median green of its middle at most :data:`SATURATED_GREEN`."""
    import numpy as np

    return float(np.median(tile[..., 1][tile_radius(TILE) < MIDDLE])) <= SATURATED_GREEN


def main(argv: list[str] | None = None) -> None:
    """Print the share of wells with a scrape and the percentiles of its measures."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_preset_options(parser, images=12, seed=700)
    args = parser.parse_args(argv)

    import numpy as np

    from platesynth.io import list_images, read_image
    from platesynth.metrics import crop_well, fit_plate_grid
    from platesynth.render.raster import render_raster
    from platesynth.scene import sample_scene

    def measure(image, discs, wells) -> tuple[int, list]:
        """(saturated wells, scrapes found) among the wells ``wells`` (indices into ``discs``) of one image."""
        saturated, found = 0, []
        for index in wells:
            tile = crop_well(image, discs[index], TILE)
            if not is_saturated(tile):
                continue
            saturated += 1
            measures = scrape_measures(tile)
            if measures is not None:
                found.append(measures)
        return saturated, found

    def report(name: str, saturated: int, found: list) -> None:
        if not saturated:
            print(f"{name:22s} no well of a saturated plate")
            return
        table = np.array(found).reshape(-1, len(COLUMNS))
        print(f"{name:22s} {saturated:4d} wells, a scrape in {len(found) / saturated:4.0%}")
        for q in (10, 50, 90):
            cells = "  ".join(f"{c} {v:6.2f}" for c, v in zip(COLUMNS, np.percentile(table, q, axis=0)))
            print(f"  {q:2d}th  {cells}")

    photos = list_images(SHARED / "data" / "plaque12" / "plates")
    if not photos:
        raise SystemExit(f"no real photos under {SHARED}: set PLATESYNTH_SHARED to the shared material")
    print("lengths and widths in pixels of a 200-pixel tile; R G B: the mean of the scrape's brightest quarter")
    for split in ("fit", "check"):
        saturated, found = 0, []
        for path in (p for p in photos if in_split(p.name, split)):
            image = read_image(path)
            discs = fit_plate_grid(image)
            n, measures = measure(image, discs, range(len(discs)))
            saturated, found = saturated + n, found + measures
        report(f"real, {split}", saturated, found)
    config, name = preset_config(args)
    saturated, found = 0, []
    for index in range(args.images):
        scene = sample_scene(config, args.seed + index)
        image = render_raster(scene, (1216, 944)).image
        discs = fit_plate_grid(image, (scene.plate.rows, scene.plate.cols))
        intact = [i for i, well in enumerate(scene.wells) if not (well.lysed or well.emptied)]
        n, measures = measure(image, discs, intact)
        saturated, found = saturated + n, found + measures
    report(name, saturated, found)


if __name__ == "__main__":
    main()
