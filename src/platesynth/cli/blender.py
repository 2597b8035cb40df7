"""``platesynth scene export``: a concrete scene as a .blend file (registered by :func:`register`)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from platesynth.cli import scene as scene_cli
from platesynth.cli._common import console, user_errors
from platesynth.cli.options import ConfigFile, Overrides, Preset, parse_overrides, parse_size
from platesynth.errors import ParameterError
from platesynth.outputs import claim_output


@user_errors
def export(
    out: Annotated[Path, typer.Option("--out", help="The .blend file to write (replaced atomically).")],
    seed: Annotated[int, typer.Option("--seed", min=0, help="Seed of the scene.")] = 0,
    preset: Preset = None,
    config: ConfigFile = None,
    overrides: Overrides = None,
    scene_file: Annotated[
        Path | None,
        typer.Option("--scene", help="A saved concrete scene (e.g. a dataset's params/*.json) instead of a seed."),
    ] = None,
    size: Annotated[str, typer.Option("--size", help="Render size WIDTHxHEIGHT set in the file.")] = "1024x768",
    samples: Annotated[int, typer.Option("--samples", min=1, help="Cycles samples per pixel set in the file.")] = 16,
    overwrite: Annotated[
        bool, typer.Option("--overwrite", help="Replace a file in --out that is not a .blend scene, or an input.")
    ] = False,
) -> None:
    """Save a concrete scene as a .blend that opens in Blender 5.0: geometry nodes with named inputs, named
    material values, the compositor's post-processing. Render it with Blender or drive it from other tools."""
    from platesynth.render.blender import export_blend
    from platesynth.scene import load_config, load_scene, sample_scene

    if scene_file is not None and (preset or config or overrides):
        raise ParameterError("--scene gives a concrete scene: leave out --preset, --config and --set")
    if out.suffix.lower() != ".blend":
        raise ParameterError(f"{out}: the file name must end in .blend")
    render_size = parse_size(size)
    claim_output(out, "blend", inputs=[config, scene_file], overwrite=overwrite)
    if scene_file:
        scene = load_scene(scene_file)
    else:
        scene = sample_scene(load_config(preset, config, parse_overrides(overrides)), seed)
    with console.status("building the scene in Blender"):
        path = export_blend(scene, out, render_size, samples=samples)
    typer.echo(str(path))


def register(app: typer.Typer) -> None:
    """Add ``platesynth scene export`` to the ``scene`` command group (register :mod:`platesynth.cli.scene` too)."""
    del app  # the command joins the scene group, which the scene module adds to the main app
    scene_cli.app.command("export")(export)
