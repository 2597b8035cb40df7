"""The paper's study, on any assay: arms of datasets rendered, measured, trained on and evaluated, with tables.

Modules, one concern each: :mod:`~platesynth.study.spec` (the study file, validated before anything is written),
:mod:`~platesynth.study.cache` (stage keys and stored results), :mod:`~platesynth.study.stages` (render, measure,
train, evaluate), :mod:`~platesynth.study.run` (the stages of every arm on an executor, :func:`run_study`),
:mod:`~platesynth.study.tables` (Markdown, CSV, JSON) and :mod:`~platesynth.study.radar` (radar charts).
See docs/study.md.
"""

from platesynth.study.run import StudyPlan, StudyResult, plan_study, run_study
from platesynth.study.spec import StudySpec, load_study, parse_study

__all__ = ["StudyPlan", "StudyResult", "StudySpec", "load_study", "parse_study", "plan_study", "run_study"]
