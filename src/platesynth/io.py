"""Reading and writing images and masks, with clear errors and atomic writes."""

from __future__ import annotations

import contextlib
import json
import os
import struct
import uuid
import zlib
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import tifffile
from PIL import Image, UnidentifiedImageError

from platesynth.errors import EmptyDatasetError, ImageReadError
from platesynth.limits import open_image, read_tiff

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
    ResourceLimitError
        If its header claims more pixels, or more memory, than the limits (:mod:`platesynth.limits`).
    """
    path = Path(path)
    if not path.is_file():
        raise ImageReadError(f"{path}: no such file")
    try:
        if path.suffix.lower() in (".tif", ".tiff"):
            array = read_tiff(path)
        else:
            with open_image(path) as img:
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


def read_mask(path: str | os.PathLike, first_channel: bool = False) -> np.ndarray:
    """Read an instance mask (a TIFF of integer ids, as the dataset writer and Blender's compositor write them).

    Parameters
    ----------
    path : str or path-like
        TIFF file.
    first_channel : bool
        Take the first channel of an ``(H, W, C)`` file (Blender writes the ids into every channel of an RGB TIFF).

    Returns
    -------
    numpy.ndarray
        ``(H, W)`` integer array, dtype as stored.

    Raises
    ------
    ImageReadError
        If the file is missing or unreadable, or does not hold a 2-D integer array.
    """
    path = Path(path)
    if not path.is_file():
        raise ImageReadError(f"{path}: no such mask")
    try:
        mask = read_tiff(path)
    except (OSError, ValueError, tifffile.TiffFileError) as exc:
        raise ImageReadError(f"{path}: cannot read mask ({exc.__class__.__name__}: {exc})") from None
    if first_channel and mask.ndim == 3:
        mask = mask[..., 0]
    if mask.ndim != 2 or not np.issubdtype(mask.dtype, np.integer):
        raise ImageReadError(f"{path}: expected a 2-D integer instance mask, got {mask.dtype} {mask.shape}")
    return mask


def image_size(path: str | os.PathLike) -> tuple[int, int]:
    """``(width, height)`` of an image file, from its header (the pixels are not decoded).

    Raises
    ------
    ImageReadError
        If the file is missing or not an image Pillow can open.
    ResourceLimitError
        If the header claims more pixels, or more memory, than the limits (:mod:`platesynth.limits`).
    """
    path = Path(path)
    try:
        with open_image(path) as img:
            return img.size
    except (OSError, UnidentifiedImageError, ValueError) as exc:
        raise ImageReadError(f"{path}: cannot read image ({exc.__class__.__name__}: {exc})") from None


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
    except OSError as exc:
        if exc.errno is None or (exc.filename is not None and Path(exc.filename) not in (tmp, path)):
            raise
        # a full disk, a read-only folder...: name the file being written, not its temporary name
        raise OSError(exc.errno, exc.strerror, str(path)) from None
    finally:
        with contextlib.suppress(OSError):
            tmp.unlink(missing_ok=True)  # a failed write leaves no partial file


PNG_COMPRESS_LEVEL = 6
"""zlib level of :func:`write_png` by default."""
_PNG_COLOUR_TYPES = {1: 0, 3: 2, 4: 6}  # channels -> PNG colour type: gray, RGB, RGBA


def _png_chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def encode_png(
    image: np.ndarray, compress_level: int = PNG_COMPRESS_LEVEL, text: dict[str, str] | None = None
) -> bytes:
    """The PNG file of an 8-bit gray, RGB or RGBA image, every row filtered with PNG's "Up" filter.

    Pillow chooses a filter per row by trying all five, which took longer than compressing: with the one filter
    (the difference to the row above, computed at once by numpy) a 1024x768 render is encoded about twice as fast
    at the same zlib level, its file 2-5 % larger. Lossless like every PNG.

    Parameters
    ----------
    image : (H, W), (H, W, 1), (H, W, 3) or (H, W, 4) uint8.
    compress_level : zlib's level, 0 (none) to 9.
    text : optional ``tEXt`` chunks, keyword -> Latin-1 text (e.g. what wrote the file).
    """
    if image.dtype != np.uint8 or image.ndim not in (2, 3) or (image.ndim == 3 and image.shape[2] not in (1, 3, 4)):
        raise ValueError(f"expected an 8-bit gray, RGB or RGBA image, got {image.dtype} {image.shape}")
    height, width = image.shape[:2]
    channels = 1 if image.ndim == 2 else image.shape[2]
    rows = np.ascontiguousarray(image).reshape(height, width * channels)
    filtered = np.empty((height, width * channels + 1), dtype=np.uint8)
    filtered[:, 0] = 2  # "Up"; above the first row the image is zero, so the first row stays as it is
    filtered[0, 1:] = rows[0]
    np.subtract(rows[1:], rows[:-1], out=filtered[1:, 1:])  # modulo 256, as PNG defines it
    header = struct.pack(">IIBBBBB", width, height, 8, _PNG_COLOUR_TYPES[channels], 0, 0, 0)
    return b"".join(
        (
            b"\x89PNG\r\n\x1a\n",
            _png_chunk(b"IHDR", header),
            *(_png_chunk(b"tEXt", f"{key}\0{value}".encode("latin-1")) for key, value in (text or {}).items()),
            _png_chunk(b"IDAT", zlib.compress(filtered.data, compress_level)),
            _png_chunk(b"IEND", b""),
        )
    )


def write_png(
    path: str | os.PathLike,
    image: np.ndarray,
    compress_level: int = PNG_COMPRESS_LEVEL,
    text: dict[str, str] | None = None,
) -> None:
    """Write an 8- or 16-bit image as PNG, atomically.

    8-bit images are encoded by :func:`encode_png`, others by Pillow. ``compress_level`` is zlib's, 0 (none) to 9;
    every level is lossless: 1 writes a 1024x768 render about four times faster than 6, the file about 10 % larger.
    ``text`` adds ``tEXt`` chunks (keyword -> text).
    """
    with atomic_path(path) as tmp:
        if image.dtype == np.uint8 and (image.ndim == 2 or (image.ndim == 3 and image.shape[2] in (1, 3, 4))):
            tmp.write_bytes(encode_png(image, compress_level, text))
        else:
            from PIL.PngImagePlugin import PngInfo

            info = PngInfo()
            for key, value in (text or {}).items():
                info.add_text(key, value)
            Image.fromarray(image).save(tmp, format="PNG", compress_level=compress_level, pnginfo=info)


def write_tiff(path: str | os.PathLike, array: np.ndarray) -> None:
    """Write an array (e.g. an instance mask) as a zlib-compressed TIFF, atomically."""
    with atomic_path(path) as tmp:
        tifffile.imwrite(tmp, array, compression="zlib")


def write_json(path: str | os.PathLike, obj: object) -> None:
    """Write ``obj`` as indented JSON, atomically."""
    write_text(path, json.dumps(obj, indent=2, sort_keys=False) + "\n")


def write_text(path: str | os.PathLike, text: str) -> None:
    """Write ``text`` as UTF-8, atomically (a temporary file beside ``path``, then a rename)."""
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
