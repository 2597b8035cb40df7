"""``platesynth render``, ``preview`` and ``demo``: datasets on disk, contact sheets, the newcomer's first run."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer
from rich.progress import ProgressColumn, Task
from rich.text import Text

from platesynth.cli._common import console, print_json, print_table, progress_bar, styled, user_errors
from platesynth.cli.options import (
    Backend,
    BlenderDevice,
    ConfigFile,
    ConnectTimeout,
    Engine,
    ExecutorKind,
    Out,
    Overrides,
    Plate,
    Preset,
    Samples,
    Scheduler,
    Seed,
    open_executor,
    parse_overrides,
    parse_size,
)
from platesynth.data.batch import BatchSummary, build_manifest, render_dataset, render_item
from platesynth.data.executor import make_executor
from platesynth.data.layout import Manifest, list_items, load_item
from platesynth.data.writer import check_directory
from platesynth.errors import ParameterError
from platesynth.io import write_png
from platesynth.limits import check_render
from platesynth.outputs import PREVIEW_TEXT_KEY, claim_output


class _RateColumn(ProgressColumn):
    """Images per second, averaged over the last seconds."""

    def render(self, task: Task) -> Text:
        speed = task.finished_speed or task.speed
        return Text(f"{speed:.2f} img/s" if speed else "- img/s", style="progress.data.speed")


def _render_with_progress(directory: Path, manifest: Manifest, executor: Any, overwrite: bool) -> BatchSummary:
    bar = progress_bar(transient=False)
    bar.columns = (*bar.columns, _RateColumn())
    task_id: list[Any] = []

    def progress(done: int, total: int) -> None:
        if not task_id:
            task_id.append(bar.add_task("rendering", total=total, completed=done))
        else:
            bar.update(task_id[0], completed=done)

    with bar:
        return render_dataset(directory, manifest, executor=executor, overwrite=overwrite, progress=progress)


def _report(summary: BatchSummary, as_json: bool) -> None:
    if as_json:
        from platesynth.schemas import RenderSummary, dump, from_result

        print_json(dump(from_result(RenderSummary, summary.to_dict())))
    console.print(
        f"{summary.rendered} rendered, {summary.skipped} already there, {len(summary.failed)} failed "
        f"in {summary.seconds:.1f} s -> {summary.directory}",
        highlight=False,
    )
    for name, error in list(summary.failed.items())[:10]:
        console.print(styled("failed:", "bold red", f"{name}: {error.splitlines()[0]}"), highlight=False, soft_wrap=True)
    if len(summary.failed) > 10:
        console.print(f"... and {len(summary.failed) - 10} more (see manifest.json)", highlight=False)


@user_errors
def render(
    out: Out,
    count: Annotated[int, typer.Option("--count", "-n", help="Number of images.")],
    seed: Seed = 0,
    preset: Preset = None,
    plate: Plate = None,
    size: Annotated[str, typer.Option("--size", help="Image size WIDTHxHEIGHT.")] = "1024x768",
    config: ConfigFile = None,
    overrides: Overrides = None,
    backend: Backend = "raster",
    samples: Samples = None,
    engine: Engine = None,
    device: BlenderDevice = None,
    workers: Annotated[
        int, typer.Option("--workers", "-j", help="Local worker processes (or Dask LocalCluster workers).")
    ] = 1,
    executor: ExecutorKind = "local",
    scheduler: Scheduler = None,
    connect_timeout: ConnectTimeout = 10.0,
    coco: Annotated[bool, typer.Option("--coco", help="Also write annotations.coco.json (wells and plaques).")] = False,
    overwrite: Annotated[
        bool, typer.Option("--overwrite", help="Replace a different dataset, or another kind of output, in --out.")
    ] = False,
    as_json: Annotated[bool, typer.Option("--json", help="Print a JSON summary on stdout.")] = False,
) -> None:
    """Render an annotated dataset: images, instance masks, params, counts.csv (resumes an interrupted run)."""
    manifest = build_manifest(
        preset=preset,
        config_file=config,
        overrides=parse_overrides(overrides, plate),
        seed=seed,
        count=count,
        size=parse_size(size),
        backend=backend,
        samples=samples,
        engine=engine,
        device=device,
        coco=coco,
    )
    check_render(manifest.size, manifest.backend, workers=1 if scheduler else workers, count=manifest.count)
    claim = claim_output(
        out, "dataset", inputs=[config], overwrite=overwrite, check=lambda: check_directory(out, manifest, overwrite)
    )
    with claim, open_executor(executor, workers, scheduler, connect_timeout) as pool:
        claim.take()
        console.print(f"rendering {manifest.count} images into {out} on {pool.describe()}", highlight=False)
        summary = _render_with_progress(out, manifest, pool, overwrite)
    _report(summary, as_json)
    if summary.failed:
        raise typer.Exit(code=1)


@user_errors
def preview(
    out: Annotated[Path, typer.Option("--out", "-o", help="Contact sheet to write (.png).")],
    count: Annotated[int, typer.Option("--count", "-n", help="Number of scenes.")] = 12,
    seed: Seed = 0,
    preset: Preset = None,
    plate: Plate = None,
    size: Annotated[str, typer.Option("--size", help="Size of each image WIDTHxHEIGHT.")] = "320x240",
    config: ConfigFile = None,
    overrides: Overrides = None,
    backend: Backend = "raster",
    samples: Samples = None,
    engine: Engine = None,
    device: BlenderDevice = None,
    columns: Annotated[int, typer.Option("--columns", help="Images per row.")] = 4,
    outlines: Annotated[bool, typer.Option("--outlines/--no-outlines", help="Draw well and plaque outlines.")] = True,
    overwrite: Annotated[
        bool, typer.Option("--overwrite", help="Replace a file in --out that is not a contact sheet.")
    ] = False,
) -> None:
    """Render a few scenes small and tile them into one contact sheet, to look at a configuration."""
    from platesynth.data.preview import contact_sheet, draw_outlines  # scikit-image: not for every command

    if out.suffix.lower() != ".png":
        raise ParameterError(f"{out}: the contact sheet is a PNG file; give a name ending in .png")
    if columns < 1:
        raise ParameterError(f"columns must be >= 1, got {columns}")
    manifest = build_manifest(
        preset=preset,
        config_file=config,
        overrides=parse_overrides(overrides, plate),
        seed=seed,
        count=count,
        size=parse_size(size),
        backend=backend,
        samples=samples,
        engine=engine,
        device=device,
    )
    claim_output(out, "preview", inputs=[config], overwrite=overwrite)
    check_render(manifest.size, manifest.backend, count=count, kept_images=count)
    tiles = []
    with progress_bar() as bar:
        for index in bar.track(range(count), description="rendering"):
            result, _ = render_item(manifest, index)
            tiles.append(draw_outlines(result.image, result.wells, result.plaques) if outlines else result.image)
    sheet = contact_sheet(tiles, columns=columns, tile_width=manifest.size[0])
    write_png(out, sheet, text={PREVIEW_TEXT_KEY: "preview"})
    console.print(f"wrote {out} ({count} scenes, seed {seed})", highlight=False)


@user_errors
def demo(
    out: Out = Path("demo-output"),
    count: Annotated[int, typer.Option("--count", "-n", help="Number of images.")] = 12,
    size: Annotated[str, typer.Option("--size", help="Image size WIDTHxHEIGHT.")] = "512x384",
    preset: Preset = "high",
    seed: Seed = 0,
    workers: Annotated[int, typer.Option("--workers", "-j", help="Local worker processes.")] = 1,
    overwrite: Annotated[
        bool, typer.Option("--overwrite", help="Replace a different demo, or another kind of output, in --out.")
    ] = False,
    model: Annotated[
        Path | None,
        typer.Option(
            "--model", help="A trained model directory: also count plaques per well and compare with the truth."
        ),
    ] = None,
) -> None:
    """Render a small 12-well dataset with counts and COCO, a contact sheet, and print its dataset metrics."""
    from platesynth.data.preview import contact_sheet, draw_outlines
    from platesynth.metrics.dataset import dataset_metrics

    manifest = build_manifest(
        preset=preset, overrides={"plate.format": 12}, seed=seed, count=count, size=parse_size(size), coco=True
    )
    check_render(manifest.size, workers=workers, count=count, metrics=True)
    network = _load_counter(model) if model is not None else None  # a bad --model is refused before rendering
    claim = claim_output(
        out, "demo", inputs=[model], overwrite=overwrite, check=lambda: check_directory(out, manifest, overwrite)
    )
    with claim:
        with make_executor("local", workers=workers) as pool:
            claim.take()
            summary = _render_with_progress(out, manifest, pool, overwrite)
        _report(summary, as_json=False)
        items = list_items(out)
        tiles = [draw_outlines(*load_item(item)) for item in items[:12]]
        sheet = out / "preview.png"
        write_png(sheet, contact_sheet(tiles, columns=4, tile_width=256))
    print_table(dataset_metrics(out / "images"), title=f"dataset metrics of {out / 'images'}")
    console.print(
        f"images, masks and params in {out}/; per-well counts in {out / 'counts.csv'}; "
        f"COCO in {out / 'annotations.coco.json'}; contact sheet {sheet}",
        highlight=False,
    )
    if model is not None:
        _demo_counts(network, model, out)
    if summary.failed:
        raise typer.Exit(code=1)


def _load_counter(model_dir: Path) -> Any:
    from platesynth.segment.model import load_model, select_device

    return load_model(model_dir, select_device("auto"))


def _demo_counts(network: Any, model_dir: Path, out: Path) -> None:
    """Count plaques per well in the demo images with a trained model, against the counts the renderer wrote."""
    import functools

    from platesynth.cli.segment import print_count_summary
    from platesynth.segment.counts import evaluate_counts
    from platesynth.segment.predict import predict_image

    predictor = functools.partial(predict_image, network, plate_format=12)
    report = evaluate_counts(predictor, out / "images", out / "counts.csv", plate_format=12)
    print_count_summary(report, title=f"plaques per well: {model_dir} against the rendered truth")


def register(app: typer.Typer) -> None:
    """Add ``render``, ``preview`` and ``demo`` to the main platesynth app."""
    app.command("render")(render)
    app.command("preview")(preview)
    app.command("demo")(demo)
