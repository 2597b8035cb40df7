"""What an optimisation writes into its output folder: the trials as CSV and JSON, the best configuration as YAML,
the report of the start and the best configuration on the fit and check photos, a contact sheet and Optuna's plots.
"""

from __future__ import annotations

import csv
import io
import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from platesynth.io import atomic_path, write_json, write_png, write_text
from platesynth.optimise.objective import TERMS
from platesynth.optimise.space import SearchSpace
from platesynth.scene.catalogue import SceneConfig
from platesynth.scene.loading import dump_config

SETTINGS_FILE = "optimise.json"
SPLIT_FILE = "split.json"
STUDY_FILE = "study.db"
TRIALS_CSV = "trials.csv"
TRIALS_JSON = "trials.json"
PARETO_CSV = "pareto.csv"
BEST_CONFIG = "best.yaml"
REPORT_JSON = "report.json"
REPORT_MD = "report.md"
CONTACT_SHEET = "contact_sheet.png"
HISTORY_PLOT = "history.png"
IMPORTANCE_PLOT = "importances.png"
IMPORTANCE_PARAMETERS = 20
"""The most important parameters shown in the importance plot (all are in ``report.json``)."""
PARETO_PLOT = "pareto.png"
OUTPUT_FILES = (
    SETTINGS_FILE, SPLIT_FILE, STUDY_FILE, f"{STUDY_FILE}-journal", f"{STUDY_FILE}-wal", f"{STUDY_FILE}-shm", TRIALS_CSV, TRIALS_JSON, PARETO_CSV, BEST_CONFIG,
    REPORT_JSON, REPORT_MD, CONTACT_SHEET, HISTORY_PLOT, IMPORTANCE_PLOT, PARETO_PLOT,
)
"""Every file an optimisation run may write into its folder."""

SHEET_TILES = 8
"""Renders of the best configuration on the contact sheet, and as many photos of the check part."""


def _finite(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def trial_rows(study: Any, space: SearchSpace) -> list[dict[str, Any]]:
    """One row per trial: number, state, objective, every term, seconds, error, then every parameter."""
    rows = []
    for trial in study.get_trials(deepcopy=False):
        terms = trial.user_attrs.get("terms", {})
        row: dict[str, Any] = {
            "number": trial.number,
            "state": trial.state.name.lower(),
            "objective": _finite(trial.user_attrs.get("objective")),
            **{name: _finite(terms.get(name)) for name in TERMS},
            "seconds": trial.user_attrs.get("seconds"),
            "error": trial.user_attrs.get("error"),
            "start": bool(trial.user_attrs.get("start", False)),
        }
        row.update({name: trial.params.get(name) for name in space.names})
        rows.append(row)
    return rows


def _csv_text(rows: Sequence[dict[str, Any]]) -> str:
    buffer = io.StringIO()
    if rows:
        writer = csv.DictWriter(buffer, fieldnames=list(rows[0]), lineterminator="\n")
        writer.writeheader()
        writer.writerows({k: "" if v is None else v for k, v in row.items()} for row in rows)
    return buffer.getvalue()


def write_trials(out: Path, study: Any, space: SearchSpace, pareto: Sequence[int] = ()) -> list[dict[str, Any]]:
    """Write ``trials.csv`` and ``trials.json`` (and ``pareto.csv``, the rows of the trials numbered in ``pareto``)."""
    rows = trial_rows(study, space)
    write_text(out / TRIALS_CSV, _csv_text(rows))
    write_json(out / TRIALS_JSON, rows)
    if pareto:
        write_text(out / PARETO_CSV, _csv_text([row for row in rows if row["number"] in set(pareto)]))
    return rows


def write_best_config(out: Path, config: SceneConfig, header: Sequence[str]) -> Path:
    """Write the best configuration as a complete YAML file that ``--config`` takes, ``header`` as comments."""
    text = "".join(f"# {line}\n" for line in header) + dump_config(config)
    write_text(out / BEST_CONFIG, text)
    return out / BEST_CONFIG


def report_markdown(report: dict[str, Any]) -> str:
    """The report's tables (one per part of the photos) as Markdown."""
    lines = []
    for part in ("fit", "check"):
        table = report["evaluation"][part]
        if not table:
            continue
        columns = ["objective", *[t for t in TERMS if any(t in row for row in table.values())]]
        lines += [f"### {part} photos ({len(report['split'][part])})", "",
                  "| configuration | " + " | ".join(columns) + " |", "|---" * (len(columns) + 1) + "|"]
        for name, row in table.items():
            cells = [f"{row[c]:.4g}" if isinstance(row.get(c), float) else "" for c in columns]
            lines.append(f"| {name} | " + " | ".join(cells) + " |")
        lines.append("")
    return "\n".join(lines)


def write_report(out: Path, report: dict[str, Any]) -> None:
    """Write ``report.json`` and ``report.md``."""
    write_json(out / REPORT_JSON, report)
    header = (f"# platesynth optimise: {report['start']} -> best trial {report['best_trial']} "
              f"of {report['n_trials']} ({report['n_complete']} complete, {report['n_failed']} failed)\n\n")
    write_text(out / REPORT_MD, header + report_markdown(report))


def write_contact_sheet(out: Path, renders: Sequence[np.ndarray], photos: Sequence[np.ndarray]) -> Path:
    """Renders of the best configuration (top rows) above real photos of the check part (bottom rows)."""
    from platesynth.data.preview import contact_sheet

    columns = 4
    tile = min(min(image.shape[1] for image in [*renders, *photos]), 320)
    sheet = contact_sheet([*renders, *photos], columns=columns, tile_width=tile)
    write_png(out / CONTACT_SHEET, sheet)
    return out / CONTACT_SHEET


def _save(axes: Any, path: Path) -> None:
    import matplotlib.pyplot as plt

    figure = axes.figure if hasattr(axes, "figure") else np.ravel(axes)[0].figure
    figure.set_size_inches(9, 6)
    figure.tight_layout()
    with atomic_path(path) as tmp:
        figure.savefig(tmp, dpi=100, format="png")
    plt.close(figure)


def importances(study: Any) -> dict[str, float]:
    """Each parameter's importance for the single objective (the weighted sum), most important first (Optuna's
    PED-ANOVA evaluator, which needs no scikit-learn); empty with fewer than 2 completed trials."""
    import warnings

    from optuna.importance import PedAnovaImportanceEvaluator, get_param_importances
    from optuna.trial import TrialState

    if len(study.get_trials(deepcopy=False, states=(TrialState.COMPLETE,))) < 2:
        return {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # "computes the importances ... to achieve low values": wanted
        return dict(get_param_importances(study, evaluator=PedAnovaImportanceEvaluator(), target=_objective))


def _objective(trial: Any) -> float:
    return trial.user_attrs.get("objective", float("nan"))


def write_plots(out: Path, study: Any, objectives: Sequence[str] | None, ranked: Sequence[str] = ()) -> list[str]:
    """Optuna's matplotlib plots as PNG: the history and the parameter importances (the ``ranked`` first
    :data:`IMPORTANCE_PARAMETERS`) of the single objective (the weighted sum), and for a multi-objective study the
    Pareto front of the first two or three terms.

    Returns
    -------
    list of str
        A note for each plot left out (too few trials, or an error of the plot).
    """
    import warnings

    import matplotlib

    matplotlib.use("Agg", force=False)
    from optuna.importance import PedAnovaImportanceEvaluator
    from optuna.trial import TrialState
    from optuna.visualization import matplotlib as plots

    kwargs = {"target": _objective, "target_name": "objective (weighted sum)"}
    complete = study.get_trials(deepcopy=False, states=(TrialState.COMPLETE,))
    notes = []
    shown = list(ranked[:IMPORTANCE_PARAMETERS]) or None
    jobs = [(HISTORY_PLOT, lambda: plots.plot_optimization_history(study, **kwargs), 1),
            (IMPORTANCE_PLOT, lambda: plots.plot_param_importances(
                study, evaluator=PedAnovaImportanceEvaluator(), params=shown, **kwargs), 2)]
    if objectives is not None:
        names = list(objectives[:3]) if len(objectives) <= 3 else list(objectives[:2])

        def pareto() -> Any:
            return plots.plot_pareto_front(study, targets=lambda t: tuple(t.values[: len(names)]), target_names=names)

        jobs.append((PARETO_PLOT, pareto, 1))
    for name, plot, needed in jobs:
        if len(complete) < needed:
            notes.append(f"{name} left out: {len(complete)} complete trial(s), it needs {needed}")
            continue
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", UserWarning)
                _save(plot(), out / name)
        except (ValueError, RuntimeError, ZeroDivisionError, KeyError) as exc:
            notes.append(f"{name} left out: {type(exc).__name__}: {exc}")
    return notes


def settings_differences(mine: dict[str, Any], theirs: dict[str, Any]) -> list[str]:
    """The keys of two runs' settings that differ (what decides the trials' results)."""
    return [key for key in mine if mine[key] != theirs.get(key)]


def resolve(path: str | os.PathLike | None) -> str | None:
    """An absolute path as text (None stays None)."""
    return None if path is None else str(Path(path).expanduser().resolve())
