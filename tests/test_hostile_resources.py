"""Hostile inputs against resources (issue 13), one table of cases through the real command line.

The classes: memory (requests whose estimate is above the limit, images whose header claims a huge size, YAML that
expands, configuration files that are not UTF-8), code execution (a checkpoint or weights file holding a pickle
payload) and unfinished trainings (a model directory whose training was interrupted, during an epoch or while tuning
its thresholds).

Every case runs in one worker process under ``RLIMIT_AS`` (:data:`ADDRESS_SPACE`), so a request that slips past its
check fails its case with a memory error instead of taking the machine down. Each case asserts a non-zero exit, one
line ``error: ...`` holding the expected text, no traceback, nothing written or changed in the world, and that no
pickle payload ran (its marker file is absent).
"""

from __future__ import annotations

import builtins
import hashlib
import json
import pickle
import shutil
import struct
import subprocess
import sys
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import pytest
import torch
from typer.testing import CliRunner

from platesynth.cli import app
from platesynth.segment.model import ModelConfig
from platesynth.segment.train import TrainConfig, train

ROOT = Path(__file__).resolve().parents[1]
SHIPPED_MODEL = ROOT / "models" / "plaque12"
ADDRESS_SPACE = 4 * 1024**3
"""The worker's address-space limit: the command line with torch needs about 1 GB of it."""
SMALL = ["--count", "1", "--preset", "high", "--seed", "3", "--size", "64x48"]
TINY_MODEL = {"channels": [8, 12, 16], "context_dilations": [2], "input_long_side": 128}
TINY_TRAIN = ["--model-config", "{w}/tiny.json", "--epochs", "1", "--steps", "1", "--batch-size", "1",
              "--patch", "32x32", "--no-tune", "--threads", "1"]
HUGE = 100_000

pytestmark = pytest.mark.usefixtures("one_torch_thread")


def ok(*args: str | Path) -> None:
    result = CliRunner().invoke(app, [str(a) for a in args])
    assert result.exit_code == 0, result.output


# --- hostile files ----------------------------------------------------------------------------------------------------


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def png_header(width: int, height: int, depth: int = 8) -> bytes:
    """A 69-byte PNG whose header claims ``width`` x ``height`` RGB pixels."""
    header = struct.pack(">IIBBBBB", width, height, depth, 2, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + _chunk(b"IHDR", header) + _chunk(b"IDAT", zlib.compress(b"\0" * 64)) + _chunk(b"IEND", b"")


def tiff_header(width: int, height: int) -> bytes:
    """A small zlib TIFF whose only strip claims ``width`` x ``height`` gray pixels."""
    data = zlib.compress(b"\0" * 64)
    entries = [(256, 4, width), (257, 4, height), (258, 3, 8), (259, 3, 8), (262, 3, 1), (273, 4, 0), (277, 3, 1),
               (278, 4, height), (279, 4, len(data))]
    data_offset = 8 + 2 + 12 * len(entries) + 4
    out = b"II*\0" + struct.pack("<IH", 8, len(entries))
    for tag, kind, value in entries:
        value = data_offset if tag == 273 else value
        out += struct.pack("<HHI", tag, kind, 1) + (struct.pack("<HH", value, 0) if kind == 3 else struct.pack("<I", value))
    return out + struct.pack("<I", 0) + data


def bmp_header(width: int, height: int) -> bytes:
    """A 58-byte BMP whose header claims ``width`` x ``height`` 24-bit pixels."""
    info = struct.pack("<IiiHHIIiiII", 40, width, height, 1, 24, 0, 4, 2835, 2835, 0, 0)
    return b"BM" + struct.pack("<IHHI", 14 + 40 + 4, 0, 0, 54) + info + b"\0" * 4


def alias_bomb(levels: int = 9) -> str:
    """The "billion laughs": 9 levels of 9 aliases each, 9**9 (387 million) strings from 600 bytes."""
    lines = ['a0: &a0 ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]']
    for level in range(1, levels):
        lines.append(f"a{level}: &a{level} [{', '.join([f'*a{level - 1}'] * 9)}]")
    return "\n".join(lines) + f"\nplaques: {{radius_mm: *a{levels - 1}}}\n"


class Payload:
    """Unpickling this creates the file ``path``: what a crafted checkpoint could do instead."""

    def __init__(self, path: Path) -> None:
        self.path = str(path)

    def __reduce__(self):
        return builtins.open, (self.path, "w")


def interrupted(work: Path, name: str, when: str) -> Path:
    """A model directory of a real training (2 epochs) stopped ``"epoch1"`` (during epoch 1), ``"epoch2"`` (during
    epoch 2) or ``"tuning"`` (while tuning its thresholds), as a kill would leave it."""

    class Stop(Exception):
        pass

    def progress(event: dict) -> None:
        if (when == "epoch1" and "loss" in event) or (when == "epoch2" and event.get("epoch") == 2 and "loss" in event):
            raise Stop

    model_dir = work / name
    config = TrainConfig(data=[str(work / "ds")], epochs=2, steps_per_epoch=1, batch_size=1, patch=(32, 32),
                         val_fraction=0.5, tune_thresholds=when == "tuning")
    if when == "tuning":
        import platesynth.segment.train as training

        tune, training.threshold_scores = training.threshold_scores, lambda *a, **k: (_ for _ in ()).throw(Stop())
        try:
            with pytest.raises(Stop):
                train(config, model_dir, ModelConfig(**TINY_MODEL))
        finally:
            training.threshold_scores = tune
    else:
        with pytest.raises(Stop):
            train(config, model_dir, ModelConfig(**TINY_MODEL), progress=progress)
    return model_dir


@pytest.fixture(scope="module")
def world(tmp_path_factory) -> Path:
    w = tmp_path_factory.mktemp("resources") / "w"
    w.mkdir()
    ok("render", "--out", w / "ds", *SMALL[:1], "2", *SMALL[2:])
    (w / "tiny.json").write_text(json.dumps(TINY_MODEL) + "\n")
    (w / "wide.json").write_text(json.dumps({**TINY_MODEL, "input_long_side": 100_000}) + "\n")
    # images whose headers claim 100000 x 100000 pixels (30 GB as RGB)
    (w / "huge.png").write_bytes(png_header(HUGE, HUGE))
    (w / "huge16.png").write_bytes(png_header(20_000, 20_000, depth=16))
    (w / "huge.tif").write_bytes(tiff_header(HUGE, HUGE))
    (w / "huge.bmp").write_bytes(bmp_header(HUGE, HUGE))
    (w / "huge_folder").mkdir()
    (w / "huge_folder" / "plate.png").write_bytes(png_header(HUGE, HUGE))
    shutil.copytree(w / "ds", w / "ds_huge")
    (w / "ds_huge" / "images" / "000001.png").write_bytes(png_header(HUGE, HUGE))
    # configuration files
    (w / "bomb.yaml").write_text(alias_bomb())
    (w / "merge.yaml").write_text("base: &base {format: 12}\nplate:\n  <<: *base\n")
    (w / "deep.yaml").write_text("plate: " + "[" * 5000 + "]" * 5000 + "\n")
    (w / "latin1.yaml").write_bytes("# plaque count of caf\xe9 plates\nplate:\n  format: 12\n".encode("latin-1"))
    (w / "utf16.yaml").write_bytes("plate:\n  format: 12\n".encode("utf-16"))
    (w / "big.yaml").write_text("# padding\n" * 200_000 + "plate:\n  format: 12\n")
    # models: complete ones with hostile files, unfinished ones as interruptions leave them
    ok("train", "--data", w / "ds", "--out", w / "model", *[a.format(w=w) for a in TINY_TRAIN])
    for name, payload in {
        "ckpt_zip": lambda m: torch.save({"model": Payload(w / "PWNED")}, m / "checkpoint.pt"),
        "ckpt_pickle": lambda m: (m / "checkpoint.pt").write_bytes(pickle.dumps(Payload(w / "PWNED"))),
        "ckpt_garbage": lambda m: (m / "checkpoint.pt").write_bytes(b"not a checkpoint"),
        "ckpt_foreign": lambda m: torch.save({"weights": torch.zeros(3)}, m / "checkpoint.pt"),
        "weights_zip": lambda m: torch.save(Payload(w / "PWNED"), m / "weights.pt"),
        "weights_pickle": lambda m: (m / "weights.pt").write_bytes(pickle.dumps(Payload(w / "PWNED"), protocol=2)),
    }.items():
        shutil.copytree(w / "model", w / name)
        payload(w / name)
    interrupted(w, "stopped_epoch1", "epoch1")
    interrupted(w, "stopped_epoch2", "epoch2")
    interrupted(w, "stopped_tuning", "tuning")
    shutil.copytree(w / "model", w / "legacy_unfinished")  # written before 'complete': no 'training' yet
    config = json.loads((w / "model" / "config.json").read_text())
    legacy = {k: v for k, v in config.items() if k != "complete"} | {"training": {}}
    (w / "legacy_unfinished" / "config.json").write_text(json.dumps(legacy))
    shutil.copytree(SHIPPED_MODEL, w / "plaque12")
    shutil.copytree(SHIPPED_MODEL, w / "wide_model")
    wide = json.loads((SHIPPED_MODEL / "config.json").read_text()) | {"input_long_side": 200_000}
    (w / "wide_model" / "config.json").write_text(json.dumps(wide))
    return w


# --- the table --------------------------------------------------------------------------------------------------------


@dataclass
class Case:
    id: str
    args: list[str]
    message: str | list[str]
    env: dict[str, str] = field(default_factory=dict)


M = ["--model", "{w}/plaque12"]
TRAIN = ["train", "--data", "{w}/ds", *TINY_TRAIN]
LIMIT_8G = {"PLATESYNTH_MEMORY_LIMIT": "8G"}
REFUSED = "refused, not a file of tensors and plain data only"
UNFINISHED = "is an unfinished training"
RESUME = "resume it by running the same `platesynth train --out"

CASES = [
    # 1. memory: requests estimated above the limit (the default: a share of the memory available under RLIMIT_AS)
    Case("render-largest-size", ["render", "--out", "{w}/new", *SMALL[:-1], "16384x16384"],
         ["render at 16384x16384 needs about 30 GB of memory, above the limit of", "set PLATESYNTH_MEMORY_LIMIT"]),
    Case("render-workers", ["render", "--out", "{w}/new", *SMALL[:-1], "8000x8000", "--workers", "4"],
         "render at 8000x8000 with 4 workers needs about 30 GB of memory, above the limit of 8.0 GB "
         "(PLATESYNTH_MEMORY_LIMIT=8G)", LIMIT_8G),
    Case("render-a-billion-images", ["render", "--out", "{w}/new", "--count", "1000000000", "--size", "64x48"],
         "render of 1,000,000,000 images at 64x48 needs about 2,000 GB of memory"),
    Case("render-limit-share", ["render", "--out", "{w}/new", *SMALL[:-1], "4000x3000"],
         ["render at 4000x3000 needs about 1.7 GB of memory", "(PLATESYNTH_MEMORY_LIMIT=1% of the"],
         {"PLATESYNTH_MEMORY_LIMIT": "1%"}),
    Case("render-limit-not-an-amount", ["render", "--out", "{w}/new", *SMALL],
         "PLATESYNTH_MEMORY_LIMIT='lots': expected an amount of memory such as 8G",
         {"PLATESYNTH_MEMORY_LIMIT": "lots"}),
    Case("preview-largest-size", ["preview", "--out", "{w}/new.png", "--size", "16384x16384"],
         "render of 12 images at 16384x16384 for a contact sheet needs about"),
    Case("preview-many-tiles", ["preview", "--out", "{w}/new.png", "--count", "100000", "--size", "640x480"],
         "render of 100,000 images at 640x480 for a contact sheet needs about 185 GB", LIMIT_8G),
    Case("demo-metrics-size", ["demo", "--out", "{w}/new", "--count", "2", "--size", "12000x9000"],
         "render of 2 images at 12000x9000 and their dataset metrics needs about 33 GB"),
    Case("metrics-dataset-huge-size", ["metrics", "dataset", "{w}/ds/images", "--size", "100000x100000"],
         "computing the dataset metrics at 100000x100000 needs about 3,050 GB of memory"),
    Case("metrics-dataset-large-size", ["metrics", "dataset", "{w}/ds/images", "--size", "6000x6000", "--no-frechet"],
         "computing the dataset metrics at 6000x6000 needs about 11 GB of memory, above the limit of 8.0 GB", LIMIT_8G),
    Case("metrics-well-size", ["metrics", "dataset", "{w}/ds", "--wells", "--reference", "{w}/ds/images", "--well-size",
                               "100000", "--no-frechet"], "cropping wells to 100000x100000 needs about"),
    Case("train-huge-patch", [*TRAIN, "--out", "{w}/new", "--patch", "65536x65536"],
         "training with a batch of 1 patches of 65536x65536 (working size 128) needs about"),
    Case("train-huge-batch", [*TRAIN, "--out", "{w}/new", "--batch-size", "100000000"],
         "training with a batch of 100000000 patches of 32x32 (working size 128) needs about"),
    Case("train-huge-working-size", [*TRAIN, "--out", "{w}/new", "--model-config", "{w}/wide.json"],
         "(working size 100000) needs about"),
    Case("predict-huge-working-size", ["predict", "{w}/ds/images/000000.png", "--model", "{w}/wide_model", "--out", "{w}/new"],
         # the shipped model knows its training well size, so a photo may be predicted at up to twice the working size
         "000000.png: prediction on 64x48 pixels (working size 400000) needs about"),
    # 1b. memory: images whose header claims more pixels than the limit, refused before decoding
    Case("predict-huge-png", ["predict", "{w}/huge.png", *M, "--out", "{w}/new"],
         "huge.png: the header says 100000x100000 pixels, above the limit of 268,435,456 pixels"),
    Case("predict-huge-tiff", ["predict", "{w}/huge.tif", *M, "--out", "{w}/new"],
         "huge.tif: the header says 100000x100000 pixels, above the limit"),
    Case("predict-huge-bmp", ["predict", "{w}/huge.bmp", *M, "--out", "{w}/new"],
         "huge.bmp: the header says 100000x100000 pixels, above the limit"),
    Case("pair-huge-png", ["metrics", "pair", "{w}/huge.png", "{w}/ds/images/000000.png"],
         "huge.png: the header says 100000x100000 pixels"),
    Case("pair-huge-16-bit-png", ["metrics", "pair", "{w}/ds/images/000000.png", "{w}/huge16.png"],
         "huge16.png: the header says 20000x20000 pixels"),
    Case("dataset-huge-png", ["metrics", "dataset", "{w}/huge_folder"], "plate.png: the header says 100000x100000 pixels"),
    Case("evaluate-masks-huge-image", ["evaluate", "masks", *M, "--data", "{w}/ds_huge"],
         "000001.png: the header says 100000x100000 pixels"),
    Case("train-huge-image", [*TRAIN, "--data", "{w}/ds_huge", "--out", "{w}/new"],
         "000001.png: the header says 100000x100000 pixels"),
    Case("pixel-limit-setting", ["predict", "{w}/ds/images/000000.png", *M, "--out", "{w}/new"],
         ["000000.png: the header says 64x48 pixels, above the limit of 1,000 pixels", "PLATESYNTH_MAX_IMAGE_PIXELS"],
         {"PLATESYNTH_MAX_IMAGE_PIXELS": "1000"}),
    Case("decoding-above-memory-limit", ["metrics", "pair", "{w}/ds/images/000000.png", "{w}/ds/images/000001.png"],
         "000000.png: decoding 64x48 pixels needs about", {"PLATESYNTH_MEMORY_LIMIT": "1M"}),
    # 1c. memory: configuration files that expand, nest without end, or are not UTF-8
    Case("yaml-billion-laughs", ["render", "--out", "{w}/new", *SMALL, "--config", "{w}/bomb.yaml"],
         "bomb.yaml: cannot read YAML (anchor &a0: anchors and aliases are not allowed"),
    Case("yaml-billion-laughs-show", ["scene", "show", "--config", "{w}/bomb.yaml"], "anchors and aliases are not allowed"),
    Case("yaml-merge-key", ["scene", "sample", "--config", "{w}/merge.yaml"], "anchor &base: anchors and aliases"),
    Case("yaml-alias-in-set", ["scene", "show", "--set", "plaques.radius_mm=[&a [1, 2], *a, *a]"], "the value is not valid YAML"),
    Case("yaml-deep-nesting", ["preview", "--out", "{w}/new.png", "--config", "{w}/deep.yaml"], "nested more than 32 levels deep"),
    Case("yaml-too-large", ["scene", "show", "--config", "{w}/big.yaml"], "larger than the 1,000,000 bytes a configuration"),
    Case("yaml-latin-1", ["render", "--out", "{w}/new", *SMALL, "--config", "{w}/latin1.yaml"],
         "latin1.yaml: not a UTF-8 text file (byte 0xe9 at position 21); save it as UTF-8"),
    Case("yaml-utf-16", ["scene", "show", "--config", "{w}/utf16.yaml"], "utf16.yaml: not a UTF-8 text file (byte 0xff at position 0)"),
    # 2. code execution: files from disk hold only tensors and plain data, or are refused without being unpickled
    Case("checkpoint-pickle-payload-zip", [*TRAIN, "--out", "{w}/ckpt_zip"], ["checkpoint.pt: " + REFUSED, "it names io.open"]),
    Case("checkpoint-pickle-payload-legacy", [*TRAIN, "--out", "{w}/ckpt_pickle"], "checkpoint.pt: " + REFUSED),
    Case("checkpoint-garbage", [*TRAIN, "--out", "{w}/ckpt_garbage"], "checkpoint.pt: " + REFUSED),
    Case("checkpoint-foreign-tensors", [*TRAIN, "--out", "{w}/ckpt_foreign"], "checkpoint.pt: not a platesynth training checkpoint"),
    Case("weights-pickle-payload-predict", ["predict", "{w}/ds/images/000000.png", "--model", "{w}/weights_zip", "--out", "{w}/new"],
         "weights.pt: " + REFUSED),
    Case("weights-pickle-payload-evaluate", ["evaluate", "masks", "--model", "{w}/weights_pickle", "--data", "{w}/ds"],
         "weights.pt: " + REFUSED),
    # 3. unfinished trainings are not models
    Case("predict-stopped-in-epoch-2", ["predict", "{w}/ds/images/000000.png", "--model", "{w}/stopped_epoch2", "--out", "{w}/new"],
         [f"stopped_epoch2 {UNFINISHED} (stopped during epoch 2 of 2); {RESUME}", "train.json"]),
    Case("evaluate-masks-stopped-in-epoch-2", ["evaluate", "masks", "--model", "{w}/stopped_epoch2", "--data", "{w}/ds"],
         f"{UNFINISHED} (stopped during epoch 2 of 2)"),
    Case("evaluate-counts-stopped-tuning", ["evaluate", "counts", "--model", "{w}/stopped_tuning", "--images", "{w}/ds/images",
                                            "--counts", "{w}/ds/counts.csv"],
         f"stopped_tuning {UNFINISHED} (stopped after epoch 2 of 2, while tuning its thresholds); {RESUME}"),
    Case("predict-stopped-in-epoch-1", ["predict", "{w}/ds/images/000000.png", "--model", "{w}/stopped_epoch1", "--out", "{w}/new"],
         f"{UNFINISHED} (stopped during epoch 1 of 2)"),
    Case("demo-stopped-tuning", ["demo", "--out", "{w}/new", "--count", "1", "--size", "64x48", "--model", "{w}/stopped_tuning"],
         f"{UNFINISHED} (stopped after epoch 2 of 2, while tuning its thresholds)"),
    Case("wells-model-stopped-in-epoch-2", ["metrics", "dataset", "{w}/ds/images", "--reference", "{w}/ds/images", "--wells",
                                            "--no-frechet", "--model", "{w}/stopped_epoch2"], UNFINISHED),
    Case("predict-legacy-unfinished", ["predict", "{w}/ds/images/000000.png", "--model", "{w}/legacy_unfinished", "--out", "{w}/new"],
         f"legacy_unfinished {UNFINISHED} (stopped after epoch 1 of 1, while tuning its thresholds)"),
]

RUNNER = r"""
import hashlib, json, resource, sys
resource.setrlimit(resource.RLIMIT_AS, (int(sys.argv[1]), resource.RLIM_INFINITY))
import torch
torch.set_num_threads(1)
from pathlib import Path
from typer.testing import CliRunner
from platesynth.cli import app

def snapshot(root):
    return {p.relative_to(root).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else "dir"
            for p in sorted(root.rglob("*"))}

world = Path(sys.argv[2])
for line in sys.stdin:
    case = json.loads(line)
    before = snapshot(world)
    try:
        result = CliRunner().invoke(app, case["args"], env=case["env"])
        report = {"exit_code": result.exit_code, "output": result.output,
                  "exception": None if result.exception is None or isinstance(result.exception, SystemExit)
                  else repr(result.exception)}
    except BaseException as exc:
        report = {"exit_code": None, "output": "", "exception": repr(exc)}
    after = snapshot(world)
    report["changed"] = sorted(k for k in before.keys() | after.keys() if before.get(k) != after.get(k))
    print(json.dumps({"id": case["id"], **report}), flush=True)
"""


@pytest.fixture(scope="module")
def results(world) -> dict[str, dict]:
    """Every case's outcome, from one worker process under RLIMIT_AS."""
    lines = "".join(
        json.dumps({"id": c.id, "args": [a.format(w=world) for a in c.args],
                    "env": {"PLATESYNTH_MEMORY_LIMIT": None, "PLATESYNTH_MAX_IMAGE_PIXELS": None, **c.env}}) + "\n"
        for c in CASES
    )
    done = subprocess.run([sys.executable, "-c", RUNNER, str(ADDRESS_SPACE), str(world)], input=lines,
                          capture_output=True, text=True, timeout=300, cwd=world)
    reports = {}
    for line in done.stdout.splitlines():
        if line.startswith("{"):
            report = json.loads(line)
            reports[report["id"]] = report
    reports["__stderr__"] = {"output": done.stderr[-3000:], "returncode": done.returncode}
    return reports


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_hostile_resource_is_refused_in_one_line_and_changes_nothing(case, world, results):
    report = results.get(case.id)
    assert report is not None, f"the worker died before this case: {results['__stderr__']}"
    output = report["output"]
    assert report["exception"] is None, report["exception"]
    assert report["exit_code"] not in (0, None), output
    assert "Traceback" not in output
    lines = [line for line in output.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), output
    for text in [case.message] if isinstance(case.message, str) else case.message:
        assert text in lines[0], output
    assert report["changed"] == [], report["changed"]
    assert not (world / "PWNED").exists(), "a pickle payload ran"


def test_the_table_is_large_enough():
    assert len(CASES) >= 25 and len({c.id for c in CASES}) == len(CASES)


# --- what the table cannot show ------------------------------------------------------------------------------------


def test_unfinished_training_resumes_into_a_complete_model(world, tmp_path):
    model_dir = tmp_path / "stopped"
    shutil.copytree(world / "stopped_epoch2", model_dir)
    assert json.loads((model_dir / "config.json").read_text())["complete"] is False
    config = TrainConfig(data=[str(world / "ds")], epochs=2, steps_per_epoch=1, batch_size=1, patch=(32, 32),
                         val_fraction=0.5, tune_thresholds=False)
    summary = train(config, model_dir, ModelConfig(**TINY_MODEL))
    assert summary.resumed_from_epoch == 1 and summary.epochs_done == 2
    assert json.loads((model_dir / "config.json").read_text())["complete"] is True
    ok("predict", world / "ds" / "images" / "000000.png", "--model", model_dir, "--out", tmp_path / "pred")


def test_the_shipped_model_is_complete_and_loads():
    from platesynth.segment.model import is_complete, load_model

    model = load_model(SHIPPED_MODEL)
    assert model.config.complete is True and is_complete(model.config, SHIPPED_MODEL)
    digest = hashlib.sha256((SHIPPED_MODEL / "weights.pt").read_bytes()).hexdigest()
    assert digest == "acd6b3f074e8475655d622560138247b341e00acabea799f28de25ee8d6b3032"


def test_default_limit_follows_the_address_space_limit():
    code = (
        "import resource; resource.setrlimit(resource.RLIMIT_AS, (3 * 1024**3, resource.RLIM_INFINITY)); "
        "from platesynth.limits import memory_limit; limit = memory_limit(); print(limit.bytes, limit.source)"
    )
    env = {k: v for k, v in __import__("os").environ.items() if not k.startswith("PLATESYNTH_MEMORY")}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True).stdout.split()
    assert 0 < int(out[0]) < 3 * 1024**3 and "available now" in " ".join(out[1:])
