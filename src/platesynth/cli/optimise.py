"""``platesynth optimise``: search the scene parameters for renders closer to real photos (Optuna, TPE)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console
from rich.progress import TextColumn
from rich.table import Table
from rich.text import Text

from platesynth.cli._common import console, print_json, progress_bar, styled, user_errors
from platesynth.cli.options import (
    ConfigFile,
    ConnectTimeout,
    ExecutorKind,
    Overrides,
    Preset,
    Scheduler,
    open_executor,
    parse_overrides,
    parse_size,
)
from platesynth.errors import ParameterError


def parse_weights(items: list[str] | None) -> dict[str, float]:
    """``["fd_wells=2"]`` -> ``{"fd_wells": 2.0}`` (the terms are checked by the library)."""
    weights = {}
    for item in items or []:
        name, sep, value = item.partition("=")
        try:
            weights[name.strip()] = float(value)
        except ValueError:
            sep = ""
        if not sep or not name.strip():
            raise ParameterError(f"--weight {item!r}: expected TERM=NUMBER, e.g. fd_wells=2")
    return weights


def _progress() -> tuple[Any, Any]:
    """A progress bar on stderr with the best objective so far, and its ``progress(stage, done, total, best)``."""
    bar = progress_bar(transient=False)
    bar.columns = (*bar.columns, TextColumn("{task.fields[best]}", markup=False))
    labels = {"reference": "measuring the photos", "trials": "trials", "evaluation": "evaluating start and best"}
    tasks: dict[str, Any] = {}

    def progress(stage: str, done: int, total: int, best: float | None) -> None:
        text = f"best {best:.4g}" if best is not None else ""
        if stage not in tasks:
            tasks[stage] = bar.add_task(labels.get(stage, stage), total=total, completed=done, best=text)
        else:
            bar.update(tasks[stage], total=total, completed=done, best=text)

    return bar, progress


def _print_report(report: dict[str, Any]) -> None:
    from platesynth.optimise import TERMS

    out = Console()
    for part in ("fit", "check"):
        rows = report["evaluation"][part]
        columns = ["objective", *[t for t in TERMS if any(t in row for row in rows.values())]]
        table = Table(title=Text(f"{part} photos ({len(report['split'][part])}), {report['eval_count']} new renders each"))
        table.add_column("configuration")
        for column in columns:
            table.add_column(column, justify="right")
        for name, row in rows.items():
            table.add_row(Text(name), *(Text(f"{row[c]:.4g}" if c in row else row.get("error", "")[:40])
                                        for c in columns))
        out.print(table)


@user_errors
def optimise(
    reference: Annotated[Path, typer.Option("--reference", help="Folder of real plate photos (split into fit and check).")],
    out: Annotated[Path, typer.Option("--out", "-o", help="Output folder (the study, its trials and report).")],
    trials: Annotated[int, typer.Option("--trials", "-n", help="Finished trials the study should hold (resumes).")],
    preset: Preset = None,
    config: ConfigFile = None,
    overrides: Overrides = None,
    space: Annotated[
        Path | None, typer.Option("--space", help="YAML search space (default: the look's parameters, narrowed).")
    ] = None,
    narrow: Annotated[
        float | None, typer.Option("--narrow", help="Half-width of the default ranges, share of each valid range.")
    ] = None,
    timeout: Annotated[float | None, typer.Option("--timeout", help="Start no trial after this many seconds.")] = None,
    seed: Annotated[int, typer.Option("--seed", help="Seed of the split, the sampler and the renders.")] = 0,
    count: Annotated[int | None, typer.Option("--count", help="Images per trial.")] = None,
    size: Annotated[str | None, typer.Option("--size", help="Render size WIDTHxHEIGHT.")] = None,
    compare_size: Annotated[
        str | None, typer.Option("--compare-size", help="Size renders and photos are measured at (default --size).")
    ] = None,
    eval_count: Annotated[
        int | None, typer.Option("--eval-count", help="Images of the final evaluation of start and best.")
    ] = None,
    well_size: Annotated[int | None, typer.Option("--well-size", help="Side of the well crops, pixels.")] = None,
    check_fraction: Annotated[
        float | None, typer.Option("--check-fraction", help="Share of the photos kept out for checking.")
    ] = None,
    weight: Annotated[
        list[str] | None, typer.Option("--weight", help="Weight of a term, e.g. --weight fd_wells=2; repeatable.")
    ] = None,
    plaque_model: Annotated[
        Path | None,
        typer.Option("--plaque-model", help="Segmentation model (e.g. models/plaque12) measuring plaque sizes in "
                     "renders and photos alike: adds the plaque_sizes and plaques_found terms."),
    ] = None,
    multi_objective: Annotated[
        bool, typer.Option("--multi-objective", help="Optimise the terms together (a Pareto front).")
    ] = False,
    storage: Annotated[
        str | None, typer.Option("--storage", help="SQLAlchemy URL of the study (default: sqlite in --out).")
    ] = None,
    workers: Annotated[int, typer.Option("--workers", "-j", help="Trials evaluated at a time (local processes).")] = 1,
    executor: ExecutorKind = "local",
    scheduler: Scheduler = None,
    connect_timeout: ConnectTimeout = 10.0,
    compare: Annotated[
        list[str] | None, typer.Option("--compare", help="Also measure this preset in the report; repeatable.")
    ] = None,
    overwrite: Annotated[
        bool, typer.Option("--overwrite", help="Start afresh over an earlier optimisation or another output.")
    ] = False,
    as_json: Annotated[bool, typer.Option("--json", help="Print the report as JSON on stdout.")] = False,
) -> None:
    """Search the scene parameters for renders closer to real photos; resumes an interrupted run."""
    from platesynth.optimise import optimise as run_optimise

    pool = open_executor(executor, workers, scheduler, connect_timeout)
    given = {  # options left out take the library's defaults
        "narrow": narrow,
        "timeout": timeout,
        "count": count,
        "size": parse_size(size) if size is not None else None,
        "compare_size": parse_size(compare_size) if compare_size is not None else None,
        "eval_count": eval_count,
        "well_size": well_size,
        "check_fraction": check_fraction,
        "storage": storage,
    }
    bar, progress = _progress()

    def announce() -> None:
        console.print(f"optimising from {preset or config or 'the defaults'} into {out} on {pool.describe()}",
                      highlight=False)

    with bar:
        result = run_optimise(
            reference,
            out,
            preset=preset,
            config=config,
            overrides=parse_overrides(overrides),
            space=space,
            trials=trials,
            seed=seed,
            weights=parse_weights(weight),
            plaque_model=plaque_model,
            multi_objective=multi_objective,
            executor=pool,
            batch=workers,
            compare=compare or (),
            overwrite=overwrite,
            progress=progress,
            before_writing=announce,
            **{name: value for name, value in given.items() if value is not None},
        )
    for note in result.notes:
        console.print(styled("note:", "yellow", note), highlight=False, soft_wrap=True)
    report = result.report
    console.print(
        f"best trial {report['best_trial']} of {report['n_trials']} ({report['n_failed']} failed) in "
        f"{report['seconds']:.0f} s -> {result.best_config}",
        highlight=False,
    )
    if as_json:
        print_json(report)
    else:
        _print_report(report)


def register(app: typer.Typer) -> None:
    """Add ``optimise`` to the main platesynth app."""
    app.command("optimise")(optimise)
