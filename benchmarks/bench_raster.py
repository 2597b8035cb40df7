"""Speed of the raster renderer: images per second at 1024x768 for each preset (target: 4 img/s on 2 cores).

There is no reference renderer to compare with, so the script prints each preset's rate against the project's
target of 4 images/s, and the machine's load average (the CPUs are shared) next to it. It also prints the CPU
time per image (all threads), which other processes on the machine affect much less than the wall-clock rate:
N cores free for this work give about N * 1000 / (cpu ms) images/s. Every image is a new scene (seeds
0..n-1); scene sampling is timed separately from rendering. The first render of a process compiles (or loads
from cache) the numba kernels and is not timed.

Run: ``python benchmarks/bench_raster.py`` (``--count N``, ``--size WxH``, ``--presets high,low``,
``--threads T`` to pin numba's thread count).
"""

from __future__ import annotations

import argparse
import os
import time

TARGET_IMAGES_PER_SECOND = 4.0


def main(argv: list[str] | None = None) -> None:
    """Print images/s per preset."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=20, help="images per preset")
    parser.add_argument("--size", default="1024x768", help="WIDTHxHEIGHT")
    parser.add_argument("--presets", default="high,medium,low,lightbox12,diverse")
    parser.add_argument("--threads", type=int, default=None, help="numba threads (default: all cores)")
    args = parser.parse_args(argv)
    if args.threads:
        os.environ["NUMBA_NUM_THREADS"] = str(args.threads)

    from platesynth.render.raster import render_raster
    from platesynth.scene import load_config, sample_scene

    width, height = (int(v) for v in args.size.lower().split("x"))
    import numba

    print(f"raster renderer, {width}x{height}, {args.count} images per preset, numba threads "
          f"{numba.get_num_threads()}, {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.2f} at start")
    render_raster(sample_scene(load_config("high"), 0), (width, height))  # compile / load the kernels
    print(f"{'preset':12s} {'sample ms':>10s} {'render ms':>10s} {'cpu ms':>8s} {'img/s':>7s} {'x target':>9s}")
    for preset in args.presets.split(","):
        config = load_config(preset)
        start, cpu_start = time.perf_counter(), time.process_time()
        scenes = [sample_scene(config, seed) for seed in range(args.count)]
        sampled = time.perf_counter() - start
        start = time.perf_counter()
        for scene in scenes:
            render_raster(scene, (width, height))
        rendered = time.perf_counter() - start
        cpu = time.process_time() - cpu_start
        rate = args.count / (sampled + rendered)
        print(f"{preset:12s} {1000 * sampled / args.count:10.1f} {1000 * rendered / args.count:10.1f} "
              f"{1000 * cpu / args.count:8.1f} {rate:7.2f} {rate / TARGET_IMAGES_PER_SECOND:9.2f}")
    print(f"load average {os.getloadavg()[0]:.2f} at end")


if __name__ == "__main__":
    main()
