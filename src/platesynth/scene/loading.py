"""Loading a configuration: presets, YAML files, merging, dotted overrides, validation and dumping.

:func:`load_config` starts from a preset (``presets/*.yaml``), applies a user YAML file over it, then dotted
overrides (``{"plate.format": 24}``), and validates the result against the catalogue
(:mod:`platesynth.scene.catalogue`), turning the first error into a one-line :class:`ParameterError`.
"""

from __future__ import annotations

import difflib
from pathlib import Path
from typing import Any

import yaml
from pydantic import BaseModel, ValidationError

from platesynth.errors import ParameterError
from platesynth.limits import read_yaml_file
from platesynth.scene.catalogue import SceneConfig, parameter_names, sections

PRESET_DIR = Path(__file__).parent / "presets"


def _format_error(error: dict[str, Any], source: str) -> str:
    loc = [str(p) for p in error["loc"] if not str(p).startswith("function-")]
    # drop pydantic's internal location parts ('Dist', '[...]') after the parameter name
    loc = loc[:2]
    name = ".".join(loc) or "configuration"
    message = error["msg"].removeprefix("Value error, ")
    if error["type"] == "extra_forbidden":
        known = list(SceneConfig.model_fields) if len(loc) == 1 else [
            p for p in sections().get(loc[0], BaseModel).model_fields
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
    data : dict
        Mapping of sections to mappings of parameters (and an optional ``name``).
    source : str
        Where the data came from (a file name), used in the message.

    Returns
    -------
    SceneConfig

    Raises
    ------
    ParameterError
        For an unknown parameter, a wrong type or a value out of range (the first one found).
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
    """A configuration file's mapping: UTF-8 YAML without anchors or aliases (:func:`platesynth.limits.read_yaml_file`)."""
    data = read_yaml_file(path, ParameterError)
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ParameterError(f"{path}: expected a mapping of sections, got {type(data).__name__}")
    return data


def _merge(base: dict[str, Any], update: dict[str, Any]) -> dict[str, Any]:
    merged = dict(base)
    for key, value in update.items():
        if isinstance(value, dict) and isinstance(merged.get(key), dict) and key in sections():
            merged[key] = {**merged[key], **value}
        else:
            merged[key] = value
    return merged


def check_parameter_name(dotted: str, source: str = "override") -> None:
    """Refuse a dotted name that is not a catalogue parameter, with the message ``--set`` gives.

    Parameters
    ----------
    dotted : str
        E.g. ``"plaques.radius_mm"``.
    source : str
        What named it, the start of the message (``"override"`` for ``--set``, a file name for a search space).

    Raises
    ------
    ParameterError
        ``override plaques.radius: unknown parameter (did you mean plaques.radius_mm?)``.
    """
    names = parameter_names()
    if dotted not in names:
        guess = difflib.get_close_matches(str(dotted), names, n=1)
        hint = f" (did you mean {guess[0]}?)" if guess else " (see `platesynth scene catalogue`)"
        raise ParameterError(f"{source} {dotted}: unknown parameter{hint}")


def _apply_overrides(data: dict[str, Any], overrides: dict[str, Any]) -> dict[str, Any]:
    data = {k: dict(v) if isinstance(v, dict) else v for k, v in data.items()}
    for dotted, value in overrides.items():
        if dotted != "name":
            check_parameter_name(dotted)
        if dotted == "name":
            data["name"] = value
            continue
        section, name = dotted.split(".")
        data.setdefault(section, {})[name] = value
    return data


def check_preset_name(name: str) -> str:
    """Return ``name`` if it names a shipped preset; presets are names, never paths.

    Raises
    ------
    ParameterError
        For anything else: an unknown name, a file name or a path (those go through a configuration file).
    """
    names = list_presets()
    if name not in names:
        hint = ""
        if any(sep in name for sep in ("/", "\\", ".")) or Path(name).exists():
            hint = "; presets are names, a configuration file goes through --config"
        raise ParameterError(f"unknown preset {name!r}: available presets are {', '.join(names)}{hint}")
    return name


def load_config(
    preset: str | None = None, path: str | Path | None = None, overrides: dict[str, Any] | None = None
) -> SceneConfig:
    """Build a validated configuration from a preset, a user YAML file and dotted overrides (in that order).

    Parameters
    ----------
    preset : str, optional
        Name of a shipped preset (see :func:`list_presets`); ``None`` starts from the defaults
        (or only from ``path``).
    path : str or Path, optional
        A YAML file with the same layout as the presets; its values replace the preset's.
    overrides : dict, optional
        ``{"plate.format": 24, "plaques.radius_mm": [0.5, 1.0]}``; applied last.

    Returns
    -------
    SceneConfig

    Raises
    ------
    ParameterError
        For an unknown preset, an unreadable file, an unknown parameter, a wrong type or a value out of range.
    """
    data: dict[str, Any] = {}
    source = "configuration"
    if preset is not None:
        data = _read_yaml(PRESET_DIR / f"{check_preset_name(preset)}.yaml")
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
