"""The scene configuration: a range or distribution for every scene parameter, validated, defined once.

A configuration is a nested mapping ``section.parameter -> value``. A numeric parameter's value is

* a number: always that value;
* ``[low, high]``: uniform between the two;
* ``{loguniform: [low, high]}``, ``{normal: [mean, sd]}`` (clipped to the valid range),
  ``{choice: [a, b, ...], weights: [...]}`` or ``{mixture: [[low, high], [low, high], ...], weights: [...]}``
  (uniform within one of several ranges).

A probability is a number in [0, 1]; a category is a name or a mapping ``{name: weight}``.
Each parameter's name, type, unit, valid range, default and description live in its field below;
:func:`parameter_table` reads them for the CLI and the docs.
"""

from __future__ import annotations

import difflib
import math
from pathlib import Path
from typing import Any, Literal

import numpy as np
import yaml
from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    ValidationInfo,
    field_validator,
    model_serializer,
    model_validator,
)

from platesynth.errors import ParameterError

PRESET_DIR = Path(__file__).parent / "presets"

_DIST_KINDS = ("uniform", "loguniform", "normal", "choice", "mixture")


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)


class Dist(BaseModel):
    """A distribution of one numeric parameter (see the module docstring for the YAML forms)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    kind: Literal["const", "uniform", "loguniform", "normal", "choice", "mixture"]
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
        if self.kind in ("uniform", "loguniform", "normal") and n != 2:
            raise ValueError(f"{self.kind} needs two numbers")
        if self.kind in ("uniform", "loguniform", "mixture"):
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
        """Draw one value (clipped to ``bounds``; rounded when ``integer``)."""
        if self.kind == "const":
            value = self.values[0]
        elif self.kind == "uniform":
            value = rng.uniform(*self.values)
        elif self.kind == "loguniform":
            value = math.exp(rng.uniform(math.log(self.values[0]), math.log(self.values[1])))
        elif self.kind == "normal":
            value = rng.normal(*self.values)
        elif self.kind == "mixture":
            p = None if self.weights is None else np.asarray(self.weights) / sum(self.weights)
            index = int(rng.choice(len(self.values) // 2, p=p))
            value = rng.uniform(self.values[2 * index], self.values[2 * index + 1])
        else:
            p = None if self.weights is None else np.asarray(self.weights) / sum(self.weights)
            value = self.values[int(rng.choice(len(self.values), p=p))]
        value = float(min(max(value, bounds[0]), bounds[1]))
        return float(round(value)) if integer else value


def _plain(value: float) -> int | float:
    return int(value) if float(value).is_integer() else value


class Categorical(BaseModel):
    """A categorical parameter: one name, or weights over names."""

    model_config = ConfigDict(frozen=True, extra="forbid")

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
        """Draw one name."""
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
) -> Any:
    """A numeric parameter: default (any :class:`Dist` form), valid range (or ``choices``), unit, description."""
    extra: dict[str, Any] = {"kind": "integer" if integer else "number", "unit": unit, "bounds": (low, high)}
    if choices is not None:
        extra["choices"] = choices
    return Field(default=Dist.model_validate(default), description=description, json_schema_extra=extra)


def probability(default: float, description: str) -> Any:
    """A probability in [0, 1]."""
    return Field(
        default=default, description=description, json_schema_extra={"kind": "probability", "unit": "", "bounds": (0, 1)}
    )


def category(default: Any, options: tuple[str, ...], description: str) -> Any:
    """A categorical parameter with the given options."""
    return Field(
        default=Categorical.model_validate(default),
        description=description,
        json_schema_extra={"kind": "category", "unit": "", "options": options},
    )


class Section(BaseModel):
    """A group of parameters; checks each against its valid range."""

    model_config = ConfigDict(extra="forbid", frozen=True, strict=True)

    @field_validator("*", mode="after")
    @classmethod
    def _within_range(cls, value: Any, info: ValidationInfo) -> Any:
        extra = cls.model_fields[info.field_name].json_schema_extra or {}
        kind = extra.get("kind")
        if kind in ("number", "integer", "probability"):
            low, high = extra["bounds"]
            unit = f" {extra['unit']}" if extra.get("unit") else ""
            values = value.support() if isinstance(value, Dist) else (value,)
            for v in values:
                if not low <= v <= high:
                    raise ValueError(f"{v:g} is out of range: valid range is [{low:g}, {high:g}]{unit}")
                if kind == "integer" and not float(v).is_integer():
                    raise ValueError(f"{v:g} is not a whole number")
                if "choices" in extra and v not in extra["choices"]:
                    valid = ", ".join(f"{c:g}" for c in extra["choices"])
                    raise ValueError(f"{v:g} is not allowed: valid values are {valid}")
            if "choices" in extra and value.kind not in ("const", "choice"):
                raise ValueError("expected a number or {choice: [...]}")
        elif kind == "category":
            unknown = sorted(set(value.weights) - set(extra["options"]))
            if unknown:
                raise ValueError(f"unknown option {unknown[0]!r}: valid options are {', '.join(extra['options'])}")
        return value

    def draw(self, name: str, rng: np.random.Generator) -> Any:
        """Draw the parameter ``name`` of this section with ``rng``."""
        value = getattr(self, name)
        extra = type(self).model_fields[name].json_schema_extra or {}
        if isinstance(value, Dist):
            drawn = value.sample(rng, extra["bounds"], integer=extra["kind"] == "integer")
            return int(drawn) if extra["kind"] == "integer" else drawn
        if isinstance(value, Categorical):
            return value.sample(rng)
        return bool(rng.random() < value)  # a probability


class PlateConfig(Section):
    """The plate."""

    format: Dist = number(12, 6, 96, "wells", "number of wells (use {choice: [...]} to mix formats)", True, (6, 12, 24, 96))
    transmittance: Dist = number([0.72, 0.85], 0.3, 1.0, "", "light passing the plastic between wells")
    tint: Dist = number([0.0, 0.04], 0.0, 0.3, "", "blue tint of the plastic (0 = neutral)")
    rim_darkness: Dist = number([0.25, 0.45], 0.0, 1.0, "", "darkness of the well-wall outlines")
    label_strength: Dist = number([0.35, 0.7], 0.0, 1.0, "", "contrast of the embossed labels and rings")


class CameraConfig(Section):
    """Camera pose relative to the plate."""

    from_below: float = probability(1.0, "chance the plate is photographed through its bottom (mirrored)")
    plate_fill: Dist = number([1.13, 1.21], 0.2, 1.5, "", "plate length as a fraction of the image width")
    rotation_deg: Dist = number({"normal": [0.0, 0.6]}, -10.0, 10.0, "deg", "in-plane rotation")
    tilt_deg: Dist = number([0.0, 2.0], 0.0, 15.0, "deg", "tilt of the plate away from the camera axis")
    offset: Dist = number({"normal": [0.0, 0.012]}, -0.2, 0.2, "image", "offset of the plate centre, per axis")
    distance_mm: Dist = number([300, 500], 100, 2000, "mm", "camera distance (sets the parallax of the walls)")
    defocus_px: Dist = number([0.0, 0.4], 0.0, 5.0, "px", "optical blur at 1024 px image width")


class BackgroundConfig(Section):
    """What lies around the plate."""

    kind: Categorical = category("lightbox", ("lightbox", "desk"), "a light box under the plate, or a desk")
    brightness: Dist = number([0.88, 1.0], 0.0, 1.0, "", "brightness of the light box panel or the desk")
    desk_gray: Dist = number([0.03, 0.2], 0.0, 1.0, "", "grey level of the desk (or what surrounds the light box)")
    texture: Dist = number([0.0, 0.05], 0.0, 0.5, "", "amplitude of the desk's surface texture")
    ruler: float = probability(0.0, "chance of a ruler along the light box's edges")
    panel_margin_x_mm: Dist = number([40, 120], -50, 300, "mm",
                                     "distance from the plate's side to the nearest side edge of the light panel")
    panel_margin_y_mm: Dist = number([-5, 3], -50, 300, "mm",
                                     "distance from the plate's top/bottom to the nearest edge of the light panel")
    panel_below: float = probability(0.85, "chance the nearest panel edge lies below the plate (else above)")


class StainConfig(Section):
    """The stained cell monolayer."""

    hue_deg: Dist = number([246, 286], 0.0, 360.0, "deg", "stain hue (crystal violet 240-290, neutral red 345-360)")
    saturation: Dist = number([0.9, 1.0], 0.0, 1.0, "", "stain saturation at nominal density")
    value: Dist = number([0.9, 1.0], 0.0, 1.0, "", "stain value (brightness) at nominal density")
    density: Dist = number([0.9, 1.15], 0.0, 3.0, "", "plate-wide stain density relative to nominal")
    well_density_jitter: Dist = number([0.02, 0.08], 0.0, 0.5, "", "relative density change from well to well (sd)")
    unevenness: Dist = number([0.04, 0.12], 0.0, 1.0, "", "low-frequency density variation")
    unevenness_scale_mm: Dist = number([2.0, 6.0], 0.5, 30.0, "mm", "size of low-frequency blotches")
    centre_gradient: Dist = number([0.0, 0.15], 0.0, 1.0, "", "extra density of the elongated dark centre")
    centre_elongation: Dist = number([1.0, 2.0], 1.0, 5.0, "", "aspect ratio of the dark centre")
    drying_detail: Dist = number([0.01, 0.04], 0.0, 1.0, "", "high-frequency drying texture")
    rim_clearing_mm: Dist = number([0.1, 0.6], 0.0, 5.0, "mm", "width of the paler band along the rim")
    translucency: Dist = number([0.0, 0.008], 0.0, 1.0, "", "fraction of light passing un-absorbed")


class WellsConfig(Section):
    """Which wells hold what."""

    emptied: float = probability(0.01, "chance a well holds no cells (clear), so no fixed pattern is learned")


class PlaquesConfig(Section):
    """Plaque counts (a dilution series across columns), sizes and shapes."""

    negative_plate: float = probability(0.5, "chance the plate holds no plaque at all")
    top_count: Dist = number({"loguniform": [20, 3000]}, 0, 100000, "plaques", "mean count in the least diluted column")
    dilution_factor: Dist = number({"choice": [10, 5, 3], "weights": [0.7, 0.2, 0.1]}, 1.0, 100.0, "",
                                   "dilution from one column to the next")
    reverse_series: float = probability(0.0, "chance the series runs from the last column to the first")
    lysis_count: Dist = number([120, 300], 1, 100000, "plaques", "mean count above which a well is lysed")
    radius_mm: Dist = number({"loguniform": [0.35, 1.5]}, 0.05, 10.0, "mm", "median plaque radius of the plate")
    radius_spread: Dist = number([0.2, 0.45], 0.0, 2.0, "", "sd of log radius within the plate")
    irregularity: Dist = number([0.02, 0.08], 0.0, 0.5, "", "amplitude of the outline's Fourier harmonics")
    softness: Dist = number([0.2, 0.45], 0.0, 2.0, "", "width of the fuzzy edge, fraction of the radius")
    clearness: Dist = number([0.95, 1.0], 0.0, 1.0, "", "fraction of stain removed inside a plaque")
    edge_bias: Dist = number([0.0, 0.3], 0.0, 1.0, "", "tendency of plaques to lie near the well's rim")
    max_overlap: Dist = number(1.0, 0.0, 1.0, "", "largest overlap of two plaques, fraction of the smaller radius")


class ArtifactsConfig(Section):
    """Scratches, marker writing, blots and debris."""

    pipette_scratch: float = probability(0.85, "chance of a pipette scratch near the top of a well")
    scratch_length_mm: Dist = number([0.8, 2.5], 0.0, 20.0, "mm", "length of a pipette scratch")
    scratch_width_mm: Dist = number([0.2, 0.4], 0.01, 3.0, "mm", "width of a scratch")
    extra_scratches: Dist = number([0.0, 0.3], 0.0, 10.0, "per well", "mean number of other scratches per well")
    marker: float = probability(0.6, "chance of marker writing on the plate")
    blots: Dist = number([0.0, 1.0], 0.0, 20.0, "per plate", "mean number of stains/smudges on the plate")
    debris: Dist = number([0.0, 6.0], 0.0, 200.0, "per well", "mean number of dark specks per well")


class LightingConfig(Section):
    """Light and exposure."""

    exposure_ev: Dist = number([-0.55, -0.1], -3.0, 3.0, "EV", "exposure correction")
    color_temperature_k: Dist = number([9000, 13000], 2500, 15000, "K",
                                       "colour temperature the camera's white balance leaves (higher: bluer)")
    vignetting: Dist = number([0.0, 0.15], 0.0, 1.0, "", "darkening at the image corners")
    glare: Dist = number([0.0, 0.04], 0.0, 1.0, "", "strength of a soft glare spot")


class PostConfig(Section):
    """Post-processing: each effect is switched on with a probability and drawn with a strength."""

    brightness: float = probability(0.5, "chance of a brightness change")
    brightness_strength: Dist = number([-0.08, 0.08], -1.0, 1.0, "", "brightness change")
    white_balance: float = probability(0.5, "chance of a colour cast")
    white_balance_strength: Dist = number([0.0, 0.05], 0.0, 1.0, "", "size of the colour cast")
    clarity: float = probability(0.4, "chance of a local contrast change")
    clarity_strength: Dist = number([-0.2, 0.3], -1.0, 1.0, "", "local contrast change")
    motion_blur: float = probability(0.1, "chance of motion blur")
    motion_blur_strength: Dist = number([0.5, 2.0], 0.0, 30.0, "px", "motion blur length at 1024 px width")
    shadows: float = probability(0.3, "chance of low-frequency shadows")
    shadows_strength: Dist = number([0.02, 0.08], 0.0, 1.0, "", "depth of the shadows")
    chromatic_aberration: float = probability(0.3, "chance of chromatic aberration")
    chromatic_aberration_strength: Dist = number([0.3, 1.2], 0.0, 10.0, "px", "colour shift at the corners")
    bloom: float = probability(0.3, "chance of bloom")
    bloom_strength: Dist = number([0.05, 0.2], 0.0, 1.0, "", "glow around bright areas")
    sharpen: float = probability(1.0, "chance of sharpening")
    sharpen_strength: Dist = number([1.0, 2.0], 0.0, 2.0, "", "unsharp-mask amount")
    noise: float = probability(1.0, "chance of sensor noise")
    noise_strength: Dist = number([1.0, 2.5], 0.0, 30.0, "levels", "noise sd in 8-bit levels")
    jpeg: float = probability(0.9, "chance of JPEG compression")
    jpeg_strength: Dist = number([0.05, 0.2], 0.0, 0.9, "", "1 - JPEG quality/100")


class SceneConfig(BaseModel):
    """Ranges and distributions of every scene parameter; :func:`platesynth.scene.sample_scene` draws a Scene."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    name: str = Field(default="custom", description="name of the configuration (the preset's name)")
    plate: PlateConfig = PlateConfig()
    camera: CameraConfig = CameraConfig()
    background: BackgroundConfig = BackgroundConfig()
    stain: StainConfig = StainConfig()
    wells: WellsConfig = WellsConfig()
    plaques: PlaquesConfig = PlaquesConfig()
    artifacts: ArtifactsConfig = ArtifactsConfig()
    lighting: LightingConfig = LightingConfig()
    post: PostConfig = PostConfig()


def _sections() -> dict[str, type[Section]]:
    return {
        name: field.annotation
        for name, field in SceneConfig.model_fields.items()
        if isinstance(field.annotation, type) and issubclass(field.annotation, Section)
    }


def parameter_names() -> list[str]:
    """Every parameter's dotted name, e.g. ``plaques.radius_mm``."""
    return [f"{s}.{p}" for s, model in _sections().items() for p in model.model_fields]


def parameter_table() -> list[dict[str, Any]]:
    """One row per parameter: name, type, unit, range, default and description (read from the fields).

    Returns
    -------
    list of dict
        Keys ``name``, ``type``, ``unit``, ``range`` (``[low, high]`` or the list of options), ``default``
        (in the form a YAML file takes), ``description``.
    """
    rows = []
    for section, model in _sections().items():
        for name, field in model.model_fields.items():
            extra = field.json_schema_extra or {}
            default = field.default
            rows.append(
                {
                    "name": f"{section}.{name}",
                    "type": extra["kind"],
                    "unit": extra.get("unit", ""),
                    "range": list(extra.get("options") or extra.get("choices") or extra["bounds"]),
                    "default": default.model_dump() if isinstance(default, BaseModel) else default,
                    "description": field.description,
                }
            )
    return rows


def _format_error(error: dict[str, Any], source: str) -> str:
    loc = [str(p) for p in error["loc"] if not str(p).startswith("function-")]
    # drop pydantic's internal location parts ('Dist', '[...]') after the parameter name
    loc = loc[:2]
    name = ".".join(loc) or "configuration"
    message = error["msg"].removeprefix("Value error, ")
    if error["type"] == "extra_forbidden":
        known = list(SceneConfig.model_fields) if len(loc) == 1 else [
            p for p in _sections().get(loc[0], BaseModel).model_fields
        ]
        guess = difflib.get_close_matches(loc[-1], known, n=1)
        hint = f" (did you mean {'.'.join(loc[:-1] + guess)}?)" if guess else f" (known: {', '.join(known)})"
        message = f"unknown parameter{hint}"
    elif error["type"] in ("float_type", "int_type", "bool_type", "string_type", "model_type", "dict_type"):
        message = f"wrong type ({error['msg']}), got {error.get('input')!r}"
    prefix = f"{source}: " if source else ""
    return f"{prefix}{name}: {message}"


def validate_config(data: dict[str, Any], source: str = "") -> SceneConfig:
    """Validate a configuration mapping, raising :class:`ParameterError` with a one-line message.

    Parameters
    ----------
    data : mapping of sections to mappings of parameters.
    source : where the data came from (a file name), used in the message.
    """
    if not isinstance(data, dict):
        raise ParameterError(f"{source or 'configuration'}: expected a mapping of sections, got {type(data).__name__}")
    try:
        return SceneConfig.model_validate(data)
    except ValidationError as exc:
        raise ParameterError(_format_error(exc.errors()[0], source)) from None


def list_presets() -> list[str]:
    """Names of the presets shipped with platesynth."""
    return sorted(p.stem for p in PRESET_DIR.glob("*.yaml"))


def _read_yaml(path: Path) -> dict[str, Any]:
    try:
        data = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise ParameterError(f"{path}: cannot read YAML ({exc.__class__.__name__}: {exc})".splitlines()[0]) from None
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ParameterError(f"{path}: expected a mapping of sections, got {type(data).__name__}")
    return data


def _merge(base: dict[str, Any], update: dict[str, Any]) -> dict[str, Any]:
    merged = dict(base)
    for key, value in update.items():
        if isinstance(value, dict) and isinstance(merged.get(key), dict) and key in _sections():
            merged[key] = {**merged[key], **value}
        else:
            merged[key] = value
    return merged


def _apply_overrides(data: dict[str, Any], overrides: dict[str, Any]) -> dict[str, Any]:
    data = {k: dict(v) if isinstance(v, dict) else v for k, v in data.items()}
    names = parameter_names()
    for dotted, value in overrides.items():
        if dotted not in names and dotted != "name":
            guess = difflib.get_close_matches(dotted, names, n=1)
            hint = f" (did you mean {guess[0]}?)" if guess else " (see `platesynth scene params`)"
            raise ParameterError(f"override {dotted}: unknown parameter{hint}")
        if dotted == "name":
            data["name"] = value
            continue
        section, name = dotted.split(".")
        data.setdefault(section, {})[name] = value
    return data


def load_config(
    preset: str | None = None, path: str | Path | None = None, overrides: dict[str, Any] | None = None
) -> SceneConfig:
    """Build a validated configuration from a preset, a user YAML file and dotted overrides (in that order).

    Parameters
    ----------
    preset : name of a shipped preset (see :func:`list_presets`); ``None`` starts from the defaults
        (or only from ``path``).
    path : a YAML file with the same layout as the presets; its values replace the preset's.
    overrides : ``{"plate.format": 24, "plaques.radius_mm": [0.5, 1.0]}``; applied last.

    Raises
    ------
    ParameterError
        For an unknown preset, an unreadable file, an unknown parameter, a wrong type or a value out of range.
    """
    data: dict[str, Any] = {}
    source = "configuration"
    if preset is not None:
        preset_path = PRESET_DIR / f"{preset}.yaml"
        if not preset_path.is_file():
            raise ParameterError(f"unknown preset {preset!r}: available presets are {', '.join(list_presets())}")
        data = _read_yaml(preset_path)
        data.setdefault("name", preset)
        source = f"preset {preset}"
    if path is not None:
        path = Path(path)
        if not path.is_file():
            raise ParameterError(f"{path}: no such configuration file")
        user = _read_yaml(path)
        data = _merge(data, user)
        if "name" not in user:
            data["name"] = path.stem
        source = str(path)
    if overrides:
        data = _apply_overrides(data, overrides)
        source = f"{source} with overrides" if data else "overrides"
    return validate_config(data, source)


def dump_config(config: SceneConfig) -> str:
    """The configuration as YAML, in the form :func:`load_config` reads."""
    return yaml.safe_dump(config.model_dump(), sort_keys=False, default_flow_style=None)
