"""``platesynth metrics ...``: pair and dataset metrics."""

from __future__ import annotations

import typer

app = typer.Typer(help="Realism and diversity metrics for image pairs and datasets.", no_args_is_help=True)
