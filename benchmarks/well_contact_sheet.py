"""A contact sheet of real and synthetic well crops, shuffled, to judge by eye which is which.

Real wells are cropped from the shared 12-well photos, synthetic ones from raster renders of a preset at the photos'
size, both the same way: with the plate grid fitted to the image (:func:`platesynth.metrics.fit_plate_grid`), at the
same crop size. The same framing matters: the fitted grid puts the stain's edge at about 0.97 of a crop's half-side on
photos and renders alike, the renders' true masks at 0.99, so the stain touched the tile's edge on renders only. The
tiles are shuffled (seeded) into one PNG; the key (which tile is real) is written beside it as a text file, so that a
person can look first and check after.

Run: ``python benchmarks/well_contact_sheet.py --out sheet.png`` (``--preset high``, ``--config look.yaml`` over it,
``--wells 24`` of each kind, ``--split fit|check|all``, ``--tile 160``, ``--first-scene 20000`` for renders of other
scenes: by default every sheet draws its renders from the scenes 10000, 10001, ...). A judge's answers, one line per
tile in the key's form (``row 0, column 3: real``), are scored against the key with ``--score ANSWERS.txt --out
sheet.png``.
"""

from __future__ import annotations

import argparse
import os
import re
from pathlib import Path

from shared_split import in_split

ROOT = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("PLATESYNTH_SHARED", ROOT.parent / "shared"))


TILE_LINE = re.compile(r"row (\d+), column (\d+): (real|synthetic)")


def score(key_path: Path, answers_path: Path) -> str:
    """How many of a judge's answers match the key: in all, among the renders and among the photos."""
    for path in (key_path, answers_path):
        if not path.is_file():
            raise SystemExit(f"{path}: no such file (the key is written beside the sheet, as SHEET.png.key.txt)")
    key = {(r, c): kind for r, c, kind in TILE_LINE.findall(key_path.read_text())}
    answers = {(r, c): kind for r, c, kind in TILE_LINE.findall(answers_path.read_text())}
    if set(answers) != set(key):
        raise SystemExit(f"{answers_path}: {len(answers)} answers for the {len(key)} tiles of {key_path}")
    right = {kind: sum(answers[t] == kind for t in key if key[t] == kind) for kind in ("synthetic", "real")}
    total = {kind: sum(kind == k for k in key.values()) for kind in ("synthetic", "real")}
    return (f"{sum(right.values())}/{len(key)} right: {right['synthetic']}/{total['synthetic']} renders found, "
            f"{right['real']}/{total['real']} photos called real (chance: half)")


def main(argv: list[str] | None = None) -> None:
    """Write the sheet and its key, or score a judge's answers against the key."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True, help="PNG to write (the key goes to OUT.key.txt)")
    parser.add_argument("--preset", default="high")
    parser.add_argument("--config", type=Path, help="a YAML scene configuration applied over the preset")
    parser.add_argument("--wells", type=int, default=24, help="wells of each kind")
    parser.add_argument("--split", choices=("all", "fit", "check"), default="fit")
    parser.add_argument("--tile", type=int, default=160, help="tile side in pixels")
    parser.add_argument("--seed", type=int, default=0, help="seed of the choice of photos, wells and their order")
    parser.add_argument("--first-scene", type=int, default=10_000,
                        help="seed of the first rendered scene (the renders are of scenes FIRST, FIRST + 1, ...)")
    parser.add_argument("--score", type=Path, help="a judge's answers to score against OUT's key (writes nothing)")
    args = parser.parse_args(argv)
    if args.score:
        print(score(Path(f"{args.out}.key.txt"), args.score))
        return

    import numpy as np
    from PIL import Image

    from platesynth.io import list_images, read_image
    from platesynth.metrics import crop_well, fit_plate_grid
    from platesynth.render.raster import render_raster
    from platesynth.scene import load_config, sample_scene

    rng = np.random.default_rng(args.seed)
    plates = [p for p in list_images(SHARED / "data" / "plaque12" / "plates") if in_split(p.name, args.split)]
    if not plates:
        raise SystemExit(f"no real photos of the {args.split} split under {SHARED}")
    real = []
    for path in rng.permutation(plates):
        image = read_image(path)
        discs = fit_plate_grid(image)
        for index in rng.permutation(len(discs))[:3]:
            real.append(crop_well(image, discs[index], args.tile))
        if len(real) >= args.wells:
            break
    synthetic = []
    config = load_config(args.preset, path=args.config)
    seed = 0
    while len(synthetic) < args.wells:
        scene = sample_scene(config, args.first_scene + seed)
        seed += 1
        image = render_raster(scene, (1216, 944)).image
        discs = fit_plate_grid(image, (scene.plate.rows, scene.plate.cols))
        for index in rng.permutation(len(discs))[:3]:
            synthetic.append(crop_well(image, discs[index], args.tile))
    tiles = [(tile, "real") for tile in real[: args.wells]] + [(tile, "synthetic") for tile in synthetic[: args.wells]]
    order = rng.permutation(len(tiles))
    columns = 8
    rows = -(-len(tiles) // columns)
    sheet = Image.new("RGB", (columns * args.tile, rows * args.tile), (255, 255, 255))
    key = []
    for position, index in enumerate(order):
        tile, kind = tiles[index]
        sheet.paste(Image.fromarray(tile), ((position % columns) * args.tile, (position // columns) * args.tile))
        key.append(f"row {position // columns}, column {position % columns}: {kind}")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    sheet.save(args.out)
    Path(f"{args.out}.key.txt").write_text("\n".join(key) + "\n")
    look = args.preset + (f" with {args.config}" if args.config else "")
    print(f"{args.out}: {len(tiles)} wells ({args.split} photos, preset {look}); key in {args.out}.key.txt")


if __name__ == "__main__":
    main()
