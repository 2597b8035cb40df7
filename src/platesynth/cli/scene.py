"""``platesynth scene ...``: the parameter catalogue, presets, configurations and sampled scenes."""

from __future__ import annotations

import json
from typing import Annotated

import typer
from rich.console import Console
from rich.table import Table

from platesynth.cli._common import print_json, user_errors
from platesynth.cli.options import ConfigFile, Overrides, Preset, parse_overrides

app = typer.Typer(help="Scene parameter catalogue, presets and sampled scenes.", no_args_is_help=True)



def _range_text(row: dict) -> str:
    values = row["range"]
    if row["type"] == "category" or len(values) != 2 or "choices" in row:
        return ", ".join(str(v) for v in values)
    return f"[{values[0]:g}, {values[1]:g}]"


@app.command("catalogue")
@user_errors
def catalogue(as_json: Annotated[bool, typer.Option("--json", help="Print JSON instead of a table.")] = False) -> None:
    """The parameter catalogue: every scene parameter's name, type, unit, valid range, default and description."""
    from platesynth.schemas import catalogue as read_catalogue
    from platesynth.schemas import dump

    parameters = read_catalogue().parameters
    if as_json:
        print_json([dump(row) for row in parameters])
        return
    rows = [row.model_dump() for row in parameters]
    table = Table(title="scene parameters (YAML: section: {parameter: value})")
    for column in ("name", "type", "unit", "range", "default", "description"):
        table.add_column(column, overflow="fold")
    for row in rows:
        table.add_row(
            row["name"], row["type"], row["unit"], _range_text(row), json.dumps(row["default"]), row["description"]
        )
    Console().print(table)


@app.command("presets")
@user_errors
def presets(as_json: Annotated[bool, typer.Option("--json", help="Print JSON instead of text.")] = False) -> None:
    """List the shipped presets with their first comment line."""
    from platesynth.schemas import dump
    from platesynth.schemas import presets as read_presets

    rows = read_presets().presets
    if as_json:
        print_json([dump(row) for row in rows])
        return
    for row in rows:
        typer.echo(f"{row.name:12s} {row.description}")


@app.command("show")
@user_errors
def show(preset: Preset = None, config: ConfigFile = None, overrides: Overrides = None) -> None:
    """Print the full, validated configuration as YAML (a starting point for --config files)."""
    from platesynth.scene import dump_config, load_config

    typer.echo(dump_config(load_config(preset, config, parse_overrides(overrides))), nl=False)


@app.command("sample")
@user_errors
def sample(
    seed: Annotated[int, typer.Option("--seed", min=0, help="Seed of the scene.")] = 0,
    preset: Preset = None,
    config: ConfigFile = None,
    overrides: Overrides = None,
) -> None:
    """Draw one concrete scene and print it as JSON."""
    from platesynth.scene import load_config, sample_scene

    scene = sample_scene(load_config(preset, config, parse_overrides(overrides)), seed)
    print_json(scene.model_dump(mode="json"))


def register(main_app: typer.Typer) -> None:
    """Add ``platesynth scene`` to the main app."""
    main_app.add_typer(app, name="scene")
