"""A tiny study shared by tests/test_study.py and tests/test_report.py: built once per test session.

Real inputs come from ``../shared`` (a few plate photos shrunk into a temporary folder, their rows of counts.csv);
the tests that use them skip with a clear message where it is absent.
"""

from __future__ import annotations

import contextlib
import csv
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import yaml

REFERENCE = ("Brisbane_plate2", "Brisbane_plate3", "PR8_plate1")
EVALUATED = ("PR8_plate3", "PR8_plate4")
PHOTO_SIZE = (304, 236)
TINY_MODEL = {"channels": [8, 12, 16], "context_dilations": [2], "input_long_side": 128}
ARMS = [
    {"name": "high-S", "preset": "high", "count": 4, "seeds": [1]},
    {"name": "low-S", "preset": "low", "count": 4, "seeds": [1, 2]},
]
ADDED_ARMS = [
    {"name": "medium-S", "preset": "medium", "count": 4, "seeds": [3]},
    {"name": "mix", "label": "high+low", "mix": {"high-S": 0.5, "low-S": 0.5}, "seeds": [1]},
]

_built: dict[str, Any] = {}


def study_data(arms: list[dict[str, Any]], inputs: Path) -> dict[str, Any]:
    """A tiny study: 128x96 images, 1 epoch of 2 steps of a small network, a 2-image test set."""
    return {
        "name": "tiny",
        "reference": str(inputs / "reference"),
        "evaluation": {"images": str(inputs / "photos"), "counts": str(inputs / "counts.csv"),
                       "test": {"preset": "high", "count": 2, "seed": 999}},
        "size": "128x96",
        "recipe": {"epochs": 1, "steps": 2, "batch_size": 2, "patch": "64x64", "val_fraction": 0.25,
                   "model": TINY_MODEL},
        "metrics": {"entropy_subset": 3, "entropy_subsets": 2},
        "arms": arms,
    }


def write_study(path: Path, arms: list[dict[str, Any]], inputs: Path) -> Path:
    """Write a study file."""
    path.write_text(yaml.safe_dump(study_data(arms, inputs), sort_keys=False), encoding="utf-8")
    return path


def make_inputs(folder: Path, shared: Path) -> Path:
    """Shrunk copies of a few shared photos (reference and evaluated) and the counts of the evaluated ones."""
    from PIL import Image

    plates = shared / "data" / "plaque12" / "plates"
    for subfolder, names in (("reference", REFERENCE), ("photos", EVALUATED)):
        (folder / subfolder).mkdir(parents=True, exist_ok=True)
        for name in names:
            with Image.open(plates / f"{name}.jpg") as image:
                image.convert("RGB").resize(PHOTO_SIZE, Image.Resampling.LANCZOS).save(folder / subfolder / f"{name}.png")
    with (shared / "data" / "plaque12" / "counts.csv").open(encoding="utf-8", newline="") as handle:
        rows = [row for row in csv.DictReader(handle) if row["image"].removesuffix(".jpg") in EVALUATED]
    with (folder / "counts.csv").open("w", encoding="utf-8", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["image", "row", "col", "well", "count"])
        for row in rows:
            writer.writerow([row["image"].replace(".jpg", ".png"), row["row"], row["col"], row["well"], row["count"]])
    return folder


@contextlib.contextmanager
def offline_weights(world: dict[str, Any]) -> Iterator[None]:
    """While the block runs: the developers' AlexNet weights, offline, no Inception weights, one torch thread."""
    import torch

    saved = {k: os.environ.get(k) for k in ("PLATESYNTH_WEIGHTS_DIR", "PLATESYNTH_OFFLINE", "TORCH_HOME",
                                            "PLATESYNTH_FID_WEIGHTS")}
    threads = torch.get_num_threads()
    os.environ["PLATESYNTH_WEIGHTS_DIR"] = str(world["shared"] / "weights")
    os.environ["PLATESYNTH_OFFLINE"] = "1"
    os.environ["TORCH_HOME"] = str(world["root"] / "torch-home")
    os.environ.pop("PLATESYNTH_FID_WEIGHTS", None)
    torch.set_num_threads(1)
    try:
        yield
    finally:
        torch.set_num_threads(threads)
        for key, value in saved.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value


def tiny_study(tmp_path_factory: Any) -> dict[str, Any]:
    """The two-arm study, run once per session: ``{"inputs", "study_file", "out", "result"}``."""
    from conftest import shared_path

    shared = shared_path("data", "plaque12", "plates").parents[2]  # skips where ../shared is absent
    shared_path("weights", "alexnet_features-7be5be79.pth")
    if "study" not in _built:
        from platesynth.study import load_study, run_study

        root = tmp_path_factory.mktemp("tiny-study")
        world: dict[str, Any] = {"shared": shared, "root": root, "inputs": make_inputs(root / "inputs", shared)}
        world["study_file"] = write_study(root / "study.yaml", ARMS, world["inputs"])
        world["out"] = root / "out"
        with offline_weights(world):
            world["result"] = run_study(load_study(world["study_file"]), world["out"], inputs=(world["study_file"],))
        _built["study"] = world
    return _built["study"]
