"""``platesynth train``, ``predict``, ``evaluate masks`` and ``evaluate counts``: the segmentation model's commands."""

from __future__ import annotations

import functools
import json
import math
import re
from pathlib import Path
from typing import Annotated, Any

import typer
from pydantic import ValidationError

from platesynth.cli._common import console, print_json, print_table, progress_bar, user_errors
from platesynth.errors import ParameterError
from platesynth.io import list_images
from platesynth.outputs import TABLE_COLUMNS, claim_output

ModelDir = Annotated[Path, typer.Option("--model", "-m", help="Model directory (written by `platesynth train`).")]
Json = Annotated[bool, typer.Option("--json", help="Print the result as JSON on stdout.")]
PlateFormat = Annotated[
    int | None, typer.Option("--plate", help="Wells per plate, for sorting wells into rows and columns (default: the model's).")
]
FromBelow = Annotated[
    bool,
    typer.Option("--from-below/--from-above", help="Plates photographed through their bottom (mirrored labels) or from above."),
]

Threads = Annotated[
    int,
    typer.Option("--threads", help="CPU threads for torch (0: torch's default; on a busy machine 1 is often fastest)."),
]

Device = Annotated[str, typer.Option("--device", help="auto (CUDA if available), cpu or cuda.")]

WellProb = Annotated[float | None, typer.Option("--well-prob", help="Override the wells' probability threshold.")]
WellNms = Annotated[float | None, typer.Option("--well-nms", help="Override the wells' NMS threshold.")]
PlaqueProb = Annotated[float | None, typer.Option("--plaque-prob", help="Override the plaques' probability threshold.")]
PlaqueNms = Annotated[float | None, typer.Option("--plaque-nms", help="Override the plaques' NMS threshold.")]

_PATCH = re.compile(r"^\s*(\d+)\s*[xX]\s*(\d+)\s*$")


def _set_threads(threads: int) -> None:
    if threads < 0:
        raise ParameterError(f"--threads must be >= 0, got {threads}")
    if threads:
        import torch

        torch.set_num_threads(threads)


def _parse_patch(text: str) -> tuple[int, int]:
    match = _PATCH.match(text)
    if not match or min(int(match[1]), int(match[2])) < 1:
        raise ParameterError(f"--patch {text!r}: expected HEIGHTxWIDTH in pixels, e.g. 256x256")
    return int(match[1]), int(match[2])


def _parse_mix(text: str | None) -> list[float] | None:
    if text is None:
        return None
    try:
        return [float(part) for part in text.split(",")]
    except ValueError:
        raise ParameterError(f"--mix {text!r}: expected comma-separated fractions, e.g. 0.9,0.1") from None


def _validation_message(exc: ValidationError) -> str:
    error = exc.errors()[0]
    where = ".".join(str(part) for part in error["loc"])
    return f"{where}: {error['msg']}" if where else error["msg"]


def _model_config(path: Path | None) -> Any:
    from platesynth.segment.model import ModelConfig

    if path is None:
        return ModelConfig()
    try:
        return ModelConfig.model_validate(json.loads(path.read_text()))
    except OSError as exc:
        raise ParameterError(f"{path}: cannot read model configuration ({exc.strerror})") from None
    except json.JSONDecodeError as exc:
        raise ParameterError(f"{path}: not JSON ({exc.msg}, line {exc.lineno})") from None
    except ValidationError as exc:
        raise ParameterError(f"{path}: {_validation_message(exc)}") from None


@user_errors
def train_command(
    data: Annotated[list[Path], typer.Option("--data", "-d", help="Dataset directory in the platesynth layout; repeatable.")],
    out: Annotated[Path, typer.Option("--out", "-o", help="Model directory to write (re-running resumes).")],
    mix: Annotated[
        str | None, typer.Option("--mix", help="Sampling fraction per --data, e.g. 0.9,0.1 (default: by size).")
    ] = None,
    epochs: Annotated[int, typer.Option("--epochs", help="Epochs.")] = 20,
    steps: Annotated[int, typer.Option("--steps", help="Optimiser steps per epoch.")] = 50,
    batch_size: Annotated[int, typer.Option("--batch-size", help="Patches per step.")] = 4,
    patch: Annotated[str, typer.Option("--patch", help="Training patch HEIGHTxWIDTH in working pixels.")] = "256x256",
    learning_rate: Annotated[float, typer.Option("--lr", help="Adam learning rate (cosine decay to 5%).")] = 1e-3,
    val_fraction: Annotated[float, typer.Option("--val-fraction", help="Fraction of each dataset held out.")] = 0.1,
    max_val: Annotated[int, typer.Option("--max-val", help="At most this many validation images are evaluated, taken from the datasets in turn.")] = 24,
    seed: Annotated[int, typer.Option("--seed", help="Seed of the split, initial weights, sampling and augmentation.")] = 0,
    augment: Annotated[bool, typer.Option("--augment/--no-augment", help="Flips, rotations, scale, intensity, noise.")] = True,
    within_well: Annotated[float, typer.Option("--within-well", help="Weight of the penalty on plaques outside wells.")] = 0.0,
    scratch_weight: Annotated[
        float,
        typer.Option(
            "--scratch-weight",
            help="Extra weight of the plaque probability loss where a rendered item's scratches scraped the stain "
            "off (pale lesions that are not plaques; 0: none).",
        ),
    ] = 0.0,
    tune: Annotated[
        bool, typer.Option("--tune/--no-tune", help="Tune probability/NMS thresholds on the validation images.")
    ] = True,
    min_resolved_cells: Annotated[
        float,
        typer.Option(
            "--min-resolved-cells",
            help="Tuning leaves out rendered plaques narrower than this many grid cells, and predictions on them "
            "(0: every plaque).",
        ),
    ] = 0.0,
    model_config: Annotated[
        Path | None, typer.Option("--model-config", help="JSON ModelConfig (architecture, working size, grids).")
    ] = None,
    device: Device = "auto",
    threads: Threads = 0,
    workers: Annotated[int, typer.Option("--workers", help="Data-loading processes.")] = 0,
    overwrite: Annotated[
        bool, typer.Option("--overwrite", help="Replace a different training, or another kind of output, in --out.")
    ] = False,
    as_json: Json = False,
) -> None:
    """Train the two-branch StarDist model (wells, plaques) on one or more datasets."""
    from platesynth.segment.model import select_device
    from platesynth.segment.train import TrainConfig, train

    _set_threads(threads)
    select_device(device)
    try:
        config = TrainConfig(
            data=[str(d) for d in data],
            mix=_parse_mix(mix),
            epochs=epochs,
            steps_per_epoch=steps,
            batch_size=batch_size,
            patch=_parse_patch(patch),
            learning_rate=learning_rate,
            val_fraction=val_fraction,
            max_val_images=max_val,
            seed=seed,
            augment=augment,
            within_well_weight=within_well,
            scratch_weight=scratch_weight,
            tune_thresholds=tune,
            min_resolved_cells=min_resolved_cells,
            num_workers=workers,
        )
    except ValidationError as exc:
        raise ParameterError(_validation_message(exc)) from None
    network_config = _model_config(model_config)
    claim = claim_output(out, "model", inputs=[*data, model_config], overwrite=overwrite)
    bar = progress_bar(transient=False)
    task_id = bar.add_task("epoch", total=config.epochs * config.steps_per_epoch, visible=False)

    def progress(event: dict[str, Any]) -> None:
        if "loss" in event:
            done = (event["epoch"] - 1) * config.steps_per_epoch + event["step"]
            description = f"epoch {event['epoch']}/{config.epochs} loss {event['loss']:.3f}"
            bar.update(task_id, completed=done, visible=True, description=description)
        else:
            val_loss = "n/a" if event["val_loss"] is None else f"{event['val_loss']:.4f}"
            message = f"epoch {event['epoch']}: train loss {event['train_loss']:.4f}, validation loss {val_loss}"
            bar.console.print(message, highlight=False)

    with claim, bar:
        summary = train(
            config, out, network_config, overwrite=overwrite, device=device, progress=progress, before_writing=claim.take
        )
    if as_json:
        from platesynth.schemas import dump, train_result

        print_json(dump(train_result(summary)))
    else:
        resumed = f", resumed after epoch {summary.resumed_from_epoch}" if summary.resumed_from_epoch else ""
        message = f"model written to {summary.model_dir} (best validation loss {summary.best_val_loss:.4f}{resumed})"
        console.print(message, highlight=False)


def _image_paths(inputs: list[Path]) -> list[Path]:
    paths: list[Path] = []
    for path in inputs:
        paths += list_images(path) if path.is_dir() else [path]
    return paths


def _load_network(
    model_dir: Path, device: str, threads: int, well: tuple[float | None, float | None], plaque: tuple[float | None, float | None]
) -> tuple[Any, dict[str, tuple[float, float]]]:
    """The trained network and its per-branch (prob, nms) thresholds: the model's own unless overridden."""
    from platesynth.segment.model import load_model, select_device

    for option, value, low, high in (
        ("--well-prob", well[0], 0.0, 1.0), ("--plaque-prob", plaque[0], 0.0, 1.0),
        ("--well-nms", well[1], 0.0, 1.0), ("--plaque-nms", plaque[1], 0.0, 1.0),
    ):
        if value is not None and not (low < value < high if option.endswith("prob") else low <= value <= high):
            interval = f"({low:g}, {high:g})" if option.endswith("prob") else f"[{low:g}, {high:g}]"
            raise ParameterError(f"{option} must be in {interval}, got {value}")
    _set_threads(threads)
    network = load_model(model_dir, select_device(device))
    thresholds = {}
    for name, (prob, nms) in {"wells": well, "plaques": plaque}.items():
        branch = network.config.branches[name]
        thresholds[name] = (branch.prob_thresh if prob is None else prob, branch.nms_thresh if nms is None else nms)
    return network, thresholds


def _with_progress(description: str, run: Any) -> Any:
    bar = progress_bar()
    task_id: list[Any] = []

    def progress(done: int, total: int) -> None:
        if not task_id:
            task_id.append(bar.add_task(description, total=total))
        bar.update(task_id[0], completed=done)

    with bar:
        return run(progress)


@user_errors
def predict_command(
    images: Annotated[list[Path], typer.Argument(help="Image files or folders of images.")],
    model: ModelDir,
    out: Annotated[Path, typer.Option("--out", "-o", help="Output directory (dataset layout plus counts.csv).")],
    plate: PlateFormat = None,
    from_below: FromBelow = True,
    well_prob: WellProb = None,
    well_nms: WellNms = None,
    plaque_prob: PlaqueProb = None,
    plaque_nms: PlaqueNms = None,
    device: Device = "auto",
    threads: Threads = 0,
    overwrite: Annotated[
        bool, typer.Option("--overwrite", help="Write into --out even where it holds another kind of output or the inputs.")
    ] = False,
) -> None:
    """Predict well and plaque instance masks and plaques per well (counts.csv) for plate images."""
    from platesynth.segment.predict import predict_files

    network, thresholds = _load_network(model, device, threads, (well_prob, well_nms), (plaque_prob, plaque_nms))
    paths = _image_paths(images)
    claim = claim_output(out, "prediction", inputs=[*paths, model], overwrite=overwrite)

    def run(progress: Any) -> Path:
        done = iter(range(1, len(paths) + 1))
        return predict_files(
            network, paths, out, thresholds, plate, from_below,
            progress=lambda _path: progress(next(done), len(paths)), before_writing=claim.take,
        )

    with claim:
        counts = _with_progress("predicting", run)
    console.print(f"{len(paths)} image(s) -> {out} (plaques per well: {counts})", highlight=False)


evaluate_app = typer.Typer(
    help="Evaluate a model: instance masks (AP, IoU_R) or plaques per well against counts.", no_args_is_help=True
)


def _print_masks(report: dict[str, Any]) -> None:
    rows: dict[str, Any] = {"images": report["n_images"]}
    for name in ("wells", "plaques"):
        for tau, summary in report[name].items():
            rows[f"{name} AP@{tau}"] = f"{summary['ap_mean']:.3f} ± {summary['ap_std']:.3f}"
            rows[f"{name} IoU_R@{tau}"] = f"{summary['iou_r_mean']:.3f} ± {summary['iou_r_std']:.3f}"
    print_table(rows, title="instance masks (mean ± std over images)")


@evaluate_app.command("masks")
@user_errors
def evaluate_masks_command(
    model: ModelDir,
    data: Annotated[Path, typer.Option("--data", "-d", help="Dataset with true masks (platesynth layout).")],
    tau: Annotated[list[float] | None, typer.Option("--tau", help="IoU threshold; repeatable (default 0.5).")] = None,
    well_prob: WellProb = None,
    well_nms: WellNms = None,
    plaque_prob: PlaqueProb = None,
    plaque_nms: PlaqueNms = None,
    device: Device = "auto",
    threads: Threads = 0,
    as_json: Json = False,
) -> None:
    """Per class, AP = TP/(TP+FP+FN) and IoU_R at each tau: mean and spread over images."""
    from platesynth.segment.matching import evaluate_masks
    from platesynth.segment.predict import predict_image

    taus = tuple(tau or (0.5,))
    if any(not 0 < t <= 1 for t in taus):
        raise ParameterError(f"--tau must be in (0, 1], got {', '.join(map(str, taus))}")
    network, thresholds = _load_network(model, device, threads, (well_prob, well_nms), (plaque_prob, plaque_nms))
    predictor = functools.partial(predict_image, network, thresholds=thresholds)
    report = _with_progress("evaluating", lambda progress: evaluate_masks(predictor, data, taus, progress))
    if as_json:
        from platesynth.schemas import MaskReport, dump, from_result

        print_json(dump(from_result(MaskReport, report)))
    else:
        _print_masks(report)


@evaluate_app.command("counts")
@user_errors
def evaluate_counts_command(
    model: ModelDir,
    images: Annotated[Path, typer.Option("--images", help="Folder holding the images named in the counts table.")],
    counts: Annotated[Path, typer.Option("--counts", help="image,row,col,well,count table; blank counts are not scored.")],
    plate: PlateFormat = None,
    from_below: FromBelow = True,
    table: Annotated[Path | None, typer.Option("--table", help="Also write the per-well table to this CSV file.")] = None,
    well_prob: WellProb = None,
    well_nms: WellNms = None,
    plaque_prob: PlaqueProb = None,
    plaque_nms: PlaqueNms = None,
    device: Device = "auto",
    threads: Threads = 0,
    overwrite: Annotated[
        bool, typer.Option("--overwrite", help="Let --table replace a file that is not such a table, or an input.")
    ] = False,
    as_json: Json = False,
) -> None:
    """Predicted plaques per well against a person's counts: MAE, RMSE, Pearson r, and the training-mean baseline."""
    from platesynth.segment.counts import evaluate_counts, write_count_table
    from platesynth.segment.predict import predict_image

    if table is not None:
        claim_output(table, "table", inputs=[counts, images, model], overwrite=overwrite)
    network, thresholds = _load_network(model, device, threads, (well_prob, well_nms), (plaque_prob, plaque_nms))
    plate_format = plate or network.config.plate_format
    predictor = functools.partial(predict_image, network, thresholds=thresholds, plate_format=plate_format, from_below=from_below)
    baseline = network.config.training.get("mean_plaques_per_well")
    baseline = baseline if isinstance(baseline, (int, float)) and math.isfinite(baseline) else None
    report = _with_progress(
        "counting", lambda progress: evaluate_counts(predictor, images, counts, plate_format, baseline, progress)
    )
    if table is not None:
        columns = TABLE_COLUMNS
        write_count_table(table, [tuple("" if w[c] is None else w[c] for c in columns) for w in report["wells"]], columns)
    if as_json:
        from platesynth.schemas import CountReport, dump, from_result

        print_json(dump(from_result(CountReport, report)))
        return
    print_count_summary(report, title="plaques per well")


def print_count_summary(report: dict[str, Any], title: str) -> None:
    """Print the summary of an :func:`~platesynth.segment.counts.evaluate_counts` report as a table."""
    rows = {key: report[key] for key in ("n_images", "n_wells", "n_wells_not_detected", "mae", "rmse", "pearson_r", "bias")}
    rows.update({f"uncountable wells: {k}": report["countability"][k] for k in ("n_uncountable", "precision", "recall", "f1")})
    if "baseline" in report:
        rows.update({f"baseline ({report['baseline']['count']:.2f}/well) {k}": report["baseline"][k] for k in ("mae", "rmse")})
    print_table(rows, title=title)


def register(app: typer.Typer) -> None:
    """Add this module's commands to the main platesynth app."""
    app.command("train")(train_command)
    app.command("predict")(predict_command)
    app.add_typer(evaluate_app, name="evaluate")
