"""Scene parameters: the configuration (ranges), presets, seeded sampling and the concrete scene.

Parts: :mod:`~platesynth.scene.distributions` (what a configured value may be and how it is drawn),
:mod:`~platesynth.scene.catalogue` (every parameter, by section), :mod:`~platesynth.scene.loading` (presets, YAML,
overrides, validation), :mod:`~platesynth.scene.sample` (seed -> concrete scene) and the concrete scene itself.
"""

from platesynth.scene.catalogue import SceneConfig, parameter_names, parameter_table
from platesynth.scene.concrete import Plaque, PlaqueLook, Scene, Well, load_scene
from platesynth.scene.distributions import Categorical, Dist, DistVector
from platesynth.scene.loading import dump_config, list_presets, load_config, validate_config
from platesynth.scene.sample import color_temperature_rgb, plate_geometry, sample_scene, stain_rgb

__all__ = [
    "Categorical",
    "Dist",
    "DistVector",
    "Plaque",
    "PlaqueLook",
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
