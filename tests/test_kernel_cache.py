"""The raster renderer's numba cache is dropped when any of the renderer's sources changes."""

from __future__ import annotations

from pathlib import Path

from platesynth.render import kernel_cache


def _package(tmp_path: Path) -> Path:
    package = tmp_path / "render"
    (package / "__pycache__").mkdir(parents=True)
    (package / "shading.py").write_text("from appearance import CONSTANT\n")
    (package / "appearance.py").write_text("CONSTANT = 1.0\n")
    return package


def _compile(package: Path) -> list[Path]:
    """Stand-ins for the index and data files numba writes for a cached kernel."""
    cache = package / "__pycache__"
    files = [cache / "shading.shade-12.py311.nbi", cache / "shading.shade-12.py311.1.nbc"]
    for path in files:
        path.write_bytes(b"compiled")
    return files


def test_the_cache_is_kept_while_the_sources_stay_and_dropped_when_another_module_changes(tmp_path):
    package = _package(tmp_path)
    kernels = _compile(package)
    assert kernel_cache.drop_stale_kernels(package)  # no fingerprint yet: a cache of unknown sources goes
    assert not any(path.exists() for path in kernels)
    kernels = _compile(package)
    assert not kernel_cache.drop_stale_kernels(package)
    assert all(path.exists() for path in kernels)
    (package / "appearance.py").write_text("CONSTANT = 2.0\n")  # the kernel's own file is unchanged
    assert kernel_cache.drop_stale_kernels(package)
    assert not any(path.exists() for path in kernels)
    other = package / "__pycache__" / "shading.cpython-311.pyc"
    other.write_bytes(b"bytecode")
    (package / "look.py").write_text("WIDTH = 0.2\n")  # a new module changes the fingerprint too
    _compile(package)
    assert kernel_cache.drop_stale_kernels(package) and other.exists()  # Python's own bytecode stays


def test_the_fingerprint_covers_names_and_contents(tmp_path):
    package = _package(tmp_path)
    before = kernel_cache.sources_fingerprint(package)
    assert before == kernel_cache.sources_fingerprint(package)
    (package / "appearance.py").rename(package / "colours.py")
    assert kernel_cache.sources_fingerprint(package) != before


def test_the_installed_renderer_has_a_current_fingerprint():
    import platesynth.render  # noqa: F401  (its import checks the cache)

    stamp = kernel_cache.RENDER_PACKAGE / "__pycache__" / kernel_cache.FINGERPRINT_FILE
    assert stamp.read_text() == kernel_cache.sources_fingerprint(kernel_cache.RENDER_PACKAGE)
