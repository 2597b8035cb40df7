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

Run: ``python benchmarks/stain_colour.py`` (``--preset P``, ``--images N``, ``--set name=value`` overrides,
``--per-plate``).
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from preset_options import add_preset_options, preset_config
from shared_split import in_split

ROOT = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("PLATESYNTH_SHARED", ROOT.parent / "shared"))
CENTRE_SHARE = 0.6
"""Pixels within this share of the well's radius from its centre are measured."""
GRAIN_BLUR_PX = 1.5
"""The grain is what a Gaussian blur of this sd (pixels, at the photos' size) takes away."""


def main(argv: list[str] | None = None) -> None:
    """Print the percentiles of the wells' median hue, saturation and value."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_preset_options(parser, images=12, seed=700)
    parser.add_argument("--per-plate", action="store_true", help="also each plate's median over its wells")
    args = parser.parse_args(argv)

    import numpy as np
    from scipy import ndimage
    from skimage.color import rgb2hsv

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

    def plate_median(label: str, medians: np.ndarray) -> None:
        hue, sat, val, green, grain = np.median(medians, axis=0)
        print(f"  {label:22s} hue {hue * 360:5.0f}  saturation {sat:4.2f}  value {val:4.2f}  green {green:5.0f}  "
              f"grain {grain:5.2f}")

    photos = list_images(SHARED / "data" / "plaque12" / "plates")
    if not photos:
        raise SystemExit(f"no real photos under {SHARED}: set PLATESYNTH_SHARED to the shared material")
    print(f"{'wells of':24s} {'n':>5s}  percentiles 10, 50, 90")
    for split in ("fit", "check"):
        names = [p for p in photos if in_split(p.name, split)]
        medians = [well_medians(image, fit_plate_grid(image)) for image in (read_image(p) for p in names)]
        report(f"real, {split}", np.concatenate(medians))
        if args.per_plate:
            for path, plate in zip(names, medians):
                plate_median(path.stem, plate)
    config, label = preset_config(args)
    medians = []
    for index in range(args.images):
        result = render_raster(sample_scene(config, args.seed + index), (1216, 944))
        medians.append(well_medians(result.image, wells_from_mask(result.wells)))
    report(label, np.concatenate(medians))
    if args.per_plate:
        for index, plate in enumerate(medians):
            plate_median(f"seed {args.seed + index}", plate)


if __name__ == "__main__":
    main()
