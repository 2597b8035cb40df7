"""What a request may cost: memory estimated before allocating, pixels of decoded images, YAML without aliases.

Every command estimates the memory a request needs where the request enters (a render size, a metric's
``--size``, a training patch and batch, an image to predict on) and refuses it with a one-line
:class:`ResourceLimitError` when the estimate is above the memory limit, before anything is allocated or written.

- The memory limit is ``PLATESYNTH_MEMORY_LIMIT`` (bytes with an optional unit, ``8G``, ``500M``, ``16GiB``, or a
  share of the memory available now, ``50%``; ``none`` turns the check off). By default it is
  :data:`DEFAULT_FRACTION` of the memory available now: the least of ``MemAvailable`` (``/proc/meminfo``), the
  room left under a cgroup memory limit and the room left under the process's address-space limit
  (``RLIMIT_AS``).
- Images are decoded only when their header's size is within ``PLATESYNTH_MAX_IMAGE_PIXELS`` pixels (default
  :data:`DEFAULT_MAX_IMAGE_PIXELS`, the largest render, 16384 x 16384) and their decoded size within the memory
  limit.
- Configuration files (YAML) are read by :func:`load_yaml`: no anchors or aliases (a few lines of aliases expand
  to billions of values), at most :data:`MAX_YAML_DEPTH` levels of nesting and :data:`MAX_YAML_BYTES` bytes, UTF-8.

The estimates are deliberately generous (measured peaks plus a margin); ``docs/safety.md`` lists them.
"""

from __future__ import annotations

import math
import os
import re
import resource
import threading
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from platesynth.errors import PlatesynthError

MEMORY_ENV = "PLATESYNTH_MEMORY_LIMIT"
PIXELS_ENV = "PLATESYNTH_MAX_IMAGE_PIXELS"
DEFAULT_FRACTION = 0.75
"""Share of the memory available now that a request may use when ``PLATESYNTH_MEMORY_LIMIT`` is not set."""
DEFAULT_MAX_IMAGE_PIXELS = 16384 * 16384
"""Largest image decoded by default: the largest size the renderers draw."""
MAX_YAML_BYTES = 1_000_000
"""Largest configuration file read (the shipped presets are about 3 KB)."""
MAX_YAML_DEPTH = 32
"""Deepest nesting of mappings and lists in a configuration file (a configuration needs 3)."""

_GB = 1_000_000_000
_MB = 1_000_000


class ResourceLimitError(PlatesynthError):
    """A request would need more memory than the limit, or an input is larger than what platesynth reads."""


# ------------------------------------------------------------------------------------------------- memory limit


@dataclass(frozen=True)
class MemoryLimit:
    """The memory a request may use (``None``: no limit) and where that figure comes from, for messages."""

    bytes: int | None
    source: str


_UNITS = {
    "": 1, "b": 1,
    "k": 1000, "kb": 1000, "kib": 1024,
    "m": _MB, "mb": _MB, "mib": 1024**2,
    "g": _GB, "gb": _GB, "gib": 1024**3,
    "t": 1000 * _GB, "tb": 1000 * _GB, "tib": 1024**4,
}
_AMOUNT = re.compile(r"^\s*(\d+(?:\.\d*)?|\.\d+)\s*([a-zA-Z]*|%)\s*$")


def parse_bytes(text: str, name: str = MEMORY_ENV) -> tuple[float, bool]:
    """``"8G"`` -> ``(8e9, False)``; ``"50%"`` -> ``(0.5, True)`` (a share). Units: k, M, G, T (powers of 1000)
    and KiB, MiB, GiB, TiB (powers of 1024), case-insensitive, ``B`` optional.

    Raises
    ------
    ResourceLimitError
        If the text is not an amount.
    """
    match = _AMOUNT.match(text)
    unit = match[2].lower() if match else ""
    if not match or (unit != "%" and unit not in _UNITS):
        raise ResourceLimitError(
            f"{name}={text!r}: expected an amount of memory such as 8G, 500M, 16GiB or 50% (of the memory "
            "available), or none"
        )
    value = float(match[1])
    if unit == "%":
        if not 0 < value <= 100:
            raise ResourceLimitError(f"{name}={text!r}: a share must be in (0, 100] %")
        return value / 100.0, True
    if value <= 0:
        raise ResourceLimitError(f"{name}={text!r}: must be above 0 (none turns the limit off)")
    return value * _UNITS[unit], False


def _meminfo_available() -> int | None:
    try:
        with open("/proc/meminfo") as stream:
            for line in stream:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, AttributeError):
        return None


def _read_int(path: str) -> int | None:
    try:
        text = Path(path).read_text().strip()
    except OSError:
        return None
    return int(text) if text.isdigit() else None


def _cgroup_room() -> int | None:
    """Room left under the cgroup's memory limit (v2, then v1); None without a limit."""
    for limit_file, usage_file in (
        ("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory.current"),
        ("/sys/fs/cgroup/memory/memory.limit_in_bytes", "/sys/fs/cgroup/memory/memory.usage_in_bytes"),
    ):
        limit, usage = _read_int(limit_file), _read_int(usage_file)
        if limit is not None and usage is not None and limit < 1 << 60:
            return max(limit - usage, 0)
    return None


def _address_space_room() -> int | None:
    """Room left under ``RLIMIT_AS`` (the soft limit less the address space in use); None without a limit."""
    soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    if soft == resource.RLIM_INFINITY:
        return None
    used = 0
    try:
        with open("/proc/self/status") as stream:
            for line in stream:
                if line.startswith("VmSize:"):
                    used = int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return max(soft - used, 0)


def available_memory() -> int | None:
    """Memory a new allocation can get now: the least of MemAvailable, the cgroup's room and RLIMIT_AS's room."""
    figures = [f for f in (_meminfo_available(), _cgroup_room(), _address_space_room()) if f is not None]
    return min(figures) if figures else None


def memory_limit() -> MemoryLimit:
    """The memory limit for one request (see the module docstring).

    Raises
    ------
    ResourceLimitError
        If ``PLATESYNTH_MEMORY_LIMIT`` is set to something that is not an amount.
    """
    text = os.environ.get(MEMORY_ENV, "").strip()
    if text.lower() in ("none", "off", "unlimited"):
        return MemoryLimit(None, f"{MEMORY_ENV}={text}")
    if text:
        value, share = parse_bytes(text)
        if not share:
            return MemoryLimit(int(value), f"{MEMORY_ENV}={text}")
        fraction, source = value, f"{MEMORY_ENV}={text} of the {{available}} available now"
    else:
        fraction = DEFAULT_FRACTION
        source = f"{DEFAULT_FRACTION:.0%} of the {{available}} available now; set {MEMORY_ENV}, e.g. to 32G, to change it"
    available = available_memory()
    if available is None:
        return MemoryLimit(None, "the available memory is unknown")
    return MemoryLimit(int(fraction * available), source.format(available=format_bytes(available)))


def format_bytes(count: float) -> str:
    """``29.4e9`` -> ``"29 GB"``, ``1.23e9`` -> ``"1.2 GB"``, ``3.5e8`` -> ``"350 MB"`` (powers of 1000)."""
    if count >= 10 * _GB:
        return f"{count / _GB:,.0f} GB"
    if count >= _GB:
        return f"{count / _GB:.1f} GB"
    return f"{max(count / _MB, 1):.0f} MB"


def require_memory(nbytes: float, request: str) -> None:
    """Refuse a request whose estimated memory ``nbytes`` is above :func:`memory_limit`.

    Parameters
    ----------
    nbytes : estimated peak memory of the request, bytes.
    request : what is asked, for the message (e.g. ``"render at 16384x16384"``).

    Raises
    ------
    ResourceLimitError
        ``"render at 16384x16384 needs about 30 GB of memory, above the limit of 17 GB (...)"``.
    """
    limit = memory_limit()
    if limit.bytes is not None and nbytes > limit.bytes:
        raise ResourceLimitError(
            f"{request} needs about {format_bytes(nbytes)} of memory, above the limit of "
            f"{format_bytes(limit.bytes)} ({limit.source})"
        )


# ----------------------------------------------------------------------------------------------------- images


def max_image_pixels() -> int | None:
    """The largest image (width x height) decoded: ``PLATESYNTH_MAX_IMAGE_PIXELS`` or 16384 x 16384; None: any."""
    text = os.environ.get(PIXELS_ENV, "").strip()
    if not text:
        return DEFAULT_MAX_IMAGE_PIXELS
    if text.lower() in ("none", "off", "unlimited"):
        return None
    if not text.isdigit() or int(text) <= 0:
        raise ResourceLimitError(f"{PIXELS_ENV}={text!r}: expected a positive number of pixels, or none")
    return int(text)


def check_image(path: str | os.PathLike, width: int, height: int, nbytes: int, frames: int = 1) -> None:
    """Refuse to decode an image whose header claims more pixels than the limit, or more memory than the limit.

    ``nbytes`` is the size of the decoded array; decoding and converting it needs about three times as much.

    Raises
    ------
    ResourceLimitError
        ``"x.png: the header says 100000x100000 pixels, above the limit of 268,435,456 pixels ..."``.
    """
    limit = max_image_pixels()
    frames = max(int(frames), 1)
    pixels = int(width) * int(height) * frames
    size = f"{width}x{height}" + (f" pixels in {frames} frames" if frames > 1 else " pixels")
    if limit is not None and pixels > limit:
        raise ResourceLimitError(
            f"{path}: the header says {size}, above the limit of {limit:,} pixels an image may have "
            f"(images are checked before decoding; set {PIXELS_ENV} to change it)"
        )
    require_memory(3 * int(nbytes) + 50 * _MB, f"{path}: decoding {size}")


_PIL_LOCK = threading.Lock()


def open_image(path: str | os.PathLike) -> Any:
    """``PIL.Image.open(path)`` once the header's size has passed :func:`check_image` (the pixels are decoded
    later, by ``load()``, only for a size within the limits). Pillow's own decompression-bomb check gives way to
    this one.

    Raises
    ------
    ResourceLimitError
        For an image above the limits; Pillow's errors for files it cannot open.
    """
    from PIL import Image

    with _PIL_LOCK:
        saved, Image.MAX_IMAGE_PIXELS = Image.MAX_IMAGE_PIXELS, None
        try:
            image = Image.open(path)
        finally:
            Image.MAX_IMAGE_PIXELS = saved
    try:
        width, height = image.size
        wide = image.mode in ("I", "F") or image.mode.startswith("I;")
        check_image(path, width, height, width * height * 4 * (4 if wide else 1))
    except BaseException:
        image.close()
        raise
    return image


def read_tiff(path: str | os.PathLike) -> Any:
    """``tifffile.imread(path)`` (the first series) once its shape has passed :func:`check_image`.

    Raises
    ------
    ResourceLimitError
        For an image above the limits; tifffile's errors for files it cannot read.
    """
    import numpy as np
    import tifffile

    with tifffile.TiffFile(path) as tif:
        if not tif.series:
            raise tifffile.TiffFileError("no image in the file")
        series = tif.series[0]
        shape, axes = tuple(int(s) for s in series.shape), series.axes
        width = shape[axes.index("X")] if "X" in axes else (shape[-1] if shape else 1)
        height = shape[axes.index("Y")] if "Y" in axes else (shape[-2] if len(shape) > 1 else 1)
        samples = shape[axes.index("S")] if "S" in axes else 1
        total = math.prod(shape)
        frames = max(total // max(width * height * samples, 1), 1)
        check_image(path, width, height, total * np.dtype(series.dtype).itemsize, frames)
        return tif.asarray()


# ---------------------------------------------------------------------------------------------------- renders

_RASTER_BYTES_PER_PIXEL = 110
"""Raster renderer, writing included: measured 70-80 bytes per pixel at 12-28 Mpx (presets high, diverse)."""
_BLENDER_BYTES_PER_PIXEL = 250
"""Blender: its float render passes and compositor buffers, then the same post-processing as the raster renderer.
Measured peaks (``/usr/bin/time -v platesynth render --backend blender --samples 4``): 0.53 GB at 640x480, 0.75 GB
at 1280x960, 1.09 GB at 2560x1920, about 120 bytes per pixel over 0.5 GB; this estimate is twice that."""
_BASE = {"raster": 400 * _MB, "blender": 1500 * _MB}


def render_bytes(width: int, height: int, backend: str = "raster") -> int:
    """Estimated peak memory of rendering and writing one image of ``width`` x ``height``."""
    per_pixel = _BLENDER_BYTES_PER_PIXEL if backend == "blender" else _RASTER_BYTES_PER_PIXEL
    return int(width) * int(height) * per_pixel + _BASE.get(backend, _BASE["raster"])


_ITEM_BYTES = 2000
"""Bookkeeping of one item of a dataset render (its paths, its task, its record)."""


def check_render(
    size: Sequence[int],
    backend: str = "raster",
    *,
    workers: int = 1,
    count: int = 0,
    kept_images: int = 0,
    metrics: bool = False,
) -> None:
    """Refuse a render request above the memory limit: ``workers`` images at a time, the bookkeeping of ``count``
    items, ``kept_images`` images kept in memory (a contact sheet's tiles and the sheet), and with ``metrics`` the
    dataset metrics of the ``count`` images afterwards (``platesynth demo``).

    Raises
    ------
    ResourceLimitError
    """
    width, height = int(size[0]), int(size[1])
    workers = max(int(workers), 1)
    need = (
        workers * render_bytes(width, height, backend)
        + _ITEM_BYTES * max(int(count), 0)
        + 6 * width * height * max(int(kept_images), 0)
    )
    request = f"render of {count:,} images at {width}x{height}" if count > 1 else f"render at {width}x{height}"
    if workers > 1:
        request += f" with {workers} workers"
    if kept_images:
        request += " for a contact sheet"
    if metrics:
        need = max(need, entropy_bytes(height, width, count))
        request += " and their dataset metrics"
    require_memory(need, request)


# ---------------------------------------------------------------------------------------------------- metrics


def entropy_bytes(height: int, width: int, n_images: int, bins: int = 256) -> int:
    """Peak memory of the per-position metrics (pixel entropy and brightness variability) at ``height x width``.

    The entropy's state is one histogram of ``bins`` counts per position, its integer type widened as images come
    (1 byte up to 255 images, 2 up to 65535, then 4; both types live while widening); the variability holds two
    int64 sums per position; computing the entropy and the variance takes a few float64 maps.
    """
    pixels = int(height) * int(width)
    itemsize = 1 if n_images <= 255 else 2 if n_images <= 65535 else 4
    widening = itemsize + (itemsize // 2 if itemsize > 1 else 0)
    pending = min(128 * pixels, max(64 * _MB, pixels))  # buffered gray images before counting
    return pixels * (bins * widening + 16 + 4 * 8) + pending + 300 * _MB


def check_dataset_metrics(size: Sequence[int], n_images: int, bins: int = 256) -> None:
    """Refuse the dataset metrics at ``size`` = (height, width) over ``n_images`` images above the memory limit."""
    height, width = int(size[0]), int(size[1])
    require_memory(entropy_bytes(height, width, n_images, bins), f"computing the dataset metrics at {width}x{height}")


def well_crop_bytes(size: int, wells_per_plate: int = 96) -> int:
    """Peak memory of cropping and measuring the wells of one plate at ``size`` x ``size`` (spectra in complex128)."""
    pixels = int(size) * int(size)
    return pixels * (200 + 3 * wells_per_plate) + 300 * _MB


def check_well_crops(size: int, wells_per_plate: int = 96) -> None:
    """Refuse well crops of ``size`` x ``size`` pixels above the memory limit."""
    require_memory(well_crop_bytes(size, wells_per_plate), f"cropping wells to {size}x{size}")


def pair_bytes(height: int, width: int) -> int:
    """Peak memory of the pair metrics (SSIM in float64, naturalness, LPIPS) on two images of ``height x width``."""
    return int(height) * int(width) * 200 + 400 * _MB


def check_pair(height: int, width: int) -> None:
    """Refuse the pair metrics on images of ``height x width`` above the memory limit."""
    require_memory(pair_bytes(height, width), f"computing the pair metrics at {width}x{height}")


# ------------------------------------------------------------------------------------------------ the network


def _network_floats_per_pixel(config: Any) -> float:
    """Activations the network keeps per input pixel (floats): conv and norm outputs of every level, both decoders.

    Counted from the architecture (:class:`platesynth.segment.model.ModelConfig`): 212 for the default network,
    whose measured peaks are about 1000 bytes per pixel and sample while training and 350 while predicting.
    """
    channels = list(config.channels)
    floats = 3.0
    for level, width in enumerate(channels):
        floats += 4 * width / 4**level
        if level:
            floats += channels[level - 1] / 4**level  # max-pooled input
    deepest = len(channels) - 1
    floats += 2 * channels[-1] * len(config.context_dilations) / 4**deepest
    for branch in config.branches.values():
        level = int(round(math.log2(branch.grid)))
        for i in range(deepest - 1, level - 1, -1):
            floats += (channels[i + 1] + (channels[i + 1] + channels[i]) + 2 * channels[i]) / 4**i
        floats += (2 * channels[level] + 2 * (1 + config.n_rays)) / 4**level
    return floats


_TRAIN_BYTES_PER_FLOAT = 8.0
"""Forward activations, their gradients and the optimiser's temporaries: measured about 5 bytes per kept float."""
_PREDICT_BYTES_PER_FLOAT = 3.0
"""Without gradients: measured about 1.7 bytes per kept float (the skips and the largest level live together)."""
_NETWORK_BASE = 500 * _MB


def working_pixels(config: Any, shape: Sequence[int], long_side: int | None = None) -> int:
    """Pixels of the network input for an image of ``shape`` (H, W, ...): resized so that its longest side is
    ``long_side`` (default: the model's working size), padded."""
    scale = (long_side or config.input_long_side) / max(int(shape[0]), int(shape[1]), 1)
    multiple = 2 ** (len(config.channels) - 1)
    rows, cols = (max(1, round(int(s) * scale)) for s in shape[:2])
    return (-(-rows // multiple) * multiple) * (-(-cols // multiple) * multiple)


def prediction_bytes(config: Any, shape: Sequence[int], long_side: int | None = None) -> int:
    """Peak memory of predicting on one image of ``shape`` (H, W, ...): the network with the image's longest side
    at ``long_side`` (default: the working size), and the image, its normalised copy and the masks at the image's
    own size."""
    pixels = int(shape[0]) * int(shape[1])
    network = working_pixels(config, shape, long_side) * _network_floats_per_pixel(config) * _PREDICT_BYTES_PER_FLOAT
    return int(network + 60 * pixels + _NETWORK_BASE)


def check_prediction(config: Any, shape: Sequence[int], name: str = "", long_side: int | None = None) -> None:
    """Refuse a prediction on an image of ``shape`` above the memory limit (the network's input with its longest
    side at ``long_side``, default the working size)."""
    what = f"{name}: prediction" if name else "prediction"
    require_memory(
        prediction_bytes(config, shape, long_side),
        f"{what} on {int(shape[1])}x{int(shape[0])} pixels (working size {long_side or config.input_long_side})",
    )


def training_bytes(
    config: Any, patch: Sequence[int], batch_size: int, source_pixels: int = 0, loaders: int = 1
) -> int:
    """Peak memory of a training step (``batch_size`` patches of ``patch`` = (height, width)), or of validating
    whole images at the working size, whichever is larger, plus the images being read into patches."""
    floats = _network_floats_per_pixel(config)
    step = int(batch_size) * int(patch[0]) * int(patch[1]) * floats * _TRAIN_BYTES_PER_FLOAT
    validation = config.input_long_side**2 * floats * _TRAIN_BYTES_PER_FLOAT / 2
    reading = 40 * int(source_pixels) * max(int(loaders), 1)
    return int(max(step, validation) + reading + _NETWORK_BASE)


def check_training(config: Any, patch: Sequence[int], batch_size: int, source_pixels: int = 0, loaders: int = 1) -> None:
    """Refuse a training whose steps would need more memory than the limit."""
    require_memory(
        training_bytes(config, patch, batch_size, source_pixels, loaders),
        f"training with a batch of {batch_size} patches of {int(patch[0])}x{int(patch[1])} "
        f"(working size {config.input_long_side})",
    )


# ------------------------------------------------------------------------------------------------ torch files


def load_torch_file(path: str | os.PathLike, device: Any = "cpu") -> Any:
    """``torch.load(path, weights_only=True)``: tensors and plain data only, whatever the file holds.

    Raises
    ------
    RefusedFileError
        If the file holds anything else (an object whose unpickling would run code): it is never unpickled.
    Exception
        torch's own errors for a file that is not a torch file (callers turn them into their own message).
    """
    import pickle
    import warnings

    import torch

    with warnings.catch_warnings():  # torch warns about unusual pickle protocols before refusing them
        warnings.simplefilter("ignore")
        try:
            return torch.load(path, map_location=device, weights_only=True)
        except pickle.UnpicklingError as exc:
            text = str(exc)
            detail = text.partition("WeightsUnpickler error:")[2].strip() or text.strip()
            first = (detail.splitlines() or ["unreadable"])[0].strip().rstrip(".")
            first = first.split(" was not an allowed global")[0].replace("Unsupported global: GLOBAL ", "it names ")
            raise RefusedFileError(
                f"{path}: refused, not a file of tensors and plain data only ({first}); platesynth never unpickles "
                "other objects, which could run code"
            ) from None


class RefusedFileError(PlatesynthError):
    """A file holds more than tensors and plain data, so it is not loaded."""


# -------------------------------------------------------------------------------------------------------- YAML


class _ConfigLoader(yaml.SafeLoader):
    """PyYAML's safe loader without anchors and aliases, and with a bounded depth."""

    def __init__(self, stream: Any) -> None:
        super().__init__(stream)
        self._depth = 0

    def compose_node(self, parent: Any, index: Any) -> Any:
        event = self.peek_event()
        if isinstance(event, yaml.AliasEvent):
            raise yaml.composer.ComposerError(
                None, None, f"alias *{event.anchor}: anchors and aliases are not allowed, write the values out", event.start_mark
            )
        if getattr(event, "anchor", None) is not None:
            raise yaml.composer.ComposerError(
                None, None, f"anchor &{event.anchor}: anchors and aliases are not allowed, write the values out", event.start_mark
            )
        self._depth += 1
        try:
            if self._depth > MAX_YAML_DEPTH:
                raise yaml.composer.ComposerError(
                    None, None, f"nested more than {MAX_YAML_DEPTH} levels deep", event.start_mark
                )
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1


def _one_line(exc: BaseException) -> str:
    if isinstance(exc, yaml.MarkedYAMLError):
        mark = exc.problem_mark or exc.context_mark
        where = f"; line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        return f"{exc.problem or exc.context or 'invalid YAML'}{where}"
    text = str(exc).strip().splitlines()
    return text[0] if text else exc.__class__.__name__


def load_yaml(text: str, source: str = "YAML") -> Any:
    """Parse YAML text into plain data (mappings, lists, scalars) without anchors, aliases, tags or deep nesting.

    Raises
    ------
    ResourceLimitError
        If the text is larger than :data:`MAX_YAML_BYTES`.
    yaml.YAMLError
        For invalid YAML, an anchor, an alias or too deep a nesting (callers turn it into their own error).
    """
    if len(text) > MAX_YAML_BYTES:
        raise ResourceLimitError(f"{source}: {len(text):,} characters, more than the {MAX_YAML_BYTES:,} a configuration may have")
    loader = _ConfigLoader(text)
    try:
        return loader.get_single_data()
    except RecursionError:
        raise yaml.YAMLError(f"nested more than {MAX_YAML_DEPTH} levels deep") from None
    finally:
        loader.dispose()


def read_yaml_file(path: str | os.PathLike, error: type[PlatesynthError] = PlatesynthError) -> Any:
    """Read a UTF-8 YAML configuration file with :func:`load_yaml`; every problem is one line of ``error``.

    Raises
    ------
    error
        If the file cannot be read, is larger than :data:`MAX_YAML_BYTES`, is not UTF-8 or not valid YAML, or
        uses anchors or aliases.
    """
    path = Path(path)
    try:
        with open(path, "rb") as stream:
            data = stream.read(MAX_YAML_BYTES + 1)
    except OSError as exc:
        raise error(f"{path}: cannot read ({exc.strerror or exc.__class__.__name__})") from None
    if len(data) > MAX_YAML_BYTES:
        raise ResourceLimitError(f"{path}: larger than the {MAX_YAML_BYTES:,} bytes a configuration file may have")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise error(
            f"{path}: not a UTF-8 text file (byte 0x{data[exc.start]:02x} at position {exc.start}); save it as UTF-8"
        ) from None
    try:
        return load_yaml(text, str(path))
    except yaml.YAMLError as exc:
        raise error(f"{path}: cannot read YAML ({_one_line(exc)})") from None
