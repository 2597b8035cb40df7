"""Realism of the raster renderer's presets against the real 12-well plate photos.

Renders ``--count`` images per preset (seeds 0..count-1, or from ``--first-seed``) into a temporary folder and
prints, for each preset and for the real set, the AlexNet Fréchet distance and kernel distance to the real photos, the naturalness factor and
dNf = |nf_real - nf|, the pixel entropy (size-matched: mean over subsets as large as the smaller set, since entropy
grows with the number of images) and the brightness variability, all from :func:`platesynth.metrics.dataset_metrics`;
then the well-crop metrics of :mod:`platesynth.metrics.wells` (wells of the renders from their true masks, wells of
the photos from a fitted 3x4 grid, crops of 128x128): ``fd_wells`` and ``kid_wells`` (AlexNet features of the
crops), ``nn_acc_wells`` (leave-one-out accuracy of the nearest neighbour in that feature space at telling the
renders' wells from the photos': 0.5 when they cannot be told apart; not measured for the real set), ``dnf_wells``
(|difference of the crops' mean Nf|), ``spec_wells`` (RMS difference of the mean log10 power spectra of the
monolayer, decades: the renders' plaques left out, the photos' kept as they have no masks) and ``spec_w_plaques``
(the same with plaques kept in both sets, like for like).

The real set is ``../shared/data/plaque12/plates`` (39 crops of ~1200x950 px). The renders are made at 1216x944
(the crops' typical size and aspect); ``--compare-size`` resizes both sets (Lanczos) before measuring, e.g. to
compare quickly at half size.

Run: ``python benchmarks/realism_table.py`` (``--count 100`` is the issue's protocol; ``--count 20 --compare-size
608x472`` takes a few minutes). Needs the AlexNet weights (``PLATESYNTH_WEIGHTS_DIR`` or ``../shared/weights``).
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
import warnings
from pathlib import Path

from shared_split import split_folder

ROOT = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("PLATESYNTH_SHARED", ROOT.parent / "shared"))
COLUMNS = ("fd_alexnet", "kid_alexnet", "nf", "dnf", "entropy", "brightness_var", "fd_wells", "kid_wells",
           "nn_acc_wells", "dnf_wells", "spec_wells", "spec_w_plaques")
SEED_STRIDE = 1000
"""``--repeats`` draws its sets of scenes this many seeds apart."""


def _size(text: str) -> tuple[int, int]:
    width, height = (int(v) for v in text.lower().split("x"))
    return width, height


def _resized(image, size: tuple[int, int] | None):
    from PIL import Image

    image = Image.fromarray(image) if not isinstance(image, Image.Image) else image.convert("RGB")
    return image if size is None else image.resize(size, Image.Resampling.LANCZOS)


def _resized_reference(source: Path, size: tuple[int, int], target: Path) -> Path:
    from PIL import Image

    from platesynth.io import list_images

    target.mkdir(parents=True, exist_ok=True)
    for path in list_images(source):
        with Image.open(path) as image:
            _resized(image, size).save(target / f"{path.stem}.png")
    return target


def _render_preset(preset: str, seeds: range, size: tuple[int, int], compare: tuple[int, int] | None, folder: Path):
    """Render into a dataset layout (images/, masks/wells/, masks/plaques/, params/), masks resized like the images."""
    import numpy as np
    from PIL import Image

    from platesynth.data.layout import item_paths
    from platesynth.io import write_json, write_tiff
    from platesynth.render import render
    from platesynth.scene import load_config, sample_scene

    def nearest(mask):
        if compare is None:
            return mask
        return np.asarray(Image.fromarray(mask).resize(compare, Image.Resampling.NEAREST))

    config = load_config(path=preset) if preset.endswith(".yaml") else load_config(preset)
    start = time.perf_counter()
    for seed in seeds:
        scene = sample_scene(config, seed)
        result = render(scene, size)
        item = item_paths(folder, f"{Path(preset).stem}_{seed:04d}")
        item.image_path.parent.mkdir(parents=True, exist_ok=True)
        _resized(result.image, compare).save(item.image_path)
        write_tiff(item.wells_path, nearest(result.wells))
        write_tiff(item.plaques_path, nearest(result.plaques))
        write_json(item.params_path, {"scene": scene.model_dump(mode="json")})
    return time.perf_counter() - start


def paired_differences(rows: dict[str, list[dict[str, float]]]) -> dict[str, tuple]:
    """Each preset's :data:`COLUMNS` minus the first preset's, scene set by scene set (``rows[name][k]`` the row of
    set ``k``): ``{name: (mean, sd)}`` over the sets, arrays in :data:`COLUMNS` order, for every preset but the
    first (sd with one degree of freedom: nan for one set)."""
    import numpy as np

    first, *others = rows
    differences = {name: np.array([[row[c] - base[c] for c in COLUMNS] for row, base in zip(rows[name], rows[first],
                                                                                            strict=True)])
                   for name in others}
    return {name: (d.mean(axis=0), d.std(axis=0, ddof=1) if len(d) > 1 else np.full(len(COLUMNS), np.nan))
            for name, d in differences.items()}


def main(argv: list[str] | None = None) -> None:
    """Print the realism table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=100, help="images per preset")
    parser.add_argument("--first-seed", type=int, default=0,
                        help="seeds first..first+count-1 (another set of scenes: how far the figures move by chance)")
    parser.add_argument("--repeats", type=int, default=1,
                        help=f"sets of scenes, each {SEED_STRIDE} seeds after the last: the table's mean over them, "
                             "and each preset's difference to the first, set by set (mean and sd)")
    parser.add_argument("--size", type=_size, default=(1216, 944), help="render size WIDTHxHEIGHT")
    parser.add_argument("--presets", default="high,medium,low",
                        help="comma-separated preset names or configuration files (*.yaml, labelled by their stem)")
    parser.add_argument("--split", choices=("all", "fit", "check"), default="all",
                        help="real photos to compare with: all, or the fit or check viruses (benchmarks/shared_split.py)")
    parser.add_argument("--reference", type=Path, default=SHARED / "data" / "plaque12" / "plates")
    parser.add_argument("--compare-size", type=_size, default=None, help="resize renders and photos to WIDTHxHEIGHT")
    parser.add_argument("--keep", type=Path, default=None, help="keep the renders in this folder")
    args = parser.parse_args(argv)
    if not args.reference.is_dir():
        sys.exit(f"{args.reference}: no such folder (set PLATESYNTH_SHARED to the shared material)")
    os.environ.setdefault("PLATESYNTH_WEIGHTS_DIR", str(SHARED / "weights"))

    import numpy as np

    from platesynth.io import list_images
    from platesynth.metrics import (
        MetricSkippedWarning,
        collect_well_crops,
        compare_well_crops,
        dataset_metrics,
        get_feature_extractor,
        size_matched_entropy,
    )

    warnings.simplefilter("ignore", MetricSkippedWarning)  # no Inception weights offline: AlexNet only
    with tempfile.TemporaryDirectory() as tmp:
        work = args.keep or Path(tmp)
        reference = args.reference
        if args.split != "all":
            reference = split_folder(reference, args.split, Path(tmp) / f"reference-{args.split}")
        if args.compare_size:
            reference = _resized_reference(reference, args.compare_size, Path(tmp) / "reference")
        n_real = len(list_images(reference))
        extractor = get_feature_extractor("alexnet")
        real_wells = collect_well_crops(reference, extractor=extractor)  # once: the same for every preset
        rows: dict[str, list[dict[str, float]]] = {}
        real_row: dict[str, float] = {}
        for repeat in range(args.repeats):
            seeds = range(args.first_seed + repeat * SEED_STRIDE, args.first_seed + repeat * SEED_STRIDE + args.count)
            for preset in args.presets.split(","):
                folder = work / f"{Path(preset).stem}-{repeat}"
                seconds = _render_preset(preset, seeds, args.size, args.compare_size, folder)
                metrics = dataset_metrics(folder / "images", reference)
                wells = compare_well_crops(collect_well_crops(folder, extractor=extractor), real_wells)
                subset = min(args.count, n_real)
                shape = tuple(metrics["size"])
                rows.setdefault(Path(preset).stem, []).append({
                    "fd_alexnet": metrics["fd_alexnet"],
                    "kid_alexnet": metrics["kid_alexnet"],
                    "nf": metrics["nf_mean"],
                    "dnf": metrics["dnf"],
                    "entropy": size_matched_entropy(list_images(folder / "images"), subset, size=shape),
                    "brightness_var": metrics["brightness_variability"],
                    "fd_wells": wells["fd_wells"],
                    "kid_wells": wells["kid_wells"],
                    "nn_acc_wells": wells["nn_accuracy_wells"],
                    "dnf_wells": wells["dnf_wells"],
                    "spec_wells": wells["spectrum_distance_wells"],
                    "spec_w_plaques": wells["spectrum_distance_wells_with_plaques"],
                })
                real_row = real_row or {  # the photos' own row: the same for every preset and set of scenes
                    "fd_alexnet": 0.0,
                    "kid_alexnet": 0.0,
                    "nf": metrics["nf_mean_reference"],
                    "dnf": 0.0,
                    "entropy": size_matched_entropy(list_images(reference), subset, size=shape),
                    "brightness_var": metrics["brightness_variability_reference"],
                    "fd_wells": 0.0,
                    "kid_wells": 0.0,
                    "nn_acc_wells": float("nan"),  # not measured: a set against itself
                    "dnf_wells": 0.0,
                    "spec_wells": 0.0,
                    "spec_w_plaques": 0.0,
                }
                print(f"[{preset}, seeds {seeds.start}-{seeds.stop - 1}: {args.count} renders at "
                      f"{args.size[0]}x{args.size[1]} in {seconds:.0f} s; {wells['n_wells']} wells against "
                      f"{wells['n_wells_reference']} real ones]", file=sys.stderr)
    compared = f", both resized to {args.compare_size[0]}x{args.compare_size[1]}" if args.compare_size else ""
    sets = f"; the mean of {args.repeats} sets of scenes" if args.repeats > 1 else ""
    print(f"realism against {args.reference} ({n_real} images); {args.count} renders per preset at "
          f"{args.size[0]}x{args.size[1]}{compared}; entropy over subsets of {min(args.count, n_real)} images; "
          f"well crops 128x128{sets}")
    print(f"{'set':10s}" + "".join(f"{c:>16s}" for c in COLUMNS))
    for name, measured in [*rows.items(), ("real", [real_row])]:
        print(f"{name:10s}" + "".join(f"{np.mean([row[c] for row in measured]):16.4f}" for c in COLUMNS))
    if args.repeats > 1 and len(rows) > 1:
        first = next(iter(rows))
        print(f"\neach preset minus {first}, scene set by scene set: mean and sd over the {args.repeats} sets")
        print(f"{'set':10s}" + "".join(f"{c:>16s}" for c in COLUMNS))
        for name, (mean, sd) in paired_differences(rows).items():
            print(f"{name:10s}" + "".join(f"{m:+9.3f} ±{d:5.2f}" for m, d in zip(mean, sd)))

if __name__ == "__main__":
    main()
