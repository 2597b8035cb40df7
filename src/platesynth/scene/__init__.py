"""Scene parameters: the configuration (ranges), presets, seeded sampling and the concrete scene."""

from platesynth.scene.config import (
    Categorical,
    Dist,
    SceneConfig,
    dump_config,
    list_presets,
    load_config,
    parameter_names,
    parameter_table,
    validate_config,
)
from platesynth.scene.params import Plaque, Scene, Well, load_scene
from platesynth.scene.sample import color_temperature_rgb, plate_geometry, sample_scene, stain_rgb

__all__ = [
    "Categorical",
    "Dist",
    "Plaque",
    "Scene",
    "SceneConfig",
    "Well",
    "color_temperature_rgb",
    "dump_config",
    "list_presets",
    "load_config",
    "load_scene",
    "parameter_names",
    "parameter_table",
    "plate_geometry",
    "sample_scene",
    "stain_rgb",
    "validate_config",
]
