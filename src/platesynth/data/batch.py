"""Rendering a dataset: "render item i of this manifest and write it", over any executor, resumable.

Item ``i`` of a dataset with seed ``S`` has its own seed :func:`item_seed` ``(S, i)``, so any subset of items
can be rendered anywhere, in any order, with identical files.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from platesynth import __version__
from platesynth.data.executor import Executor, SerialExecutor
from platesynth.data.layout import DatasetItem, Manifest, item_name, item_paths, read_params
from platesynth.data.writer import (
    check_directory,
    finished_items,
    prepare_directory,
    write_counts_csv,
    write_item,
    write_manifest,
)
from platesynth.errors import DatasetError, ParameterError, RenderError
from platesynth.outputs import output_lock
from platesynth.render import BACKENDS, render, render_options, renderer_settings
from platesynth.render.result import RenderResult, check_size
from platesynth.scene import Scene, SceneConfig, load_config, sample_scene


def item_seed(seed: int, index: int) -> int:
    """The 63-bit seed of item ``index`` of a dataset with seed ``seed`` (numpy ``SeedSequence`` spawn key)."""
    state = np.random.SeedSequence(seed, spawn_key=(index,)).generate_state(1, np.uint64)[0]
    return int(state >> np.uint64(1))


def build_manifest(
    *,
    preset: str | None = None,
    config_file: str | os.PathLike | None = None,
    overrides: dict[str, Any] | None = None,
    seed: int = 0,
    count: int = 1,
    size: tuple[int, int] = (1024, 768),
    backend: str = "raster",
    samples: int | None = None,
    engine: str | None = None,
    device: str | None = None,
    coco: bool = False,
) -> Manifest:
    """Validate a dataset request and describe it as a :class:`~platesynth.data.layout.Manifest`.

    Parameters
    ----------
    preset, config_file, overrides
        The scene configuration, as for :func:`platesynth.scene.load_config`.
    seed : int
        Dataset seed (>= 0).
    count : int
        Number of images (> 0).
    size : (width, height)
        Image size in pixels.
    backend : str
        Renderer name (see :data:`platesynth.render.BACKENDS`).
    samples, engine, device
        Blender's settings (see :func:`platesynth.render.blender.blender_settings`); where not given, their
        environment variables or defaults. The manifest records them (``renderer``, with the backend and its
        version: Blender's, or platesynth's for the raster renderer) and every item is rendered with them.
    coco : bool
        Also write ``annotations.coco.json``.

    Raises
    ------
    ParameterError
        For a bad count, seed, size, backend or renderer setting, Blender settings for the raster backend, or an
        invalid scene configuration.
    RenderError
        For the Blender backend where bpy is not installed.
    """
    if count <= 0:
        raise ParameterError(f"count must be > 0, got {count}")
    if seed < 0:
        raise ParameterError(f"seed must be >= 0, got {seed}")
    width, height = check_size(size)
    if backend not in BACKENDS:
        raise ParameterError(f"unknown backend {backend!r} (choose from {', '.join(BACKENDS)})")
    given = {"samples": samples, "engine": engine, "device": device}
    options = {key: value for key, value in given.items() if value is not None}
    renderer = renderer_settings(backend, **options)
    config = load_config(preset=preset, path=config_file, overrides=overrides)
    return Manifest(
        platesynth_version=__version__,
        preset=preset,
        config_file=str(config_file) if config_file is not None else None,
        overrides=overrides or {},
        config=config.model_dump(mode="json"),
        seed=seed,
        count=count,
        size=(width, height),
        backend=backend,
        renderer=renderer,
        coco=coco,
    )


def render_item(manifest: Manifest, index: int) -> tuple[RenderResult, dict[str, Any]]:
    """Render item ``index`` of ``manifest``.

    Returns
    -------
    result : RenderResult
    params : dict
        Everything needed to render the image again (see :func:`rerender`): version, seeds, size, backend, the
        renderer's settings (``renderer``; with Blender also ``device_used``, the device that rendered it) and the
        concrete scene.

    Raises
    ------
    RenderError
        Also where this process would render with another renderer than the manifest records (e.g. another
        platesynth or Blender version on a cluster's worker).
    """
    config = SceneConfig.model_validate(manifest.config)
    seed = item_seed(manifest.seed, index)
    scene = sample_scene(config, seed)
    size = tuple(manifest.size)
    options = render_options(manifest.renderer)
    if manifest.renderer and (here := renderer_settings(manifest.backend, **options)) != manifest.renderer:
        keys = {**here, **manifest.renderer}
        differ = ", ".join(f"{k} {here.get(k)!r}" for k in keys if here.get(k) != manifest.renderer.get(k))
        raise RenderError(f"this process would render with {differ}, not as the dataset records: {manifest.renderer}")
    stats: dict[str, Any] = {}
    extra = {"stats": stats} if manifest.backend == "blender" else {}  # Blender reports the device it used
    result = render(scene, size=size, backend=manifest.backend, **options, **extra)
    params = {
        "platesynth_version": __version__,
        "index": index,
        "dataset_seed": manifest.seed,
        "seed": seed,
        "size": list(size),
        "backend": manifest.backend,
        "renderer": manifest.renderer,
        **({"device_used": stats["device"]} if stats.get("device") else {}),
        "scene": scene.model_dump(mode="json"),
    }
    return result, params


def rerender(params: dict[str, Any] | DatasetItem) -> RenderResult:
    """Render an item again from its params (a dict, or a :class:`DatasetItem` whose params file is read).

    With the renderer's recorded settings (``renderer``; params written before they were recorded: the backend's
    defaults). The same image, byte for byte, needs the same renderer version (``renderer["version"]``).
    """
    if isinstance(params, DatasetItem):
        params = read_params(params)
    scene = Scene.model_validate(params["scene"])
    options = render_options(params.get("renderer") or {})
    return render(scene, size=tuple(params["size"]), backend=params["backend"], **options)


MAX_LOG_CHARS = 8000


def describe_failure(exc: Exception) -> str:
    """One line naming the error, followed by the renderer's log (e.g. Blender's, its last part) where it has one."""
    text = f"{type(exc).__name__}: {exc}"
    log = getattr(exc, "log", "") or ""
    if log:
        text += f"\n--- renderer log (last {MAX_LOG_CHARS} characters) ---\n{log[-MAX_LOG_CHARS:]}"
    return text


@dataclass(frozen=True)
class ItemRecord:
    """What a worker reports about one item: its index and name, the error if rendering failed, the time taken."""

    index: int
    name: str
    error: str | None = None
    seconds: float = 0.0


@dataclass(frozen=True)
class RenderTask:
    """Render item ``index`` of ``manifest`` and write it into ``directory`` (picklable; runs on any worker).

    A renderer error is reported in the record, not raised, so that the batch goes on; a write error raises.
    """

    directory: str
    manifest: Manifest

    def __call__(self, index: int) -> ItemRecord:
        start = time.perf_counter()
        name = item_name(index)
        try:
            result, params = render_item(self.manifest, index)
        except Exception as exc:  # noqa: BLE001 -- any renderer failure is recorded and the batch continues
            return ItemRecord(index, name, describe_failure(exc), time.perf_counter() - start)
        try:
            write_item(item_paths(self.directory, name), result, params)
        except OSError as exc:
            where = exc.filename or self.directory
            raise DatasetError(f"{where}: cannot write item {name} ({exc.strerror or exc})") from None
        return ItemRecord(index, name, None, time.perf_counter() - start)


@dataclass
class BatchSummary:
    """The outcome of :func:`render_dataset`."""

    directory: Path
    count: int
    rendered: int = 0
    skipped: int = 0
    failed: dict[str, str] = field(default_factory=dict)
    seconds: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        """A JSON-friendly view."""
        return {
            "directory": str(self.directory),
            "count": self.count,
            "rendered": self.rendered,
            "skipped": self.skipped,
            "failed": self.failed,
            "seconds": round(self.seconds, 3),
        }


def render_dataset(
    directory: str | os.PathLike,
    manifest: Manifest,
    *,
    executor: Executor | None = None,
    overwrite: bool = False,
    progress: Callable[[int, int], None] | None = None,
) -> BatchSummary:
    """Render the dataset ``manifest`` describes into ``directory``, resuming where a previous run stopped.

    Parameters
    ----------
    directory : str or path-like
        Output directory (created). If it holds the same dataset (same identity, see
        :meth:`Manifest.identity`), finished items are skipped and a larger ``count`` extends it.
    manifest : Manifest
        From :func:`build_manifest`.
    executor : optional
        An entered executor (``with ProcessExecutor(4) as ex: ...``); default: this process.
    overwrite : bool
        Replace another dataset found in ``directory`` (only this layout's files are removed).
    progress : callable, optional
        Called as ``progress(done, total)`` once before the first item and after every item.

    Returns
    -------
    BatchSummary
        Items rendered, skipped (already finished) and failed (name -> error; also in ``manifest.json``).

    Raises
    ------
    DatasetError
        If ``directory`` cannot take this dataset (see :func:`platesynth.data.writer.check_directory`) or a
        file cannot be written.
    OutputError
        If another process is writing into ``directory`` (see :func:`platesynth.outputs.output_lock`).
    """
    directory = Path(directory).resolve()
    check_directory(directory, manifest, overwrite)  # refused before anything is created
    directory.mkdir(parents=True, exist_ok=True)
    with output_lock(directory):  # a second run into this folder is refused while this one runs
        return _render_locked(directory, manifest, executor, overwrite, progress)


def _render_locked(
    directory: Path,
    manifest: Manifest,
    executor: Executor | None,
    overwrite: bool,
    progress: Callable[[int, int], None] | None,
) -> BatchSummary:
    started = time.perf_counter()
    manifest, todo = prepare_directory(directory, manifest, overwrite)
    summary = BatchSummary(directory=directory, count=manifest.count, skipped=manifest.count - len(todo))
    if progress is not None:
        progress(summary.skipped, manifest.count)
    if todo:
        task = RenderTask(str(directory), manifest)
        if executor is None:
            with SerialExecutor() as serial:
                _collect(serial.map_unordered(task, todo), summary, progress)
        else:
            _collect(executor.map_unordered(task, todo), summary, progress)
    finished = finished_items(directory, manifest.count)
    write_counts_csv(directory, finished)
    if manifest.coco:
        from platesynth.data.coco import write_coco  # scipy.ndimage: not imported by every worker process

        write_coco(directory, finished)
    summary.failed = dict(sorted(summary.failed.items()))
    write_manifest(directory, manifest.model_copy(update={"failed": summary.failed}))
    summary.seconds = time.perf_counter() - started
    return summary


def _collect(records: Any, summary: BatchSummary, progress: Callable[[int, int], None] | None) -> None:
    for record in records:
        if record.error is None:
            summary.rendered += 1
        else:
            summary.failed[record.name] = record.error
        if progress is not None:
            progress(summary.skipped + summary.rendered + len(summary.failed), summary.count)
