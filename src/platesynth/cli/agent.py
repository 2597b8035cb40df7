"""``platesynth mcp`` (the MCP server for agents) and ``platesynth skill reference`` (the skill's generated part)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from platesynth.cli._common import console, user_errors
from platesynth.errors import PlatesynthError

skill_app = typer.Typer(help="The agentskills.io skill in skills/platesynth/.", no_args_is_help=True)


@user_errors
def mcp_command(
    workspace: Annotated[
        Path, typer.Option("--workspace", "-w", help="The folder the tools read and write in (created if missing).")
    ],
    transport: Annotated[str, typer.Option("--transport", help="stdio (for a local client) or http.")] = "stdio",
    read_only_root: Annotated[
        list[Path] | None,
        typer.Option("--read-only-root", help="A folder the tools may read from (absolute paths); repeatable."),
    ] = None,
    host: Annotated[str, typer.Option("--host", help="http: the address to listen on.")] = "127.0.0.1",
    port: Annotated[int, typer.Option("--port", help="http: the port.")] = 8000,
    max_images: Annotated[int, typer.Option("--max-images", help="Images per job (render, preview, predict, metrics).")] = 1000,
    max_image_side: Annotated[int, typer.Option("--max-image-side", help="Longest side of a rendered image, px.")] = 2048,
    max_jobs: Annotated[int, typer.Option("--max-jobs", help="Jobs (render, train) running at once.")] = 1,
    max_job_seconds: Annotated[float, typer.Option("--max-job-seconds", help="Seconds a job may run.")] = 3600.0,
    max_train_steps: Annotated[
        int, typer.Option("--max-train-steps", help="Optimiser steps (epochs x steps) of one training.")
    ] = 20000,
    max_read_bytes: Annotated[
        int, typer.Option("--max-read-bytes", help="Largest file the read_result tool returns.")
    ] = 2_000_000,
) -> None:
    """Serve platesynth's tools over MCP (Model Context Protocol): stdout carries only the protocol in stdio mode.

    Every path a client names stays inside --workspace (or, for reading, a --read-only-root); see docs/agents.md.
    """
    from platesynth.agent.workspace import Limits, Workspace

    if transport not in ("stdio", "http"):
        raise PlatesynthError(f"--transport {transport!r}: choose stdio or http")
    try:
        from platesynth.agent.server import run
    except ImportError as exc:
        raise PlatesynthError(
            f"the MCP server needs the mcp package ({exc}); install it with: pip install 'platesynth[agent]'"
        ) from None
    limits = Limits(
        max_images=max_images, max_image_side=max_image_side, max_jobs=max_jobs, max_job_seconds=max_job_seconds,
        max_train_steps=max_train_steps, max_read_bytes=max_read_bytes,
    )
    space = Workspace.create(workspace, tuple(read_only_root or ()))
    console.print(f"platesynth MCP server over {transport}, workspace {space.root}", highlight=False)
    run(space, limits, "stdio" if transport == "stdio" else "http", host=host, port=port)


@skill_app.command("reference")
@user_errors
def reference_command(
    out: Annotated[
        Path, typer.Option("--out", "-o", help="The reference file to write.")
    ] = Path("skills/platesynth/references/parameters.md"),
    check: Annotated[bool, typer.Option("--check", help="Only check that the file is up to date (exit 1 if not).")] = False,
) -> None:
    """Write the skill's parameter reference from the catalogue (or check that it is current)."""
    from platesynth.agent.reference import parameter_reference
    from platesynth.io import write_text

    text = parameter_reference()
    if check:
        current = out.read_text(encoding="utf-8") if out.is_file() else None
        if current != text:
            raise PlatesynthError(f"{out}: stale, not what the catalogue gives now; run `platesynth skill reference`")
        console.print(f"{out} is up to date", highlight=False)
        return
    write_text(out, text)
    console.print(f"wrote {out}", highlight=False)


def register(app: typer.Typer) -> None:
    """Add ``mcp`` and ``skill`` to the main app."""
    app.command("mcp")(mcp_command)
    app.add_typer(skill_app, name="skill")
