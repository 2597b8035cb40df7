"""Metric-guided optimisation of the scene parameters (``platesynth optimise``).

:func:`optimise` searches the parameters of a start configuration with Optuna's TPE sampler for renders whose
realism metrics against real photos are lower, and reports the start and the best configuration on a fit part of
the photos (which the objective sees) and a check part (which it never sees). Optuna is an optional dependency
(``pip install 'platesynth[optimise]'``), imported only when a study runs.
"""

from platesynth.optimise.objective import DEFAULT_WEIGHTS, TERMS
from platesynth.optimise.reference import Split, split_reference
from platesynth.optimise.run import OptimiseResult, optimise
from platesynth.optimise.space import SearchParameter, SearchSpace, default_space, load_space

__all__ = [
    "DEFAULT_WEIGHTS",
    "TERMS",
    "OptimiseResult",
    "SearchParameter",
    "SearchSpace",
    "Split",
    "default_space",
    "load_space",
    "optimise",
    "split_reference",
]
