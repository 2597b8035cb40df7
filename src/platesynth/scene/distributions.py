"""The distribution language: what a configuration value may be, how it is checked and how it is drawn.

A numeric parameter's value (a :class:`Dist`) is

* a number: always that value;
* ``[low, high]``: uniform between the two;
* ``{loguniform: [low, high]}``, ``{normal: [mean, sd]}`` (clipped to the valid range),
  ``{integers: [low, high]}`` (a whole number from low to high, both included),
  ``{choice: [a, b, ...], weights: [...]}`` or ``{mixture: [[low, high], [low, high], ...], weights: [...]}``
  (uniform within one of several ranges).

A vector parameter (a colour, a position; a :class:`DistVector`) is a list with one such value per component,
e.g. ``[[0.3, 0.7], [0.2, 0.6], 0.5]`` for R, G and B.

A probability is a number in [0, 1]; a category (a :class:`Categorical`) is a name or a mapping ``{name: weight}``.

:func:`number`, :func:`probability` and :func:`category` declare a parameter of each kind (its default, unit,
valid range and description, kept in the pydantic field); :func:`check_value` checks a value against that
declaration and :func:`draw_value` draws it. Which parameters exist is the catalogue's business
(:mod:`platesynth.scene.catalogue`).
"""

from __future__ import annotations

import math
from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_serializer, model_validator

_DIST_KINDS = ("uniform", "loguniform", "normal", "integers", "choice", "mixture")


_NUMBERS: dict[str, Any] = {"type": "array", "items": {"type": "number"}, "minItems": 1}
DIST_JSON_SCHEMA: dict[str, Any] = {
    "title": "Dist",
    "description": "a number; [low, high] (uniform); or one of {loguniform: [low, high]}, {normal: [mean, sd]}, "
    "{integers: [low, high]}, {choice: [a, b, ...], weights: [...]}, {mixture: [[low, high], ...], weights: [...]}",
    "anyOf": [
        {"type": "number"},
        {"type": "array", "items": {"type": "number"}, "minItems": 2, "maxItems": 2},
        {
            "type": "object",
            "properties": {
                **{kind: _NUMBERS for kind in ("loguniform", "normal", "integers", "choice")},
                "mixture": {"type": "array", "items": {"type": "array", "items": {"type": "number"}, "minItems": 2,
                                                       "maxItems": 2}},
                "weights": _NUMBERS,
                "kind": {"enum": ["const", *_DIST_KINDS]},
                "values": _NUMBERS,
            },
            "minProperties": 1,
            "additionalProperties": False,
        },
    ],
}
"""The JSON schema of a :class:`Dist` as configurations write it and :meth:`Dist.model_dump` returns it."""
DIST_VECTOR_JSON_SCHEMA: dict[str, Any] = {
    "title": "DistVector",
    "description": "one Dist per component, e.g. [[0.3, 0.7], [0.2, 0.6], 0.5] for R, G and B",
    "type": "array",
    "items": DIST_JSON_SCHEMA,
    "minItems": 1,
}
CATEGORICAL_JSON_SCHEMA: dict[str, Any] = {
    "title": "Categorical",
    "description": "a name, or a mapping {name: weight >= 0}",
    "anyOf": [{"type": "string"}, {"type": "object", "additionalProperties": {"type": "number", "minimum": 0}}],
}


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)


def _plain(value: float) -> int | float:
    return int(value) if float(value).is_integer() else value


class Dist(BaseModel):
    """A distribution of one numeric parameter (see the module docstring for the YAML forms).

    Attributes
    ----------
    kind : ``const``, ``uniform``, ``loguniform``, ``normal``, ``integers``, ``choice`` or ``mixture``.
    values : the numbers of the form (a mixture: low and high of each range in turn).
    weights : the options' weights (``choice`` and ``mixture`` only); ``None`` for equal weights.
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    @classmethod
    def __get_pydantic_json_schema__(cls, core_schema: Any, handler: Any) -> dict[str, Any]:
        return dict(DIST_JSON_SCHEMA)

    kind: Literal["const", "uniform", "loguniform", "normal", "integers", "choice", "mixture"]
    values: tuple[float, ...]  # mixture: low, high of each range in turn
    weights: tuple[float, ...] | None = None

    @model_validator(mode="before")
    @classmethod
    def _parse(cls, data: Any) -> Any:
        if isinstance(data, Dist):
            return data
        if _is_number(data):
            return {"kind": "const", "values": (float(data),)}
        if isinstance(data, (list, tuple)):
            if len(data) != 2 or not all(_is_number(v) for v in data):
                raise ValueError(f"a range must be two numbers [low, high], got {list(data)!r}")
            return {"kind": "uniform", "values": tuple(float(v) for v in data)}
        if isinstance(data, dict):
            if "kind" in data:
                return data
            kinds = [k for k in data if k != "weights"]
            if len(kinds) != 1 or kinds[0] not in _DIST_KINDS:
                raise ValueError(f"expected one of {', '.join(_DIST_KINDS)} (with 'weights' for choice), got {sorted(data)}")
            kind = kinds[0]
            values = data[kind]
            if kind == "mixture":
                ranges = values if isinstance(values, (list, tuple)) else None
                if not ranges or not all(
                    isinstance(r, (list, tuple)) and len(r) == 2 and all(_is_number(v) for v in r) for r in ranges
                ):
                    raise ValueError(f"mixture needs a list of [low, high] ranges, got {values!r}")
                values = [v for r in ranges for v in r]
            if not isinstance(values, (list, tuple)) or not values or not all(_is_number(v) for v in values):
                raise ValueError(f"{kind} needs a list of numbers, got {values!r}")
            out: dict[str, Any] = {"kind": kind, "values": tuple(float(v) for v in values)}
            if "weights" in data:
                out["weights"] = data["weights"]
            return out
        raise ValueError(
            f"expected a number, a [low, high] range or a mapping like {{loguniform: [low, high]}}, got {data!r}"
        )

    @model_validator(mode="after")
    def _check(self) -> Dist:
        n = len(self.values)
        if self.kind == "const" and n != 1:
            raise ValueError("a constant has one value")
        if self.kind in ("uniform", "loguniform", "normal", "integers") and n != 2:
            raise ValueError(f"{self.kind} needs two numbers")
        if self.kind == "integers" and not all(v.is_integer() for v in self.values):
            raise ValueError(f"integers needs two whole numbers, got {list(self.values)}")
        if self.kind in ("uniform", "loguniform", "integers", "mixture"):
            if n % 2 or any(lo > hi for lo, hi in zip(self.values[::2], self.values[1::2])):
                raise ValueError(f"each range needs low <= high, got {list(self.values)}")
        if self.kind == "loguniform" and self.values[0] <= 0:
            raise ValueError("loguniform needs low > 0")
        if self.kind == "normal" and self.values[1] < 0:
            raise ValueError("normal needs sd >= 0")
        if self.weights is not None:
            if self.kind not in ("choice", "mixture"):
                raise ValueError("weights belong to choice and mixture only")
            options = n // 2 if self.kind == "mixture" else n
            if len(self.weights) != options or min(self.weights) < 0 or sum(self.weights) <= 0:
                raise ValueError(f"{self.kind} needs one non-negative weight per option, not all zero")
        return self

    @model_serializer
    def _compact(self) -> Any:
        if self.kind == "const":
            return _plain(self.values[0])
        if self.kind == "uniform":
            return [_plain(v) for v in self.values]
        if self.kind == "mixture":
            ranges: list[Any] = [[_plain(lo), _plain(hi)] for lo, hi in zip(self.values[::2], self.values[1::2])]
            out: dict[str, Any] = {"mixture": ranges}
        else:
            out = {self.kind: [_plain(v) for v in self.values]}
        if self.weights is not None:
            out["weights"] = list(self.weights)
        return out

    def support(self) -> tuple[float, ...]:
        """The values that bound what can be drawn (the mean for a normal)."""
        return self.values[:1] if self.kind == "normal" else self.values

    def sample(self, rng: np.random.Generator, bounds: tuple[float, float], integer: bool = False) -> float:
        """Draw one value.

        Parameters
        ----------
        rng : the scene's generator; a constant draws nothing from it.
        bounds : the parameter's valid range; the value is clipped to it.
        integer : round the value to a whole number.

        Returns
        -------
        float
        """
        if self.kind == "const":
            value = self.values[0]
        elif self.kind == "uniform":
            value = rng.uniform(*self.values)
        elif self.kind == "loguniform":
            value = math.exp(rng.uniform(math.log(self.values[0]), math.log(self.values[1])))
        elif self.kind == "normal":
            value = rng.normal(*self.values)
        elif self.kind == "integers":
            value = rng.integers(int(self.values[0]), int(self.values[1]) + 1)
        elif self.kind == "mixture":
            p = None if self.weights is None else np.asarray(self.weights) / sum(self.weights)
            index = int(rng.choice(len(self.values) // 2, p=p))
            value = rng.uniform(self.values[2 * index], self.values[2 * index + 1])
        else:
            p = None if self.weights is None else np.asarray(self.weights) / sum(self.weights)
            value = self.values[int(rng.choice(len(self.values), p=p))]
        value = float(min(max(value, bounds[0]), bounds[1]))
        return float(round(value)) if integer else value


class DistVector(BaseModel):
    """Independent distributions, one per component of a vector parameter (R, G, B; x, y).

    Attributes
    ----------
    components : one :class:`Dist` per component, drawn in order.
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    @classmethod
    def __get_pydantic_json_schema__(cls, core_schema: Any, handler: Any) -> dict[str, Any]:
        return dict(DIST_VECTOR_JSON_SCHEMA)

    components: tuple[Dist, ...]

    @model_validator(mode="before")
    @classmethod
    def _parse(cls, data: Any) -> Any:
        if isinstance(data, DistVector):
            return data
        if isinstance(data, (list, tuple)) and data:
            return {"components": tuple(data)}
        if isinstance(data, dict) and "components" in data:
            return data
        raise ValueError(f"expected a list with one value per component, like [[0.3, 0.7], 0.5], got {data!r}")

    @model_serializer
    def _compact(self) -> Any:
        return [component.model_dump() for component in self.components]

    def support(self) -> tuple[float, ...]:
        """The values that bound what can be drawn, over all components."""
        return tuple(v for component in self.components for v in component.support())

    def sample(self, rng: np.random.Generator, bounds: tuple[float, float], integer: bool = False) -> tuple[float, ...]:
        """Draw each component in turn (see :meth:`Dist.sample`)."""
        return tuple(component.sample(rng, bounds, integer) for component in self.components)


class Categorical(BaseModel):
    """A categorical parameter: one name, or weights over names.

    Attributes
    ----------
    weights : ``{name: weight}``; one name with weight 1 for a fixed choice.
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    @classmethod
    def __get_pydantic_json_schema__(cls, core_schema: Any, handler: Any) -> dict[str, Any]:
        return dict(CATEGORICAL_JSON_SCHEMA)

    weights: dict[str, float]

    @model_validator(mode="before")
    @classmethod
    def _parse(cls, data: Any) -> Any:
        if isinstance(data, Categorical):
            return data
        if isinstance(data, str):
            return {"weights": {data: 1.0}}
        if isinstance(data, dict) and "weights" not in data:
            if not all(isinstance(k, str) and _is_number(v) and v >= 0 for k, v in data.items()) or not data:
                raise ValueError(f"expected a name or a mapping {{name: weight >= 0}}, got {data!r}")
            if sum(data.values()) <= 0:
                raise ValueError("weights are all zero")
            return {"weights": {k: float(v) for k, v in data.items()}}
        if isinstance(data, dict):
            return data
        raise ValueError(f"expected a name or a mapping {{name: weight}}, got {data!r}")

    @model_serializer
    def _compact(self) -> Any:
        if len(self.weights) == 1:
            return next(iter(self.weights))
        return {k: _plain(v) for k, v in self.weights.items()}

    def sample(self, rng: np.random.Generator) -> str:
        """Draw one name (always one draw from ``rng``, even for a fixed name)."""
        names = list(self.weights)
        p = np.asarray([self.weights[n] for n in names], dtype=float)
        return names[int(rng.choice(len(names), p=p / p.sum()))]


def number(
    default: Any,
    low: float,
    high: float,
    unit: str,
    description: str,
    integer: bool = False,
    choices: tuple[float, ...] | None = None,
    size: int | None = None,
) -> Any:
    """Declare a numeric parameter (a pydantic field holding a :class:`Dist`).

    Parameters
    ----------
    default : any :class:`Dist` form.
    low, high : the valid range; every value a distribution can give must lie in it.
    unit : unit of the values ("" for none).
    description : one line for the parameter table.
    integer : values are whole numbers.
    choices : the only allowed values (then the value is a number or ``{choice: [...]}``).
    size : a vector of this many components (a :class:`DistVector`), each within ``[low, high]``.
    """
    extra: dict[str, Any] = {"kind": "integer" if integer else "number", "unit": unit, "bounds": (low, high)}
    if choices is not None:
        extra["choices"] = choices
    if size is not None:
        extra["size"] = size
        return Field(default=DistVector.model_validate(default), description=description, json_schema_extra=extra)
    return Field(default=Dist.model_validate(default), description=description, json_schema_extra=extra)


def probability(default: float, description: str) -> Any:
    """Declare a probability in [0, 1] (a pydantic field holding a float)."""
    return Field(
        default=default, description=description, json_schema_extra={"kind": "probability", "unit": "", "bounds": (0, 1)}
    )


def category(default: Any, options: tuple[str, ...], description: str) -> Any:
    """Declare a categorical parameter with the given options (a pydantic field holding a :class:`Categorical`)."""
    return Field(
        default=Categorical.model_validate(default),
        description=description,
        json_schema_extra={"kind": "category", "unit": "", "options": options},
    )


def check_value(value: Any, declared: dict[str, Any]) -> Any:
    """Check a parsed value against its declaration (the ``json_schema_extra`` of :func:`number` & co.).

    Returns
    -------
    The value, unchanged.

    Raises
    ------
    ValueError
        With a message naming the valid range, the valid values or the valid options.
    """
    kind = declared.get("kind")
    if kind in ("number", "integer", "probability"):
        low, high = declared["bounds"]
        unit = f" {declared['unit']}" if declared.get("unit") else ""
        if "size" in declared and len(value.components) != declared["size"]:
            raise ValueError(f"expected {declared['size']} components, got {len(value.components)}")
        values = value.support() if isinstance(value, (Dist, DistVector)) else (value,)
        for v in values:
            if not low <= v <= high:
                raise ValueError(f"{v:g} is out of range: valid range is [{low:g}, {high:g}]{unit}")
            if kind == "integer" and not float(v).is_integer():
                raise ValueError(f"{v:g} is not a whole number")
            if "choices" in declared and v not in declared["choices"]:
                valid = ", ".join(f"{c:g}" for c in declared["choices"])
                raise ValueError(f"{v:g} is not allowed: valid values are {valid}")
        if "choices" in declared and value.kind not in ("const", "choice"):
            raise ValueError("expected a number or {choice: [...]}")
    elif kind == "category":
        unknown = sorted(set(value.weights) - set(declared["options"]))
        if unknown:
            raise ValueError(f"unknown option {unknown[0]!r}: valid options are {', '.join(declared['options'])}")
    return value


def draw_value(value: Any, declared: dict[str, Any], rng: np.random.Generator) -> Any:
    """Draw one value of a parameter: a number (an ``int`` for an integer parameter), a tuple of numbers (a
    vector), a name or a bool.

    Parameters
    ----------
    value : the configured :class:`Dist`, :class:`Categorical` or probability.
    declared : the parameter's declaration (see :func:`check_value`).
    rng : the scene's generator.
    """
    if isinstance(value, Dist):
        drawn = value.sample(rng, declared["bounds"], integer=declared["kind"] == "integer")
        return int(drawn) if declared["kind"] == "integer" else drawn
    if isinstance(value, DistVector):
        return value.sample(rng, declared["bounds"], integer=declared["kind"] == "integer")
    if isinstance(value, Categorical):
        return value.sample(rng)
    return bool(rng.random() < value)  # a probability
