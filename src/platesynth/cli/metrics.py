"""``platesynth metrics ...``: pair and dataset metrics."""

from __future__ import annotations

import typer

app = typer.Typer(help="Realism and diversity metrics for image pairs and datasets.", no_args_is_help=True)


def register(main_app: typer.Typer) -> None:
    """Add ``platesynth metrics`` to the main app."""
    main_app.add_typer(app, name="metrics")
