"""Render settings and the two passes: the image (many samples, compositor effects) and the exact masks.

Cycles averages AOVs over samples and the pixel filter, so ids at object edges would be fractions. The mask
pass therefore renders again with one sample, a 0.01 px filter (the pixel centre), no denoising and no
adaptive sampling, with every surface given the opaque mask material whose AOVs hold the rounded ids; the
image-only objects (light box, bottom sheet, fringes, artifacts) are hidden. The result: the well and plaque
seen at each pixel centre, as the raster renderer defines its masks.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import bpy

from platesynth.render.blender.inside import compositor, materials, scene

ENGINES = ("CYCLES", "BLENDER_EEVEE")
IMAGE_FILTER_PX = 1.0
"""Width of the image pass's pixel filter (Blackman-Harris), pixels."""
DEVICES = ("auto", "CPU", "GPU")


def _choose_device(requested: str) -> str:
    """``"CPU"`` or ``"GPU"``: with ``"auto"``, the GPU where Cycles finds an OptiX or CUDA device."""
    if requested not in DEVICES:
        raise ValueError(f"device must be one of {', '.join(DEVICES)}, got {requested!r}")
    if requested == "CPU":
        return "CPU"
    preferences = bpy.context.preferences.addons["cycles"].preferences
    for backend in ("OPTIX", "CUDA"):
        try:
            devices = [d for d in preferences.get_devices_for_type(backend) if d.type == backend]
        except (TypeError, ValueError):
            continue
        if devices:
            preferences.compute_device_type = backend
            for device in preferences.devices:
                device.use = device.type == backend
            return "GPU"
    if requested == "GPU":
        raise ValueError("device GPU was asked for, but Cycles finds no OptiX or CUDA device")
    return "CPU"


def configure(options: Mapping[str, Any], view: Mapping[str, Any], seed: int) -> str:
    """Resolution, engine, device, samples and colour management shared by both passes; return the device used."""
    bl_scene = bpy.context.scene
    render = bl_scene.render
    render.resolution_x, render.resolution_y = int(view["width"]), int(view["height"])
    render.resolution_percentage = 100
    render.use_compositing = True
    render.dither_intensity = 0.0
    render.film_transparent = False
    engine = options.get("engine", "CYCLES")
    if engine not in ENGINES:
        raise ValueError(f"engine must be one of {', '.join(ENGINES)}, got {engine!r}")
    render.engine = engine
    # values are written as rendered: the compositor does exposure, colour and the 1/2.2 gamma itself
    bl_scene.view_settings.view_transform = "Raw"
    bl_scene.view_settings.look = "None"
    bl_scene.view_settings.exposure = 0.0
    bl_scene.view_settings.gamma = 1.0
    device = "CPU"
    if engine == "CYCLES":
        cycles = bl_scene.cycles
        device = _choose_device(options.get("device", "auto"))
        cycles.device = device
        cycles.seed = seed % (2**31 - 1)
        cycles.max_bounces = 4
        cycles.transparent_max_bounces = 64
        # no Russian roulette through the stacked films: it would end paths at random where many overlap (speckle)
        cycles.min_transparent_bounces = cycles.transparent_max_bounces
        cycles.min_light_bounces = cycles.max_bounces
        cycles.diffuse_bounces = cycles.glossy_bounces = cycles.transmission_bounces = 0
        cycles.volume_bounces = 0
        cycles.caustics_reflective = cycles.caustics_refractive = False
        threads = options.get("threads")
        if threads:
            render.threads_mode, render.threads = "FIXED", int(threads)
    else:
        bl_scene.eevee.taa_render_samples = int(options.get("samples", 16))
    return device


def _image_pass(options: Mapping[str, Any], description: Mapping[str, Any], directory: str) -> None:
    bl_scene = bpy.context.scene
    scene.show_pass("image")
    bpy.context.view_layer.material_override = None
    bl_scene.render.filter_size = bl_scene.cycles.filter_width = IMAGE_FILTER_PX
    if bl_scene.render.engine == "CYCLES":
        cycles = bl_scene.cycles
        cycles.samples = int(options.get("samples", 16))
        cycles.use_adaptive_sampling = False
        cycles.use_denoising = bool(options.get("denoise", False))
        if cycles.use_denoising:
            cycles.denoiser = "OPENIMAGEDENOISE"
            cycles.denoising_quality = "FAST"
    bl_scene.compositing_node_group = compositor.image_tree(description["scene"], description["view"], directory)
    bpy.ops.render.render(write_still=False)


def _mask_pass(directory: str) -> None:
    bl_scene = bpy.context.scene
    scene.show_pass("mask")
    bpy.context.view_layer.material_override = materials.mask_material()
    bl_scene.render.engine = "CYCLES"  # AOVs at exact pixel centres: Cycles with one sample whatever the image's engine
    cycles = bl_scene.cycles
    cycles.samples = 1
    cycles.use_adaptive_sampling = False
    cycles.use_denoising = False
    bl_scene.cycles.filter_width = 0.01  # Cycles' own setting (render.filter_size is EEVEE's)
    bl_scene.compositing_node_group = compositor.mask_tree(directory)
    bpy.ops.render.render(write_still=False)


def _expect(path: Path) -> str:
    if not path.is_file():
        raise RuntimeError(f"Blender did not write {path.name}")
    return str(path)


def render_to_files(description: Mapping[str, Any], options: Mapping[str, Any], out_dir: str) -> dict[str, str]:
    """Build the scene and render both passes into ``out_dir``.

    Returns
    -------
    dict
        ``{"image": .../image.png, "well_id": .../well_id.tif, "plaque_id": .../plaque_id.tif, "device": ...}``
        (masks hold ``id / 65535`` as 16-bit integers, i.e. the ids themselves).
    """
    directory = Path(out_dir)
    directory.mkdir(parents=True, exist_ok=True)
    scene.reset()
    scene.build(description)
    device = configure(options, description["view"], int(description["scene"]["seed"]))
    _image_pass(options, description, str(directory))
    _mask_pass(str(directory))
    files = {"image": _expect(directory / f"{compositor.IMAGE_FILE}.png")}
    files |= {name: _expect(directory / f"{name}.tif") for name in materials.MASK_AOVS}
    return files | {"device": device}


def export_blend(description: Mapping[str, Any], options: Mapping[str, Any], path: str) -> str:
    """Build the scene with the image pass's settings and save it as a .blend file at ``path``."""
    scene.reset()
    scene.build(description)
    configure(options, description["view"], int(description["scene"]["seed"]))
    scene.show_pass("image")
    bl_scene = bpy.context.scene
    bl_scene.cycles.samples = int(options.get("samples", 16))
    output_dir = str(Path(path).with_suffix("")) + "_render"
    bl_scene.compositing_node_group = compositor.image_tree(description["scene"], description["view"], output_dir)
    # also keep the mask compositor and material, for whoever wants to redo the mask pass
    compositor.mask_tree(output_dir).use_fake_user = True
    materials.mask_material().use_fake_user = True
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    temporary = target.with_name(f".{target.stem}.{os.getpid()}.tmp.blend")
    try:
        bpy.ops.wm.save_as_mainfile(filepath=str(temporary), compress=True, copy=True)
        os.replace(temporary, target)
    finally:
        if temporary.exists():
            temporary.unlink()
    return str(target)
