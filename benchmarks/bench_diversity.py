"""Pixel entropy and brightness variability: platesynth's streaming metrics against granatpy 0.1.3.

Writes deterministic plate-like PNG datasets to a temporary directory (100 images of 256x256 and 1000 of 512x384),
runs both implementations on the same files and prints the time of each, their ratio and the largest absolute
difference. Both sides are timed end to end from the file paths (PNG decoding included, single thread); the
"metric only" line compares our update/compute on images already in memory with granatpy's time minus its own image
loading (the same ``Image.open(path).convert("L")`` loop, timed separately). Our times are the best of 3 runs,
granatpy's a single run; the first use of our numba kernels is timed apart.

Run: ``python benchmarks/bench_diversity.py`` (``--quick`` for the small dataset only). Exits 1 if a value differs
from granatpy by more than 1e-9.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from PIL import Image

from platesynth.io import read_image
from platesynth.metrics.diversity import BrightnessVariability, PixelEntropy, grayscale

TOLERANCE = 1e-9
OUR_REPEATS = 3  # ours runs in seconds: its best of 3 is robust to other processes' bursts; granatpy runs once
DATASETS = ((100, 256, 256), (1000, 512, 384))  # (images, width, height)


def write_dataset(directory: Path, n_images: int, width: int, height: int, seed: int = 0) -> list[Path]:
    """Write ``n_images`` plate-like RGB PNGs: a lit background, dark stained wells with clear plaques, noise."""
    rng = np.random.default_rng(seed)
    rows, cols = np.mgrid[0:height, 0:width].astype(np.float32)
    well_radius = min(width / 4, height / 3) * 0.42
    centres = [((c + 0.5) * width / 4, (r + 0.5) * height / 3) for r in range(3) for c in range(4)]
    paths = []
    for index in range(n_images):
        light = 200 + 30 * rng.uniform(-1, 1) * (cols / width - 0.5) + 20 * rng.uniform(-1, 1) * (rows / height - 0.5)
        stain = np.zeros((height, width), np.float32)
        for cx, cy in centres:
            cx, cy = cx + rng.normal(0, 2), cy + rng.normal(0, 2)
            inside = (cols - cx) ** 2 + (rows - cy) ** 2 < well_radius**2
            stain[inside] = rng.uniform(0.5, 0.8)
            for _ in range(rng.integers(0, 12)):
                px, py = cx + rng.uniform(-0.7, 0.7) * well_radius, cy + rng.uniform(-0.7, 0.7) * well_radius
                stain[(cols - px) ** 2 + (rows - py) ** 2 < rng.uniform(2, 8) ** 2] *= 0.2
        violet = np.array([0.45, 0.85, 0.35], np.float32)  # fraction of light absorbed per channel at full stain
        image = light[..., None] * (1 - stain[..., None] * violet)
        image += rng.normal(0, 4, image.shape).astype(np.float32)
        path = directory / f"plate_{index:04d}.png"
        Image.fromarray(np.clip(image, 0, 255).astype(np.uint8)).save(path)
        paths.append(path)
    return paths


def stream_files(paths: list[Path], metrics: list) -> list[float]:
    """Read every file once (as :func:`platesynth.metrics.dataset_metrics` does) and feed every metric."""
    for path in paths:
        gray = grayscale(read_image(path))
        for metric in metrics:
            metric.update(gray)
    return [metric.compute() for metric in metrics]


def stream_arrays(grays: list[np.ndarray], metrics: list) -> list[float]:
    for gray in grays:
        for metric in metrics:
            metric.update(gray)
    return [metric.compute() for metric in metrics]


def warm_up() -> float:
    """Load (or compile) the numba kernels for uint8 and uint16 counts; return the seconds it took."""
    start = time.perf_counter()
    stream_arrays([np.full((2, 2), i, np.uint8) for i in range(260)], [PixelEntropy()])
    return time.perf_counter() - start


def timed(func, *args):
    start = time.perf_counter()
    value = func(*args)
    return value, time.perf_counter() - start


def best_of(repeats: int, func, make_args):
    """Value and smallest time of ``repeats`` calls of ``func(*make_args())`` (fresh metrics each time)."""
    runs = [timed(func, *make_args()) for _ in range(repeats)]
    return runs[0][0], min(seconds for _, seconds in runs)


def run_dataset(n_images: int, width: int, height: int) -> bool:
    from granatpy.metrics import brightness_var, dataset_entropy

    with tempfile.TemporaryDirectory(prefix="bench_diversity_") as tmp:
        paths = write_dataset(Path(tmp), n_images, width, height)
        names = [str(p) for p in paths]
        stream_files(paths, [])  # a first read of every file (page cache, allocator), for both sides
        (our_entropy,), our_entropy_time = best_of(OUR_REPEATS, stream_files, lambda: (paths, [PixelEntropy()]))
        (our_variability,), our_variability_time = best_of(
            OUR_REPEATS, stream_files, lambda: (paths, [BrightnessVariability()])
        )
        _, our_both_time = best_of(
            OUR_REPEATS, stream_files, lambda: (paths, [PixelEntropy(), BrightnessVariability()])
        )
        grays = [grayscale(read_image(p)) for p in paths]
        _, our_metric_time = best_of(
            OUR_REPEATS, stream_arrays, lambda: (grays, [PixelEntropy(), BrightnessVariability()])
        )
        grays = None  # free the decoded images before the reference runs
        their_entropy, their_entropy_time = timed(dataset_entropy, names, None)
        their_variability, their_variability_time = timed(brightness_var, names, None)
        _, their_loading_time = timed(lambda: [np.array(Image.open(p).convert("L"), dtype=np.uint8) for p in names])

    their_both_time = their_entropy_time + their_variability_time
    their_metric_time = their_both_time - 2 * their_loading_time  # granatpy reads the files once per metric
    entropy_diff = abs(our_entropy - their_entropy)
    variability_diff = abs(our_variability - their_variability)
    print(f"{n_images} images of {width}x{height} (load average {os.getloadavg()[0]:.1f}):")
    print(
        f"  entropy                values ours {our_entropy:.12f}  granatpy {their_entropy:.12f}  "
        f"|diff| {entropy_diff:.1e}"
    )
    print(
        f"  brightness variability values ours {our_variability:.9f}  granatpy {their_variability:.9f}  "
        f"|diff| {variability_diff:.1e}"
    )
    print("  times from the PNG files (decoding included):")
    print(
        f"    entropy                ours {our_entropy_time:8.3f} s  granatpy {their_entropy_time:8.3f} s  "
        f"ratio {their_entropy_time / our_entropy_time:6.1f}x"
    )
    print(
        f"    brightness variability ours {our_variability_time:8.3f} s  granatpy {their_variability_time:8.3f} s  "
        f"ratio {their_variability_time / our_variability_time:6.1f}x"
    )
    print(
        f"    both (ours: one pass)  ours {our_both_time:8.3f} s  granatpy {their_both_time:8.3f} s  "
        f"ratio {their_both_time / our_both_time:6.1f}x"
    )
    print(
        f"  both, metric only (images in memory): ours {our_metric_time:.3f} s, granatpy ~{their_metric_time:.3f} s "
        f"(its time minus 2 x {their_loading_time:.3f} s of loading), ratio ~{their_metric_time / our_metric_time:.0f}x"
    )
    return entropy_diff <= TOLERANCE and variability_diff <= TOLERANCE


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="only the small dataset")
    args = parser.parse_args(argv if argv is not None else [])
    print(f"first use (numba kernels loaded or compiled): {warm_up():.2f} s, not counted below")
    ok = True
    for n_images, width, height in DATASETS[:1] if args.quick else DATASETS:
        ok &= run_dataset(n_images, width, height)
    print("parity:", "OK" if ok else f"FAILED (a difference above {TOLERANCE})")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
