"""``platesynth study``: render, measure, train on and evaluate every arm of a study file; write its tables."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console
from rich.markdown import Markdown

from platesynth.cli._common import console, print_json, progress_bar, styled, user_errors
from platesynth.cli.options import ConnectTimeout, ExecutorKind, Scheduler, open_executor


def _progress() -> tuple[Any, Any]:
    bar = progress_bar(transient=False)
    tasks: dict[str, Any] = {}

    def progress(stage: str, done: int, total: int) -> None:
        if stage not in tasks:
            tasks[stage] = bar.add_task(f"{stage} stages", total=total, completed=done)
        else:
            bar.update(tasks[stage], total=total, completed=done)

    return bar, progress


@user_errors
def study(
    study_file: Annotated[Path, typer.Argument(help="The study file (YAML; see docs/study.md).", metavar="STUDY.yaml")],
    out: Annotated[Path, typer.Option("--out", "-o", help="Output folder of the study (reused: done stages are kept).")],
    workers: Annotated[int, typer.Option("--workers", "-j", help="Stages run at a time (local processes).")] = 1,
    executor: ExecutorKind = "local",
    scheduler: Scheduler = None,
    connect_timeout: ConnectTimeout = 10.0,
    overwrite: Annotated[
        bool, typer.Option("--overwrite", help="Replace another kind of output in --out (its files only).")
    ] = False,
    as_json: Annotated[bool, typer.Option("--json", help="Print the tables as JSON on stdout.")] = False,
) -> None:
    """Run a study: every arm's dataset rendered, measured, trained on and evaluated; tables and radar charts.

    Every stage is cached by what it depends on: a rerun does no work, an added arm only its own.
    """
    from platesynth.study import load_study, run_study
    from platesynth.study.tables import to_markdown

    spec = load_study(study_file)
    pool = open_executor(executor, workers, scheduler, connect_timeout)
    bar, progress = _progress()

    def announce() -> None:
        console.print(f"study {spec.name}: {len(spec.arms)} arms into {out} on {pool.describe()}", highlight=False)

    with bar:
        result = run_study(spec, out, executor=pool, inputs=(study_file,), overwrite=overwrite, progress=progress,
                           before_writing=announce)
    for note in result.notes:
        console.print(styled("note:", "yellow", note), highlight=False, soft_wrap=True)
    console.print(f"{len(result.ran)} stage(s) run, {len(result.cached)} found done, {len(result.failed)} failed, "
                  f"in {result.seconds:.0f} s; tables in {out / 'tables'}", highlight=False)
    for name, error in result.failed.items():
        console.print(styled("failed:", "bold red", f"{name}: {error}"), highlight=False, soft_wrap=True)
    if as_json:
        print_json({"ran": result.ran, "cached": result.cached, "failed": result.failed, "tables": result.tables})
    else:
        Console().print(Markdown("\n".join(to_markdown(table) for table in result.tables.values())))
    if result.failed:
        raise typer.Exit(code=1)


def register(app: typer.Typer) -> None:
    """Add ``study`` to the main platesynth app."""
    app.command("study")(study)
