"""Colour of the stain in the wells: a preset's renders against the shared real 12-well photos.

For every well, the median hue, saturation and value (HSV) of the pixels within 0.6 of its radius from its centre
(the stained monolayer, mostly; the median is robust to a few plaques), and the median of its green channel in
8-bit levels (a saturated violet has almost none: how far a camera's tone curve crushes it), and its fine grain: the
standard deviation, in 8-bit levels, of the luminance (the post-processing's weights) less its Gaussian blur of 1.5 px
(a phone's smooth saturated wells have almost none, sensor noise and a sharpened texture have some). Real wells are
found with the fitted plate grid (:func:`platesynth.metrics.fit_plate_grid`), synthetic ones with their true masks, raster
renders at the photos' size. Prints the 10th, 50th and 90th percentiles per split and for the preset; with
``--per-plate``, also the median over each plate's wells, photo by photo and render by render (the photos' plates
fall into kinds: saturated wells with the green crushed to 0, and pale bluish ones).

And the green of each well's layer by its plaque count (the person's count in the photos, uncountable wells left
out; the true count in the renders, lysed and emptied wells left out): the median green of the pixels within
:data:`CENTRE_SHARE` of the radius whose blue exceeds their green by :data:`STAIN_MARGIN` (the stain between the
plaques), by virus and for the preset, in bins of the count. The photos' saturated plates keep their green at 0 up to
about 20 plaques and at 60-80 in wells of more (``stain.crowd_thinning``). And the blue of the same pixels in the
plain wells (no plaque): its 5th, 50th and 95th percentiles, by virus and for the preset; a phone's auto exposure holds
the photos' saturated plain wells at 198-224 (5th to 95th percentile, Brisbane and PR8).

Run: ``python benchmarks/stain_colour.py`` (``--preset P``, ``--images N``, ``--set name=value`` overrides,
``--per-plate``).
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from preset_options import add_preset_options, preset_config
from shared_split import in_split, virus

ROOT = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("PLATESYNTH_SHARED", ROOT.parent / "shared"))
CENTRE_SHARE = 0.6
"""Pixels within this share of the well's radius from its centre are measured."""
GRAIN_BLUR_PX = 1.5
"""The grain is what a Gaussian blur of this sd (pixels, at the photos' size) takes away."""
STAIN_MARGIN = 60
"""A pixel is the violet stain (not a plaque) where its blue exceeds its green by this many 8-bit levels."""
COUNT_BINS = ((0, 0), (1, 5), (6, 20), (21, 50), (51, 10_000))
"""Bins of the plaque count for the green by count."""


def main(argv: list[str] | None = None) -> None:
    """Print the percentiles of the wells' median hue, saturation and value."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_preset_options(parser, images=12, seed=700)
    parser.add_argument("--per-plate", action="store_true", help="also each plate's median over its wells")
    args = parser.parse_args(argv)

    import numpy as np
    from scipy import ndimage
    from skimage.color import rgb2hsv

    from platesynth.data.layout import read_counts_csv
    from platesynth.io import list_images, read_image
    from platesynth.metrics import fit_plate_grid, wells_from_mask
    from platesynth.render.look import LUMINANCE
    from platesynth.render.raster import render_raster
    from platesynth.scene import sample_scene

    def well_medians(image, discs) -> np.ndarray:
        """Per well: median hue, saturation, value (0..1) and green level (0..255) of its centre, and its grain."""
        hsv_green = np.concatenate([rgb2hsv(image), image[..., 1:2].astype(np.float64)], axis=2)
        luminance = image[..., :3].astype(np.float64) @ np.array(LUMINANCE)
        fine = luminance - ndimage.gaussian_filter(luminance, GRAIN_BLUR_PX)
        yy, xx = np.mgrid[: image.shape[0], : image.shape[1]]
        rows = []
        for d in discs:
            centre = (yy - d.cy) ** 2 + (xx - d.cx) ** 2 < (CENTRE_SHARE * d.radius) ** 2
            rows.append([*np.median(hsv_green[centre], axis=0), fine[centre].std()])
        return np.array(rows)

    def report(label: str, medians: np.ndarray) -> None:
        hue, sat, val, green, grain = (np.percentile(medians[:, k], [10, 50, 90]) for k in range(5))
        print(f"{label:24s} {len(medians):5d}  hue {np.round(hue * 360).astype(int)}  saturation {np.round(sat, 2)}  "
              f"value {np.round(val, 2)}  green {np.round(green).astype(int)}  grain {np.round(grain, 2)}")

    def stain_levels(image, disc) -> tuple[float, float]:
        """The median green and blue (8-bit) of the stain's pixels in ``disc``'s centre, NaN where there are too few."""
        yy, xx = np.mgrid[: image.shape[0], : image.shape[1]]
        pixels = image[(yy - disc.cy) ** 2 + (xx - disc.cx) ** 2 < (CENTRE_SHARE * disc.radius) ** 2][:, :3]
        stain = pixels[pixels[:, 2].astype(int) > pixels[:, 1].astype(int) + STAIN_MARGIN]
        if len(stain) <= 50:
            return float("nan"), float("nan")
        return float(np.median(stain[:, 1])), float(np.median(stain[:, 2]))

    def report_green(label: str, counted: list[tuple[int, float, float]]) -> None:
        pairs = np.array(counted, dtype=np.float64).reshape(-1, 3)
        cells = []
        for low, high in COUNT_BINS:
            green = pairs[(pairs[:, 0] >= low) & (pairs[:, 0] <= high) & ~np.isnan(pairs[:, 1]), 1]
            cells.append(f"{low}-{high if high < 10_000 else ''}: {np.median(green) if len(green) else np.nan:3.0f} "
                         f"({len(green)})")
        print(f"{label:24s} " + "  ".join(cells))

    def report_blue(label: str, counted: list[tuple[int, float, float]]) -> None:
        levels = np.array(counted, dtype=np.float64).reshape(-1, 3)
        blue = levels[(levels[:, 0] == 0) & ~np.isnan(levels[:, 2]), 2]
        percentiles = np.round(np.percentile(blue, [5, 50, 95])).astype(int) if len(blue) else "-"
        print(f"{label:24s} {len(blue):5d}  {percentiles}")

    def plate_median(label: str, medians: np.ndarray) -> None:
        hue, sat, val, green, grain = np.median(medians, axis=0)
        print(f"  {label:22s} hue {hue * 360:5.0f}  saturation {sat:4.2f}  value {val:4.2f}  green {green:5.0f}  "
              f"grain {grain:5.2f}")

    photos = list_images(SHARED / "data" / "plaque12" / "plates")
    if not photos:
        raise SystemExit(f"no real photos under {SHARED}: set PLATESYNTH_SHARED to the shared material")
    counted_rows: dict[str, list] = {}
    for row in read_counts_csv(SHARED / "data" / "plaque12" / "counts.csv"):
        if row.count is not None:
            counted_rows.setdefault(row.image, []).append(row)
    counted_by_virus: dict[str, list[tuple[int, float, float]]] = {}
    print(f"{'wells of':24s} {'n':>5s}  percentiles 10, 50, 90")
    for split in ("fit", "check"):
        names = [p for p in photos if in_split(p.name, split)]
        medians = []
        for path in names:  # each photo read and its plate grid fitted once, for both measures
            image = read_image(path)
            discs = fit_plate_grid(image)
            medians.append(well_medians(image, discs))
            counted_by_virus.setdefault(virus(path.name), []).extend(
                (row.count, *stain_levels(image, discs[row.row * 4 + row.col])) for row in counted_rows.get(path.name, []))
        report(f"real, {split}", np.concatenate(medians))
        if args.per_plate:
            for path, plate in zip(names, medians):
                plate_median(path.stem, plate)
    config, label = preset_config(args)
    medians, rendered_levels = [], []
    for index in range(args.images):
        scene = sample_scene(config, args.seed + index)
        result = render_raster(scene, (1216, 944))
        discs = wells_from_mask(result.wells)
        medians.append(well_medians(result.image, discs))
        counts = {well.id: 0 for well in scene.wells if not (well.lysed or well.emptied)}
        for plaque in scene.plaques:
            if plaque.well in counts:
                counts[plaque.well] += 1
        rendered_levels += [(counts[d.id], *stain_levels(result.image, d)) for d in discs if d.id in counts]
    report(label, np.concatenate(medians))
    if args.per_plate:
        for index, plate in enumerate(medians):
            plate_median(f"seed {args.seed + index}", plate)

    print(f"\n{'green of the stain, of':24s} median 8-bit green of the stain between the plaques, by plaque count "
          "(wells)")
    for name, counted in sorted(counted_by_virus.items()):
        report_green(f"real, {name}", counted)
    report_green(label, rendered_levels)

    print(f"\n{'blue of the stain, of':24s} wells  8-bit blue of the stain in the plain wells: percentiles 5, 50, 95")
    for name, counted in sorted(counted_by_virus.items()):
        report_blue(f"real, {name}", counted)
    report_blue(label, rendered_levels)


if __name__ == "__main__":
    main()
