"""Blender's compositor: the camera and post-processing effects on the image pass, and the mask pass's output.

The image chain follows the raster renderer's order: in linear light exposure and the light's colour
(its colour temperature, normalised to its strongest channel), vignetting and glare; then the sRGB encoding and,
on the encoded image, the optical blur and the enabled post-processing effects (brightness, white balance, clarity, motion blur, shadows, chromatic aberration, bloom, sharpening, sensor
noise, the tone curve's black point). Lengths given for 1024-pixel-wide images are scaled by ``px_scale``. Each effect's strength is a
named node input, so the .blend shows and lets one change them. JPEG compression is not a compositor effect:
the host applies it to the written image.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import bpy

from platesynth.render.blender.inside.materials import MASK_AOVS
from platesynth.render.blender.inside.nodes import add, feed, link, output
from platesynth.render.look import (
    BLOOM_RADIUS,
    BLOOM_THRESHOLD,
    CLARITY_RADIUS,
    LUMINANCE,
    NOISE_FLOOR,
    NOISE_MID_GREY,
    NOISE_OWN,
    NOISE_SHARED,
    noise_grain_gain,
)

IMAGE_FILE = "image"
"""The image pass's File Output item (written as ``image.png``)."""



def _tree(name: str) -> tuple[bpy.types.NodeTree, bpy.types.Node, bpy.types.Node]:
    tree = bpy.data.node_groups.new(name, "CompositorNodeTree")
    tree.interface.new_socket(name="Image", in_out="OUTPUT", socket_type="NodeSocketColor")
    layers = add(tree, "CompositorNodeRLayers")
    group_out = add(tree, "NodeGroupOutput")
    return tree, layers, group_out


def _file_output(tree: bpy.types.NodeTree, directory: str, file_format: str, depth: str, mode: str, as_render: bool) -> bpy.types.Node:
    node = add(tree, "CompositorNodeOutputFile", name="platesynth.file_output")
    node.format.media_type = "IMAGE"  # before the file format (the default is a multi-layer EXR)
    node.format.file_format = file_format
    node.format.color_depth = depth
    node.format.color_mode = mode
    node.directory = directory
    node.file_name = ""
    node.save_as_render = as_render
    return node


class _Chain:
    """Builds an image chain of compositor nodes: each step takes the current image and returns the next."""

    def __init__(self, tree: bpy.types.NodeTree, image: bpy.types.NodeSocket) -> None:
        self.tree = tree
        self.image = image

    def mix(self, blend: str, b: Any, factor: Any = 1.0, a: Any = None, name: str | None = None) -> bpy.types.NodeSocket:
        node = add(self.tree, "ShaderNodeMix", name=name, data_type="RGBA", blend_type=blend, clamp_result=False, clamp_factor=False)
        feed(self.tree, node, Factor=factor, A=self.image if a is None else a, B=b)
        return output(node, "Result")

    def math(self, operation: str, a: Any, b: Any = None, name: str | None = None) -> bpy.types.NodeSocket:
        node = add(self.tree, "ShaderNodeMath", name=name, operation=operation)
        feed(self.tree, node, Value=a, **({} if b is None else {"Value_1": b}))
        return output(node, "Value")

    def value(self, name: str, value: float) -> bpy.types.NodeSocket:
        node = add(self.tree, "ShaderNodeValue", name=name)
        node.outputs[0].default_value = value
        return node.outputs[0]

    def gray(self, value: Any) -> bpy.types.NodeSocket:
        node = add(self.tree, "CompositorNodeCombineColor")
        feed(self.tree, node, Red=value, Green=value, Blue=value)
        return output(node, "Image")

    def blur(self, image: Any, sigma_px: float) -> bpy.types.NodeSocket:
        node = add(self.tree, "CompositorNodeBlur")
        radius = max(3.0 * sigma_px, 0.0)  # Blender's Gaussian reaches ~3 sigma at its size
        feed(self.tree, node, Image=image, Size=(radius, radius), Extend_Bounds=False)
        return output(node, "Image")

    def luminance(self, image: Any) -> bpy.types.NodeSocket:
        separate = feed(self.tree, add(self.tree, "CompositorNodeSeparateColor"), Image=image)
        red, green, blue = (output(separate, channel) for channel in ("Red", "Green", "Blue"))
        return _madd(self, blue, LUMINANCE[2], _madd(self, green, LUMINANCE[1], self.math("MULTIPLY", red, LUMINANCE[0])))

    def resampled(self, image: Any, u: Any, v: Any) -> bpy.types.NodeSocket:
        """``image`` sampled at normalised coordinates (u, v) (pixel centres at (i + 0.5) / size, v up), edges
        extended; the result keeps the image's size."""
        uv = feed(self.tree, add(self.tree, "ShaderNodeCombineXYZ"), X=u, Y=v, Z=1.0)  # z: the UV's alpha
        node = add(self.tree, "CompositorNodeMapUV")
        feed(self.tree, node, Image=image, UV=uv, Extension_X="Extend", Extension_Y="Extend")
        return output(node, "Image")

    def moved(self, image: Any, x: float, y: float, size: tuple[int, int]) -> bpy.types.NodeSocket:
        """``image`` shifted by (x, y) pixels (y down)."""
        u, v = self.normalized()
        return self.resampled(image, self.math("SUBTRACT", u, x / size[0]), self.math("ADD", v, y / size[1]))

    def normalized(self) -> tuple[bpy.types.NodeSocket, bpy.types.NodeSocket]:
        xy = feed(self.tree, add(self.tree, "ShaderNodeSeparateXYZ"), Vector=output(self.coordinates(), "Normalized"))
        return output(xy, "X"), output(xy, "Y")

    def coordinates(self) -> bpy.types.Node:
        return feed(self.tree, add(self.tree, "CompositorNodeImageCoordinates"), Image=self.image)


def _madd(chain: _Chain, a: Any, b: float, c: Any) -> bpy.types.NodeSocket:
    node = add(chain.tree, "ShaderNodeMath", operation="MULTIPLY_ADD")
    feed(chain.tree, node, Value=a, Value_1=b, Value_2=c)
    return output(node, "Value")


def image_tree(scene_data: Mapping[str, Any], view: Mapping[str, Any], directory: str) -> bpy.types.NodeTree:
    """The image pass's compositor: lighting and post-processing, written as an 8-bit RGB PNG in ``directory``."""
    tree, layers, group_out = _tree("platesynth.image_compositor")
    chain = _Chain(tree, output(layers, "Image"))
    lighting = scene_data["lighting"]
    width, height = int(view["width"]), int(view["height"])
    aspect = width / height
    px_scale = float(view["px_scale"])

    exposure = feed(tree, add(tree, "CompositorNodeExposure", name="Exposure EV"), Image=chain.image, Exposure=float(lighting["exposure_ev"]))
    chain.image = output(exposure, "Image")
    gains = feed(tree, add(tree, "ShaderNodeCombineXYZ", name="Light Colour"), X=view["light_rgb"][0], Y=view["light_rgb"][1], Z=view["light_rgb"][2])
    chain.image = chain.mix("MULTIPLY", output(gains, "Vector"))

    normalized = output(chain.coordinates(), "Normalized")
    xy = feed(tree, add(tree, "ShaderNodeSeparateXYZ"), Vector=normalized)
    x_centred = chain.math("MULTIPLY", chain.math("SUBTRACT", output(xy, "X"), 0.5), aspect)
    y_centred = chain.math("SUBTRACT", 0.5, output(xy, "Y"))  # Blender's y counts from the bottom
    radius2 = chain.math("ADD", chain.math("POWER", x_centred, 2.0), chain.math("POWER", y_centred, 2.0))
    vignetting = chain.value("Vignetting", float(lighting["vignetting"]))
    falloff = chain.math("SUBTRACT", 1.0, chain.math("MULTIPLY", vignetting, chain.math("DIVIDE", radius2, 0.25 * (aspect**2 + 1))))
    chain.image = chain.mix("MULTIPLY", chain.gray(falloff))
    glare_x, glare_y = lighting["glare_center"]
    diagonal = math.hypot(aspect, 1.0)
    gx = chain.math("MULTIPLY", chain.math("SUBTRACT", output(xy, "X"), float(glare_x)), aspect)
    gy = chain.math("SUBTRACT", chain.math("SUBTRACT", 1.0, output(xy, "Y")), float(glare_y))
    glare_distance2 = chain.math("ADD", chain.math("POWER", gx, 2.0), chain.math("POWER", gy, 2.0))
    glare_width2 = (float(lighting["glare_radius"]) * diagonal) ** 2
    glare = chain.math("MULTIPLY", chain.value("Glare Strength", float(lighting["glare_strength"])), chain.math("EXPONENT", chain.math("DIVIDE", glare_distance2, -glare_width2)))
    chain.image = chain.mix("ADD", chain.gray(glare))

    encode = add(tree, "CompositorNodeConvertColorSpace", name="Display Encoding", from_color_space="Linear Rec.709", to_color_space="sRGB")
    chain.image = output(feed(tree, encode, Image=chain.image), "Image")
    sigma = float(scene_data["camera"]["defocus_px"]) * px_scale
    if sigma > 0.05:  # the optical blur, on the encoded image as the raster renderer does it
        chain.image = chain.blur(chain.image, sigma)
    _post(chain, scene_data["post"], int(scene_data["seed"]), px_scale, width, height)

    link(tree, chain.image, group_out.inputs[0])
    file_output = _file_output(tree, directory, "PNG", "8", "RGB", as_render=True)
    file_output.file_output_items.new("RGBA", IMAGE_FILE)
    link(tree, chain.image, file_output.inputs[IMAGE_FILE])
    return tree


def _post(chain: _Chain, post: Mapping[str, Any], seed: int, px_scale: float, width: int, chain_height: int) -> None:
    """The enabled post-processing effects, in the raster renderer's order, on the display-encoded image."""
    tree = chain.tree

    def enabled(name: str) -> float | None:
        effect = post[name]
        return float(effect["strength"]) if effect["enabled"] else None

    if (strength := enabled("brightness")) is not None:
        if strength >= 0:  # towards white
            chain.image = chain.mix("MIX", (1.0, 1.0, 1.0, 1.0), factor=chain.value("Brightness", strength))
        else:  # towards black
            chain.image = chain.mix("MULTIPLY", chain.gray(chain.math("ADD", 1.0, chain.value("Brightness", strength))))
    if enabled("white_balance") is not None:
        gains = [float(g) for g in post["white_balance_shift"]]
        grey = sum(g * w for g, w in zip(gains, LUMINANCE))
        colour = add(tree, "ShaderNodeCombineXYZ", name="White Balance Gains")
        feed(tree, colour, X=gains[0] / grey, Y=gains[1] / grey, Z=gains[2] / grey)
        chain.image = chain.mix("MULTIPLY", output(colour, "Vector"))
    if (strength := enabled("clarity")) is not None:
        base = chain.blur(chain.image, CLARITY_RADIUS * width)
        luminance = chain.luminance(chain.image)
        midtones = chain.math("SUBTRACT", 1.0, chain.math("POWER", _madd(chain, luminance, 2.0, -1.0), 2.0))
        detail = chain.mix("SUBTRACT", base)
        weight = chain.math("MULTIPLY", midtones, chain.value("Clarity", strength))
        chain.image = chain.mix("ADD", chain.mix("MULTIPLY", chain.gray(weight), a=detail))
    if (strength := enabled("motion_blur")) is not None and strength * px_scale > 0.5:
        length = strength * px_scale
        angle = math.radians(float(post["motion_blur_angle_deg"]))
        steps = max(1, int(math.ceil(length)))
        source, total = chain.image, None
        for i in range(steps + 1):  # the mean of copies shifted along the line, as the raster renderer does
            t = -0.5 + i / steps
            shifted = chain.moved(source, t * length * math.cos(angle), t * length * math.sin(angle), (width, chain_height))
            total = shifted if total is None else chain.mix("ADD", shifted, a=total)
        chain.image = chain.mix("MULTIPLY", (1.0 / (steps + 1),) * 3 + (1.0,), a=total)
    if (strength := enabled("shadows")) is not None:
        # a field this smooth needs no full-resolution noise: evaluate it on a 1/16 image and sample that back at
        # every pixel (Map UV keeps the full image's size)
        small = add(tree, "CompositorNodeScale")
        feed(tree, small, Image=chain.image, X=1.0 / 16, Y=1.0 / 16)
        small_coordinates = feed(tree, add(tree, "CompositorNodeImageCoordinates"), Image=output(small, "Image"))
        noise = add(tree, "ShaderNodeTexNoise", noise_dimensions="4D", name="Shadow Field")
        feed(tree, noise, Vector=output(small_coordinates, "Normalized"), Scale=2.0, Detail=0.0, W=float(seed % 1000) + 0.5)
        field = chain.math("MULTIPLY", chain.value("Shadows", strength), output(noise, "Factor"))
        u, v = chain.normalized()
        full = chain.resampled(chain.gray(chain.math("SUBTRACT", 1.0, field)), u, v)
        chain.image = chain.mix("MULTIPLY", full)
    if (strength := enabled("chromatic_aberration")) is not None:
        # red scaled outward and blue inward about the centre by the strength (px at the corners)
        half_diagonal = 0.5 * math.hypot(width, float(chain_height))
        separate = feed(tree, add(tree, "CompositorNodeSeparateColor"), Image=chain.image)
        combine = add(tree, "CompositorNodeCombineColor", name="Chromatic Aberration")
        u, v = chain.normalized()
        for channel, sign in (("Red", 1.0), ("Green", 0.0), ("Blue", -1.0)):
            band = output(separate, channel)
            if sign:
                shrink = 1.0 / (1.0 + sign * strength * px_scale / half_diagonal)
                source_u = _madd(chain, chain.math("SUBTRACT", u, 0.5), shrink, 0.5)
                source_v = _madd(chain, chain.math("SUBTRACT", v, 0.5), shrink, 0.5)
                moved = chain.resampled(chain.gray(band), source_u, source_v)
                band = output(feed(tree, add(tree, "CompositorNodeSeparateColor"), Image=moved), "Red")
            link(tree, band, combine.inputs[channel])
        chain.image = output(combine, "Image")
    if (strength := enabled("bloom")) is not None:
        bright = chain.mix("SUBTRACT", (BLOOM_THRESHOLD,) * 3 + (1.0,))
        bright = chain.mix("MULTIPLY", (1.0 / (1.0 - BLOOM_THRESHOLD),) * 3 + (1.0,), a=bright)
        clamp_low = add(tree, "ShaderNodeMix", data_type="RGBA", blend_type="LIGHTEN", clamp_result=False)
        feed(tree, clamp_low, Factor=1.0, A=bright, B=(0.0, 0.0, 0.0, 1.0))
        glow = chain.blur(output(clamp_low, "Result"), BLOOM_RADIUS * width)
        chain.image = chain.mix("ADD", glow, factor=chain.value("Bloom", strength))
    if (strength := enabled("sharpen")) is not None:
        soft = chain.blur(chain.image, max(0.5, px_scale))
        detail = chain.mix("SUBTRACT", soft)
        if (luma := float(post["sharpen_luma"])) > 0.0:  # the luminance's detail in every channel, for that share
            detail = chain.mix("MIX", chain.gray(chain.luminance(detail)), factor=chain.value("Sharpen Luma", luma), a=detail)
        if (threshold := float(post["sharpen_threshold"]) / 255.0) > 0.0:  # coring: only detail beyond it
            channels = feed(tree, add(tree, "CompositorNodeSeparateColor"), Image=detail)
            cored = add(tree, "CompositorNodeCombineColor")
            # per channel with math nodes: the colour mix's darken and lighten, tried first, cored only half the detail
            for channel in ("Red", "Green", "Blue"):
                value = output(channels, channel)
                within = chain.math("MAXIMUM", chain.math("MINIMUM", value, threshold), -threshold)
                link(tree, chain.math("SUBTRACT", value, within), cored.inputs[channel])
            detail = output(cored, "Image")
        chain.image = chain.mix("ADD", detail, factor=chain.value("Sharpen", strength))
    if (strength := enabled("noise")) is not None:
        pixel = output(chain.coordinates(), "Pixel")
        uniform = add(tree, "ShaderNodeTexWhiteNoise", noise_dimensions="4D", name="Sensor Noise")
        feed(tree, uniform, Vector=pixel, W=float(seed % 100003))
        common = add(tree, "ShaderNodeTexWhiteNoise", noise_dimensions="4D")
        feed(tree, common, Vector=pixel, W=float(seed % 100003) + 0.5)
        # uniform noise with unit variance: (u - 0.5) * sqrt(12)
        own = chain.mix("SUBTRACT", (0.5, 0.5, 0.5, 1.0), a=output(uniform, "Color"))
        shared = chain.gray(chain.math("SUBTRACT", output(common, "Value"), 0.5))
        mixed = chain.mix("ADD", chain.mix("MULTIPLY", (NOISE_OWN,) * 3 + (1.0,), a=own), a=chain.mix("MULTIPLY", (NOISE_SHARED,) * 3 + (1.0,), a=shared))
        level = chain.math("SQRT", chain.math("DIVIDE", chain.math("MAXIMUM", chain.luminance(chain.image), NOISE_FLOOR), NOISE_MID_GREY))
        sd = chain.math("MULTIPLY", level, chain.math("MULTIPLY", chain.value("Noise Levels", strength), math.sqrt(12.0) / 255.0))
        noise = chain.mix("MULTIPLY", chain.gray(sd), a=mixed)
        if (grain := float(post["noise_grain_px"]) * px_scale) > 0.0:  # clumped into grains, its sd kept
            gain = noise_grain_gain(grain)
            noise = chain.mix("MULTIPLY", (gain, gain, gain, 1.0), a=chain.blur(noise, grain))
        chain.image = chain.mix("ADD", noise)
    if (level := float(post["black_level"])) > 0.0:  # the tone curve's black point (below 0 clips when written)
        black = chain.value("Black Level", level)
        shifted = chain.mix("SUBTRACT", chain.gray(black))
        chain.image = chain.mix("MULTIPLY", chain.gray(chain.math("DIVIDE", 1.0, chain.math("SUBTRACT", 1.0, black))),
                                a=shifted)


def mask_tree(directory: str) -> bpy.types.NodeTree:
    """The mask pass's compositor: each id AOV divided by 65535 and written as a 16-bit TIFF (exact integers)."""
    tree, layers, group_out = _tree("platesynth.mask_compositor")
    link(tree, output(layers, "Image"), group_out.inputs[0])
    file_output = _file_output(tree, directory, "TIFF", "16", "BW", as_render=False)
    for name in MASK_AOVS:
        file_output.file_output_items.new("FLOAT", name)
        scaled = add(tree, "ShaderNodeMath", operation="DIVIDE")
        feed(tree, scaled, Value=output(layers, name), Value_1=65535.0)
        link(tree, scaled, file_output.inputs[name])
    return tree
