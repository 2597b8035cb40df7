"""Speed of the Blender backend in a warm worker, beside the raster renderer on the same scenes, same run.

For each scene (preset ``high``, seeds 1..n) the script renders with Blender (Cycles, CPU, the default samples,
image pass + exact-mask pass) and with the raster renderer, and prints per image: Blender's wall time as seen by
the caller, the worker's CPU time (all threads; other processes on the shared machine change it much less than the
wall time), the raster renderer's wall time, the ratio of the two, and how well the masks agree (share of pixels
with the same well id; intersection over union of the plaque pixels). The issue's target: at most 5 s per
1024x768 image including exact masks on 2 cores. The worker is started and warmed by a tiny render first (not
timed); so is the raster renderer's numba compilation.

``--realism N`` also renders N images of each backend at the real crops' size (1216x944) and prints the AlexNet
Fréchet distance and dNf of both against ``../shared/data/plaque12/plates`` (needs the AlexNet weights).

Run: ``python benchmarks/bench_blender.py`` (``--count N``, ``--size WxH``, ``--samples S``, ``--preset P``,
``--realism N``, ``--compare-size WxH``).
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("PLATESYNTH_SHARED", ROOT.parent / "shared"))
TARGET_SECONDS = 5.0


def _size(text: str) -> tuple[int, int]:
    width, height = (int(v) for v in text.lower().split("x"))
    return width, height


def _agreement(blender, raster) -> tuple[float, float]:
    wells = float((blender.wells == raster.wells).mean())
    both = ((blender.plaques > 0) & (raster.plaques > 0)).sum()
    either = ((blender.plaques > 0) | (raster.plaques > 0)).sum()
    return wells, float(both / either) if either else 1.0


def speed(args: argparse.Namespace) -> None:
    from platesynth.render.blender import DEFAULT_SAMPLES, render_blender
    from platesynth.render.raster import render_raster
    from platesynth.scene import load_config, sample_scene

    size = _size(args.size)
    samples = args.samples or DEFAULT_SAMPLES
    config = load_config(args.preset)
    print(f"Blender backend vs raster renderer, preset {args.preset}, {size[0]}x{size[1]}, {samples} samples, "
          f"{os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.2f} at start")
    warm = sample_scene(config, 0)
    render_blender(warm, (64, 48), samples=1)  # start the worker: import bpy, load the kernels
    render_raster(warm, (64, 48))  # compile / load the numba kernels
    print(f"{'seed':>4s} {'plaques':>7s} {'blender s':>9s} {'cpu s':>6s} {'raster s':>8s} {'ratio':>6s} {'wells =':>8s} {'plaque IoU':>10s}")
    walls, cpus, rasters = [], [], []
    for seed in range(1, args.count + 1):
        scene = sample_scene(config, seed)
        stats: dict = {}
        start = time.perf_counter()
        blender = render_blender(scene, size, samples=samples, stats=stats)
        wall = time.perf_counter() - start
        start = time.perf_counter()
        raster = render_raster(scene, size)
        raster_wall = time.perf_counter() - start
        wells, plaques = _agreement(blender, raster)
        walls.append(wall)
        cpus.append(stats["cpu_seconds"])
        rasters.append(raster_wall)
        print(f"{seed:4d} {len(scene.plaques):7d} {wall:9.2f} {stats['cpu_seconds']:6.2f} {raster_wall:8.2f} "
              f"{wall / raster_wall:6.1f} {wells:8.4f} {plaques:10.4f}")
    median_wall, median_cpu, median_raster = (statistics.median(v) for v in (walls, cpus, rasters))
    print(f"median: blender {median_wall:.2f} s/image (cpu {median_cpu:.2f} s, i.e. about {median_cpu / 2:.2f} s on 2 "
          f"free cores), raster {median_raster:.2f} s/image, ratio {median_wall / median_raster:.1f}; "
          f"target {TARGET_SECONDS:.0f} s -> {'met' if median_wall <= TARGET_SECONDS else 'not met'} by wall time")
    print(f"load average {os.getloadavg()[0]:.2f} at end")


def realism(args: argparse.Namespace) -> None:
    from PIL import Image

    from platesynth.io import list_images
    from platesynth.metrics.dataset import dataset_metrics
    from platesynth.render.blender import render_blender
    from platesynth.render.raster import render_raster
    from platesynth.scene import load_config, sample_scene

    real = SHARED / "data" / "plaque12" / "plates"
    if not os.environ.get("PLATESYNTH_WEIGHTS_DIR") and (SHARED / "weights").is_dir():
        os.environ["PLATESYNTH_WEIGHTS_DIR"] = str(SHARED / "weights")
    if not real.is_dir():
        print(f"realism skipped: {real} not found (set PLATESYNTH_SHARED)")
        return
    render_size, compare = (1216, 944), _size(args.compare_size)
    config = load_config(args.preset)
    with tempfile.TemporaryDirectory(prefix="bench-blender-") as tmp:
        folders = {name: Path(tmp) / name for name in ("real", "blender", "raster")}
        for folder in folders.values():
            folder.mkdir()
        for path in list_images(real):
            with Image.open(path) as image:
                image.convert("RGB").resize(compare, Image.Resampling.LANCZOS).save(folders["real"] / f"{path.stem}.png")
        for seed in range(args.realism):
            scene = sample_scene(config, 1000 + seed)
            for name, draw in (("blender", lambda s: render_blender(s, render_size, samples=args.samples)), ("raster", lambda s: render_raster(s, render_size))):
                image = Image.fromarray(draw(scene).image).resize(compare, Image.Resampling.LANCZOS)
                image.save(folders[name] / f"{seed:04d}.png")
        print(f"realism against {real} ({len(list_images(real))} photos), {args.realism} images per backend "
              f"rendered at {render_size[0]}x{render_size[1]}, compared at {compare[0]}x{compare[1]}")
        print(f"{'backend':8s} {'FD alexnet':>11s} {'KID':>8s} {'nf':>7s} {'dNf':>7s}")
        for name in ("blender", "raster"):
            metrics = dataset_metrics(folders[name], folders["real"])
            print(f"{name:8s} {metrics['fd_alexnet']:11.2f} {metrics['kid_alexnet']:8.4f} {metrics['nf_mean']:7.4f} {metrics['dnf']:7.4f}")


def main(argv: list[str] | None = None) -> int:
    """Print the speed table (and the realism table with ``--realism N``)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=5, help="timed scenes (0: only the realism table)")
    parser.add_argument("--size", default="1024x768", help="WIDTHxHEIGHT of the timed renders")
    parser.add_argument("--samples", type=int, default=None, help="Cycles samples (default: the backend's)")
    parser.add_argument("--preset", default="high")
    parser.add_argument("--realism", type=int, default=0, help="images per backend for the realism table (0: none)")
    parser.add_argument("--compare-size", default="608x472", help="WIDTHxHEIGHT the realism sets are resized to")
    parser.add_argument("--quick", action="store_true", help="2 timed scenes, no realism table")
    args = parser.parse_args(argv)
    from platesynth.render.blender import bpy_available

    if not bpy_available():
        print("bench_blender skipped: bpy is not installed (pip install 'platesynth[blender]')")
        return 0
    if args.quick:
        args.count, args.realism = 2, 0
    if args.count:
        speed(args)
    if args.realism:
        realism(args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
