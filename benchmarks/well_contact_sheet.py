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

Each key line also names what its tile shows: its class, its plate and well, and the median 8-bit colour of the
middle of the tile (``row 0, column 3: real | photo PR8, 0 plaques | PR8_plate4.jpg B2 | centre RGB 80 0 218``; a
render's class says whether its plate is a pale or a saturated one and whether the well is lysed), so that
``--breakdown SHEET.png=ANSWERS.txt ...`` can count the calls right per class of tile over many sheets and judges
(``--by plate``: per photo or rendered scene): which renders are found, and which photos are doubted.

``--interior`` keeps only the middle disc of every tile (:data:`INTERIOR`), the rest white: the stained layer without
the wall, the plastic and the light box around it, to tell which of the two a judge's calls rest on.
"""

from __future__ import annotations

import argparse
import os
import re
from pathlib import Path

from shared_split import in_split, virus

ROOT = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("PLATESYNTH_SHARED", ROOT.parent / "shared"))


TILE_LINE = re.compile(r"row (\d+), column (\d+): (real|synthetic)")
KEY_FIELDS = re.compile(r"^row (\d+), column (\d+): (?:real|synthetic) \| ([^|]+?) \| (\S+(?: \d+)?) (\w+)",
                        re.MULTILINE)
"""A key line's tile, class, plate (a photo's file name, or ``scene N``) and well."""
CENTRE = 0.3
"""Half-side of the middle of a tile whose median colour a key line gives, share of the tile's side."""
# a scene whose stain is less saturated than this is one of the pale, bluish plates (stain.pale_plates): the
# threshold lies between the catalogue's pale_saturation (0.45-0.7) and saturation (0.9-1.0)
PALE_SATURATION = 0.8
MAX_SCENES = 1000
"""Scenes a sheet renders at most looking for wells that match ``--renders``."""
INTERIOR = 0.94
"""With ``--interior``, a tile keeps the disc of this share of its half-side (the stain's edge lies at about 0.97)."""


def count_class(count: int | None) -> str:
    """A well's plaque count in the classes the breakdown groups by (``None``: a well judged uncountable)."""
    if count is None:
        return "uncountable"
    if count == 0:
        return "0 plaques"
    return "1-10 plaques" if count <= 10 else "over 10 plaques"


def tile_radius(side: int):
    """Each pixel's distance from the centre of a square tile of ``side`` pixels, in half-sides (the stain's edge lies
    at about 0.97)."""
    import numpy as np

    y, x = np.mgrid[:side, :side] - (side - 1) / 2
    return np.hypot(x, y) / (side / 2)


def interior_only(tile):
    """``tile`` (square, RGB uint8) with everything outside its middle disc (:data:`INTERIOR`) white."""
    out = tile.copy()
    out[tile_radius(tile.shape[0]) > INTERIOR] = 255
    return out


def photo_class(name: str, count: int | None) -> str:
    """The class of a photo's well: its virus and its person's count."""
    return f"photo {virus(name)}, {count_class(count)}"


def render_class(scene, well) -> str:
    """The class of a render's well: a pale or a saturated plate, and its plaque count (lysed: uncountable; a well
    drawn without cells, ``wells.emptied``, which no photo has: empty)."""
    plate = "pale" if scene.stain.saturation < PALE_SATURATION else "saturated"
    if well.emptied:
        return f"render {plate} plate, empty"
    count = sum(plaque.well == well.id for plaque in scene.plaques) if well.countable else None
    return f"render {plate} plate, {count_class(count)}"


def _read_key(key_path: Path) -> dict[tuple[str, str], str]:
    if not key_path.is_file():
        raise SystemExit(f"{key_path}: no such file (the key is written beside the sheet, as SHEET.png.key.txt)")
    return {(r, c): kind for r, c, kind in TILE_LINE.findall(key_path.read_text())}


def _read_answers(answers_path: Path, key: dict[tuple[str, str], str], key_path: Path) -> dict[tuple[str, str], str]:
    if not answers_path.is_file():
        raise SystemExit(f"{answers_path}: no such file")
    answers = {(r, c): kind for r, c, kind in TILE_LINE.findall(answers_path.read_text())}
    if set(answers) != set(key):
        raise SystemExit(f"{answers_path}: {len(answers)} answers for the {len(key)} tiles of {key_path}")
    return answers


def score(key_path: Path, answers_path: Path) -> str:
    """How many of a judge's answers match the key: in all, among the renders and among the photos."""
    key = _read_key(key_path)
    answers = _read_answers(answers_path, key, key_path)
    right = {kind: sum(answers[t] == kind for t in key if key[t] == kind) for kind in ("synthetic", "real")}
    total = {kind: sum(kind == k for k in key.values()) for kind in ("synthetic", "real")}
    return (f"{sum(right.values())}/{len(key)} right: {right['synthetic']}/{total['synthetic']} renders found, "
            f"{right['real']}/{total['real']} photos called real (chance: half)")


def centre_colour(tile) -> str:
    """The median 8-bit RGB of the middle of a tile (its central ``2 * CENTRE`` of each side), as a key line gives it."""
    import numpy as np

    side = tile.shape[0]
    low, high = round(side * (0.5 - CENTRE)), round(side * (0.5 + CENTRE))
    return "centre RGB " + " ".join(str(int(v)) for v in np.median(tile[low:high, low:high].reshape(-1, 3), axis=0))


def rim_torn_wells(scene_seed: int, preset: str = "high", config: Path | None = None) -> set[str]:
    """Labels of the wells of a rendered scene that hold a tear at the rim (``artifacts.rim_tears``): the scratches
    beyond those of the same scene drawn without tears, which draw from a stream of their own after all else."""
    from platesynth.scene import load_config, sample_scene

    torn = sample_scene(load_config(preset, path=config), scene_seed)
    plain = sample_scene(load_config(preset, path=config, overrides={"artifacts.rim_tears": 0.0}), scene_seed)
    tears = torn.artifacts.scratches[len(plain.artifacts.scratches):]
    labels = {well.id: well.label for well in torn.wells}
    return {labels[tear.well] for tear in tears}


def breakdown(pairs: list[tuple[Path, Path]], by: str = "class", preset: str = "high",
              config: Path | None = None) -> str:
    """Calls right per class of tile (``by="class"``), per plate (``"plate"``: a photo, or a rendered scene) or, for
    the renders, by whether their well holds a tear at the rim (``"rim-tear"``, the photos by class; the sheets'
    ``preset`` and ``config`` give the scenes) over (key, answers) pairs: a table of the group, tiles judged and calls
    right.

    A render is called right when found (called synthetic), a photo when called real; a group where most calls are
    right is one that the judges tell apart.
    """
    right: dict[str, int] = {}
    judged: dict[str, int] = {}
    torn_wells: dict[int, set[str]] = {}
    for key_path, answers_path in pairs:
        key = _read_key(key_path)
        fields = {(r, c): (name, plate, well) for r, c, name, plate, well in KEY_FIELDS.findall(key_path.read_text())}
        classes = {tile: plate if by == "plate" else name for tile, (name, plate, _) in fields.items()}
        if by == "rim-tear":
            for tile, (_, plate, well) in fields.items():
                if plate.startswith("scene "):
                    seed = int(plate.split()[1])
                    if seed not in torn_wells:
                        torn_wells[seed] = rim_torn_wells(seed, preset, config)
                    classes[tile] = "render, a rim tear" if well in torn_wells[seed] else "render, no rim tear"
        if set(classes) != set(key):
            raise SystemExit(f"{key_path}: a key without the tiles' classes (made before they were written); make the "
                             "sheet again with the same options")
        answers = _read_answers(answers_path, key, key_path)
        for tile, kind in key.items():
            judged[classes[tile]] = judged.get(classes[tile], 0) + 1
            right[classes[tile]] = right.get(classes[tile], 0) + (answers[tile] == kind)
    width = max(map(len, judged))
    lines = [f"{by:<{width}}  calls  right", *(
        f"{name:<{width}}  {judged[name]:5d}  {right[name]:5d} ({right[name] / judged[name]:.0%})"
        for name in sorted(judged))]
    return "\n".join(lines)


def collect_tiles(rng, split: str, wells: int, tile: int, photos: str = "", renders: str = "", preset: str = "high",
                  config: Path | None = None, first_scene: int = 10_000, interior: bool = False):
    """The photo and render tiles of one sheet, before shuffling: two lists of ``(tile, description)``, ``wells`` of
    each kind, drawn with ``rng`` (the sheet's seeded generator, which goes on to shuffle them).

    Photos of ``split`` are taken in a random order, up to three matching wells of each (``photos``: a regular
    expression on the class); renders are of scenes ``first_scene``, ``first_scene + 1``, ... of ``preset`` with
    ``config`` over it, up to three matching wells of each (``renders``). Raises SystemExit where too few match."""
    from platesynth.data.layout import read_counts_csv
    from platesynth.io import list_images, read_image
    from platesynth.metrics import crop_well, fit_plate_grid
    from platesynth.render.raster import render_raster
    from platesynth.scene import load_config, sample_scene

    root = SHARED / "data" / "plaque12"
    plates = [p for p in list_images(root / "plates") if in_split(p.name, split)]
    if not plates:
        raise SystemExit(f"no real photos of the {split} split under {SHARED}")
    counts = {(row.image, row.row, row.col): row for row in read_counts_csv(root / "counts.csv")}
    grid = (3, 4)  # the shared photos' 12-well plates; fit_plate_grid numbers the discs row by row
    photos_wanted, renders_wanted = re.compile(photos), re.compile(renders)
    real = []
    for path in rng.permutation(plates):
        plate_wells = [counts[(path.name, *divmod(index, grid[1]))] for index in range(grid[0] * grid[1])]
        chosen = [int(i) for i in rng.permutation(len(plate_wells))
                  if photos_wanted.search(photo_class(path.name, plate_wells[i].count))][:3]
        if not chosen:
            continue
        image = read_image(path)
        discs = fit_plate_grid(image, grid)
        for index in chosen:
            crop = crop_well(image, discs[index], tile)
            crop = interior_only(crop) if interior else crop
            well = plate_wells[index]
            real.append((crop, f"{photo_class(path.name, well.count)} | {path.name} {well.well} | {centre_colour(crop)}"))
        if len(real) >= wells:
            break
    if len(real) < wells:
        raise SystemExit(f"only {len(real)} photo wells of the {split} split match --photos {photos!r}")
    synthetic = []
    scene_config = load_config(preset, path=config)
    seed = 0
    while len(synthetic) < wells:
        if seed == MAX_SCENES:
            raise SystemExit(f"only {len(synthetic)} wells of {MAX_SCENES} scenes match --renders {renders!r}")
        scene = sample_scene(scene_config, first_scene + seed)
        seed += 1
        chosen = [int(i) for i in rng.permutation(len(scene.wells))
                  if renders_wanted.search(render_class(scene, scene.wells[i]))][:3]
        if not chosen:
            continue
        image = render_raster(scene, (1216, 944)).image
        discs = fit_plate_grid(image, (scene.plate.rows, scene.plate.cols))
        for index in chosen:
            well = scene.wells[index]
            crop = crop_well(image, discs[index], tile)
            crop = interior_only(crop) if interior else crop
            synthetic.append((crop, f"{render_class(scene, well)} | scene {first_scene + seed - 1} {well.label} | "
                                    f"{centre_colour(crop)}"))
    return real[:wells], synthetic[:wells]


def main(argv: list[str] | None = None) -> None:
    """Write the sheet and its key, or score a judge's answers against the key."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, help="PNG to write (the key goes to OUT.key.txt)")
    parser.add_argument("--preset", default="high")
    parser.add_argument("--config", type=Path, help="a YAML scene configuration applied over the preset")
    parser.add_argument("--wells", type=int, default=24, help="wells of each kind")
    parser.add_argument("--split", choices=("all", "fit", "check"), default="fit")
    parser.add_argument("--tile", type=int, default=160, help="tile side in pixels")
    parser.add_argument("--seed", type=int, default=0, help="seed of the choice of photos, wells and their order")
    parser.add_argument("--first-scene", type=int, default=10_000,
                        help="seed of the first rendered scene (the renders are of scenes FIRST, FIRST + 1, ...)")
    parser.add_argument("--photos", default="",
                        help="only photo wells whose class matches this regular expression (e.g. 'PR8|Brisbane')")
    parser.add_argument("--renders", default="",
                        help="only rendered wells whose class matches this regular expression (e.g. 'saturated')")
    parser.add_argument("--interior", action="store_true",
                        help="keep only the middle disc of every tile: the layer without what surrounds the well")
    parser.add_argument("--score", type=Path, help="a judge's answers to score against OUT's key (writes nothing)")
    parser.add_argument("--breakdown", nargs="+", metavar="SHEET=ANSWERS",
                        help="calls right per class of tile over these sheets' judges (writes nothing; no --out)")
    parser.add_argument("--by", choices=("class", "plate", "rim-tear"), default="class",
                        help="group --breakdown's calls by class of tile, by plate (photo or rendered scene) or, for "
                             "the renders, by whether their well holds a tear at the rim (with the sheets' --preset "
                             "and --config)")
    args = parser.parse_args(argv)
    if args.breakdown:
        pairs = [item.split("=", 1) for item in args.breakdown]
        if any(len(pair) != 2 for pair in pairs):
            raise SystemExit("--breakdown takes SHEET.png=ANSWERS.txt pairs")
        print(breakdown([(Path(f"{sheet}.key.txt"), Path(answers)) for sheet, answers in pairs], by=args.by,
                        preset=args.preset, config=args.config))
        return
    if args.out is None:
        parser.error("--out is required (the sheet to write, or the sheet whose key --score reads)")
    if args.score:
        print(score(Path(f"{args.out}.key.txt"), args.score))
        return

    import numpy as np
    from PIL import Image

    rng = np.random.default_rng(args.seed)
    real, synthetic = collect_tiles(rng, args.split, args.wells, args.tile, args.photos, args.renders, args.preset,
                                    args.config, args.first_scene, args.interior)
    tiles = [(*tile, "real") for tile in real] + [(*tile, "synthetic") for tile in synthetic]
    order = rng.permutation(len(tiles))
    columns = 8
    rows = -(-len(tiles) // columns)
    sheet = Image.new("RGB", (columns * args.tile, rows * args.tile), (255, 255, 255))
    key = []
    for position, index in enumerate(order):
        tile, what, kind = tiles[index]
        sheet.paste(Image.fromarray(tile), ((position % columns) * args.tile, (position // columns) * args.tile))
        key.append(f"row {position // columns}, column {position % columns}: {kind} | {what}")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    sheet.save(args.out)
    Path(f"{args.out}.key.txt").write_text("\n".join(key) + "\n")
    look = args.preset + (f" with {args.config}" if args.config else "")
    print(f"{args.out}: {len(tiles)} wells ({args.split} photos, preset {look}); key in {args.out}.key.txt")


if __name__ == "__main__":
    main()
