"""The options of the benchmarks that render a preset to compare with the photos: which preset, how many images, from
which seed, with which overrides (``--set name=value``, as ``platesynth render`` takes them)."""

from __future__ import annotations

import argparse


def add_preset_options(parser: argparse.ArgumentParser, images: int, seed: int) -> None:
    """Add ``--preset``, ``--images``, ``--seed`` and ``--set`` to ``parser``."""
    parser.add_argument("--preset", default="high")
    parser.add_argument("--images", type=int, default=images, help="synthetic images")
    parser.add_argument("--seed", type=int, default=seed)
    parser.add_argument("--set", action="append", default=[], metavar="NAME=VALUE", help="override a parameter")


def preset_config(args: argparse.Namespace):
    """The scene configuration the options name, and its label for a table ("high", or "high (with --set)")."""
    import yaml

    from platesynth.scene import load_config

    overrides = {name: yaml.safe_load(value) for name, value in (item.split("=", 1) for item in args.set)}
    label = args.preset + (" (with --set)" if overrides else "")
    return load_config(args.preset, overrides=overrides), label
