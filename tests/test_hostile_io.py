"""Hostile and careless input through the real command line (issue 13), one table of cases.

Every case runs a command in a fresh copy of a small world (a rendered dataset, a demo folder, a prediction folder,
a tiny trained model, the shipped model, tables, broken files) and asserts: a non-zero exit, one line ``error: ...``
holding the expected text, no traceback (the command ended by ``SystemExit``), and nothing written or changed (the
hashes of every file and the list of folders are the same before and after), or, where a failure strikes half way
(a full disk), no partial file.

The classes: overwriting inputs or another kind of output, validation before the first write, paths (presets are
names, image names that leave their folder, brackets in paths), errors that were tracebacks (read-only folders,
files where folders belong, truncated TIFFs, text that is not UTF-8, a full disk, no memory), tables that mean
nothing, and a second process writing into the same folder.
"""

from __future__ import annotations

import errno
import hashlib
import os
import pathlib
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest
import tifffile
from typer.testing import CliRunner

from platesynth.cli import app

ROOT = Path(__file__).resolve().parents[1]
SHIPPED_MODEL = ROOT / "models" / "plaque12"
SMALL = ["--size", "64x48", "--count", "1", "--preset", "high", "--seed", "3"]
TINY_TRAIN = ["--model-config", "{w}/tiny.json", "--epochs", "1", "--steps", "1", "--batch-size", "1",
              "--patch", "32x32", "--no-tune", "--threads", "1"]

pytestmark = pytest.mark.usefixtures("one_torch_thread")


def invoke(*args: str | Path):
    return CliRunner().invoke(app, [str(a) for a in args])


def ok(*args: str | Path) -> None:
    result = invoke(*args)
    assert result.exit_code == 0, result.output


# --- the world ------------------------------------------------------------------------------------------------------


def _truncated_tiff(path: Path, array: np.ndarray) -> None:
    """A zlib-compressed TIFF cut short inside its compressed pixel data."""
    tifffile.imwrite(path, array, compression="zlib")
    data = path.read_bytes()
    path.write_bytes(data[: len(data) - max(16, len(data) // 8)])
    with pytest.raises(Exception, match="truncated"):
        tifffile.imread(path)


@pytest.fixture(scope="module")
def world(tmp_path_factory) -> Path:
    """Built once; every case works in its own copy."""
    base = tmp_path_factory.mktemp("hostile") / "w"
    base.mkdir()
    ok("render", "--out", base / "ds", *SMALL)
    ok("demo", "--out", base / "demo", "--count", "1", "--size", "64x48")
    ok("predict", base / "ds" / "images" / "000000.png", "--model", SHIPPED_MODEL, "--out", base / "pred")
    (base / "tiny.json").write_text('{"channels": [8, 12, 16], "context_dilations": [2], "input_long_side": 128}\n')
    shutil.copytree(SHIPPED_MODEL, base / "plaque12")  # a model directory written before output markers existed
    (base / "foreign").mkdir()
    (base / "foreign" / "notes.txt").write_text("my notes\n")
    (base / "a_file").write_text("x\n")
    (base / "photo.png").write_bytes((base / "ds" / "images" / "000000.png").read_bytes())
    (base / "photos").mkdir()
    (base / "photos" / "plate.png").write_bytes((base / "ds" / "images" / "000000.png").read_bytes())
    (base / "sheet_dir.png").mkdir()
    (base / "table_dir").mkdir()
    (base / "other.csv").write_text("name,value\na,1\n")
    (base / "broken[red].png").write_bytes(b"not an image")
    (base / "plate[").mkdir()
    (base / "plate[" / "]x").write_text("a file\n")  # the path plate[/]x
    (base / "high.yaml").write_text("plate:\n  format: 12\n")
    _truncated_tiff(base / "trunc.tif", np.random.default_rng(0).integers(0, 255, (48, 64, 3), dtype=np.uint8))
    shutil.copytree(base / "ds", base / "ds_bad")
    wells = tifffile.imread(base / "ds" / "masks" / "wells" / "000000.tif")
    _truncated_tiff(base / "ds_bad" / "masks" / "wells" / "000000.tif", wells)
    counts = base / "counts"
    counts.mkdir()
    rows = (base / "ds" / "counts.csv").read_text().splitlines()
    header = rows[0]
    (counts / "header_only.csv").write_text(header + "\n")
    blank = [",".join(r.split(",")[:4]) + "," for r in rows[1:]]
    (counts / "all_blank.csv").write_text("\n".join([header, *blank]) + "\n")
    (counts / "missing_field.csv").write_text("\n".join([header, rows[1], ",".join(rows[2].split(",")[:4])]) + "\n")
    (counts / "latin1.csv").write_bytes(("\n".join([header, rows[1].replace("000000.png", "plaque_é.png")]) + "\n").encode("latin-1"))
    (counts / "up.csv").write_text("\n".join([header, "../photo.png,0,0,A4,3"]) + "\n")
    (counts / "absolute.csv").write_text("\n".join([header, f"{base / 'photo.png'},0,0,A4,3"]) + "\n")
    (counts / "not_a_number.csv").write_text("\n".join([header, "000000.png,0,0,A4,many"]) + "\n")
    return base


@pytest.fixture
def work(world, tmp_path) -> Path:
    target = tmp_path / "w"
    shutil.copytree(world, target, symlinks=True)
    return target


def snapshot(root: Path) -> dict[str, str]:
    state = {}
    for path in sorted(root.rglob("*")):
        rel = path.relative_to(root).as_posix()
        state[rel] = hashlib.sha256(path.read_bytes()).hexdigest() if path.is_file() else "dir"
    return state


# --- what some cases need around them --------------------------------------------------------------------------------


def _can_write(folder: Path) -> bool:
    try:
        (folder / ".probe").write_text("x")
    except OSError:
        return False
    (folder / ".probe").unlink()
    return True


def read_only(name: str) -> Callable[[Path], Callable[[], None]]:
    """Make ``work/name`` (created empty) a folder nobody may write into: chmod, or as root the immutable flag."""

    def setup(work: Path) -> Callable[[], None]:
        folder = work / name
        folder.mkdir(exist_ok=True)
        folder.chmod(0o555)
        if not _can_write(folder):
            return lambda: folder.chmod(0o755)
        if shutil.which("chattr") and subprocess.run(["chattr", "+i", str(folder)], capture_output=True).returncode == 0:
            return lambda: (subprocess.run(["chattr", "-i", str(folder)], check=False), folder.chmod(0o755))
        folder.chmod(0o755)
        pytest.skip("cannot make a folder read-only here (root without chattr)")

    return setup


LOCK_HOLDER = """
import fcntl, os, sys, time
fd = os.open(sys.argv[1], os.O_RDWR | os.O_CREAT, 0o644)
fcntl.flock(fd, fcntl.LOCK_EX)
os.ftruncate(fd, 0)
os.write(fd, b"%d\\n" % os.getpid())
print("locked", flush=True)
time.sleep(120)
"""


def locked(name: str, before: Callable[[Path], None] | None = None) -> Callable[[Path], Callable[[], None]]:
    """Another process (as a running render or training would) holds the lock of ``work/name``."""

    def setup(work: Path) -> Callable[[], None]:
        if sys.platform == "win32":
            pytest.skip("folder locks are POSIX flock")
        if before is not None:
            before(work)
        folder = work / name
        folder.mkdir(exist_ok=True)
        holder = subprocess.Popen([sys.executable, "-c", LOCK_HOLDER, str(folder / ".platesynth.lock")], stdout=subprocess.PIPE, text=True)
        assert holder.stdout.readline().strip() == "locked"

        def cleanup() -> None:
            holder.kill()
            holder.wait()

        return cleanup

    return setup


def half_written_temp_file(work: Path) -> None:
    """What a running render has under way: a temporary file that a second run must not delete."""
    (work / "ds" / "images" / ".000001.0123456789ab.tmp.png").write_bytes(b"half an image")


def train_tiny(work: Path) -> None:
    ok("train", "--data", work / "ds", "--out", work / "model", *[a.format(w=work) for a in TINY_TRAIN])


def full_disk_for(name: str) -> Callable[[pytest.MonkeyPatch], None]:
    """The disk fills up half way through writing the file ``name`` (its temporary file, as atomic writes do)."""

    def patch(monkeypatch: pytest.MonkeyPatch) -> None:
        write_text = pathlib.Path.write_text

        def failing(self, data, *args, **kwargs):
            if name.split(".")[0] in self.name:
                write_text(self, data[: len(data) // 2], *args, **kwargs)
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(self))
            return write_text(self, data, *args, **kwargs)

        monkeypatch.setattr(pathlib.Path, "write_text", failing)

    return patch


def no_memory(monkeypatch: pytest.MonkeyPatch) -> None:
    def render(*args, **kwargs):
        raise MemoryError

    monkeypatch.setattr("platesynth.data.batch.render", render)


def cuda_available() -> bool:
    import torch

    return torch.cuda.is_available()


# --- the table --------------------------------------------------------------------------------------------------------


@dataclass
class Case:
    id: str
    args: list[str]
    message: str | list[str]
    setup: Callable[[Path], Callable[[], None] | None] | None = None
    patch: Callable[[pytest.MonkeyPatch], None] | None = None
    quiet: bool = True  # the error line is all the command prints
    no_partial: str | None = None  # instead of "nothing changed": this file and temporary files are absent
    skip: Callable[[], str | None] | None = field(default=None)


M = ["--model", "{w}/plaque12"]
EVAL = ["evaluate", "counts", *M, "--images", "{w}/ds/images"]

CASES = [
    # 1. data loss: outputs that would replace inputs, or another kind of output
    Case("table-is-the-counts", [*EVAL, "--counts", "{w}/ds/counts.csv", "--table", "{w}/ds/counts.csv"],
         "would replace an input of this command"),
    Case("predict-into-dataset", ["predict", "{w}/photo.png", *M, "--out", "{w}/ds"],
         "holds a rendered dataset, not a prediction folder"),
    Case("predict-into-its-images-folder", ["predict", "{w}/photos", *M, "--out", "{w}/photos"],
         "would replace an input of this command"),
    Case("predict-into-own-dataset-images", ["predict", "{w}/ds/images/000000.png", *M, "--out", "{w}/ds"],
         "would replace an input of this command"),
    Case("predict-into-a-model", ["predict", "{w}/photo.png", *M, "--out", "{w}/model"],
         "holds a model directory, not a prediction folder", setup=lambda w: train_tiny(w)),
    Case("predict-into-foreign-folder", ["predict", "{w}/photo.png", *M, "--out", "{w}/foreign"],
         "is not empty and holds no prediction folder"),
    Case("render-into-predictions", ["render", "--out", "{w}/pred", *SMALL], "holds a prediction folder, not a rendered dataset"),
    Case("render-into-legacy-model", ["render", "--out", "{w}/plaque12", *SMALL], "holds a model directory, not a rendered dataset"),
    Case("render-into-demo", ["render", "--out", "{w}/demo", *SMALL], "holds a demo folder, not a rendered dataset"),
    Case("render-into-foreign-folder", ["render", "--out", "{w}/foreign", *SMALL], "is not empty and holds no rendered dataset"),
    Case("demo-into-dataset", ["demo", "--out", "{w}/ds", "--count", "1", "--size", "64x48"], "holds a rendered dataset, not a demo folder"),
    Case("demo-into-predictions", ["demo", "--out", "{w}/pred", "--count", "1", "--size", "64x48"], "holds a prediction folder, not a demo folder"),
    Case("train-into-its-data", ["train", "--data", "{w}/ds", "--out", "{w}/ds", *TINY_TRAIN], "would replace an input of this command"),
    Case("train-into-predictions", ["train", "--data", "{w}/ds", "--out", "{w}/pred", *TINY_TRAIN],
         "holds a prediction folder, not a model directory"),
    Case("preview-over-a-dataset-image", ["preview", "--out", "{w}/ds/images/000000.png", "--count", "1", "--size", "64x48"],
         "exists and is not a contact sheet"),
    Case("preview-over-a-photo", ["preview", "--out", "{w}/photo.png", "--count", "1", "--size", "64x48"],
         "exists and is not a contact sheet"),
    Case("table-over-a-manifest", [*EVAL, "--counts", "{w}/ds/counts.csv", "--table", "{w}/ds/manifest.json"],
         "exists and is not a per-well count table"),
    Case("table-over-another-csv", [*EVAL, "--counts", "{w}/ds/counts.csv", "--table", "{w}/other.csv"],
         "exists and is not a per-well count table"),
    Case("export-over-a-file", ["scene", "export", "--out", "{w}/a_file.blend", "--preset", "high"],
         "exists and is not a .blend scene", setup=lambda w: (w / "a_file.blend").write_text("x")),
    # 2. validation before the first write
    Case("train-patch-0x0", ["train", "--data", "{w}/ds", "--out", "{w}/new", *TINY_TRAIN, "--patch", "0x0"], "--patch '0x0'"),
    Case("train-patch-not-a-multiple", ["train", "--data", "{w}/ds", "--out", "{w}/new", *TINY_TRAIN, "--patch", "30x30"],
         "must be a positive multiple of 4"),
    Case("train-cuda-without-gpu", ["train", "--data", "{w}/ds", "--out", "{w}/new", *TINY_TRAIN, "--device", "cuda"],
         "CUDA is not available", skip=lambda: "a GPU is here" if cuda_available() else None),
    Case("train-unknown-device", ["train", "--data", "{w}/ds", "--out", "{w}/new", *TINY_TRAIN, "--device", "tpu"], "unknown device 'tpu'"),
    Case("train-negative-threads", ["train", "--data", "{w}/ds", "--out", "{w}/new", *TINY_TRAIN, "--threads", "-1"], "--threads must be >= 0"),
    Case("train-zero-epochs", ["train", "--data", "{w}/ds", "--out", "{w}/new", *TINY_TRAIN, "--epochs", "0"], "epochs"),
    Case("train-missing-model-config", ["train", "--data", "{w}/ds", "--out", "{w}/new", *TINY_TRAIN, "--model-config", "{w}/none.json"],
         "none.json: cannot read model configuration"),
    Case("predict-bad-threshold", ["predict", "{w}/photo.png", *M, "--out", "{w}/new", "--well-prob", "1.5"], "--well-prob must be in (0, 1)"),
    Case("demo-missing-model", ["demo", "--out", "{w}/new", "--count", "1", "--size", "64x48", "--model", "{w}/none"],
         "config.json: no such file"),
    Case("preview-zero-columns", ["preview", "--out", "{w}/new.png", "--count", "1", "--size", "64x48", "--columns", "0"],
         "columns must be >= 1"),
    # 3. paths
    Case("preset-relative-path", ["render", "--out", "{w}/new", *SMALL, "--preset", "../high"], "presets are names"),
    Case("preset-absolute-yaml", ["render", "--out", "{w}/new", *SMALL, "--preset", "{w}/high.yaml"], "presets are names"),
    Case("preset-file-name", ["scene", "sample", "--preset", "high.yaml"], "presets are names"),
    Case("counts-image-up-and-out", [*EVAL, "--counts", "{w}/counts/up.csv", "--table", "{w}/new.csv"], "'../photo.png' lies outside --images"),
    Case("counts-image-absolute", [*EVAL, "--counts", "{w}/counts/absolute.csv"], "lies outside --images"),
    Case("brackets-slash-in-out", ["render", "--out", "{w}/plate[/]x", *SMALL], "plate[/]x: exists and is not a directory"),
    Case("brackets-style-in-config", ["render", "--out", "{w}/new", *SMALL, "--config", "{w}/conf[bold]x.yaml"], "conf[bold]x.yaml"),
    Case("brackets-in-image-name", ["predict", "{w}/broken[red].png", *M, "--out", "{w}/new"], "broken[red].png: cannot read image"),
    # 4. tracebacks where one line is promised
    Case("render-read-only", ["render", "--out", "{w}/ro", *SMALL], ["ro: cannot write here"], setup=read_only("ro")),
    Case("render-under-read-only", ["render", "--out", "{w}/ro/new", *SMALL], "ro/new: cannot write here", setup=read_only("ro")),
    Case("demo-read-only", ["demo", "--out", "{w}/ro/demo", "--count", "1", "--size", "64x48"], "ro/demo: cannot write here",
         setup=read_only("ro")),
    Case("preview-read-only", ["preview", "--out", "{w}/ro/sheet.png", "--count", "1", "--size", "64x48"], "ro/sheet.png: ",
         setup=read_only("ro")),
    Case("predict-read-only", ["predict", "{w}/photo.png", *M, "--out", "{w}/ro/p"], "ro/p: cannot write here", setup=read_only("ro")),
    Case("train-read-only", ["train", "--data", "{w}/ds", "--out", "{w}/ro/m", *TINY_TRAIN], "ro/m: cannot write here",
         setup=read_only("ro")),
    Case("table-read-only", [*EVAL, "--counts", "{w}/ds/counts.csv", "--table", "{w}/ro/t.csv"], "ro/t.csv: ", setup=read_only("ro")),
    Case("render-out-is-a-file", ["render", "--out", "{w}/a_file", *SMALL], "a_file: exists and is not a directory"),
    Case("predict-out-is-a-file", ["predict", "{w}/photo.png", *M, "--out", "{w}/a_file"], "a_file: exists and is not a directory"),
    Case("preview-out-is-a-folder", ["preview", "--out", "{w}/sheet_dir.png", "--count", "1", "--size", "64x48"], "sheet_dir.png: is a directory"),
    Case("table-is-a-folder", [*EVAL, "--counts", "{w}/ds/counts.csv", "--table", "{w}/table_dir"], "table_dir: is a directory"),
    Case("predict-truncated-tiff", ["predict", "{w}/trunc.tif", *M, "--out", "{w}/new"], ["trunc.tif", "truncated"]),
    Case("train-truncated-mask", ["train", "--data", "{w}/ds_bad", "--out", "{w}/new", *TINY_TRAIN], ["000000.tif", "truncated"]),
    Case("counts-not-utf8", [*EVAL, "--counts", "{w}/counts/latin1.csv"], "latin1.csv: not UTF-8 text"),
    Case("disk-full-writing-coco", ["render", "--out", "{w}/new", *SMALL, "--coco"], "annotations.coco.json: No space left on device",
         patch=full_disk_for("annotations.coco.json"), quiet=False, no_partial="new/annotations.coco.json"),
    Case("out-of-memory", ["preview", "--out", "{w}/new.png", "--count", "1", "--size", "64x48"], "out of memory", patch=no_memory),
    # 5. tables that mean nothing
    Case("counts-header-only", [*EVAL, "--counts", "{w}/counts/header_only.csv"], "lists no well"),
    Case("counts-all-blank", [*EVAL, "--counts", "{w}/counts/all_blank.csv", "--table", "{w}/new.csv"], "counts are blank"),
    Case("counts-missing-field", [*EVAL, "--counts", "{w}/counts/missing_field.csv"], "line 3: 4 field(s), the header has 5"),
    Case("counts-not-a-number", [*EVAL, "--counts", "{w}/counts/not_a_number.csv"], "must be integers"),
    # 6. a second process on the same folder
    Case("render-while-another-runs", ["render", "--out", "{w}/ds", *SMALL], "another platesynth process (pid",
         setup=locked("ds", before=half_written_temp_file)),
    Case("render-overwrite-while-another-runs", ["render", "--out", "{w}/ds", *SMALL, "--size", "80x60", "--overwrite"],
         "another platesynth process (pid", setup=locked("ds", before=half_written_temp_file), quiet=False),
    Case("demo-while-another-runs", ["demo", "--out", "{w}/demo", "--count", "1", "--size", "64x48"], "another platesynth process (pid",
         setup=locked("demo")),
    Case("predict-while-another-runs", ["predict", "{w}/photo.png", *M, "--out", "{w}/pred"], "another platesynth process (pid",
         setup=locked("pred")),
    Case("train-while-another-runs", ["train", "--data", "{w}/ds", "--out", "{w}/model", *TINY_TRAIN], "another platesynth process (pid",
         setup=locked("model", before=train_tiny)),
]


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_hostile_input_is_refused_in_one_line_and_changes_nothing(case, work, monkeypatch):
    if case.skip is not None and (reason := case.skip()):
        pytest.skip(reason)
    cleanup = case.setup(work) if case.setup is not None else None
    try:
        before = snapshot(work)
        if case.patch is not None:
            case.patch(monkeypatch)
        result = invoke(*[a.format(w=work) for a in case.args])
        monkeypatch.undo()
        after = snapshot(work)
    finally:
        if callable(cleanup):
            cleanup()
    output = result.output
    assert result.exit_code != 0, output
    assert result.exception is None or isinstance(result.exception, SystemExit), repr(result.exception)
    assert "Traceback" not in output
    lines = [line for line in output.splitlines() if line.strip()]
    errors = [line for line in lines if line.startswith("error: ")]
    assert len(errors) == 1 and errors[0] == lines[-1], output
    if case.quiet:
        assert len(lines) == 1, output
    for text in [case.message] if isinstance(case.message, str) else case.message:
        assert text in errors[0], output
    if case.no_partial is None:
        assert after == before
    else:
        assert case.no_partial not in after
        assert not [name for name in after if ".tmp" in name]


# --- what the table cannot show ------------------------------------------------------------------------------------


def test_overwrite_replaces_another_kind_and_resumes_its_own(work):
    ok("predict", work / "photo.png", "--model", work / "plaque12", "--out", work / "ds", "--overwrite")
    assert not (work / "ds" / "manifest.json").exists()  # the dataset's files went, the predictions came
    assert (work / "ds" / "params" / "photo.json").is_file() and not (work / "ds" / "params" / "000000.json").exists()
    ok("render", "--out", work / "ds", *SMALL, "--overwrite")
    assert (work / "ds" / "manifest.json").is_file() and not (work / "ds" / "params" / "photo.json").exists()
    again = invoke("render", "--out", work / "ds", *SMALL)
    assert again.exit_code == 0 and "0 rendered, 1 already there" in again.output
    assert not (work / "ds" / ".platesynth.lock").exists()


def test_overwrite_never_removes_the_commands_own_inputs(work):
    image = work / "ds" / "images" / "000000.png"
    before = image.read_bytes()
    ok("predict", image, "--model", work / "plaque12", "--out", work / "ds", "--overwrite")
    assert image.read_bytes() == before  # the input stayed (predict writes the same RGB pixels under its name)
    assert not (work / "ds" / "manifest.json").exists() and (work / "ds" / "params" / "000000.json").is_file()


def _children(pid: int) -> set[int]:
    children = set()
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            children.add(int(stat.parent.name))
    return children


def _state(pid: int) -> str | None:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return None


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_killed_render_takes_its_workers_along(tmp_path):
    script = Path(sys.executable).with_name("platesynth")
    if not script.is_file():
        pytest.skip(f"{script}: no console script beside the interpreter")
    command = [str(script), "render", "--out", str(tmp_path / "ds"), "--count", "200",
               "--size", "320x240", "--workers", "2"]
    parent = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 60
        workers: set[int] = set()
        while time.monotonic() < deadline and len(workers) < 2:
            time.sleep(0.2)
            workers = {p for p in _children(parent.pid) if "spawn_main" in Path(f"/proc/{p}/cmdline").read_text(errors="replace")}
        assert len(workers) == 2, "the workers did not start"
        parent.send_signal(signal.SIGKILL)
        parent.wait()
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline and any(_state(p) not in (None, "Z") for p in workers):
            time.sleep(0.2)
        alive = [p for p in workers if _state(p) not in (None, "Z")]  # gone, or a zombie nobody reaped
        assert not alive, f"workers {alive} outlived their parent"
    finally:
        if parent.poll() is None:
            parent.kill()
