"""The ``platesynth`` command: a thin layer of typer commands over the library's functions."""

from __future__ import annotations

import typer

from platesynth import __version__
from platesynth.cli import blender, metrics, render, scene, segment

app = typer.Typer(
    name="platesynth",
    help="Synthetic multi-well plate assay images, realism and diversity metrics, and segmentation.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=False,
)
for _module in (metrics, scene, blender, render, segment):
    _module.register(app)


def _version_callback(value: bool) -> None:
    if value:
        typer.echo(__version__)
        raise typer.Exit()


@app.callback()
def _main(
    version: bool = typer.Option(False, "--version", callback=_version_callback, is_eager=True, help="Print the version."),
) -> None:
    """platesynth command-line interface."""


def main() -> None:
    """Entry point of the ``platesynth`` console script."""
    app()
