"""Helpers shared by the CLI commands: user-facing errors, JSON output, progress bars."""

from __future__ import annotations

import functools
import json
import math
import sys
from collections.abc import Callable
from typing import Any, TypeVar

import typer
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn
from rich.table import Table

from platesynth.errors import PlatesynthError

F = TypeVar("F", bound=Callable[..., Any])

console = Console(stderr=True)
"""Human-facing messages and progress go to stderr, so stdout stays clean for ``--json``."""


def user_errors(func: F) -> F:
    """Turn a :class:`PlatesynthError` into a one-line message on stderr and exit code 1."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return func(*args, **kwargs)
        except PlatesynthError as exc:
            console.print(f"[bold red]error:[/] {exc}", highlight=False, soft_wrap=True)
            raise typer.Exit(code=1) from None

    return wrapper  # type: ignore[return-value]


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
    table = Table(title=title)
    table.add_column("metric")
    table.add_column("value", justify="right")
    for name, value in rows.items():
        text = f"{value:.6g}" if isinstance(value, float) else str(value)
        table.add_row(name, text)
    Console().print(table)


def progress_bar(transient: bool = True) -> Progress:
    """A rich progress bar on stderr with count, ETA and elapsed time; silent when stderr is not a terminal."""
    return Progress(
        TextColumn("[progress.description]{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
        console=console,
        transient=transient,
        disable=not console.is_terminal,
    )
