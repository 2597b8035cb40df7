"""The search space: which scene parameters an optimisation searches, over which ranges, and how a trial's values
become a scene configuration.

A searched parameter is a numeric or probability parameter of the catalogue (:mod:`platesynth.scene.catalogue`).
What is searched is its **centre**: a trial value ``v`` replaces the start configuration's value so that its spread
stays (a range ``[a, b]`` becomes ``[v - (b - a)/2, v + (b - a)/2]``, a log-uniform ``[a, b]`` keeps its ratio
around ``v``, a normal keeps its sd, integers keep their width, a number or a probability becomes ``v``; a choice or
a mixture becomes the number ``v``), shifted back inside the parameter's valid range where it would leave it.

The default space (:func:`default_space`) holds every numeric and probability parameter of the sections that shape
the look (:data:`SEARCHED_SECTIONS`) except those fixed by the photographs' set-up or matched to counts
(:data:`LEFT_OUT`), vectors and fixed choices, each within ``narrow`` of its valid range on either side of the
start's centre (a probability's valid range is [0, 1]; on a log scale where the valid range spans at least
:data:`LOG_DECADES` decades above zero). A space file (:func:`load_space`) names the parameters instead::

    stain.hue_deg: [250, 290]                       # the centre's range
    plaques.radius_mm: {range: [0.3, 1.5], log: true}
    post.noise: auto                                # the default range around the start
    plaques.radius_mm: fixed                        # not searched: the start's value stays

``all: auto`` starts from the whole default space; the other entries then add parameters, replace their ranges or
(``fixed``) take them out.
Every name and bound is checked against the catalogue with the messages of ``--set`` before the first trial.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from platesynth.errors import ParameterError
from platesynth.limits import read_yaml_file
from platesynth.scene.catalogue import SceneConfig, sections
from platesynth.scene.distributions import Dist
from platesynth.scene.loading import check_parameter_name, validate_config

SEARCHED_SECTIONS = ("stain", "wells", "plaques", "lighting", "camera", "post")
"""The sections of the catalogue whose parameters the default space searches (those that shape the look)."""

LEFT_OUT = (
    "camera.from_below",  # the photographs' set-up: every real plate is photographed from below
    "plaques.negative_plate",  # plaque counts: matched to the person's counts (benchmarks/count_distribution.py)
    "plaques.top_count",
    "plaques.dilution_factor",
    "plaques.reverse_series",
    "plaques.lysis_count",
    "plaques.count_jitter",
)
"""Parameters of :data:`SEARCHED_SECTIONS` the default space leaves out (a space file may name them)."""

NARROW = 0.25
"""Default half-width of a number's searched range, as a fraction of its valid range (or of its decades)."""

LOG_DECADES = 2.0
"""A number whose valid range ``[low, high]`` has ``low > 0`` and ``high / low >= 10**LOG_DECADES`` is searched on a
log scale."""

AUTO = "auto"
"""The value of a space file's entry that asks for the default range."""

FIXED = "fixed"
"""The value of a space file's entry that keeps a parameter at the start's value (out of an ``all: auto`` space)."""

ENTRY_FORMS = f"[low, high], {{range: [low, high], log: true}}, {AUTO} or {FIXED}"
"""What a space file's entry may be (for error messages)."""

ALL = "all"
"""A space file's key that starts from the whole default space (``all: auto``); its other entries then add
parameters or replace their ranges."""


@dataclass(frozen=True)
class SearchParameter:
    """One searched parameter.

    Attributes
    ----------
    name : dotted name, e.g. ``"stain.hue_deg"``.
    low, high : the range of the searched centre (``low < high``), inside the valid range.
    log : searched on a log scale.
    integer : whole numbers only.
    """

    name: str
    low: float
    high: float
    log: bool = False
    integer: bool = False

    def to_dict(self) -> dict[str, Any]:
        """A JSON-able description (as recorded with the study)."""
        return {"name": self.name, "low": self.low, "high": self.high, "log": self.log, "integer": self.integer}


@dataclass(frozen=True)
class SearchSpace:
    """The searched parameters, in order, and the configuration they start from."""

    parameters: tuple[SearchParameter, ...]
    start: SceneConfig

    @property
    def names(self) -> list[str]:
        """The dotted names, in order."""
        return [p.name for p in self.parameters]

    def to_dict(self) -> list[dict[str, Any]]:
        """A JSON-able description of the parameters."""
        return [p.to_dict() for p in self.parameters]

    def start_values(self) -> dict[str, float]:
        """The start configuration's centre of every parameter, clipped to its searched range."""
        values = {}
        for parameter in self.parameters:
            value = min(max(centre(_value(self.start, parameter.name)), parameter.low), parameter.high)
            values[parameter.name] = int(round(value)) if parameter.integer else value
        return values

    def config(self, values: dict[str, float], name: str = "optimised") -> SceneConfig:
        """The start configuration with every searched parameter's centre moved to ``values[name]``.

        Raises
        ------
        ParameterError
            If a value is missing (the space's names are all needed).
        """
        data = self.start.model_dump(mode="json")
        data["name"] = name
        for parameter in self.parameters:
            if parameter.name not in values:
                raise ParameterError(f"no value for the searched parameter {parameter.name}")
            section, key = parameter.name.split(".")
            current = _value(self.start, parameter.name)
            declared = _declared(parameter.name)
            data[section][key] = _tidy(moved(current, float(values[parameter.name]), declared["bounds"],
                                             declared["kind"] == "integer"))
        return validate_config(data, f"trial configuration ({name})")


# ------------------------------------------------------------------------------------------------ values


def _declared(dotted: str) -> dict[str, Any]:
    section, key = dotted.split(".")
    return dict(sections()[section].model_fields[key].json_schema_extra or {})


def _value(config: SceneConfig, dotted: str) -> Any:
    section, key = dotted.split(".")
    return getattr(getattr(config, section), key)


def centre(value: Any) -> float:
    """The centre of a configured value: the number, a range's middle, a log-uniform's geometric mean, a normal's
    mean, a choice's or a mixture's weighted mean (a probability is itself)."""
    if not isinstance(value, Dist):
        return float(value)
    values = value.values
    if value.kind in ("uniform", "integers"):
        return (values[0] + values[1]) / 2
    if value.kind == "loguniform":
        return math.sqrt(values[0] * values[1])
    if value.kind in ("const", "normal"):
        return values[0]
    points = [(lo + hi) / 2 for lo, hi in zip(values[::2], values[1::2])] if value.kind == "mixture" else list(values)
    weights = list(value.weights) if value.weights is not None else [1.0] * len(points)
    return sum(w * p for w, p in zip(weights, points)) / sum(weights)


def _inside(low: float, high: float, bounds: tuple[float, float]) -> tuple[float, float]:
    """Shift ``[low, high]`` inside ``bounds`` keeping its width where it fits, else clip it."""
    lo, hi = bounds
    if high - low >= hi - lo:
        return lo, hi
    if low < lo:
        return lo, lo + (high - low)
    if high > hi:
        return hi - (high - low), hi
    return low, high


SIGNIFICANT_DIGITS = 10
"""Digits a moved value keeps (``0.1 + 0.2`` is written ``0.3``; the renders do not change)."""


def _tidy(value: Any) -> Any:
    """``value`` (a number, or lists and mappings of numbers) rounded to :data:`SIGNIFICANT_DIGITS` digits."""
    if isinstance(value, float):
        return float(f"{value:.{SIGNIFICANT_DIGITS}g}")
    if isinstance(value, list):
        return [_tidy(v) for v in value]
    if isinstance(value, dict):
        return {k: _tidy(v) for k, v in value.items()}
    return value


def moved(current: Any, value: float, bounds: tuple[float, float], integer: bool = False) -> Any:
    """``current`` (a configured value) with its centre moved to ``value``, in the form a configuration takes.

    Parameters
    ----------
    current : Dist or float
        The start configuration's value (a probability is a float).
    value : float
        The new centre.
    bounds : (float, float)
        The parameter's valid range; the result stays inside it.
    integer : bool
        An integer parameter (its numbers are rounded).
    """
    lo, hi = bounds
    value = min(max(value, lo), hi)
    if integer:
        value = float(round(value))
    if not isinstance(current, Dist):
        return value
    values = current.values
    if current.kind == "uniform":
        return list(_inside(value - (values[1] - values[0]) / 2, value + (values[1] - values[0]) / 2, bounds))
    if current.kind == "integers":
        half = (values[1] - values[0]) / 2
        low, high = _inside(float(round(value - half)), float(round(value - half)) + 2 * half, bounds)
        return {"integers": [int(math.ceil(low)), int(math.floor(high))]}
    if current.kind == "loguniform" and value > 0:
        ratio = math.sqrt(values[1] / values[0])
        low, high = value / ratio, value * ratio
        if low < lo:
            low, high = lo, min(lo * ratio * ratio, hi)
        elif high > hi:
            low, high = max(hi / ratio / ratio, lo), hi
        return {"loguniform": [low, high]} if low > 0 else value
    if current.kind == "normal":
        return {"normal": [value, values[1]]}
    return value  # const, choice, mixture (and a log-uniform moved to 0)


# ------------------------------------------------------------------------------------------------ spaces


def _searchable(dotted: str, source: str) -> dict[str, Any]:
    """The declaration of a parameter a space may search; refuses the others with one line."""
    declared = _declared(dotted)
    kind = declared.get("kind")
    if kind == "category":
        raise ParameterError(f"{source}{dotted}: a category cannot be searched (only numbers and probabilities)")
    if "size" in declared:
        raise ParameterError(f"{source}{dotted}: a vector ({declared['size']} components) cannot be searched")
    if "choices" in declared:
        valid = ", ".join(f"{c:g}" for c in declared["choices"])
        raise ParameterError(f"{source}{dotted}: takes one of {valid} and cannot be searched")
    return declared


def _log_scale(bounds: tuple[float, float]) -> bool:
    lo, hi = bounds
    return lo > 0 and hi / lo >= 10**LOG_DECADES


def default_range(start: SceneConfig, dotted: str, narrow: float = NARROW) -> SearchParameter | None:
    """The default searched range of one parameter around the start (see the module docstring); None where it
    would be a single value."""
    declared = _declared(dotted)
    lo, hi = declared["bounds"]
    integer = declared["kind"] == "integer"
    c = min(max(centre(_value(start, dotted)), lo), hi)
    if _log_scale((lo, hi)):
        half = narrow * math.log10(hi / lo)
        low, high, log = max(lo, c / 10**half), min(hi, c * 10**half), True
    else:
        half = narrow * (hi - lo)
        low, high, log = max(lo, c - half), min(hi, c + half), False
    if integer:
        low, high = float(math.ceil(low)), float(math.floor(high))
    if not low < high:
        return None
    return SearchParameter(dotted, float(low), float(high), log, integer)


def default_space(start: SceneConfig, narrow: float = NARROW) -> SearchSpace:
    """Every numeric and probability parameter of :data:`SEARCHED_SECTIONS` but :data:`LEFT_OUT`, vectors and
    fixed choices, within ``narrow`` of its valid range around the start.

    Raises
    ------
    ParameterError
        If ``narrow`` is not in (0, 1].
    """
    if not 0 < narrow <= 1:
        raise ParameterError(f"narrow must be in (0, 1] (a fraction of each valid range), got {narrow:g}")
    parameters = []
    for section in SEARCHED_SECTIONS:
        for key, field in sections()[section].model_fields.items():
            dotted = f"{section}.{key}"
            declared = field.json_schema_extra or {}
            if dotted in LEFT_OUT or declared.get("kind") == "category" or "size" in declared or "choices" in declared:
                continue
            parameter = default_range(start, dotted, narrow)
            if parameter is not None:
                parameters.append(parameter)
    return SearchSpace(tuple(parameters), start)


def _bound(dotted: str, value: Any, source: str) -> float:
    """One bound of a range, checked as a value of the parameter with the messages of ``--set``."""
    section, key = dotted.split(".")
    validate_config({section: {key: value}}, source.removesuffix(": "))
    return float(value)


def _entry(dotted: str, entry: Any, start: SceneConfig, narrow: float, source: str) -> SearchParameter:
    """One parameter of a space file."""
    check_parameter_name(dotted, source.removesuffix(" "))
    declared = _searchable(dotted, source)
    if entry is None or entry == AUTO:
        parameter = default_range(start, dotted, narrow)
        if parameter is None:
            raise ParameterError(f"{source}{dotted}: its default range around the start is a single value; give a range")
        return parameter
    log = False
    if isinstance(entry, dict):
        unknown = sorted(set(entry) - {"range", "log"})
        if unknown or "range" not in entry:
            raise ParameterError(
                f"{source}{dotted}: expected {ENTRY_FORMS}, got {entry!r}"
            )
        log = entry.get("log", False)
        if not isinstance(log, bool):
            raise ParameterError(f"{source}{dotted}: log must be true or false, got {log!r}")
        entry = entry["range"]
    if not isinstance(entry, list) or len(entry) != 2:
        raise ParameterError(
            f"{source}{dotted}: expected {ENTRY_FORMS}, got {entry!r}"
        )
    low, high = (_bound(dotted, value, source) for value in entry)
    if not low < high:
        raise ParameterError(f"{source}{dotted}: the range needs low < high, got [{low:g}, {high:g}]")
    if log and low <= 0:
        raise ParameterError(f"{source}{dotted}: a log range needs low > 0, got [{low:g}, {high:g}]")
    integer = declared["kind"] == "integer"
    if integer and not (low.is_integer() and high.is_integer()):
        raise ParameterError(f"{source}{dotted}: an integer parameter needs whole bounds, got [{low:g}, {high:g}]")
    return SearchParameter(dotted, low, high, log, integer)


def load_space(path: str | os.PathLike, start: SceneConfig, narrow: float = NARROW) -> SearchSpace:
    """Read a space file (see the module docstring) and check it against the catalogue.

    Parameters
    ----------
    path : str or path-like
        A YAML mapping of dotted parameter names to ``[low, high]``, ``{range: [low, high], log: true}`` or
        ``auto`` (also written ``~``), or ``fixed`` (not searched); ``all: auto`` first takes the whole default
        space.
    start : SceneConfig
        The start configuration (for ``auto`` ranges, and whose spreads the trials keep).
    narrow : float
        Half-width of the ``auto`` ranges (see :func:`default_space`).

    Raises
    ------
    ParameterError
        With one line naming the file and the parameter: an unknown name, a category, a vector or a fixed choice,
        a bound out of the valid range or of the wrong type (the messages of ``--set``), ``low >= high``.
    """
    path = Path(path)
    if not path.is_file():
        raise ParameterError(f"{path}: no such search space file")
    data = read_yaml_file(path, ParameterError)
    source = f"{path}: "
    if not isinstance(data, dict) or not data:
        got = "nothing" if not data else type(data).__name__
        raise ParameterError(f"{path}: expected a mapping of parameter names to ranges, e.g. stain.hue_deg: [250, 290]; "
                             f"got {got}")
    parameters: dict[str, SearchParameter] = {}
    if ALL in data:
        if data[ALL] != AUTO:
            raise ParameterError(f"{source}{ALL}: expected {ALL}: {AUTO} (the default space), got {data[ALL]!r}")
        parameters = {p.name: p for p in default_space(start, narrow).parameters}
    for dotted, entry in data.items():
        if dotted == ALL:
            continue
        if entry == FIXED:
            check_parameter_name(str(dotted), source.removesuffix(" "))
            parameters.pop(str(dotted), None)
            continue
        if isinstance(entry, dict) and "range" not in entry and "log" not in entry and "." not in str(dotted):
            raise ParameterError(f"{source}{dotted}: expected dotted parameter names (e.g. {dotted}.name: [low, high]), "
                                 "not sections")
        parameters[str(dotted)] = _entry(str(dotted), entry, start, narrow, source)
    return SearchSpace(tuple(parameters.values()), start)
