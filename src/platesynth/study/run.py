"""``run_study``: the arms' stages as a graph on an executor, cached by key, then the tables and charts.

Every replicate (an arm and one of its seeds) is four stages: render -> measure, render -> train -> evaluate (a mix
arm trains on the renders of the arms it mixes, and is not measured itself). The rendered test set is one more
render, shared by every evaluation. :func:`plan_study` turns a validated study into these stages and their keys
(:mod:`platesynth.study.cache`); :func:`run_study` runs those not yet done in three waves (renders; measurements and
trainings; evaluations), each wave's stages in parallel on the executor, and writes the outputs
(:mod:`platesynth.study.tables`, :mod:`platesynth.study.radar`).
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from platesynth import __version__
from platesynth.data.batch import build_manifest
from platesynth.data.executor import Executor, SerialExecutor
from platesynth.errors import PlatesynthError
from platesynth.io import write_json
from platesynth.outputs import claim_output
from platesynth.report.html import REPORT_NAME
from platesynth.study import cache
from platesynth.study.radar import AXES, write_radars
from platesynth.study.spec import REAL, StudySpec
from platesynth.study.stages import DATA_DIR, MODEL_DIR, StageRecord, StageTask, run_task
from platesynth.study.tables import TABLES_DIR, build_tables, write_tables

SETTINGS_FILE = "study.json"
RESULTS_FILE = "results.json"
TEST_SET = "test"
WAVES = (("render",), ("measure", "train"), ("evaluate",))
OUTPUT_FILES = (SETTINGS_FILE, RESULTS_FILE, REPORT_NAME, *(f"radar_{chart}.{suffix}" for chart in AXES
                                                            for suffix in ("svg", "png", "json")))
"""The files a study writes at the top of its folder, with the page ``platesynth report`` writes there."""
OUTPUT_FOLDERS = (cache.STAGES_DIR, TABLES_DIR)
"""The folders a study writes (every file in them is the study's)."""

Progress = Callable[[str, int, int], None]
"""``progress(stage, done, total)``: called before a wave (``done=0``) and after each of its stages."""


@dataclass(frozen=True)
class Stage:
    """A stage of the plan: what it runs, under which key, and the keys it needs done first."""

    kind: str
    key: str
    depends: dict[str, Any]
    options: dict[str, Any]
    needs: tuple[str, ...] = ()


@dataclass(frozen=True)
class Replicate:
    """An arm's run with one seed: the keys of its stages (``measure`` None for a mix arm)."""

    arm: str
    seed: int
    render: str | None
    measure: str | None
    train: str
    evaluate: str


@dataclass
class StudyPlan:
    """Every stage of a study by key, the replicates of each arm and the test set's render key."""

    spec: StudySpec
    stages: dict[str, Stage] = field(default_factory=dict)
    replicates: dict[str, list[Replicate]] = field(default_factory=dict)
    test_render: str | None = None

    def add(self, stage: Stage) -> str:
        """Add a stage (once per key) and return its key."""
        self.stages.setdefault(stage.key, stage)
        return stage.key


@dataclass
class StudyResult:
    """The outcome of :func:`run_study`: the stages run, found done and failed, and the files written."""

    out: Path
    ran: list[str] = field(default_factory=list)
    cached: list[str] = field(default_factory=list)
    failed: dict[str, str] = field(default_factory=dict)
    tables: dict[str, Any] = field(default_factory=dict)
    files: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    seconds: float = 0.0
    seconds_by_stage: dict[str, float | None] = field(default_factory=dict)


def _manifest(spec: StudySpec, preset: str | None, config: str | None, overrides: dict[str, Any], seed: int,
              count: int) -> Any:
    return build_manifest(preset=preset, config_file=config, overrides={"plate.format": spec.plate, **overrides},
                          seed=seed, count=count, size=spec.size, backend=spec.backend)


def _render(plan: StudyPlan, manifest: Any) -> str:
    depends = {"dataset": manifest.identity(), "count": manifest.count}
    key = cache.stage_key("render", depends)
    return plan.add(Stage("render", key, depends, {"manifest": manifest.model_dump(mode="json")}))


def _dataset(out: Path, render_key: str) -> str:
    return str((cache.stage_dir(out, "render", render_key) / DATA_DIR).resolve())


def _train_options(spec: StudySpec, data: list[str], mix: list[float] | None, seed: int) -> dict[str, Any]:
    from pydantic import ValidationError

    from platesynth.errors import ParameterError
    from platesynth.segment.model import ModelConfig
    from platesynth.segment.train import TrainConfig
    from platesynth.study.spec import validation_line

    recipe = spec.recipe
    train = TrainConfig(data=data, mix=mix, epochs=recipe.epochs, steps_per_epoch=recipe.steps,
                        batch_size=recipe.batch_size, patch=recipe.patch, learning_rate=recipe.learning_rate,
                        val_fraction=recipe.val_fraction, max_val_images=recipe.max_val, seed=recipe.seed + seed,
                        augment=recipe.augment, tune_thresholds=recipe.tune_thresholds)
    try:
        model = ModelConfig.model_validate({"plate_format": spec.plate, **recipe.model})
    except ValidationError as exc:
        raise ParameterError(validation_line(exc, "recipe.model")) from None
    multiple = model.size_multiple
    if train.patch[0] % multiple or train.patch[1] % multiple:
        raise ValueError(f"patch {train.patch[1]}x{train.patch[0]} must be a positive multiple of {multiple} on "
                         "both sides (the network's stride)")
    return {"train": train.model_dump(mode="json"), "model": model.model_dump(mode="json"), "threads": recipe.threads,
            "device": recipe.device}


def plan_study(spec: StudySpec, out: str | os.PathLike) -> StudyPlan:
    """Every stage of ``spec`` with its key, validating every arm's dataset request and the recipe.

    Raises
    ------
    ParameterError
        For an arm whose preset, configuration or overrides are invalid (named), or a bad recipe.
    """
    from platesynth.errors import ParameterError

    out = Path(out).resolve()
    plan = StudyPlan(spec)
    evaluation = spec.evaluation
    inputs = {"reference": cache.fingerprint(spec.reference)}
    counts = None
    if evaluation.counts is not None:
        counts = {"images": evaluation.images, "counts": evaluation.counts}
        inputs["counts"] = cache.fingerprint(evaluation.counts)
        inputs["count_images"] = cache.fingerprint(evaluation.images)
    inputs["masks"] = cache.fingerprint(evaluation.masks)
    real = cache.fingerprint(spec.real_training)
    if evaluation.test is not None:
        test = evaluation.test
        try:
            plan.test_render = _render(plan, _manifest(spec, test.preset, test.config, test.overrides, test.seed,
                                                       test.count))
        except PlatesynthError as exc:
            raise ParameterError(f"{spec.source}: evaluation.test: {exc}") from None
    measure_settings = spec.metrics.model_dump(mode="json")
    renders: dict[str, list[str]] = {}
    for number, arm in enumerate(spec.arms):
        if arm.mix is None:
            try:
                renders[arm.name] = [_render(plan, _manifest(spec, arm.preset, arm.config, arm.overrides, seed,
                                                             arm.count or 1)) for seed in arm.seeds]
            except PlatesynthError as exc:
                raise ParameterError(f"{spec.source}: arms[{number}] ({arm.name}): {exc}") from None
    from platesynth.segment.counts import plate_shape

    grid = plate_shape(spec.plate)
    for arm in spec.arms:
        plan.replicates[arm.name] = []
        for number, seed in enumerate(arm.seeds):
            render_key = measure_key = None
            if arm.mix is None:
                render_key = renders[arm.name][number]
                sources, data_keys, mix = [_dataset(out, render_key)], [render_key], None
                depends = {"render": render_key, "reference": inputs["reference"], "settings": measure_settings,
                           "grid": grid}
                measure_key = plan.add(Stage(
                    "measure", cache.stage_key("measure", depends), depends,
                    {"dataset": sources[0], "reference": spec.reference, "grid": grid,
                     "reference_fingerprint": inputs["reference"], **spec.metrics.model_dump(mode="json")},
                    needs=(render_key,)))
            else:
                sources, data_keys, mix = [], [], []
                for name, fraction in arm.mix.items():
                    if name == REAL:
                        sources.append(str(spec.real_training))
                        data_keys.append(f"real:{real}")
                    else:
                        keys = renders[name]
                        data_keys.append(keys[min(number, len(keys) - 1)])
                        sources.append(_dataset(out, data_keys[-1]))
                    mix.append(fraction)
            try:
                options = _train_options(spec, sources, mix, seed)
            except ParameterError as exc:
                raise ParameterError(f"{spec.source}: {exc}") from None
            except (ValueError, PlatesynthError) as exc:
                raise ParameterError(f"{spec.source}: recipe: {' '.join(str(exc).split())}") from None
            depends = {"data": data_keys, "mix": mix, "train": {k: v for k, v in options["train"].items() if k != "data"},
                       "model": options["model"], "device": options["device"]}
            train_key = plan.add(Stage("train", cache.stage_key("train", depends), depends, options,
                                       needs=tuple(k for k in data_keys if not k.startswith("real:"))))
            evaluate_options = {
                "model": str(cache.stage_dir(out, "train", train_key) / MODEL_DIR),
                "counts": counts,
                "test": _dataset(out, plan.test_render) if plan.test_render else None,
                "masks": evaluation.masks,
                "taus": list(evaluation.taus),
                "plate": spec.plate,
                "threads": spec.recipe.threads,
            }
            depends = {"train": train_key, "test": plan.test_render, "taus": list(evaluation.taus), "plate": spec.plate,
                       **{k: v for k, v in inputs.items() if k != "reference"}}
            needs = (train_key, plan.test_render) if plan.test_render else (train_key,)
            evaluate_key = plan.add(Stage("evaluate", cache.stage_key("evaluate", depends), depends, evaluate_options,
                                          needs=needs))
            plan.replicates[arm.name].append(Replicate(arm.name, seed, render_key, measure_key, train_key, evaluate_key))
    return plan


def _wave(plan: StudyPlan, out: Path, kinds: tuple[str, ...], executor: Executor, result: StudyResult,
          done: dict[str, dict[str, Any]], progress: Progress | None) -> None:
    """Run the stages of ``kinds`` that are not done and whose inputs are; record what happened."""
    todo = []
    for stage in plan.stages.values():
        if stage.kind not in kinds:
            continue
        stored = cache.load_stored(out, stage.kind, stage.key)
        if stored is not None:
            done[stage.key] = stored["result"]
            result.seconds_by_stage[stage.key] = stored.get("seconds")
            result.cached.append(f"{stage.kind}:{stage.key}")
        elif all(need in done for need in stage.needs):
            todo.append(StageTask(stage.kind, stage.key, str(cache.stage_dir(out, stage.kind, stage.key)),
                                  stage.options))
    label = "+".join(kinds)
    if progress is not None:
        progress(label, 0, len(todo))
    for finished, record in enumerate(executor.map_unordered(run_task, todo), start=1):
        _record(plan, out, record, result, done)
        if progress is not None:
            progress(label, finished, len(todo))


def _record(plan: StudyPlan, out: Path, record: StageRecord, result: StudyResult, done: dict[str, dict[str, Any]]) -> None:
    name = f"{record.kind}:{record.key}"
    if record.error is not None or record.result is None:
        result.failed[name] = record.error or "no result"
        return
    stage = plan.stages[record.key]
    cache.save_result(out, record.kind, record.key, stage.depends, record.result, record.seconds)
    done[record.key] = cache.finite(record.result)
    result.seconds_by_stage[record.key] = round(record.seconds, 2)
    result.ran.append(name)


def _describe(plan: StudyPlan, done: dict[str, dict[str, Any]], seconds: dict[str, float | None]) -> dict[str, Any]:
    """What ``results.json`` holds: the study's settings and every replicate's stage keys and results."""
    arms = []
    for arm in plan.spec.arms:
        replicates = []
        for rep in plan.replicates[arm.name]:
            replicates.append({
                "seed": rep.seed,
                "keys": {"render": rep.render, "measure": rep.measure, "train": rep.train, "evaluate": rep.evaluate},
                "seconds": {kind: seconds.get(key) for kind, key in (("render", rep.render), ("measure", rep.measure),
                            ("train", rep.train), ("evaluate", rep.evaluate)) if key is not None},
                "render": done.get(rep.render) if rep.render else None,
                "measure": done.get(rep.measure) if rep.measure else None,
                "train": _without_history(done.get(rep.train)),
                "evaluate": done.get(rep.evaluate),
            })
        arms.append({"name": arm.name, "label": arm.title, "kind": "mix" if arm.mix else "rendered",
                     "preset": arm.preset, "config": arm.config, "overrides": arm.overrides, "count": arm.count,
                     "mix": arm.mix, "replicates": replicates})
    return {"platesynth_version": __version__, "name": plan.spec.name, "test_render": plan.test_render, "arms": arms}


def _without_history(result: dict[str, Any] | None) -> dict[str, Any] | None:
    return None if result is None else {k: v for k, v in result.items() if k != "history"}


def require(module: str, extra: str, what: str) -> None:
    """Refuse in one line, with the install hint, where an optional package is missing."""
    import importlib.util

    if importlib.util.find_spec(module) is None:
        raise PlatesynthError(f"{what} needs {module}: pip install 'platesynth[{extra}]'")


def check_study(spec: StudySpec) -> None:
    """Checks that need the library (packages, weights, memory) before anything is written.

    Raises
    ------
    PlatesynthError
        If matplotlib (the charts) or stardist (the training targets) is not installed.
    WeightsNotFoundError
        If the AlexNet weights are needed (``metrics.frechet``) and cannot be found.
    ResourceLimitError
        If rendering at the study's size would pass the memory limit.
    """
    from platesynth.limits import check_render

    require("matplotlib", "study", "platesynth study")
    require("stardist", "segment", "platesynth study")
    from platesynth.segment.model import select_device

    select_device(spec.recipe.device)  # e.g. cuda asked for where there is none
    if spec.metrics.frechet:
        from platesynth.weights import resolve_weights

        resolve_weights("alexnet")
    check_render(spec.size, workers=1, count=max((arm.count or 1) for arm in spec.arms))


def run_study(
    spec: StudySpec,
    out: str | os.PathLike,
    *,
    executor: Executor | None = None,
    inputs: tuple[str | os.PathLike | None, ...] = (),
    overwrite: bool = False,
    progress: Progress | None = None,
    before_writing: Callable[[], None] | None = None,
) -> StudyResult:
    """Run every stage of a study not yet done, then write its tables, charts and ``results.json``.

    Parameters
    ----------
    spec : a validated study (:func:`~platesynth.study.spec.load_study`).
    out : the study's folder. A folder holding a study (this one or an earlier version of it) is reused: stages
        whose keys are done there are not run again.
    executor : an executor of :mod:`platesynth.data.executor`, not yet entered (it is entered here, after the
        checks); the stages of a wave run on it in parallel. Default: this process.
    inputs : files the command reads (the study file): an output over them is refused.
    overwrite : replace another kind of output in ``out`` (its files only) instead of refusing.
    progress : ``progress(stage, done, total)``.
    before_writing : called once everything is validated, right before the first write.

    Returns
    -------
    StudyResult
        The stages run, found done and failed; ``tables`` (what the tables hold); the files written.

    Raises
    ------
    ParameterError, WeightsNotFoundError, ResourceLimitError
        Before anything is written.
    OutputError
        If ``out`` holds another kind of output, or another process writes into it.
    """
    started = time.perf_counter()
    out = Path(out)
    plan = plan_study(spec, out)
    check_study(spec)
    claim = claim_output(out, "study", inputs=[*inputs, spec.reference, spec.evaluation.images,
                                               spec.evaluation.counts, spec.evaluation.masks, spec.real_training],
                         overwrite=overwrite)
    if before_writing is not None:
        before_writing()
    result = StudyResult(out)
    done: dict[str, dict[str, Any]] = {}
    executor = executor or SerialExecutor()
    with claim, executor:
        claim.take()
        write_json(out / SETTINGS_FILE, {"platesynth_version": __version__, "spec": spec.model_dump(mode="json")})
        for kinds in WAVES:
            _wave(plan, out, kinds, executor, result, done, progress)
        skipped = [f"{s.kind}:{s.key}" for s in plan.stages.values() if s.key not in done
                   and f"{s.kind}:{s.key}" not in result.failed]
        if skipped:
            result.notes.append(f"{len(skipped)} stage(s) not run because a stage they need failed")
        described = _describe(plan, done, result.seconds_by_stage)
        write_json(out / RESULTS_FILE, described)
        result.tables = build_tables(described)
        result.files = [RESULTS_FILE, *write_tables(out, result.tables)]
        written, notes = write_radars(out, result.tables)
        result.files += written
        result.notes += notes
    result.seconds = time.perf_counter() - started
    return result
