"""The MCP server's guardrails: paths resolved inside the workspace, and the limits of a request.

Every path a client names goes through :meth:`Workspace.resolve`: relative to the workspace, without ``..``; an
absolute path is accepted only for reading and only inside a ``--read-only-root`` folder; the resolved path
(symlinks followed) must stay inside the workspace (or, for reading, a read-only root). What is written is always
inside the workspace and never inside a read-only root.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath

from platesynth.errors import PlatesynthError


class GuardrailError(PlatesynthError):
    """A request the MCP server refuses: a path leaving the workspace, or a request above a limit."""


@dataclass(frozen=True)
class Limits:
    """What one request may ask for; the defaults suit a workstation (``platesynth mcp --help`` lists the options)."""

    max_images: int = 1000
    """Images per job: rendered, previewed, predicted, or read by a metric or an evaluation."""
    max_image_side: int = 2048
    """Longest side, in pixels, of an image rendered or previewed."""
    max_jobs: int = 1
    """Jobs (render, train) running at once."""
    max_job_seconds: float = 3600.0
    """Seconds a job may run before it is stopped."""
    max_train_steps: int = 20000
    """Optimiser steps (epochs x steps per epoch) of one training."""
    max_read_bytes: int = 2_000_000
    """Largest file the ``read_result`` tool returns."""

    def __post_init__(self) -> None:
        for name in ("max_images", "max_image_side", "max_jobs", "max_train_steps", "max_read_bytes"):
            if getattr(self, name) < 1:
                raise GuardrailError(f"limit {name} must be >= 1, got {getattr(self, name)}")
        if not self.max_job_seconds > 0:
            raise GuardrailError(f"limit max_job_seconds must be > 0, got {self.max_job_seconds}")

    def check_images(self, count: int, what: str) -> None:
        """Refuse more than :attr:`max_images` images for one request."""
        if count > self.max_images:
            raise GuardrailError(
                f"{what}: {count} images asked for, above the limit of {self.max_images} images per job "
                "(the server's --max-images)"
            )

    def check_size(self, width: int, height: int, what: str) -> None:
        """Refuse an image side above :attr:`max_image_side`."""
        if max(width, height) > self.max_image_side:
            raise GuardrailError(
                f"{what}: {width}x{height} pixels asked for, above the limit of {self.max_image_side} pixels per side "
                "(the server's --max-image-side)"
            )


def _is_inside(path: Path, folder: Path) -> bool:
    return path == folder or folder in path.parents


@dataclass(frozen=True)
class Workspace:
    """The folder the server reads and writes in, and the folders it may only read."""

    root: Path
    read_only_roots: tuple[Path, ...] = field(default_factory=tuple)

    @classmethod
    def create(cls, root: str | os.PathLike, read_only_roots: tuple[str | os.PathLike, ...] = ()) -> Workspace:
        """A workspace at ``root`` (created if missing) with read-only folders (which must exist).

        Raises
        ------
        GuardrailError
            If ``root`` is not a folder, a read-only root does not exist, or the two overlap.
        """
        root_path = Path(root).expanduser().resolve()
        if root_path.exists() and not root_path.is_dir():
            raise GuardrailError(f"{root}: the workspace is not a folder")
        readable = []
        for folder in read_only_roots:
            path = Path(folder).expanduser().resolve()
            if not path.is_dir():
                raise GuardrailError(f"{folder}: a read-only root must be an existing folder")
            if _is_inside(path, root_path) or _is_inside(root_path, path):
                raise GuardrailError(f"{folder}: a read-only root may not contain or lie inside the workspace {root}")
            readable.append(path)
        root_path.mkdir(parents=True, exist_ok=True)  # only once everything is checked
        return cls(root_path, tuple(readable))

    def resolve(self, name: str, *, write: bool = False, what: str = "path") -> Path:
        """The real path of ``name``, checked against the guardrails (see the module docstring).

        Parameters
        ----------
        name : a path relative to the workspace (``/`` separated), or for reading an absolute path inside a
            read-only root.
        write : whether the tool writes there (then only the workspace is allowed).
        what : the argument's name, for messages.

        Raises
        ------
        GuardrailError
            For an empty name, ``..``, a NUL byte, an absolute path (outside the read-only roots, or for writing),
            or a path whose real location (symlinks followed) leaves the workspace or the read-only root.
        """
        if not isinstance(name, str) or not name.strip():
            raise GuardrailError(f"{what}: give a path relative to the workspace")
        if "\0" in name:
            raise GuardrailError(f"{what}: a path may not hold a NUL byte")
        text = name.replace("\\", "/")
        if ".." in PurePosixPath(text).parts:
            raise GuardrailError(f"{what} {name!r}: '..' is not allowed; name paths inside the workspace")
        if text.startswith("/") or (len(text) > 1 and text[1] == ":") or text.startswith("~"):
            if write:
                raise GuardrailError(f"{what} {name!r}: absolute paths are not allowed for outputs; name a path inside the workspace")
            real = Path(text).resolve()
            for folder in self.read_only_roots:
                if _is_inside(real, folder):
                    return real
            raise GuardrailError(
                f"{what} {name!r}: absolute paths are allowed only inside a read-only root "
                f"({', '.join(map(str, self.read_only_roots)) or 'none given'}); name a path inside the workspace"
            )
        real = (self.root / text).resolve()
        if not _is_inside(real, self.root):
            raise GuardrailError(f"{what} {name!r}: leads out of the workspace (through a symbolic link); refused")
        if write and real == self.root:
            raise GuardrailError(f"{what} {name!r}: the workspace itself cannot be an output; name a folder or file in it")
        return real

    def relative(self, path: Path) -> str:
        """``path`` as the client names it: relative to the workspace, else absolute (a read-only root)."""
        real = path.resolve()
        if _is_inside(real, self.root):
            return real.relative_to(self.root).as_posix() or "."
        return str(real)
