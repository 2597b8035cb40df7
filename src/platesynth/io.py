"""Reading and writing images and masks, with clear errors and atomic writes."""

from __future__ import annotations

import json
import os
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import tifffile
from PIL import Image, UnidentifiedImageError

from platesynth.errors import EmptyDatasetError, ImageReadError

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp", ".webp")


def read_image(path: str | os.PathLike) -> np.ndarray:
    """Read an image file into a numpy array.

    Parameters
    ----------
    path : str or path-like
        PNG, JPEG, TIFF, BMP or WebP file.

    Returns
    -------
    numpy.ndarray
        ``(H, W)`` grayscale or ``(H, W, C)`` with C in {3, 4}; dtype uint8 or uint16 as stored.

    Raises
    ------
    ImageReadError
        If the file is missing, unreadable, corrupt, empty or not an image.
    """
    path = Path(path)
    if not path.is_file():
        raise ImageReadError(f"{path}: no such file")
    try:
        if path.suffix.lower() in (".tif", ".tiff"):
            array = tifffile.imread(path)
        else:
            with Image.open(path) as img:
                img.load()
                if img.mode in ("P", "PA", "CMYK", "YCbCr", "LAB", "HSV", "1"):
                    img = img.convert("RGBA" if "A" in img.mode or "transparency" in img.info else "RGB")
                elif img.mode == "LA":
                    img = img.convert("RGBA")
                array = np.asarray(img)
    except (OSError, UnidentifiedImageError, ValueError, tifffile.TiffFileError) as exc:
        raise ImageReadError(f"{path}: cannot read image ({exc.__class__.__name__}: {exc})") from None
    if array.ndim == 3 and array.shape[-1] == 1:
        array = array[..., 0]
    if array.size == 0 or array.ndim not in (2, 3) or (array.ndim == 3 and array.shape[-1] not in (3, 4)):
        raise ImageReadError(f"{path}: unsupported image shape {array.shape}")
    if array.dtype == np.int32 and array.min() >= 0 and array.max() <= 65535:  # 16-bit PNGs open as int32
        array = array.astype(np.uint16)
    if array.dtype == bool:
        array = array.astype(np.uint8) * 255
    if array.dtype not in (np.uint8, np.uint16):
        raise ImageReadError(f"{path}: unsupported pixel type {array.dtype} (expected 8- or 16-bit)")
    return array


def to_rgb_uint8(image: np.ndarray) -> np.ndarray:
    """Bring an image to ``(H, W, 3)`` uint8: gray is repeated, alpha dropped, 16-bit scaled by 255/65535."""
    if image.dtype == np.uint16:
        image = np.round(image.astype(np.float64) * (255.0 / 65535.0)).astype(np.uint8)
    elif image.dtype != np.uint8:
        raise ValueError(f"expected uint8 or uint16, got {image.dtype}")
    if image.ndim == 2:
        return np.repeat(image[..., None], 3, axis=-1)
    return image[..., :3]


def list_images(directory: str | os.PathLike) -> list[Path]:
    """Image files directly inside ``directory``, sorted by name.

    Raises
    ------
    EmptyDatasetError
        If ``directory`` does not exist, is not a directory, or holds no image.
    """
    directory = Path(directory)
    if not directory.is_dir():
        raise EmptyDatasetError(f"{directory}: no such directory")
    paths = sorted(p for p in directory.iterdir() if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES)
    if not paths:
        raise EmptyDatasetError(f"{directory}: no images ({', '.join(IMAGE_SUFFIXES)}) found")
    return paths


@contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; rename it onto ``path`` only if the block succeeds."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    # Not mkstemp: the writer creates the file itself, so it gets the user's usual permissions (umask), not 0600.
    tmp = path.with_name(f".{path.stem}.{uuid.uuid4().hex[:12]}.tmp{path.suffix}")
    try:
        yield tmp
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


def write_png(path: str | os.PathLike, image: np.ndarray) -> None:
    """Write an 8- or 16-bit image as PNG, atomically."""
    with atomic_path(path) as tmp:
        Image.fromarray(image).save(tmp, format="PNG")


def write_tiff(path: str | os.PathLike, array: np.ndarray) -> None:
    """Write an array (e.g. an instance mask) as a zlib-compressed TIFF, atomically."""
    with atomic_path(path) as tmp:
        tifffile.imwrite(tmp, array, compression="zlib")


def write_json(path: str | os.PathLike, obj: object) -> None:
    """Write ``obj`` as indented JSON, atomically."""
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(obj, indent=2, sort_keys=False) + "\n")
