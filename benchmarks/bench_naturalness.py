"""Naturalness Nf: platesynth against granatpy 0.1.3 on 1024x768 RGB images, speed and parity.

Uses the real plate photos of ``../shared/data/plaque12/plates`` (resized to 1024x768) where they exist, else
generated plate-like 1024x768 images. For each image both implementations run on the same array in this process:
granatpy's ``naturalize_rgb_image`` and our ``naturalness`` (whole RGB image, all three channels, end to end) are
timed in turns (1 call of granatpy then 5 of ours, a few rounds) and their medians printed with their ratio and the
largest absolute differences of Nf, T1 and T2.
Our first call, which loads or compiles the numba kernels, is timed separately and left out of the medians.

Run: ``python benchmarks/bench_naturalness.py`` (``--quick`` for 2 images and 1 repeat). Exits 1 if a value differs
from granatpy by more than 1e-6 or the naturalized images differ.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np
from PIL import Image

from platesynth.io import list_images, read_image
from platesynth.metrics.naturalness import naturalize, naturalness

TOLERANCE = 1e-6
SPEED_TARGET = 20.0
OUR_CALLS_PER_REPEAT = 5  # ours is fast: more samples make its median robust to other processes' bursts
SIZE = (1024, 768)  # width, height
SHARED = Path(os.environ.get("PLATESYNTH_SHARED", Path(__file__).resolve().parents[1].parent / "shared"))
PLATES = SHARED / "data" / "plaque12" / "plates"


def generated_plate(seed: int) -> np.ndarray:
    """A plate-like RGB image: lit background, violet wells with clear plaques, sensor noise."""
    rng = np.random.default_rng(seed)
    width, height = SIZE
    rows, cols = np.mgrid[0:height, 0:width].astype(np.float32)
    light = 200 + 30 * rng.uniform(-1, 1) * (cols / width - 0.5) + 20 * rng.uniform(-1, 1) * (rows / height - 0.5)
    stain = np.zeros((height, width), np.float32)
    well_radius = min(width / 4, height / 3) * 0.42
    for r in range(3):
        for c in range(4):
            cx, cy = (c + 0.5) * width / 4, (r + 0.5) * height / 3
            stain[(cols - cx) ** 2 + (rows - cy) ** 2 < well_radius**2] = rng.uniform(0.5, 0.8)
            for _ in range(rng.integers(0, 15)):
                px, py = cx + rng.uniform(-0.7, 0.7) * well_radius, cy + rng.uniform(-0.7, 0.7) * well_radius
                stain[(cols - px) ** 2 + (rows - py) ** 2 < rng.uniform(3, 15) ** 2] *= 0.2
    image = light[..., None] * (1 - stain[..., None] * np.array([0.45, 0.85, 0.35], np.float32))
    image += rng.normal(0, 4, image.shape).astype(np.float32)
    return np.clip(np.round(image), 0, 255).astype(np.uint8)


def load_images(count: int) -> list[tuple[str, np.ndarray]]:
    """``count`` named 1024x768 RGB images: real plates where available, else generated ones."""
    if PLATES.is_dir():
        paths = list_images(PLATES)[:count]
        return [(p.name, np.asarray(Image.fromarray(read_image(p)).resize(SIZE, Image.BILINEAR))) for p in paths]
    print(f"{PLATES} not found: using generated images")
    return [(f"generated-{seed}", generated_plate(seed)) for seed in range(count)]


def timed(func, image: np.ndarray):
    start = time.perf_counter()
    result = func(image)
    return result, time.perf_counter() - start


def median_times(image: np.ndarray, repeats: int):
    """Granatpy's and our results and median seconds, the two timed in turns so that load affects both alike."""
    from granatpy.core import naturalize_rgb_image

    their_times, our_times = [], []
    for _ in range(repeats):
        theirs, seconds = timed(naturalize_rgb_image, image)
        their_times.append(seconds)
        for _ in range(OUR_CALLS_PER_REPEAT):
            ours, seconds = timed(naturalness, image)
            our_times.append(seconds)
    return theirs, statistics.median(their_times), ours, statistics.median(our_times)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="2 images, 1 repeat")
    parser.add_argument("--images", type=int, default=5, help="number of images (default 5)")
    parser.add_argument(
        "--repeats", type=int, default=3, help="rounds per image, each 1 granatpy call and 5 of ours (default 3)"
    )
    args = parser.parse_args(argv if argv is not None else [])
    count, repeats = (2, 1) if args.quick else (args.images, args.repeats)

    images = load_images(count)
    start = time.perf_counter()
    naturalness(images[0][1])
    print(f"first call (numba kernels loaded or compiled): {time.perf_counter() - start:.2f} s, not counted below")
    print(
        f"{len(images)} images of {SIZE[0]}x{SIZE[1]} RGB, median of {repeats} granatpy call(s) "
        f"and {repeats * OUR_CALLS_PER_REPEAT} of ours per image"
    )
    header = ("granatpy s", "ours s", "ratio", "max|dNf|", "max|dT1|", "max|dT2|")
    print(f"{'image':28s} " + " ".join(f"{h:>10s}" for h in header) + "  naturalized")

    ratios, worst, ok = [], 0.0, True
    for name, image in images:
        (their_image, their_nf, their_t1, their_t2, _), their_time, ours, our_time = median_times(image, repeats)
        differences = [
            np.abs(ours.nf - their_nf).max(),
            np.abs(ours.t1 - their_t1).max(),
            np.abs(ours.t2 - their_t2).max(),
        ]
        same_image = np.array_equal(naturalize(image), their_image)
        ok &= max(differences) <= TOLERANCE and same_image
        worst = max(worst, *differences)
        ratios.append(their_time / our_time)
        print(
            f"{name:28s} {their_time:10.3f} {our_time:10.4f} {ratios[-1]:9.1f}x "
            + " ".join(f"{d:10.1e}" for d in differences)
            + f"  {'identical' if same_image else 'DIFFERENT'}"
        )

    print(
        f"speed ratio granatpy/ours: median {statistics.median(ratios):.1f}x, min {min(ratios):.1f}x "
        f"(target {SPEED_TARGET:.0f}x: {'met' if min(ratios) >= SPEED_TARGET else 'NOT met'})"
    )
    print(f"largest |difference| of Nf, T1, T2: {worst:.1e}")
    print("parity:", "OK" if ok else f"FAILED (a difference above {TOLERANCE} or a different naturalized image)")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
