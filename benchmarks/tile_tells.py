"""Which simple statistics of the contact sheets' tiles tell the renders from the photos, and by how much.

The tiles are the contact sheet's (:func:`well_contact_sheet.collect_tiles`: the same wells, crops and seeds), pooled
over several sheets' seeds. Each tile gets a few statistics a person could see (:func:`tile_statistics`): the middle's
mean red, green and blue; how much the luminance of the layer varies at a few scales; the brightness of the bottom
against the top; the luminance and its spread in rings from inside the stain's edge (about 0.97 of the tile's
half-side) out over the wall; and the tile's corners, the plastic and light box around the well. For each statistic
the area under the ROC curve of telling the renders from the photos by it alone (Mann-Whitney U over the product of
the two counts: 0.5 tells nothing; 1 or 0, every photo's value lies above, or below, every render's) and the medians
of both, the strongest first. A statistic near 1 or 0 is a tell that a look can remove; which tells a person uses
only a judge can say (``well_contact_sheet.py``).

Run: ``python benchmarks/tile_tells.py --photos "PR8, 0 plaques" --renders "saturated plate, 0 plaques"``
(``--config look.yaml``, ``--seeds 921,931,941,951``, the sheet's other options; ``--top N`` rows).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from well_contact_sheet import collect_tiles, tile_radius

CENTRE = 0.6
"""The middle's colour is the mean within this share of the tile's half-side."""
LAYER = 0.85
"""The layer's variation is measured within this share (inside the rim's band and the stain's edge)."""
SCALES_PX = (0.7, 1.5, 3.0, 6.0, 12.0)
"""The luminance's variation at each scale: the sd of a difference of Gaussians of sd ``s / 2`` and ``s`` pixels."""
LOW_BLUR_PX = 15.0
"""The layer's slow unevenness: the sd of the luminance blurred by this much."""
RINGS = (0.85, 0.9, 0.93, 0.95, 0.97, 0.99, 1.01, 1.04, 1.08, 1.15)
"""Edges of the rings, shares of the tile's half-side, from inside the stain's edge out over the wall."""
CORNERS = 1.2
"""Beyond this share of the half-side (the tile's corners) lie the plastic and the light box."""


def tile_statistics(tile) -> dict[str, float]:
    """The statistics of one square RGB tile (see the module docstring), by name."""
    import numpy as np
    from scipy import ndimage

    from platesynth.render.look import LUMINANCE

    rgb = tile[..., :3].astype(np.float64)
    side = rgb.shape[0]
    yy = np.mgrid[:side, :side][0]
    radius = tile_radius(side)
    luminance = rgb @ np.array(LUMINANCE)
    middle, layer, corners = radius < CENTRE, radius < LAYER, radius > CORNERS
    stats = {f"middle {c}": float(rgb[..., i][middle].mean()) for i, c in enumerate("RGB")}
    inside = luminance.copy()  # the layer's statistics see the layer only: beyond it, its median, not the wall
    inside[~layer] = np.median(luminance[layer])
    for scale in SCALES_PX:
        band = ndimage.gaussian_filter(inside, scale / 2) - ndimage.gaussian_filter(inside, scale)
        stats[f"layer detail {scale:g} px"] = float(band[layer].std())
    stats["layer unevenness"] = float(ndimage.gaussian_filter(inside, LOW_BLUR_PX)[layer].std())
    below, above = layer & (yy > 0.6 * side), layer & (yy < 0.4 * side)
    stats["bottom - top"] = float(luminance[below].mean() - luminance[above].mean())
    centre_level = luminance[radius < 0.5].mean()
    for inner, outer in zip(RINGS[:-1], RINGS[1:]):
        ring = (radius >= inner) & (radius < outer)
        stats[f"ring {inner:.2f}-{outer:.2f} level"] = float(luminance[ring].mean() - centre_level)
        stats[f"ring {inner:.2f}-{outer:.2f} sd"] = float(luminance[ring].std())
    stats["corners level"] = float(luminance[corners].mean())
    stats["corners sd"] = float(luminance[corners].std())
    stats["corners red - green"] = float((rgb[..., 0] - rgb[..., 1])[corners].mean())
    stats["corners blue - green"] = float((rgb[..., 2] - rgb[..., 1])[corners].mean())
    stats["corners edges"] = float(ndimage.gaussian_gradient_magnitude(luminance, 1.0)[corners].mean())
    return stats


def separation(photos: list[dict[str, float]], renders: list[dict[str, float]]) -> list[tuple[str, float, float, float]]:
    """Per statistic: (name, AUC of the photos above the renders, photos' median, renders' median), the strongest
    separation first."""
    import numpy as np
    from scipy.stats import mannwhitneyu

    rows = []
    for name in photos[0]:
        real = np.array([p[name] for p in photos])
        rendered = np.array([r[name] for r in renders])
        auc = mannwhitneyu(real, rendered).statistic / (len(real) * len(rendered))
        rows.append((name, float(auc), float(np.median(real)), float(np.median(rendered))))
    return sorted(rows, key=lambda row: -abs(row[1] - 0.5))


def main(argv: list[str] | None = None) -> None:
    """Print the statistics that tell the sheets' renders from their photos, strongest first."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--preset", default="high")
    parser.add_argument("--config", type=Path, help="a YAML scene configuration applied over the preset")
    parser.add_argument("--seeds", default="921,931,941,951", help="the sheets' seeds, comma-separated")
    parser.add_argument("--wells", type=int, default=16, help="wells of each kind per sheet")
    parser.add_argument("--split", choices=("all", "fit", "check"), default="all")
    parser.add_argument("--tile", type=int, default=200, help="tile side in pixels")
    parser.add_argument("--first-scene", type=int, default=10_000)
    parser.add_argument("--photos", default="", help="only photo wells whose class matches this regular expression")
    parser.add_argument("--renders", default="", help="only rendered wells whose class matches this regular expression")
    parser.add_argument("--top", type=int, default=12, help="rows to print")
    args = parser.parse_args(argv)

    import numpy as np

    photos, renders = [], []
    for seed in (int(s) for s in args.seeds.split(",")):
        real, synthetic = collect_tiles(np.random.default_rng(seed), args.split, args.wells, args.tile, args.photos,
                                        args.renders, args.preset, args.config, args.first_scene)
        photos += [tile_statistics(tile) for tile, _ in real]
        renders += [tile_statistics(tile) for tile, _ in synthetic]
    look = args.preset + (f" with {args.config}" if args.config else "")
    print(f"{len(photos)} photo tiles ({args.photos or 'all'}) against {len(renders)} render tiles of {look} "
          f"({args.renders or 'all'}), sheets of seeds {args.seeds}")
    print(f"{'statistic':28s} {'AUC':>5s} {'photos':>8s} {'renders':>8s}")
    for name, auc, real, rendered in separation(photos, renders)[: args.top]:
        print(f"{name:28s} {auc:5.2f} {real:8.2f} {rendered:8.2f}")


if __name__ == "__main__":
    main()
