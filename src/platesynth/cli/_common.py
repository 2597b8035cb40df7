"""Helpers shared by the CLI commands: user-facing errors, JSON output, progress bars."""

from __future__ import annotations

import functools
import json
import math
import os
import sys
import zlib
from collections.abc import Callable
from types import TracebackType
from typing import Any, NoReturn, TypeVar

import tifffile
import typer
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn
from rich.table import Table
from rich.text import Text
from typer.core import TyperGroup

from platesynth.errors import PlatesynthError

F = TypeVar("F", bound=Callable[..., Any])

console = Console(stderr=True, markup=False)
"""Human-facing messages and progress go to stderr, so stdout stays clean for ``--json``. Nothing printed is read as
Rich markup (paths may hold brackets): styled words are :class:`rich.text.Text` (see :func:`styled`)."""

DECODE_ERRORS: tuple[type[BaseException], ...] = (zlib.error, tifffile.TiffFileError)
"""Errors of image decoders that reach the command line when a compressed file is truncated or corrupt."""
USER_FACING: tuple[type[BaseException], ...] = (
    PlatesynthError, OSError, UnicodeError, MemoryError, RecursionError, *DECODE_ERRORS
)
"""What the command line reports as one line (:func:`error_message`) instead of a traceback."""


def styled(label: str, style: str, message: str) -> Text:
    """``label`` in ``style``, a space, then ``message`` as plain text (never markup)."""
    return Text.assemble((label, style), " ", message)


def _path_in_traceback(tb: TracebackType | None) -> str | None:
    """The file a failed read or decode was working on: a ``path``/``filename`` variable of the innermost frame of
    platesynth's own code that has one."""
    found = None
    while tb is not None:
        frame = tb.tb_frame
        if frame.f_globals.get("__name__", "").startswith("platesynth"):
            for name in ("path", "filename", "file"):
                value = frame.f_locals.get(name)
                if isinstance(value, (str, os.PathLike)) and str(value):
                    found = str(value)
                    break
        tb = tb.tb_next
    return found


def error_message(exc: BaseException) -> str:
    """The one-line message the command line prints for an error of :data:`USER_FACING`."""
    if isinstance(exc, PlatesynthError):
        return str(exc)
    if isinstance(exc, OSError):
        reason = exc.strerror or str(exc) or type(exc).__name__
        if exc.filename is None:
            return reason
        target = f" -> {exc.filename2}" if exc.filename2 is not None else ""
        return f"{exc.filename}{target}: {reason}"
    where = _path_in_traceback(exc.__traceback__)
    prefix = f"{where}: " if where else ""
    if isinstance(exc, UnicodeDecodeError):
        byte = exc.object[exc.start : exc.start + 1].hex()
        return f"{prefix}not UTF-8 text (byte 0x{byte} at position {exc.start}); save the file as UTF-8"
    if isinstance(exc, MemoryError):
        return f"{prefix}out of memory; ask for less (e.g. a smaller --size, --count or --batch-size)"
    if isinstance(exc, RecursionError):
        return f"{prefix}input nested too deeply"
    if isinstance(exc, DECODE_ERRORS):
        name = type(exc).__name__ if type(exc).__name__ != "error" else f"{type(exc).__module__}.error"  # zlib.error
        return f"{prefix}cannot decode the file, truncated or corrupt ({name}: {exc})"
    return f"{prefix}{type(exc).__name__}: {exc}"


def fail(exc: BaseException) -> NoReturn:
    """Print ``exc`` as one line on stderr and exit with code 1 (a closed stdout, e.g. ``| head``, is left to click,
    which exits quietly)."""
    if isinstance(exc, BrokenPipeError):
        raise exc
    message = " ".join(error_message(exc).split())  # one line, whatever the exception held
    console.print(styled("error:", "bold red", message), highlight=False, soft_wrap=True)
    raise typer.Exit(code=1)


def user_errors(func: F) -> F:
    """Turn an error of :data:`USER_FACING` into a one-line message on stderr and exit code 1."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return func(*args, **kwargs)
        except USER_FACING as exc:
            fail(exc)

    return wrapper  # type: ignore[return-value]


class CommandGroup(TyperGroup):
    """The command line's group: errors raised outside a command's body (option callbacks, e.g. ``--preset``)
    are reported like those inside (:func:`user_errors`)."""

    def invoke(self, ctx: Any) -> Any:
        try:
            return super().invoke(ctx)
        except USER_FACING as exc:
            fail(exc)


def _jsonable(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if hasattr(value, "item") and callable(value.item):  # numpy scalars
        return _jsonable(value.item())
    if isinstance(value, dict):
        return {k: _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    return value


def print_json(obj: Any) -> None:
    """Print ``obj`` as JSON on stdout (non-finite floats become ``null``)."""
    sys.stdout.write(json.dumps(_jsonable(obj), indent=2) + "\n")


def print_table(rows: dict[str, Any], title: str | None = None) -> None:
    """Print a two-column name/value table for people."""
    table = Table(title=Text(title) if title is not None else None)
    table.add_column("metric")
    table.add_column("value", justify="right")
    for name, value in rows.items():
        text = f"{value:.6g}" if isinstance(value, float) else str(value)
        table.add_row(Text(name), Text(text))
    Console().print(table)


def progress_bar(transient: bool = True) -> Progress:
    """A rich progress bar on stderr with count, ETA and elapsed time; silent when stderr is not a terminal."""
    return Progress(
        TextColumn("{task.description}", style="progress.description", markup=False),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
        console=console,
        transient=transient,
        disable=not console.is_terminal,
    )
