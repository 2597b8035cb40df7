"""Throughput of the whole ``platesynth render`` command against the in-process renderer, in the same run.

``bench_raster.py`` times the renderer alone; a dataset also costs writing the files (PNG, two TIFF masks, the
params JSON), starting the worker processes (Python, imports, loading numba's cached kernels) and the tables at
the end. This script times, alternating them ``--repeat`` times so that a change in the machine's load hits
every kind alike:

- ``in-process``: ``render_item`` for every image in this process (scene sampling and rendering, numba on every
  core), nothing written: the rate the command is measured against;
- ``+ write``: the same and ``write_item`` of every item into a temporary dataset, in this process;
- ``command``: ``platesynth render --out TMP --count N --size WxH --workers W --preset P`` in a new process, from
  its start to its exit (including the interpreter's start and the worker processes').

It prints images/s, CPU ms per image (all processes and threads; other load on the shared machine changes it far
less than the wall-clock rate) and the ratio of each to the in-process rate of the same round, then the medians.
No target is asserted.

Run: ``python benchmarks/bench_render_command.py`` (``--count 24 --size 1024x768 --workers 2 --preset high
--repeat 3``; ``--quick`` for a small run).
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def _cpu_self() -> float:
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def _cpu_children() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def command_line(out: Path, args: argparse.Namespace) -> list[str]:
    """The ``platesynth render`` command, run through the console script beside this interpreter where it exists."""
    script = Path(sys.executable).with_name("platesynth")
    head = [str(script)] if script.is_file() else [sys.executable, "-c", "from platesynth.cli import main; main()"]
    return [*head, "render", "--out", str(out), "--count", str(args.count), "--size", args.size,
            "--workers", str(args.workers), "--preset", args.preset]


def time_in_process(manifest, directory: Path | None) -> tuple[float, float]:
    """Wall and CPU seconds of rendering (and, with ``directory``, writing) every item of ``manifest`` here."""
    from platesynth.data.batch import render_item
    from platesynth.data.layout import item_name, item_paths
    from platesynth.data.writer import prepare_directory, write_item

    if directory is not None:
        prepare_directory(directory, manifest)
    start, cpu = time.perf_counter(), _cpu_self()
    for index in range(manifest.count):
        result, params = render_item(manifest, index)
        if directory is not None:
            write_item(item_paths(directory, item_name(index)), result, params)
    return time.perf_counter() - start, _cpu_self() - cpu


def time_command(args: argparse.Namespace, out: Path) -> tuple[float, float]:
    """Wall and CPU seconds (the command and its workers) of one ``platesynth render`` run into a new ``out``."""
    shutil.rmtree(out, ignore_errors=True)
    start, cpu = time.perf_counter(), _cpu_children()
    done = subprocess.run(command_line(out, args), capture_output=True, text=True)
    wall, used = time.perf_counter() - start, _cpu_children() - cpu
    if done.returncode != 0:
        raise SystemExit(f"the command failed ({done.returncode}):\n{done.stderr[-2000:]}")
    return wall, used


def main(argv: list[str] | None = None) -> int:
    """Print the rates of each round and the medians."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=24, help="images per run")
    parser.add_argument("--size", default="1024x768", help="WIDTHxHEIGHT")
    parser.add_argument("--workers", type=int, default=2, help="--workers of the command")
    parser.add_argument("--preset", default="high")
    parser.add_argument("--repeat", type=int, default=3, help="rounds of the three measurements")
    parser.add_argument("--quick", action="store_true", help="8 images of 512x384, 2 rounds")
    args = parser.parse_args(sys.argv[1:] if argv is None else argv)
    if args.quick:
        args.count, args.size, args.repeat = 8, "512x384", 2

    from platesynth.data.batch import build_manifest, render_item

    width, height = (int(v) for v in args.size.lower().split("x"))
    manifest = build_manifest(preset=args.preset, seed=0, count=args.count, size=(width, height))
    render_item(manifest, 0)  # numba's kernels compiled or loaded from the cache, as bench_raster.py does
    print(f"platesynth render: {args.count} images of {width}x{height}, preset {args.preset}, --workers "
          f"{args.workers}; {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.2f} at start")
    print(f"command: {' '.join(command_line(Path('OUT'), args))}")
    print(f"{'round':>5s} {'kind':>10s} {'s':>7s} {'img/s':>7s} {'cpu ms/img':>11s} {'x in-process':>13s}")
    rates: dict[str, list[float]] = {"in-process": [], "+ write": [], "command": []}
    cpus: dict[str, list[float]] = {kind: [] for kind in rates}
    ratios: dict[str, list[float]] = {kind: [] for kind in rates}
    with tempfile.TemporaryDirectory(prefix="bench-render-") as tmp:
        for round_ in range(1, args.repeat + 1):
            timings = {
                "in-process": time_in_process(manifest, None),
                "+ write": time_in_process(manifest, Path(tmp) / f"written{round_}"),
                "command": time_command(args, Path(tmp) / "command"),
            }
            base = args.count / timings["in-process"][0]
            for kind, (wall, cpu) in timings.items():
                rate = args.count / wall
                rates[kind].append(rate)
                cpus[kind].append(1000 * cpu / args.count)
                ratios[kind].append(rate / base)
                print(f"{round_:5d} {kind:>10s} {wall:7.2f} {rate:7.2f} {1000 * cpu / args.count:11.1f} "
                      f"{rate / base:13.2f}")
    print("median:")
    for kind in rates:
        print(f"{'':5s} {kind:>10s} {'':7s} {statistics.median(rates[kind]):7.2f} "
              f"{statistics.median(cpus[kind]):11.1f} {statistics.median(ratios[kind]):13.2f}")
    print(f"load average {os.getloadavg()[0]:.2f} at end")
    return 0


if __name__ == "__main__":
    sys.exit(main())
