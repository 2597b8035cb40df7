"""The ``platesynth`` command: a thin layer of typer commands over the library's functions."""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Iterator

import typer

from platesynth import __version__
from platesynth.cli import agent, blender, metrics, optimise, render, report, scene, segment, study
from platesynth.cli._common import CommandGroup

app = typer.Typer(
    name="platesynth",
    cls=CommandGroup,
    help="Synthetic multi-well plate assay images, realism and diversity metrics, and segmentation.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=False,
)
for _module in (metrics, scene, blender, render, segment, optimise, study, report, agent):
    _module.register(app)


def _version_callback(value: bool) -> None:
    if value:
        typer.echo(__version__)
        raise typer.Exit()


@app.callback()
def _main(
    version: bool = typer.Option(
        False, "--version", callback=_version_callback, is_eager=True, help="Print the version."
    ),
) -> None:
    """The platesynth command-line interface."""


def main() -> None:
    """Entry point of the ``platesynth`` console script."""
    with _workers_skip_the_script():
        app()


@contextlib.contextmanager
def _workers_skip_the_script() -> Iterator[None]:
    """Keep worker processes started with ``spawn`` (local or Dask workers) from running the console script again.

    ``multiprocessing`` runs the parent's ``__main__`` file again in every spawned worker, in case a task was
    defined there; the commands' tasks are all platesynth's own, and running the console script imported the whole
    command line in each worker (0.5-1 s of CPU each, before its first task). A ``__main__`` without ``__file__``
    is not run, so ``__file__`` is hidden while a command runs.
    """
    script = sys.modules.get("__main__")
    path = getattr(script, "__file__", None)
    if path is None or getattr(script, "__spec__", None) is not None:  # run by module name: multiprocessing skips it
        yield
        return
    del script.__file__
    try:
        yield
    finally:
        script.__file__ = path
