"""Stage keys and stored stage results: a stage is done once, for what it depends on.

A stage's key is a hash of everything its result depends on: its kind, the platesynth version, its settings (the
dataset identity and size, the recipe and the network, the metric settings...) and the keys of the stages it reads
(a training's renders, an evaluation's training). Input files outside the study (reference photos, counts, real
masks) enter by a fingerprint of their names, sizes and contents. So a rerun finds every key done and does no
work, an added arm finds the stages it shares with the others (the test set, a mix's renders) done, and a changed
recipe makes new training and evaluation keys while the renders and measurements stay.

A stage writes into ``stages/<kind>/<key>/`` and is done when its ``result.json`` exists (written last,
atomically): an interrupted stage has none and runs again (a render or a training resumes where it stopped).
"""

from __future__ import annotations

import hashlib
import json
import math
import os
from pathlib import Path
from typing import Any

from platesynth import __version__
from platesynth.io import write_json

STAGES_DIR = "stages"
RESULT_NAME = "result.json"
KEY_LENGTH = 16
"""Hex digits of a stage key (64 bits)."""


def stage_key(kind: str, depends: dict[str, Any]) -> str:
    """The key of a stage of ``kind`` whose result depends on ``depends`` (JSON-able; order of keys irrelevant)."""
    text = json.dumps({"kind": kind, "platesynth_version": __version__, **depends}, sort_keys=True,
                      separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:KEY_LENGTH]


def _file_digest(path: Path) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def fingerprint(path: str | os.PathLike | None) -> str | None:
    """A digest of a file, or of every file under a folder (relative names and contents); None for None.

    Hidden files (locks, markers, temporary files) are left out.
    """
    if path is None:
        return None
    path = Path(path)
    if path.is_file():
        return _file_digest(path)
    digest = hashlib.sha256()
    for file in sorted(p for p in path.rglob("*") if p.is_file()):
        relative = file.relative_to(path)
        if any(part.startswith(".") for part in relative.parts):
            continue
        digest.update(f"{relative.as_posix()}\0{_file_digest(file)}\n".encode())
    return digest.hexdigest()


def stage_dir(root: str | os.PathLike, kind: str, key: str) -> Path:
    """Where the stage ``kind``/``key`` of the study in ``root`` writes."""
    return Path(root) / STAGES_DIR / kind / key


def load_stored(root: str | os.PathLike, kind: str, key: str) -> dict[str, Any] | None:
    """What a finished stage stored (``kind``, ``key``, ``depends``, ``seconds``, ``result``), or None where it
    has not finished (or its file is unreadable)."""
    path = stage_dir(root, kind, key) / RESULT_NAME
    try:
        stored = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(stored, dict) or stored.get("key") != key or not isinstance(stored.get("result"), dict):
        return None
    return stored


def load_result(root: str | os.PathLike, kind: str, key: str) -> dict[str, Any] | None:
    """The stored result of a finished stage, or None where it has not finished."""
    stored = load_stored(root, kind, key)
    return None if stored is None else stored["result"]


def finite(value: Any) -> Any:
    """``value`` with every non-finite float (NaN, infinity) replaced by None, recursively: strict JSON."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [finite(v) for v in value]
    return value


def save_result(root: str | os.PathLike, kind: str, key: str, depends: dict[str, Any], result: dict[str, Any],
                seconds: float) -> Path:
    """Store a finished stage's result with what it depended on; the stage is done from then on."""
    path = stage_dir(root, kind, key) / RESULT_NAME
    write_json(path, {"kind": kind, "key": key, "platesynth_version": __version__, "depends": depends,
                      "seconds": round(seconds, 2), "result": finite(result)})
    return path
