"""``platesynth report``: one self-contained HTML page for a study, a dataset or an optimisation run."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from platesynth.cli._common import console, user_errors


@user_errors
def report(
    directory: Annotated[Path, typer.Argument(help="A study, a rendered dataset or an optimisation run.", metavar="DIR")],
    out: Annotated[
        Path | None, typer.Option("--out", "-o", help="The HTML file (default: DIR/report.html).")
    ] = None,
    reference: Annotated[
        Path | None, typer.Option("--reference", help="Real photos shown beside a dataset's samples.")
    ] = None,
    overwrite: Annotated[bool, typer.Option("--overwrite", help="Replace a file that is not an earlier report.")] = False,
) -> None:
    """Write one static HTML page (pictures inside it, no server, opens offline) for DIR."""
    from platesynth.report import write_report

    path = write_report(directory, out, reference=reference, overwrite=overwrite)
    console.print(f"report written to {path} ({path.stat().st_size / 1e6:.1f} MB)", highlight=False)
    typer.echo(str(path))


def register(app: typer.Typer) -> None:
    """Add ``report`` to the main platesynth app."""
    app.command("report")(report)
