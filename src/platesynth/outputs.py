"""Where commands write: output kinds, claiming an output before writing it, one writer per folder at a time.

Every command that writes passes its output through :func:`claim_output` once all of its options are validated:

- A folder output (a rendered dataset, a demo folder, a prediction folder, a model directory) holds a small marker,
  ``.platesynth-output``, naming its kind; folders written before the marker existed are recognised by their files
  (:func:`folder_kind`). A folder of another kind, or a non-empty folder platesynth did not write, is refused unless
  ``overwrite``; with ``overwrite`` the files the other kind writes are removed first (nothing else, and never the
  command's own inputs).
- A file output (a contact sheet, a per-well table, a ``.blend`` scene) may replace an earlier file of its own kind
  (recognised by its content); another existing file, or one inside a platesynth output folder, is refused unless
  ``overwrite``.
- An output that would replace an input of the same command (an input file is the output, or lies inside the output
  folder) is refused unless ``overwrite``.
- The checks change nothing. :meth:`Claim.take` then creates the folder, takes its lock (:func:`output_lock`: a
  second process writing into the same folder is refused while the first runs) and writes the marker; the command
  calls it right before its first write, and the lock is released when the claim's ``with`` block ends.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import Any

from platesynth.errors import OutputError

try:  # POSIX; elsewhere folders are not locked
    import fcntl
except ImportError:  # pragma: no cover
    fcntl = None  # type: ignore[assignment]

MARKER_NAME = ".platesynth-output"
LOCK_NAME = ".platesynth.lock"

FOLDER_KINDS = {
    "dataset": "a rendered dataset",
    "demo": "a demo folder",
    "prediction": "a prediction folder",
    "model": "a model directory",
    "optimisation": "an optimisation run",
    "study": "a study",
}
FILE_KINDS = {
    "preview": "a contact sheet",
    "table": "a per-well count table",
    "blend": "a .blend scene",
    "report": "an HTML report",
}
_OTHER = "other"
_DESCRIPTIONS = {**FOLDER_KINDS, **FILE_KINDS, _OTHER: "files platesynth did not write"}

PREVIEW_TEXT_KEY = "platesynth"
"""The PNG text chunk (``platesynth: preview``) that marks a contact sheet as written by ``platesynth preview``."""
REPORT_GENERATOR = '<meta name="generator" content="platesynth report">'
"""The line in the head of an HTML page written by ``platesynth report`` that marks it as one."""
TABLE_COLUMNS = ("image", "row", "col", "well", "count", "predicted", "detected", "predicted_countable")
"""The header of the per-well table ``platesynth evaluate counts --table`` writes."""


def describe_kind(kind: str) -> str:
    """``"dataset"`` -> ``"a rendered dataset"``."""
    return _DESCRIPTIONS.get(kind, kind)


# --- recognising what is there ----------------------------------------------------------------------------------


def _read_marker(directory: Path) -> str | None:
    try:
        kind = json.loads((directory / MARKER_NAME).read_text(encoding="utf-8")).get("kind")
    except (OSError, ValueError, AttributeError):
        return None
    return kind if kind in FOLDER_KINDS else None


def _is_prediction(directory: Path) -> bool:
    params = directory / "params"
    if not params.is_dir():
        return False
    for path in sorted(params.glob("*.json"))[:1]:
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return False
        return isinstance(data, dict) and "source" in data and "thresholds" in data
    return False


def folder_kind(directory: str | os.PathLike) -> str | None:
    """The kind of output a folder holds: a key of :data:`FOLDER_KINDS`, ``"other"`` (a non-empty folder platesynth
    did not write, or a file), or ``None`` (missing or empty).

    The marker decides; without one (folders written before it existed, or by the library functions) the files do:
    ``manifest.json`` a dataset (a demo folder with ``preview.png``), ``optimise.json`` an optimisation run,
    ``study.json`` a study,
    ``train.json``, ``checkpoint.pt`` or ``weights.pt`` with ``config.json`` a model, params naming their ``source``
    image a prediction.
    """
    directory = Path(directory)
    if not directory.exists():
        return None
    if not directory.is_dir():
        return _OTHER
    if (kind := _read_marker(directory)) is not None:
        return kind
    names = {p.name for p in directory.iterdir() if p.name != LOCK_NAME}
    if not names:
        return None
    if "manifest.json" in names:
        return "demo" if "preview.png" in names else "dataset"
    if "optimise.json" in names:
        return "optimisation"
    if "study.json" in names:
        return "study"
    if {"train.json", "checkpoint.pt"} & names or {"weights.pt", "config.json"} <= names:
        return "model"
    if _is_prediction(directory):
        return "prediction"
    return _OTHER


def enclosing_output(path: str | os.PathLike) -> tuple[Path, str] | None:
    """The nearest platesynth output folder (and its kind) that ``path`` lies inside, if any."""
    for parent in Path(path).absolute().parents:
        kind = folder_kind(parent) if parent.is_dir() else None
        if kind in FOLDER_KINDS:
            return parent, kind
    return None


def file_kind(path: str | os.PathLike) -> str | None:
    """What an existing file is: a key of :data:`FILE_KINDS` when platesynth wrote it, else ``"other"``; ``None``
    if there is no file."""
    path = Path(path)
    if not path.exists():
        return None
    if not path.is_file():
        return _OTHER
    try:
        with path.open("rb") as handle:
            head = handle.read(8)
        if head.startswith(b"\x89PNG"):
            from PIL import Image

            with Image.open(path) as image:
                if getattr(image, "text", {}).get(PREVIEW_TEXT_KEY) == "preview":
                    return "preview"
        elif path.suffix.lower() == ".blend":  # plain, zstd- or gzip-compressed
            return "blend" if head[:7] == b"BLENDER" or head[:4] == b"\x28\xb5\x2f\xfd" or head[:2] == b"\x1f\x8b" else _OTHER
        elif path.suffix.lower() in (".html", ".htm"):
            with path.open("rb") as handle:
                return "report" if REPORT_GENERATOR.encode() in handle.read(2048) else _OTHER
        elif path.suffix.lower() == ".csv":
            with path.open(encoding="utf-8", newline="") as handle:
                header = handle.readline().strip().split(",")
            if tuple(header) == TABLE_COLUMNS:
                return "table"
    except (OSError, ValueError, UnicodeError):
        return _OTHER
    return _OTHER


# --- claiming -----------------------------------------------------------------------------------------------------


def _inside(path: Path, folder: Path) -> bool:
    return path == folder or folder in path.parents


def _resolved(path: str | os.PathLike) -> Path:
    return Path(path).expanduser().resolve()


class Claim:
    """An output checked by :func:`claim_output`; :meth:`take` it right before the first write.

    Use as a context manager: the folder's lock is held from :meth:`take` until the block ends.
    """

    def __init__(self, path: Path, kind: str, existing: str | None, overwrite: bool, inputs: list[Path]) -> None:
        self.path = path
        self.inputs = inputs
        self.kind = kind
        self.existing = existing
        self.overwrite = overwrite
        self.taken = False
        self._stack = ExitStack()

    def __enter__(self) -> Claim:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.release()

    def release(self) -> None:
        """Release the folder's lock (if taken)."""
        self._stack.close()

    def take(self) -> None:
        """Create the output folder, lock it, remove another kind's files (``overwrite``), write the marker.

        Nothing for a file output (the atomic writers create its folder). Taking twice does nothing.

        Raises
        ------
        OutputError
            If another process writes into the folder, or the folder cannot be written.
        """
        if self.taken or self.kind not in FOLDER_KINDS:
            self.taken = True
            return
        try:
            self.path.mkdir(parents=True, exist_ok=True)
            self._stack.enter_context(output_lock(self.path))
            if self.overwrite and self.existing in FOLDER_KINDS and self.existing != self.kind:
                remove_output_files(self.path, self.existing, keep=self.inputs)
            if _read_marker(self.path) != self.kind:
                from platesynth import __version__
                from platesynth.io import write_json

                write_json(self.path / MARKER_NAME, {"kind": self.kind, "platesynth_version": __version__})
        except OSError as exc:
            self.release()
            raise OutputError(f"{self.path}: cannot write here ({exc.strerror or exc})") from None
        self.taken = True


def claim_output(
    path: str | os.PathLike,
    kind: str,
    *,
    inputs: Sequence[str | os.PathLike | None] = (),
    overwrite: bool = False,
    check: Callable[[], Any] | None = None,
) -> Claim:
    """Check that a command may write its output ``path`` of ``kind``, changing nothing (see the module docstring).

    Parameters
    ----------
    path : the output folder or file.
    kind : a key of :data:`FOLDER_KINDS` or :data:`FILE_KINDS`.
    inputs : the files and folders the command reads (``None`` entries are skipped).
    overwrite : replace an output of another kind, or an input, instead of refusing.
    check : the command's own check of an existing output of its kind (e.g. whether a dataset there is the same
        one, to resume), run last.

    Returns
    -------
    Claim
        Call :meth:`Claim.take` before the first write; use it as a context manager to release the lock.

    Raises
    ------
    OutputError
        With a one-line message, where the output may not be written.
    """
    if kind not in FOLDER_KINDS and kind not in FILE_KINDS:
        raise ValueError(f"unknown output kind {kind!r}")
    path = Path(path)
    target = _resolved(path)
    folder = kind in FOLDER_KINDS
    if folder and path.exists() and not path.is_dir():
        raise OutputError(f"{path}: exists and is not a directory; give a folder for {describe_kind(kind)}")
    if not folder and path.is_dir():
        raise OutputError(f"{path}: is a directory; give a file name for {describe_kind(kind)}")
    if not overwrite:
        for given in inputs:
            if given is None:
                continue
            source = _resolved(given)
            if _inside(source, target) if folder else source == target:
                raise OutputError(
                    f"{path}: writing {describe_kind(kind)} here would replace an input of this command ({given}); "
                    "choose another output or pass --overwrite"
                )
    existing = folder_kind(path) if folder else file_kind(path)
    if not overwrite and existing is not None and existing != kind:
        if not folder:
            problem = f"exists and is not {describe_kind(kind)} written by platesynth"
        elif existing == _OTHER:
            problem = f"is not empty and holds no {describe_kind(kind).removeprefix('a ')}"
        else:
            problem = f"holds {describe_kind(existing)}, not {describe_kind(kind)}"
        raise OutputError(f"{path}: {problem}; choose another output or pass --overwrite to replace it")
    if not folder and not overwrite and existing is not None and (enclosing := enclosing_output(path)) is not None:
        raise OutputError(
            f"{path}: is part of {describe_kind(enclosing[1])} ({enclosing[0]}); choose another output or pass --overwrite"
        )
    if check is not None:
        check()
    return Claim(path, kind, existing, overwrite, [Path(p) for p in inputs if p is not None])


# --- removing another kind's files ---------------------------------------------------------------------------------

_MODEL_FILES = ("weights.pt", "config.json", "train.json", "checkpoint.pt", "history.json")
_ITEM_SUFFIXES = {"images": ".png", "masks/wells": ".tif", "masks/plaques": ".tif", "params": ".json"}


def _files_of(directory: Path, kind: str) -> list[Path]:
    """The files an output of ``kind`` in ``directory`` consists of (those there), temporary files included."""
    if kind == "model":
        return [directory / name for name in _MODEL_FILES]
    if kind == "optimisation":
        from platesynth.optimise.report import OUTPUT_FILES

        temporary = [p for p in directory.iterdir() if p.is_file() and p.name.startswith(".") and ".tmp" in p.name]
        return [directory / name for name in OUTPUT_FILES] + temporary
    if kind == "study":
        from platesynth.study.run import OUTPUT_FILES, OUTPUT_FOLDERS

        files = [directory / name for name in OUTPUT_FILES]
        for name in OUTPUT_FOLDERS:
            if (directory / name).is_dir():
                files += [p for p in (directory / name).rglob("*") if p.is_file()]
        return files + [p for p in directory.iterdir() if p.is_file() and p.name.startswith(".") and ".tmp" in p.name]
    from platesynth.data.layout import is_item_name

    files = [directory / name for name in ("manifest.json", "counts.csv", "annotations.coco.json")]
    if kind == "demo":
        files.append(directory / "preview.png")
    for folder_name, suffix in _ITEM_SUFFIXES.items():
        folder = directory / folder_name
        if folder.is_dir():
            files += [
                path
                for path in folder.iterdir()
                if path.is_file() and path.suffix == suffix and (kind == "prediction" or is_item_name(path.stem))
            ]
    for folder in (directory, *(directory / name for name in _ITEM_SUFFIXES)):
        if folder.is_dir():
            files += [p for p in folder.iterdir() if p.is_file() and p.name.startswith(".") and ".tmp" in p.name]
    return files


def remove_output_files(
    directory: str | os.PathLike, kind: str, keep: Iterable[str | os.PathLike | None] = ()
) -> None:
    """Delete the files an output of ``kind`` consists of from ``directory``, and nothing else; files in ``keep``
    (or inside a folder in ``keep``: a command's inputs) stay. Folders of the layout left empty are removed."""
    directory = Path(directory)
    kept = [_resolved(path) for path in keep if path is not None]
    for path in _files_of(directory, kind):
        if path.is_file() and not any(_inside(_resolved(path), folder) for folder in kept):
            path.unlink()
    for name in (*_ITEM_SUFFIXES, "masks"):
        with contextlib.suppress(OSError):
            (directory / name).rmdir()  # only where empty
    if kind == "study":  # its folders of stages and tables, deepest first, where left empty
        from platesynth.study.run import OUTPUT_FOLDERS

        for name in OUTPUT_FOLDERS:
            if (directory / name).is_dir():
                folders = [p for p in (directory / name).rglob("*") if p.is_dir()] + [directory / name]
                for folder in sorted(folders, key=lambda p: len(p.parts), reverse=True):
                    with contextlib.suppress(OSError):
                        folder.rmdir()
    (directory / MARKER_NAME).unlink(missing_ok=True)


# --- one writer per folder ------------------------------------------------------------------------------------------

_held: dict[Path, list[int]] = {}  # locked folder -> [file descriptor, depth]


@contextmanager
def output_lock(directory: str | os.PathLike) -> Iterator[None]:
    """Hold an exclusive lock on ``directory`` (an existing folder) while the block runs.

    The lock is ``fcntl.flock`` on ``.platesynth.lock`` in the folder: the kernel releases it when the holder ends,
    however it ends, so a killed run never blocks the next one. Re-entrant within a process. The lock file is
    removed when the outermost block ends. On file systems without ``flock`` the folder is not locked.

    Raises
    ------
    OutputError
        If another process holds the lock.
    """
    key = Path(directory).resolve()
    if key in _held:
        _held[key][1] += 1
        try:
            yield
        finally:
            _held[key][1] -= 1
        return
    lock_path = key / LOCK_NAME
    fd = _acquire(lock_path, directory)
    _held[key] = [fd, 1]
    try:
        yield
    finally:
        del _held[key]
        with contextlib.suppress(OSError):
            lock_path.unlink()  # while still holding it: a process waiting on this file sees it gone and retries
        os.close(fd)


def _acquire(lock_path: Path, directory: str | os.PathLike) -> int:
    while True:
        fd = os.open(lock_path, os.O_RDWR | os.O_CREAT, 0o644)
        if fcntl is None:
            return fd
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.read(fd, 32).decode("ascii", "replace").strip()
            os.close(fd)
            pid = f" (pid {holder})" if holder.isdigit() else ""
            raise OutputError(
                f"{directory}: another platesynth process{pid} is writing here; wait until it ends or choose another output"
            ) from None
        except OSError as exc:
            if exc.errno in (errno.ENOLCK, errno.EOPNOTSUPP, errno.ENOSYS):
                return fd  # no locks on this file system (some network file systems)
            os.close(fd)
            raise
        try:
            same = os.path.samestat(os.fstat(fd), os.stat(lock_path))
        except FileNotFoundError:
            same = False
        if same:
            os.ftruncate(fd, 0)
            os.write(fd, f"{os.getpid()}\n".encode())
            return fd
        os.close(fd)  # the previous holder removed the file as it ended: lock the new one
