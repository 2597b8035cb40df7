"""The Optuna study: storage, resuming, the seeded TPE sampler, and trials run in batches on an executor.

The study lives in a storage (SQLite in the output folder by default), so a run that stops resumes where it
stopped and a finished one is extended by asking for more trials. Only this process talks to the storage: trials
are asked for (:meth:`optuna.Study.ask`) in batches of as many as run at a time, rendered and measured by the
executor's workers (:class:`~platesynth.optimise.objective.TrialTask`), and told (:meth:`optuna.Study.tell`) as they
finish.

Determinism: trial ``n`` is sampled by a TPE sampler seeded with ``(seed, n)``, so its parameters depend only on
the seed, its number and the trials before it, whether the run was interrupted or not; its images are the same
seeded scenes for every trial. With more than one trial at a time, a batch's trials are sampled before any of
them is told (TPE's "constant liar" counts them as running), so results depend on the batch size too.
"""

from __future__ import annotations

import contextlib
import time
import warnings
from collections.abc import Callable, Iterator, Sequence
from typing import Any

import numpy as np

from platesynth.errors import ParameterError, PlatesynthError
from platesynth.optimise.objective import TrialItem, TrialRecord, TrialTask, weighted_sum
from platesynth.optimise.space import SearchSpace

STUDY_NAME = "platesynth-optimise"
"""The study's name in its storage."""

STARTUP_TRIALS = 10
"""Trials TPE samples at random before it models the results (the start configuration counts as one)."""

INTERRUPTED = "interrupted: the run stopped during this trial"
"""The error recorded for a trial that was running when its run stopped."""

Progress = Callable[[int, int, "float | None"], None]
"""``progress(finished, target, best)``: after every finished trial (and once before the first)."""


@contextlib.contextmanager
def quiet_optuna() -> Iterator[None]:
    """Optuna's log lines and its experimental and future warnings silenced while the block runs."""
    import optuna

    verbosity = optuna.logging.get_verbosity()
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
            warnings.simplefilter("ignore", FutureWarning)
            yield
    finally:
        optuna.logging.set_verbosity(verbosity)


def distributions(space: SearchSpace) -> dict[str, Any]:
    """Optuna's distribution of every searched parameter."""
    from optuna.distributions import FloatDistribution, IntDistribution

    return {
        p.name: IntDistribution(int(p.low), int(p.high), log=p.log) if p.integer else FloatDistribution(p.low, p.high, log=p.log)
        for p in space.parameters
    }


def trial_seed(seed: int, number: int) -> int:
    """The seed of the sampler that samples trial ``number`` (32 bits, from numpy's ``SeedSequence``)."""
    return int(np.random.SeedSequence([seed, number]).generate_state(1, np.uint32)[0])


def make_sampler(seed: int, number: int) -> Any:
    """The TPE sampler of trial ``number``."""
    import optuna

    return optuna.samplers.TPESampler(seed=trial_seed(seed, number), n_startup_trials=STARTUP_TRIALS)


def _quick_sqlite(rdb: Any) -> None:
    """Let an SQLite storage commit without waiting for the disk each time (write-ahead log, ``synchronous=NORMAL``).

    Optuna commits every parameter of a trial on its own; with SQLite's defaults each commit waits for the disk
    (7 ms here, half a second per trial of 70 parameters, while the workers wait). With a write-ahead log a process
    that is killed loses nothing and the file stays consistent; a power cut may lose the last trials, which a
    resumed run then repeats.
    """
    from sqlalchemy import event

    if rdb.engine.dialect.name != "sqlite":
        return

    def pragmas(connection: Any, _record: Any) -> None:
        cursor = connection.cursor()
        cursor.execute("PRAGMA journal_mode=WAL")
        cursor.execute("PRAGMA synchronous=NORMAL")
        cursor.close()

    event.listen(rdb.engine, "connect", pragmas)
    rdb.engine.dispose()  # connections opened before the listener get the pragmas when opened again


def open_study(storage: str, directions: Sequence[str]) -> Any:
    """Create the study in ``storage`` (an SQLAlchemy URL) or load the one there.

    Raises
    ------
    ParameterError
        If the storage holds the study with other directions (a single-objective study opened as multi-objective).
    """
    import optuna

    rdb = optuna.storages.RDBStorage(storage)
    _quick_sqlite(rdb)
    study = optuna.create_study(storage=rdb, study_name=STUDY_NAME, directions=list(directions), load_if_exists=True)
    if [d.name.lower() for d in study.directions] != [d.lower() for d in directions]:
        raise ParameterError(
            f"{storage}: its study has {len(study.directions)} objective(s), this run {len(directions)}; "
            "use another storage or --overwrite"
        )
    return study


def delete_study(storage: str) -> None:
    """Remove the study from ``storage`` if it is there."""
    import optuna

    with contextlib.suppress(KeyError):
        optuna.delete_study(study_name=STUDY_NAME, storage=storage)


def mark_interrupted(study: Any, storage: str) -> int:
    """Record the trials left running by a run that stopped as failed (:data:`INTERRUPTED`); their number."""
    import optuna
    from optuna.trial import TrialState

    stale = study.get_trials(deepcopy=False, states=(TrialState.RUNNING,))
    if stale:
        rdb = optuna.storages.RDBStorage(storage)
        study_id = rdb.get_study_id_from_name(STUDY_NAME)
        for trial in stale:
            rdb.set_trial_user_attr(rdb.get_trial_id_from_study_id_trial_number(study_id, trial.number), "error",
                                    INTERRUPTED)
            study.tell(trial.number, state=TrialState.FAIL)
    return len(stale)


def finished_trials(study: Any) -> list[Any]:
    """The trials that ended, completed or failed, in number order."""
    from optuna.trial import TrialState

    return study.get_trials(deepcopy=False, states=(TrialState.COMPLETE, TrialState.FAIL))


def best_value(study: Any) -> float | None:
    """The lowest single objective (``objective`` user attribute) of the completed trials; None before any."""
    from optuna.trial import TrialState

    values = [t.user_attrs["objective"] for t in study.get_trials(deepcopy=False, states=(TrialState.COMPLETE,))
              if "objective" in t.user_attrs]
    return min(values) if values else None


def best_trial(study: Any) -> Any | None:
    """The best completed trial: the lowest objective; for a multi-objective study the Pareto-optimal trial with
    the lowest weighted sum. None before any trial completed."""
    from optuna.trial import TrialState

    if not study.get_trials(deepcopy=False, states=(TrialState.COMPLETE,)):
        return None
    candidates = study.best_trials if len(study.directions) > 1 else [study.best_trial]
    return min(candidates, key=lambda t: (t.user_attrs.get("objective", float("inf")), t.number))


def _tell(study: Any, trial: Any, record: TrialRecord, weights: dict[str, float], objectives: Sequence[str] | None,
          reference: str) -> None:
    from optuna.trial import TrialState

    trial.set_user_attr("seconds", round(record.seconds, 3))
    if record.error is not None:
        trial.set_user_attr("error", record.error.splitlines()[0][:500])
        study.tell(trial, state=TrialState.FAIL)
        return
    terms = record.terms[reference]
    trial.set_user_attr("terms", terms)
    objective = weighted_sum(terms, weights)
    trial.set_user_attr("objective", objective)
    values = objective if objectives is None else [terms[name] for name in objectives]
    study.tell(trial, values)


def run_trials(
    study: Any,
    space: SearchSpace,
    task: TrialTask,
    executor: Any,
    *,
    target: int,
    seed: int,
    indices: tuple[int, ...],
    weights: dict[str, float],
    objectives: Sequence[str] | None = None,
    batch: int = 1,
    timeout: float | None = None,
    progress: Progress | None = None,
) -> int:
    """Ask, evaluate and tell trials until the study holds ``target`` finished ones (or ``timeout`` seconds pass).

    Parameters
    ----------
    study : optuna.Study
    space : SearchSpace
        Each trial's parameters become a configuration with :meth:`SearchSpace.config`.
    task : TrialTask
        Renders and measures a trial against its reference (the first of ``task.references``).
    executor : an entered executor of :mod:`platesynth.data.executor`.
    target : int
        Finished (completed or failed) trials the study should hold.
    seed : int
        Seeds trial ``n``'s sampler with ``(seed, n)`` (:func:`make_sampler`).
    indices : tuple of int
        The dataset items (seeded scenes) every trial renders.
    weights : dict
        Of the single objective (:func:`~platesynth.optimise.objective.weighted_sum`), also recorded for
        multi-objective trials.
    objectives : sequence of str, optional
        The terms of a multi-objective study, in the order of its directions; None for a single objective.
    batch : int
        Trials evaluated at a time.
    timeout : float, optional
        No trial is started after this many seconds.
    progress : callable, optional
        ``progress(finished, target, best)``.

    Returns
    -------
    int
        Trials finished by this call.
    """
    started = time.monotonic()
    reference = task.references[0].name
    fixed = distributions(space)
    done = 0
    if progress is not None:
        progress(len(finished_trials(study)), target, best_value(study))
    while True:
        finished = len(finished_trials(study))
        if finished >= target or (timeout is not None and time.monotonic() - started >= timeout):
            return done
        trials, items = [], []
        for _ in range(min(batch, target - finished)):
            from optuna.trial import TrialState

            number = len(study.get_trials(deepcopy=False, states=tuple(s for s in TrialState if s != TrialState.WAITING)))
            study.sampler = make_sampler(seed, number)
            trial = study.ask(fixed_distributions=fixed)
            try:
                config = space.config(trial.params, name=f"trial {trial.number}").model_dump(mode="json")
            except PlatesynthError as exc:  # recorded as failed, like a failed render
                _tell(study, trial, TrialRecord(trial.number, error=str(exc)), weights, objectives, reference)
                done += 1
                continue
            trials.append(trial)
            items.append(TrialItem(trial.number, config, indices))
        by_number = {trial.number: trial for trial in trials}
        for record in executor.map_unordered(task, items):
            _tell(study, by_number[record.number], record, weights, objectives, reference)
            done += 1
            if progress is not None:
                progress(len(finished_trials(study)), target, best_value(study))
