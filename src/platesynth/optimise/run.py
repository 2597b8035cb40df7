"""``optimise``: search the scene parameters for renders closer to real photos, and report honestly.

The steps, each in its own module: the search space (:mod:`~platesynth.optimise.space`), the split of the photos
into fit and check parts (:mod:`~platesynth.optimise.reference`), the objective (render and measure a trial,
:mod:`~platesynth.optimise.objective`), the Optuna study (:mod:`~platesynth.optimise.study`) and the outputs
(:mod:`~platesynth.optimise.report`). Everything is validated before the output folder is written.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from platesynth import __version__
from platesynth.data.batch import build_manifest
from platesynth.data.executor import Executor, SerialExecutor
from platesynth.errors import OutputError, ParameterError, PlatesynthError, WeightsNotFoundError
from platesynth.io import write_json
from platesynth.limits import check_dataset_metrics, check_render
from platesynth.metrics.wells import CROP_SIZE
from platesynth.optimise import report as files
from platesynth.optimise.objective import (
    PLAQUE_TERMS,
    TERMS,
    MeasureSettings,
    TrialItem,
    TrialTask,
    check_weights,
    measure_reference,
    resized,
    segmentation_model,
    weighted_sum,
)
from platesynth.optimise.reference import CHECK_FRACTION, read_photos, split_reference
from platesynth.optimise.space import NARROW, default_space, load_space
from platesynth.optimise.study import (
    best_trial,
    delete_study,
    finished_trials,
    mark_interrupted,
    open_study,
    quiet_optuna,
    run_trials,
)
from platesynth.outputs import claim_output
from platesynth.render.result import check_size
from platesynth.scene import load_config

COUNT = 16
"""Images each trial renders (the same seeded scenes for every trial)."""
SIZE = (608, 472)
"""Render size of the trials and the evaluation (width, height): half the real photos' ~1216x944."""
EVAL_COUNT = 48
"""Images of the final evaluation of the start and the best configuration (fresh scenes no trial rendered)."""

Progress = Callable[[str, int, int, "float | None"], None]
"""``progress(stage, done, total, best)``: stages ``"reference"``, ``"trials"`` (with the best objective so far) and
``"evaluation"``."""


@dataclass(frozen=True)
class OptimiseResult:
    """The outcome of :func:`optimise`.

    Attributes
    ----------
    out : the output folder.
    report : what ``report.json`` holds: the split, the best trial, and the terms and objective of the start, the
        best and the compared configurations on the fit and the check photos.
    best_config : the best configuration's YAML file (``None`` when no trial completed).
    notes : things left out (plots with too few trials, the Inception FID without its weights).
    """

    out: Path
    report: dict[str, Any]
    best_config: Path | None
    notes: tuple[str, ...]


def _inception_weights() -> str | None:
    """The InceptionV3 weight file where it is found without a download; None otherwise."""
    from platesynth.weights import resolve_weights

    try:
        return str(resolve_weights("inception_fid", download=False))
    except WeightsNotFoundError:
        return None


def _evaluate(task: TrialTask, executor: Executor, configs: dict[str, Any], indices: tuple[int, ...],
              weights: dict[str, float]) -> dict[str, dict[str, dict[str, float]]]:
    """Render and measure each named configuration on ``indices`` against every reference of ``task``;
    ``{part: {name: {terms..., objective}}}`` (a configuration that fails is left out with its error)."""
    items = [TrialItem(name, config.model_dump(mode="json"), indices) for name, config in configs.items()]
    records = {record.number: record for record in executor.map_unordered(task, items)}
    table: dict[str, dict[str, dict[str, Any]]] = {reference.name: {} for reference in task.references}
    for name in configs:
        record = records[name]
        for reference in task.references:
            if record.error is not None:
                table[reference.name][name] = {"error": record.error}
            else:
                terms = record.terms[reference.name]
                table[reference.name][name] = {"objective": weighted_sum(terms, weights), **terms}
    return table


def optimise(
    reference: str | os.PathLike,
    out: str | os.PathLike,
    *,
    preset: str | None = None,
    config: str | os.PathLike | None = None,
    overrides: dict[str, Any] | None = None,
    space: str | os.PathLike | None = None,
    narrow: float = NARROW,
    trials: int = 100,
    timeout: float | None = None,
    seed: int = 0,
    count: int = COUNT,
    size: tuple[int, int] = SIZE,
    compare_size: tuple[int, int] | None = None,
    eval_count: int = EVAL_COUNT,
    well_size: int = CROP_SIZE,
    check_fraction: float = CHECK_FRACTION,
    weights: dict[str, float] | None = None,
    plaque_model: str | os.PathLike | None = None,
    multi_objective: bool = False,
    storage: str | None = None,
    executor: Executor | None = None,
    batch: int | None = None,
    compare: Sequence[str] = (),
    overwrite: bool = False,
    progress: Progress | None = None,
    before_writing: Callable[[], None] | None = None,
) -> OptimiseResult:
    """Search the scene parameters for renders closer to the ``reference`` photos; write the study and its report.

    Parameters
    ----------
    reference : str or path-like
        A folder of real plate photos; split by plate (seeded) into a fit part the objective sees and a check part
        only the report measures (:func:`~platesynth.optimise.reference.split_reference`).
    out : str or path-like
        Output folder (see :mod:`platesynth.optimise.report` for its files). A folder holding the same
        optimisation (same settings) is resumed: its finished trials are kept and it runs until the study holds
        ``trials`` finished trials.
    preset, config, overrides
        The start configuration, as for :func:`platesynth.scene.load_config`.
    space : str or path-like, optional
        A search space file (:func:`~platesynth.optimise.space.load_space`); default
        :func:`~platesynth.optimise.space.default_space`.
    narrow : float
        Half-width of the default ranges, a fraction of each parameter's valid range.
    trials : int
        Finished (completed or failed) trials the study should hold at the end.
    timeout : float, optional
        Seconds after which no trial is started (the evaluation and the outputs follow).
    seed : int
        Seeds the split, the sampler of every trial and the scenes rendered.
    count : int
        Images per trial (the same seeded scenes for every trial).
    size : (width, height)
        Render size.
    compare_size : (width, height), optional
        Size both renders and photos are resized to before measuring; default ``size``.
    eval_count : int
        Images of the final evaluation (fresh scenes), at least ``count``.
    well_size : int
        Side of the well crops (at least 32, for AlexNet).
    check_fraction : float
        Share of the photos kept for the check part.
    weights : dict, optional
        Weights of the terms in the single objective, over :data:`~platesynth.optimise.objective.DEFAULT_WEIGHTS`.
    plaque_model : str or path-like, optional
        A segmentation model's folder (e.g. ``models/plaque12``): adds the ``plaque_sizes`` and ``plaques_found``
        terms, the plaques it finds in the renders against those it finds in the photos. Each trial then also runs
        the model on its images.
    multi_objective : bool
        Optimise every term with a positive weight at once (a Pareto front); the best configuration is then the
        Pareto-optimal trial with the lowest weighted sum.
    storage : str, optional
        SQLAlchemy URL of the study's storage; default SQLite in ``out`` (``study.db``).
    executor : optional
        An executor of :mod:`platesynth.data.executor` (not yet entered: it is entered here, once everything is
        validated) that renders and measures the trials; default this process.
    batch : int, optional
        Trials evaluated at a time; default the executor's workers (1 in this process).
    compare : sequence of str
        Other presets (or configuration files) measured beside the start and the best in the report.
    overwrite : bool
        Replace another optimisation (or another kind of output) in ``out`` instead of refusing or resuming.
    progress : callable, optional
        ``progress(stage, done, total, best)``.
    before_writing : callable, optional
        Called once everything is validated, right before the output folder is written.

    Returns
    -------
    OptimiseResult

    Raises
    ------
    ParameterError
        For a bad option, start configuration, search space (one line naming the parameter) or weight.
    OutputError
        If ``out`` holds something else, or an optimisation with other settings (without ``overwrite``).
    EmptyDatasetError, ImageReadError
        For a missing or empty reference folder, or an unreadable photo.
    WeightsNotFoundError
        If the AlexNet weights cannot be found.
    DatasetError, UnfinishedModelError
        If ``plaque_model`` is not a finished model folder.
    """
    try:
        import optuna  # noqa: F401 -- refused early, with the install hint, where Optuna is missing
    except ImportError:
        raise PlatesynthError("platesynth optimise needs Optuna: pip install 'platesynth[optimise]'") from None

    started = time.perf_counter()
    out = Path(out)
    # --- everything validated before anything is written
    if trials < 1:
        raise ParameterError(f"trials must be >= 1, got {trials}")
    if timeout is not None and timeout <= 0:
        raise ParameterError(f"timeout must be > 0 seconds, got {timeout:g}")
    if count < 2:
        raise ParameterError(f"count must be >= 2 images per trial (the Fréchet distances need 2), got {count}")
    if eval_count < count:
        raise ParameterError(f"eval count must be at least the trials' count ({count}), got {eval_count}")
    if well_size < 32:
        raise ParameterError(f"well size must be at least 32 pixels (AlexNet's smallest input), got {well_size}")
    size = check_size(size)
    compare_size = check_size(compare_size) if compare_size is not None else size
    weights = check_weights(dict(weights or {}))
    start = load_config(preset=preset, path=config, overrides=overrides)
    search = load_space(space, start, narrow) if space is not None else default_space(start, narrow)
    if not search.parameters:
        raise ParameterError("the search space is empty: nothing to search")
    compared = {name: load_config(path=name) if name.endswith((".yaml", ".yml")) else load_config(name)
                for name in compare}
    split = split_reference(reference, seed, check_fraction)
    manifest = build_manifest(preset=preset, config_file=config, overrides=overrides, seed=seed,
                              count=count + eval_count, size=size)
    from platesynth.weights import resolve_weights

    resolve_weights("alexnet")
    inception = _inception_weights()
    if plaque_model is not None:
        plaque_model = files.resolve(plaque_model)
        segmentation_model(plaque_model)  # refused here, before anything is written; kept for the photos
    settings = MeasureSettings(compare_size=compare_size, crop_size=well_size, inception_weights=inception,
                               plaque_model=plaque_model)
    available = {"fid_inception": inception is not None, **{t: plaque_model is not None for t in PLAQUE_TERMS}}
    present = [t for t in TERMS if weights[t] > 0 and available.get(t, True)]
    objectives = present if multi_objective else None
    if multi_objective and len(present) < 2:
        raise ParameterError(f"a multi-objective study needs at least 2 terms with a positive weight, got {present}")
    executor = executor or SerialExecutor()
    batch = batch or getattr(executor, "workers", 1)
    if batch < 1:
        raise ParameterError(f"batch must be >= 1, got {batch}")
    check_render(size, workers=batch, count=count + eval_count)
    check_dataset_metrics((compare_size[1], compare_size[0]), max(eval_count, len(split.fit), len(split.check)))
    storage_url = storage or f"sqlite:///{(out / files.STUDY_FILE).expanduser().resolve()}"
    recorded = {
        "platesynth_version": __version__,
        "reference": files.resolve(reference),
        "split": split.to_dict(),
        "check_fraction": check_fraction,
        "seed": seed,
        "start": {"preset": preset, "config_file": files.resolve(config), "overrides": overrides or {},
                  "config": start.model_dump(mode="json")},
        "space": search.to_dict(),
        "count": count,
        "size": list(size),
        "compare_size": list(compare_size),
        "eval_count": eval_count,
        "well_size": well_size,
        "weights": weights,
        "objectives": objectives,
        "inception": inception is not None,
        "plaque_model": plaque_model,
        "storage": storage_url,
    }

    def same_settings() -> None:
        import json

        path = out / files.SETTINGS_FILE
        if overwrite or not path.is_file():
            return
        try:
            theirs = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise OutputError(f"{path}: cannot read the earlier run's settings ({exc})") from None
        differ = files.settings_differences(recorded, theirs)
        if differ:
            raise OutputError(
                f"{out}: holds an optimisation with other settings ({', '.join(differ)}); resume it with the same "
                "options, choose another --out, or pass --overwrite to start afresh"
            )

    claim = claim_output(out, "optimisation", inputs=[reference, config, space], overwrite=overwrite,
                         check=same_settings)
    if before_writing is not None:
        before_writing()
    notes: list[str] = []
    if inception is None and weights["fid_inception"] > 0:
        notes.append("fid_inception left out: the FID InceptionV3 weights were not found locally")
    with claim, quiet_optuna(), executor:
        claim.take()
        if overwrite:
            delete_study(storage_url)
        write_json(out / files.SETTINGS_FILE, recorded)
        write_json(out / files.SPLIT_FILE, split.to_dict())
        # --- the reference photos, measured once
        subset = min(count, len(split.fit), len(split.check))
        references = []
        for done, (part, paths) in enumerate((("fit", split.fit), ("check", split.check))):
            if progress:
                progress("reference", done, 2, None)
            names = [p.name for p in paths]
            references.append(measure_reference(part, names, read_photos(paths), settings, subset))
        if progress:
            progress("reference", 2, 2, None)
        fit, check = references
        # --- the study
        study = open_study(storage_url, ["minimize"] * (len(objectives) if objectives else 1))
        interrupted = mark_interrupted(study, storage_url)
        if interrupted:
            notes.append(f"{interrupted} trial(s) interrupted by an earlier run recorded as failed")
        if not study.get_trials(deepcopy=False):
            study.enqueue_trial(search.start_values(), user_attrs={"start": True})
        trial_indices = tuple(range(count))
        task = TrialTask(manifest, settings, (fit.without_images(),))
        run_trials(study, search, task, executor, target=trials, seed=seed, indices=trial_indices, weights=weights,
                   objectives=objectives, batch=batch, timeout=timeout,
                   progress=(lambda done, total, best: progress("trials", done, total, best)) if progress else None)
        best = best_trial(study)
        pareto = [t.number for t in study.best_trials] if objectives and best is not None else []
        files.write_trials(out, study, search, pareto)
        ended = finished_trials(study)
        n_failed = sum(1 for t in ended if t.state.name == "FAIL")
        if best is None:
            errors = [t.user_attrs.get("error", "") for t in ended if t.user_attrs.get("error")]
            raise PlatesynthError(f"{out}: every trial failed ({len(ended)}); the first: {errors[0] if errors else '?'}")
        # --- the honest evaluation: fresh scenes, both parts
        best_config = search.config(best.params, name="optimised")
        configs: dict[str, Any] = {"start": start, "best": best_config, **compared}
        if progress:
            progress("evaluation", 0, 1, None)
        evaluation = _evaluate(TrialTask(manifest, settings, (fit.without_images(), check.without_images())),
                               executor, configs, tuple(range(count, count + eval_count)), weights)
        if progress:
            progress("evaluation", 1, 1, None)
        label = preset or (Path(config).stem if config else "defaults")
        header = [
            f"platesynth optimise: the best of {len(ended)} trials (trial {best.number}) from {label}",
            f"objective on the fit photos {best.user_attrs['objective']:.4g} (trial scenes); "
            f"see report.md for the fit and check photos",
        ]
        best_path = files.write_best_config(out, best_config, header)
        result_report = {
            "start": label,
            "best_trial": best.number,
            "best_params": best.params,
            "n_trials": len(ended),
            "n_complete": len(ended) - n_failed,
            "n_failed": n_failed,
            "pareto_trials": pareto,
            "objectives": objectives,
            "weights": weights,
            "split": split.to_dict(),
            "evaluation": evaluation,
            "importances": files.importances(study),
            "eval_count": eval_count,
            "seconds": round(time.perf_counter() - started, 1),
        }
        files.write_report(out, result_report)
        sheet_task = TrialTask(manifest, settings, ())
        tiles = min(files.SHEET_TILES, eval_count)
        renders, _ = sheet_task.render(TrialItem("sheet", best_config.model_dump(mode="json"),
                                                 tuple(range(count, count + tiles))))
        photos = [resized(photo, compare_size) for photo in read_photos(split.check[:tiles])]
        files.write_contact_sheet(out, renders, photos)
        notes += files.write_plots(out, study, objectives, list(result_report["importances"]))
    return OptimiseResult(out, result_report, best_path, tuple(notes))
