"""Numba's on-disk cache of the raster renderer's kernels, dropped when any of the renderer's sources changes.

Numba keys a cached kernel on its own source file only. The raster renderer's kernels inline functions and constants
of other modules (:mod:`~platesynth.render.appearance`, :mod:`~platesynth.render.sampling`,
:mod:`~platesynth.render.look`, ...), so after an edit of one of those, or a ``git pull`` into an editable install,
numba would load a kernel compiled from the old code and render the old look without a word.
:func:`drop_stale_kernels` keeps a fingerprint of the package's sources beside the cache and empties the cache when
the fingerprint no longer matches; :mod:`platesynth.render` calls it on import, before any kernel runs.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

RENDER_PACKAGE = Path(__file__).resolve().parent
FINGERPRINT_FILE = "platesynth-kernels.sha256"
"""Name of the fingerprint file in the package's ``__pycache__``."""


def sources_fingerprint(package: Path) -> str:
    """SHA-256 over the names and contents of the ``*.py`` files directly in ``package``."""
    digest = hashlib.sha256()
    for path in sorted(package.glob("*.py")):
        digest.update(path.name.encode() + b"\0" + path.read_bytes() + b"\0")
    return digest.hexdigest()


def drop_stale_kernels(package: Path = RENDER_PACKAGE) -> bool:
    """Delete numba's cached kernels (``*.nbi``, ``*.nbc``) in ``package/__pycache__`` if its sources changed.

    Parameters
    ----------
    package : Path
        The package folder whose modules hold the cached kernels (the raster renderer's).

    Returns
    -------
    bool
        Whether cached kernels were deleted. Where the cache cannot be written (a read-only install, whose sources
        do not change), nothing is done and numba keeps its own cache elsewhere.
    """
    cache = package / "__pycache__"
    stamp = cache / FINGERPRINT_FILE
    fingerprint = sources_fingerprint(package)
    try:
        if stamp.read_text() == fingerprint:
            return False
    except OSError:
        pass  # no fingerprint yet: the cache, if any, is of unknown sources
    try:
        stale = [*cache.glob("*.nbi"), *cache.glob("*.nbc")]
        for path in stale:
            path.unlink(missing_ok=True)
        cache.mkdir(exist_ok=True)
        stamp.write_text(fingerprint)
    except OSError:
        return False
    return bool(stale)
