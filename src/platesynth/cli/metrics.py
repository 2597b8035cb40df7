"""``platesynth metrics ...``: pair and dataset metrics."""

from __future__ import annotations

import re
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import typer

from platesynth.cli._common import console, print_json, print_table, progress_bar, styled, user_errors
from platesynth.errors import ParameterError

app = typer.Typer(help="Realism and diversity metrics for image pairs and datasets.", no_args_is_help=True)


def register(main_app: typer.Typer) -> None:
    """Add ``platesynth metrics`` to the main app."""
    main_app.add_typer(app, name="metrics")


@contextmanager
def _progress_and_notes() -> Iterator[Callable[[str, int, int], None]]:
    """Yield a ``progress(description, done, total)`` callback (bars on stderr), then print skipped-metric notes."""
    from platesynth.metrics import MetricSkippedWarning

    tasks: list[Any] = []
    bars = progress_bar()
    with warnings.catch_warnings(record=True) as caught, bars:
        warnings.simplefilter("always", MetricSkippedWarning)

        def progress(description: str, done: int, total: int) -> None:
            if done == 0 or not tasks:  # a new computation starts
                tasks.append(bars.add_task(description, total=total))
            bars.update(tasks[-1], completed=done, description=description)

        yield progress
    for warning in caught:
        if issubclass(warning.category, MetricSkippedWarning):
            console.print(styled("note:", "yellow", str(warning.message)), highlight=False, soft_wrap=True)
        else:
            warnings.showwarning(warning.message, warning.category, warning.filename, warning.lineno)


def _parse_size(text: str | None) -> tuple[int, int] | None:
    """``"512x384"`` (width x height) -> ``(384, 512)`` (height, width)."""
    if text is None:
        return None
    match = re.fullmatch(r"\s*(\d+)\s*[xX]\s*(\d+)\s*", text)
    if not match or 0 in (int(match[1]), int(match[2])):
        raise ParameterError(f"--size must be WIDTHxHEIGHT in pixels, e.g. 512x384, got {text!r}")
    return int(match[2]), int(match[1])


@app.command("pair")
@user_errors
def pair_command(
    real: Path = typer.Argument(..., help="Real (reference) image.", show_default=False),
    synthetic: Path = typer.Argument(..., help="Synthetic image to judge.", show_default=False),
    json_output: bool = typer.Option(False, "--json", help="Print one JSON object on stdout."),
    resize: bool = typer.Option(False, "--resize", help="Resize the synthetic image to the real one if sizes differ."),
    no_lpips: bool = typer.Option(False, "--no-lpips", help="Skip LPIPS."),
    no_frechet: bool = typer.Option(False, "--no-frechet", help="Skip the patch Fréchet distances."),
) -> None:
    """Compare a synthetic image with a real one: MSE, NRMSE, SSIM, PSNR, naturalness, LPIPS, patch FD.

    Identical images have an infinite PSNR, written as null in JSON.
    """
    from platesynth.metrics import compare_pair

    with _progress_and_notes() as progress:
        result = compare_pair(
            real, synthetic, lpips=not no_lpips, frechet=not no_frechet, resize=resize, progress=progress
        )
    if json_output:
        from platesynth.schemas import PairMetrics, dump, from_result

        print_json(dump(from_result(PairMetrics, result)))
    else:
        print_table(result, title=f"{synthetic} vs {real}")


def _parse_grid(text: str) -> tuple[int, int]:
    """``"3x4"`` (rows x columns) -> ``(3, 4)``."""
    match = re.fullmatch(r"\s*(\d+)\s*[xX]\s*(\d+)\s*", text)
    if not match or 0 in (int(match[1]), int(match[2])):
        raise ParameterError(f"--well-grid must be ROWSxCOLS, e.g. 3x4, got {text!r}")
    return int(match[1]), int(match[2])


@app.command("dataset")
@user_errors
def dataset_command(
    directory: Path = typer.Argument(
        ..., help="Folder of images (typically synthetic); with --wells a platesynth dataset or its images/ folder.",
        show_default=False,
    ),
    reference: Path | None = typer.Option(None, "--reference", help="Folder of reference (real) images."),
    size: str | None = typer.Option(
        None, "--size", help="WIDTHxHEIGHT for entropy and brightness variability [default: the first image's]."
    ),
    json_output: bool = typer.Option(False, "--json", help="Print one JSON object on stdout."),
    no_frechet: bool = typer.Option(False, "--no-frechet", help="Skip the Fréchet and kernel distances."),
    wells: bool = typer.Option(
        False, "--wells", help="Add the well-crop metrics against --reference (fd_wells, kid_wells, dnf_wells, "
        "spectrum and plaque figures); wells from DIR's masks, the reference's from a fitted plate grid."
    ),
    well_size: int = typer.Option(128, "--well-size", help="Side of the resized well crops, pixels.", min=31),
    well_grid: str = typer.Option("3x4", "--well-grid", help="ROWSxCOLS of the plates without masks."),
    model: Path | None = typer.Option(
        None, "--model", help="With --wells: a segmentation model whose predicted masks replace the grid."
    ),
) -> None:
    """Diversity (pixel entropy, brightness variability) and naturalness of a folder of images.

    With --reference also the naturalness difference and the Fréchet and kernel distances of AlexNet features
    (and of Inception features when its weights are available). Entropy grows with the number of images
    (at most log2 N bits): compare folders of equal size. With --wells also the well-crop metrics
    (docs/metrics.md, "Well-crop metrics"); the spectra themselves are printed with --json only.
    """
    from platesynth.data.layout import IMAGES_DIR
    from platesynth.metrics import dataset_metrics
    from platesynth.metrics.wells import find_dataset_root, well_metrics

    target_size = _parse_size(size)
    grid = _parse_grid(well_grid)
    if (wells or model is not None) and reference is None:
        raise ParameterError("--wells and --model need --reference (the real plates to compare the wells with)")
    if model is not None and not wells:
        raise ParameterError("--model is used by --wells only")
    root = find_dataset_root(directory)
    images = root / IMAGES_DIR if root is not None and wells else directory
    with _progress_and_notes() as progress:
        result = dataset_metrics(images, reference, size=target_size, frechet=not no_frechet, progress=progress)
        if wells:
            result.update(
                well_metrics(directory, reference, size=well_size, grid=grid, model=model, frechet=not no_frechet,
                             progress=progress)
            )
    if json_output:
        from platesynth.schemas import DatasetMetrics, dump, from_result

        print_json(dump(from_result(DatasetMetrics, result)))
        return
    height, width = result.pop("size")
    rows = {key: value for key, value in result.items() if not isinstance(value, list)}  # spectra: --json only
    print_table({"size (width x height)": f"{width}x{height}", **rows}, title=str(directory))
