"""The options of the benchmarks that render a preset to compare with the photos: which preset, with which YAML
configuration over it (``--config``) and overrides (``--set name=value``, as ``platesynth render`` takes them), how
many images, from which seed."""

from __future__ import annotations

import argparse


def add_preset_options(parser: argparse.ArgumentParser, images: int, seed: int) -> None:
    """Add ``--preset``, ``--config``, ``--images``, ``--seed`` and ``--set`` to ``parser``."""
    parser.add_argument("--preset", default="high")
    parser.add_argument("--config", help="a YAML scene configuration applied over the preset")
    parser.add_argument("--images", type=int, default=images, help="synthetic images")
    parser.add_argument("--seed", type=int, default=seed)
    parser.add_argument("--set", action="append", default=[], metavar="NAME=VALUE", help="override a parameter")


def preset_config(args: argparse.Namespace):
    """The scene configuration the options name, and its label for a table ("high", "high with look.yaml", or
    "high (with --set)")."""
    import yaml

    from platesynth.scene import load_config

    overrides = {name: yaml.safe_load(value) for name, value in (item.split("=", 1) for item in args.set)}
    label = args.preset + (f" with {args.config}" if args.config else "") + (" (with --set)" if overrides else "")
    return load_config(args.preset, path=args.config, overrides=overrides), label
