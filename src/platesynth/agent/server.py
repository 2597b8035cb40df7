"""``platesynth mcp``: the MCP server, a thin layer of tools and resources over the library the command line uses.

Tools take typed arguments and return the pydantic models of :mod:`platesynth.schemas` (and the library's own
models: :class:`~platesynth.scene.Scene`, :class:`~platesynth.scene.SceneConfig`,
:class:`~platesynth.segment.model.ModelConfig`), so their JSON schemas are those models' schemas. Guardrails
(:mod:`platesynth.agent.workspace`): every path inside the workspace (or, for reading, a read-only root); limits on
images per job, image size, jobs at once and seconds per job; no tool runs code or shell commands, and nothing is
unpickled (models and checkpoints are read with ``weights_only=True``, :mod:`platesynth.limits`). Errors are tool
errors with one line. Long work (render, train) runs as a job (:mod:`platesynth.agent.jobs`).

Resources: ``platesynth://datasets``, ``platesynth://models`` and ``platesynth://reports`` list what the workspace
holds; ``platesynth://dataset/{path}``, ``platesynth://model/{path}`` and ``platesynth://report/{path}`` describe
one.

This module does not use ``from __future__ import annotations``: the SDK reads the tools' annotations.
"""

import base64
import functools
import json
import logging
import time
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any, Literal

import anyio
import anyio.to_thread
import mcp_types as types
from mcp.server.mcpserver import Context, MCPServer
from mcp.server.mcpserver.exceptions import ResourceError, ToolError, UnexpectedToolError
from pydantic import BaseModel, Field, ValidationError

from platesynth import __version__
from platesynth.agent.jobs import JobList, JobManager, JobStatus, Report
from platesynth.agent.workspace import GuardrailError, Limits, Workspace
from platesynth.cli._common import USER_FACING, error_message
from platesynth.errors import ParameterError, RenderError
from platesynth.scene import Scene, SceneConfig
from platesynth.schemas import (
    Catalogue,
    CountReport,
    DatasetMetrics,
    MaskReport,
    PairMetrics,
    Presets,
    RenderSummary,
    TrainResult,
    dump,
    from_result,
    jsonable,
    train_result,
)
from platesynth.segment.model import ModelConfig

logger = logging.getLogger(__name__)

SERVER_NAME = "platesynth"
INSTRUCTIONS = (
    "platesynth renders annotated synthetic images of multi-well plate assays (plaque assays), measures how real "
    "and diverse they are against real photos, and trains and evaluates a segmentation model on them. Paths are "
    "relative to the workspace. Start with `presets` and `catalogue`, look with `preview`, compare with a real photo "
    "with `compare_images`, render with `render` (a job: poll it with `job_wait`), then `dataset_metrics`, `train` "
    "(a job), `evaluate_masks` and `evaluate_counts`. Every result carries its seed and arguments."
)

# ------------------------------------------------------------------------------------------------ tool arguments

WorkspacePath = Annotated[str, Field(description="a path relative to the workspace ('..' and absolute paths refused)")]
ReadPath = Annotated[
    str, Field(description="a path relative to the workspace, or an absolute path inside a read-only root")
]


def _preset_names() -> Any:
    from platesynth.scene import list_presets

    return Literal[tuple(list_presets())]  # type: ignore[valid-type]


Preset = _preset_names()
"""A shipped preset's name, as an enumeration in the tools' schemas."""
PresetName = Annotated[
    Preset | None, Field(description="a shipped preset's name (tool `presets`); omit it to start from the defaults")
]
ConfigPath = Annotated[
    str | None, Field(description="a YAML scene configuration in the workspace, applied over the preset")
]
Overrides = Annotated[
    dict[str, Any] | None,
    Field(
        description="dotted parameter -> value, applied last, e.g. {'plaques.radius_mm': [0.5, 1.0], "
        "'plate.format': 24}; values as in a configuration file (tool `catalogue`)"
    ),
]
Seed = Annotated[int, Field(ge=0, description="seed: the same seed and parameters give the same image")]
Size = Annotated[
    tuple[int, int], Field(description="image size [width, height] in pixels (limited by the server's --max-image-side)")
]
Backend = Annotated[Literal["raster", "blender"], Field(description="renderer: raster (fast) or blender (Cycles)")]
SaveAs = Annotated[
    str | None,
    Field(description="also write the result as a JSON report (a .json path in the workspace; see platesynth://reports)"),
]
Overwrite = Annotated[
    bool, Field(description="replace another kind of output (or a different dataset or training) at the output path")
]


# -------------------------------------------------------------------------------------------------- tool outputs


class PreviewResult(BaseModel):
    """A contact sheet of sampled scenes (the image itself is the tool's image content)."""

    seed: int
    count: int
    size: tuple[int, int] = Field(description="[width, height] of each scene")
    columns: int
    config_name: str = Field(description="the configuration's name (preset, file or 'custom')")
    item_seeds: list[int] = Field(description="the seed of each scene, in order (tool `sample_scene` draws one again)")
    png_bytes: int
    saved_as: str | None = Field(None, description="where the sheet was written, when asked")


class PredictResult(BaseModel):
    """Predicted masks and plaques per well for a set of images."""

    output: str = Field(description="the prediction folder (dataset layout plus counts.csv)")
    counts_csv: str
    n_images: int
    wells: list[dict[str, Any]] = Field(
        description="counts.csv rows: image, row, col, well, count (null for a well judged uncountable)"
    )


class FileEntry(BaseModel):
    """A file or folder of the workspace."""

    path: str
    type: Literal["file", "folder"]
    kind: str | None = Field(
        None, description="what platesynth wrote there: dataset, demo, prediction, model, optimisation, report"
    )
    bytes: int | None = None


class FileList(BaseModel):
    """The entries of a folder."""

    folder: str
    entries: list[FileEntry]
    truncated: bool = False


class ReadResult(BaseModel):
    """A result file: text files (JSON, CSV, YAML, Markdown, text) as text; images as image content."""

    path: str
    media_type: str
    bytes: int
    text: str | None = None


class SavedReport(BaseModel):
    """The JSON a ``save_as`` report holds: what was computed, with what, by which version."""

    platesynth_report: str = Field(description="the tool that wrote it")
    platesynth_version: str
    arguments: dict[str, Any]
    result: dict[str, Any]


# ------------------------------------------------------------------------------------------------------ the server

_TEXT_TYPES = {".json": "application/json", ".csv": "text/csv", ".yaml": "application/yaml", ".yml": "application/yaml",
               ".md": "text/markdown", ".txt": "text/plain", ".log": "text/plain"}
_IMAGE_TYPES = {".png": "image/png", ".jpg": "image/jpeg", ".jpeg": "image/jpeg"}
_SKIPPED_FOLDERS = {"images", "masks", "params", "__pycache__"}
RESOURCE_KINDS = {"dataset": {"dataset", "prediction"}, "model": {"model"}, "report": {"report", "optimisation"}}
"""What each resource kind lists: folder kinds of :func:`platesynth.outputs.folder_kind`, and saved reports."""


def _one_line(text: str) -> str:
    return " ".join(str(text).split())


def _validation_line(tool: str | None, exc: ValidationError) -> str:
    parts = []
    for error in exc.errors()[:3]:
        where = ".".join(str(p) for p in error["loc"]) or "arguments"
        parts.append(f"{where}: {error['msg']}")
    more = f" (and {exc.error_count() - 3} more)" if exc.error_count() > 3 else ""
    what = f"invalid arguments for {tool}" if tool else "invalid request"
    return f"{what}: {'; '.join(parts)}{more}"


class PlatesynthServer(MCPServer):
    """:class:`MCPServer` whose tool errors are one line, whatever failed (arguments, guardrails, the library)."""

    jobs: JobManager
    workspace: Workspace
    discover_resources: Callable[[], list[tuple[str, str]]]

    async def list_resources(self) -> list[types.Resource]:
        """The index resources, then every dataset, model and report found in the workspace."""
        listed = await super().list_resources()
        for kind, path in await anyio.to_thread.run_sync(self.discover_resources):
            listed.append(types.Resource(uri=f"platesynth://{kind}/{path}", name=f"{kind}: {path}",
                                         mime_type="application/json"))
        return listed

    def _message(self, text: str) -> str:
        """One line, with the workspace's paths relative to it (as the client named them)."""
        return _one_line(text).replace(f"{self.workspace.root}/", "")

    async def call_tool(self, name: str, arguments: dict[str, Any], context: Any = None) -> Any:
        try:
            return await super().call_tool(name, arguments, context)
        except UnexpectedToolError as exc:
            logger.error("tool %s crashed", name, exc_info=exc.__cause__)
            raise UnexpectedToolError(_one_line(f"{name}: internal error ({type(exc.__cause__).__name__})")) from exc
        except ToolError as exc:
            cause = exc.__cause__
            if isinstance(cause, ValidationError):
                raise ToolError(_validation_line(name, cause)) from None
            if isinstance(cause, ToolError):
                raise ToolError(self._message(str(cause))) from None
            raise ToolError(self._message(str(exc))) from None


def _describe(exc: BaseException) -> str:
    if isinstance(exc, USER_FACING):
        return error_message(exc)
    if isinstance(exc, ValidationError):
        return _validation_line(None, exc)
    return f"internal error ({type(exc).__name__}: {exc})"


def _library_errors(fn: Callable[..., Any]) -> Callable[..., Any]:
    """Run a synchronous tool body in a worker thread; turn platesynth's errors into one-line tool errors."""

    @functools.wraps(fn)
    async def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return await anyio.to_thread.run_sync(functools.partial(fn, *args, **kwargs))
        except ToolError:
            raise
        except (*USER_FACING, ValidationError, ValueError) as exc:
            raise ToolError(_one_line(_describe(exc))) from None

    return wrapper


def build_server(workspace: Workspace, limits: Limits | None = None) -> PlatesynthServer:
    """The MCP server over ``workspace`` with ``limits`` (see the module docstring)."""
    limits = limits or Limits()
    server = PlatesynthServer(
        SERVER_NAME, version=__version__, instructions=INSTRUCTIONS, log_level="WARNING",
        warn_on_duplicate_tools=True,
    )
    jobs = JobManager(limits, _describe, workspace.root)
    server.jobs = jobs
    server.workspace = workspace
    tool = server.tool
    read = functools.partial(workspace.resolve, write=False)
    write = functools.partial(workspace.resolve, write=True)

    # ------------------------------------------------------------------------------------------ scene and config

    def scene_config(preset: str | None, config: str | None, overrides: dict[str, Any] | None) -> SceneConfig:
        from platesynth.scene import load_config

        return load_config(preset, read(config, what="config") if config else None, overrides or None)

    def manifest_for(
        preset: str | None, config: str | None, overrides: dict[str, Any] | None, seed: int, count: int,
        size: tuple[int, int], backend: str, coco: bool = False,
    ) -> Any:
        from platesynth.data.batch import build_manifest

        limits.check_images(count, "count")
        limits.check_size(*size, "size")
        return build_manifest(
            preset=preset, config_file=read(config, what="config") if config else None, overrides=overrides or None,
            seed=seed, count=count, size=size, backend=backend, coco=coco,
        )

    @tool(annotations=types.ToolAnnotations(read_only_hint=True))
    @_library_errors
    def presets() -> Presets:
        """The shipped scene presets (high, medium, low, lightbox12, diverse) with one line each."""
        from platesynth.schemas import presets as read_presets

        return read_presets()

    @tool(annotations=types.ToolAnnotations(read_only_hint=True))
    @_library_errors
    def catalogue(section: Annotated[str | None, Field(description="only this section, e.g. 'plaques'")] = None) -> Catalogue:
        """Every scene parameter: dotted name, type, unit, valid range, default and description."""
        from platesynth.schemas import catalogue as read_catalogue

        result = read_catalogue()
        if section is not None:
            rows = [row for row in result.parameters if row.name.split(".")[0] == section]
            if not rows:
                sections = sorted({row.name.split(".")[0] for row in result.parameters})
                raise ParameterError(f"unknown section {section!r}: sections are {', '.join(sections)}")
            result = Catalogue(parameters=rows)
        return result

    @tool(name="scene_config", annotations=types.ToolAnnotations(read_only_hint=True))
    @_library_errors
    def scene_config_tool(preset: PresetName = None, config: ConfigPath = None, overrides: Overrides = None) -> SceneConfig:
        """The full, validated scene configuration (every parameter's configured value or range) of a preset,
        a configuration file and overrides; an invalid value is refused with one line naming it."""
        return scene_config(preset, config, overrides)

    @tool(annotations=types.ToolAnnotations(read_only_hint=True))
    @_library_errors
    def sample_scene(
        seed: Seed = 0, preset: PresetName = None, config: ConfigPath = None, overrides: Overrides = None
    ) -> Scene:
        """Draw one concrete scene (plate, wells, plaques, light, camera) from a configuration and a seed."""
        from platesynth.scene import sample_scene as draw

        return draw(scene_config(preset, config, overrides), seed)

    @tool(annotations=types.ToolAnnotations(read_only_hint=False, destructive_hint=False))
    @_library_errors
    def preview(
        seed: Seed = 0,
        preset: PresetName = None,
        config: ConfigPath = None,
        overrides: Overrides = None,
        count: Annotated[int, Field(ge=1, description="scenes on the sheet")] = 4,
        size: Size = (256, 192),
        columns: Annotated[int, Field(ge=1, description="scenes per row")] = 2,
        outlines: Annotated[bool, Field(description="draw the true well and plaque outlines")] = False,
        backend: Backend = "raster",
        save_as: Annotated[str | None, Field(description="also write the sheet as this .png in the workspace")] = None,
        overwrite: Overwrite = False,
    ) -> Annotated[types.CallToolResult, PreviewResult]:
        """Render a few scenes small and return them tiled as one PNG (image content), to look at a configuration."""
        from platesynth.data.batch import item_seed, render_item
        from platesynth.data.preview import contact_sheet, draw_outlines
        from platesynth.io import encode_png, write_png
        from platesynth.limits import check_render
        from platesynth.outputs import PREVIEW_TEXT_KEY, claim_output

        manifest = manifest_for(preset, config, overrides, seed, count, size, backend)
        target = None
        if save_as is not None:
            target = write(save_as, what="save_as")
            if target.suffix.lower() != ".png":
                raise ParameterError(f"save_as {save_as!r}: the contact sheet is a PNG file; give a name ending in .png")
            claim_output(target, "preview", overwrite=overwrite)
        check_render(manifest.size, manifest.backend, count=count, kept_images=count)
        tiles = []
        for index in range(count):
            result, _ = render_item(manifest, index)
            tiles.append(draw_outlines(result.image, result.wells, result.plaques) if outlines else result.image)
        sheet = contact_sheet(tiles, columns=min(columns, count), tile_width=manifest.size[0])
        text = {PREVIEW_TEXT_KEY: "preview"}
        png = encode_png(sheet, text=text)
        if target is not None:
            write_png(target, sheet, text=text)
        summary = PreviewResult(
            seed=seed, count=count, size=manifest.size, columns=min(columns, count),
            config_name=str(manifest.config.get("name") or "custom"),
            item_seeds=[item_seed(seed, i) for i in range(count)], png_bytes=len(png),
            saved_as=workspace.relative(target) if target is not None else None,
        )
        data = summary.model_dump(mode="json")
        return types.CallToolResult(
            content=[
                types.ImageContent(type="image", data=base64.b64encode(png).decode("ascii"), mime_type="image/png"),
                types.TextContent(type="text", text=json.dumps(data)),
            ],
            structured_content=data,
        )

    # ------------------------------------------------------------------------------------------------ render job

    @tool(annotations=types.ToolAnnotations(read_only_hint=False, destructive_hint=False, idempotent_hint=True))
    @_library_errors
    def render(
        out: Annotated[str, Field(description="dataset folder to write, relative to the workspace")],
        count: Annotated[int, Field(ge=1, description="number of images")],
        seed: Seed = 0,
        preset: PresetName = None,
        config: ConfigPath = None,
        overrides: Overrides = None,
        size: Size = (512, 384),
        backend: Backend = "raster",
        coco: Annotated[bool, Field(description="also write annotations.coco.json")] = False,
        overwrite: Overwrite = False,
        time_limit_seconds: Annotated[
            float | None, Field(gt=0, description="stop the job after this long (at most the server's limit)")
        ] = None,
    ) -> JobStatus:
        """Render an annotated dataset (images, instance masks, params, counts.csv, manifest) as a job: returns the
        job at once; follow it with `job_wait`. Rendering the same request into the same folder resumes it."""
        from platesynth.data.batch import render_dataset
        from platesynth.data.executor import make_executor
        from platesynth.data.writer import check_directory
        from platesynth.limits import check_render
        from platesynth.outputs import claim_output

        target = write(out, what="out")
        config_path = read(config, what="config") if config else None
        manifest = manifest_for(preset, config, overrides, seed, count, size, backend, coco)
        check_render(manifest.size, manifest.backend, count=manifest.count)
        claim = claim_output(
            target, "dataset", inputs=[config_path], overwrite=overwrite,
            check=lambda: check_directory(target, manifest, overwrite),
        )
        arguments = {"out": out, "count": count, "seed": seed, "preset": preset, "config": config,
                     "overrides": overrides or {}, "size": list(size), "backend": backend, "coco": coco}

        def work(report: Report) -> RenderSummary:
            report(0, count, "rendering")
            with claim, make_executor("local", workers=1) as pool:
                claim.take()
                summary = render_dataset(
                    target, manifest, executor=pool, overwrite=overwrite,
                    progress=lambda done, total: report(done, total, f"rendered {done} of {total}"),
                )
            if summary.failed:  # as the command line's exit code 1: a render with failed images is no success
                name, error = next(iter(summary.failed.items()))
                raise RenderError(
                    f"{len(summary.failed)} of {summary.count} images failed to render (first: {name}: "
                    f"{error.splitlines()[0]}); the others are written, and rendering again retries the failed ones"
                )
            result = summary.to_dict()
            result["directory"] = workspace.relative(target)
            return from_result(RenderSummary, result)

        return jobs.start("render", target, workspace.relative(target), arguments, work, time_limit_seconds)

    # ------------------------------------------------------------------------------------------------- optimise

    @tool(annotations=types.ToolAnnotations(read_only_hint=False, destructive_hint=False, idempotent_hint=True))
    @_library_errors
    def optimise(
        reference: Annotated[str, Field(description="a folder of real plate photos (split by plate into fit and check)")],
        out: Annotated[str, Field(description="the optimisation's folder; the same request again resumes it")],
        trials: Annotated[int, Field(ge=1, description="finished trials the study should hold")],
        preset: PresetName = None,
        config: ConfigPath = None,
        overrides: Overrides = None,
        space: Annotated[
            str | None, Field(description="a YAML search space in the workspace (default: the look's parameters)")
        ] = None,
        narrow: Annotated[float | None, Field(gt=0, description="half-width of the default ranges, share of each valid range")] = None,
        seed: Seed = 0,
        count: Annotated[int | None, Field(ge=1, description="images per trial")] = None,
        size: Annotated[tuple[int, int] | None, Field(description="render size [width, height]")] = None,
        compare_size: Annotated[tuple[int, int] | None, Field(description="size renders and photos are measured at")] = None,
        eval_count: Annotated[int | None, Field(ge=1, description="images of the final evaluation")] = None,
        check_fraction: Annotated[float | None, Field(gt=0, lt=1, description="share of the photos kept for checking")] = None,
        weights: Annotated[
            dict[str, float] | None,
            Field(description="weights of the objective's terms (fd_images, fd_wells, dnf, entropy_gap, plaque_sizes, "
                              "plaques_found, fid_inception)"),
        ] = None,
        plaque_model: Annotated[
            str | None,
            Field(description="a model folder (e.g. the shipped models/plaque12) that measures plaque sizes in renders "
                              "and photos alike: adds the plaque_sizes and plaques_found terms"),
        ] = None,
        multi_objective: bool = False,
        compare: Annotated[list[Preset], Field(description="presets also measured in the report")] = [],  # noqa: B006
        overwrite: Overwrite = False,
        time_limit_seconds: Annotated[
            float | None, Field(gt=0, description="stop the job after this long (at most the server's limit)")
        ] = None,
    ) -> JobStatus:
        """Search the scene parameters for renders closer to real photos (Optuna TPE on the realism metrics), as a
        job; the result names the best configuration (best.yaml, usable as `config`) and its metrics on photos
        the search never saw. Needs the AlexNet weights; resumes a stopped run."""
        from platesynth.io import list_images
        from platesynth.optimise import optimise as run_optimise
        from platesynth.optimise.run import COUNT, EVAL_COUNT, SIZE
        from platesynth.outputs import claim_output
        from platesynth.scene.loading import check_preset_name

        target = write(out, what="out")
        photos = read(reference, what="reference")
        config_path = read(config, what="config") if config else None
        space_path = read(space, what="space") if space else None
        model_dir = read(plaque_model, what="plaque_model") if plaque_model else None
        for name in ([preset] if preset else []) + list(compare):
            check_preset_name(name)  # before the first write; the search loads them later
        limits.check_images(len(list_images(photos)), "reference")
        limits.check_images(count or COUNT, "count")
        limits.check_images(eval_count or EVAL_COUNT, "eval_count")
        limits.check_size(*(size or SIZE), "size")
        if compare_size is not None:
            limits.check_size(*compare_size, "compare_size")
        claim_output(target, "optimisation", inputs=[photos, config_path, space_path], overwrite=overwrite)
        given = {"narrow": narrow, "count": count, "size": size, "compare_size": compare_size,
                 "eval_count": eval_count, "check_fraction": check_fraction}
        arguments = {"reference": reference, "out": out, "trials": trials, "preset": preset, "config": config,
                     "overrides": overrides or {}, "space": space, "seed": seed, "weights": weights or {},
                     "plaque_model": plaque_model, "multi_objective": multi_objective, "compare": compare,
                     **{k: list(v) if isinstance(v, tuple) else v for k, v in given.items()}}

        def work(report: Report) -> BaseModel:
            from platesynth.schemas import optimise_summary

            def progress(stage: str, done: int, total: int, best: float | None) -> None:
                best_text = f", best objective {best:.4g}" if best is not None else ""
                report(done, total, f"{stage}: {done} of {total}{best_text}")

            result = run_optimise(
                photos, target, preset=preset, config=config_path, overrides=overrides or None, space=space_path,
                trials=trials, seed=seed, weights=weights, plaque_model=model_dir, multi_objective=multi_objective,
                compare=tuple(compare),
                overwrite=overwrite, progress=progress, **{k: v for k, v in given.items() if v is not None},
            )
            best = workspace.relative(result.best_config) if result.best_config is not None else None
            return optimise_summary(result, workspace.relative(target), best)

        return jobs.start("optimise", target, workspace.relative(target), arguments, work, time_limit_seconds)

    # --------------------------------------------------------------------------------------------------- metrics

    def report_target(save_as: str | None) -> Path | None:
        """Check a ``save_as`` before computing anything."""
        if save_as is None:
            return None
        target = write(save_as, what="save_as")
        if target.suffix.lower() != ".json":
            raise ParameterError(f"save_as {save_as!r}: a report is a JSON file; give a name ending in .json")
        if target.exists():
            try:
                existing = json.loads(target.read_text(encoding="utf-8"))
            except (OSError, ValueError):
                existing = None
            if not (isinstance(existing, dict) and "platesynth_report" in existing):
                raise ParameterError(f"save_as {save_as!r}: exists and is not a platesynth report; choose another name")
        return target

    def save_report(target: Path | None, tool_name: str, arguments: dict[str, Any], result: BaseModel) -> None:
        from platesynth.io import write_json

        if target is None:
            return
        report = SavedReport(platesynth_report=tool_name, platesynth_version=__version__, arguments=arguments,
                             result=dump(result))
        write_json(target, report.model_dump(mode="json"))

    def count_images(path: Path, what: str) -> int:
        from platesynth.data.layout import IMAGES_DIR
        from platesynth.io import list_images

        folder = path / IMAGES_DIR if (path / IMAGES_DIR).is_dir() else path
        if not folder.is_dir():
            return 1
        count = len(list_images(folder))
        limits.check_images(count, what)
        return count

    @tool(annotations=types.ToolAnnotations(read_only_hint=False, destructive_hint=False))
    @_library_errors
    def compare_images(
        real: ReadPath,
        synthetic: ReadPath,
        resize: Annotated[bool, Field(description="resize the synthetic image to the real one if sizes differ")] = False,
        lpips: Annotated[bool, Field(description="LPIPS distance (needs the AlexNet weights)")] = False,
        frechet: Annotated[bool, Field(description="patch Fréchet distances (needs the AlexNet weights)")] = False,
        save_as: SaveAs = None,
    ) -> Annotated[types.CallToolResult, PairMetrics]:
        """Pair metrics of a synthetic image against a real photo: MSE, NRMSE, SSIM, PSNR, naturalness (Nf, dNf),
        optionally LPIPS and patch Fréchet distances. Lower dNf/LPIPS/FD and higher SSIM are closer."""
        from platesynth.metrics import compare_pair

        target = report_target(save_as)
        result = from_result(
            PairMetrics,
            compare_pair(read(real, what="real"), read(synthetic, what="synthetic"), lpips=lpips, frechet=frechet,
                         resize=resize),
        )
        save_report(target, "compare_images", {"real": real, "synthetic": synthetic, "resize": resize,
                                                 "lpips": lpips, "frechet": frechet}, result)
        return _structured(result)

    @tool(annotations=types.ToolAnnotations(read_only_hint=False, destructive_hint=False))
    @_library_errors
    def dataset_metrics(
        directory: Annotated[str, Field(description="a dataset folder, or a folder of images")],
        reference: Annotated[str | None, Field(description="a folder of reference (real) images")] = None,
        size: Annotated[
            tuple[int, int] | None, Field(description="[width, height] for entropy and brightness variability")
        ] = None,
        frechet: Annotated[bool, Field(description="Fréchet and kernel distances (need the AlexNet weights)")] = False,
        wells: Annotated[bool, Field(description="add the well-crop metrics against the reference")] = False,
        well_size: Annotated[int, Field(ge=31, le=512, description="side of the well crops, pixels")] = 128,
        well_grid: Annotated[tuple[int, int], Field(description="[rows, columns] of plates without masks")] = (3, 4),
        model: Annotated[
            str | None, Field(description="with wells: a model whose predicted wells replace the grid for photos")
        ] = None,
        save_as: SaveAs = None,
    ) -> Annotated[types.CallToolResult, DatasetMetrics]:
        """Diversity (pixel entropy, brightness variability) and naturalness of a folder of images; with a reference
        also dNf (and Fréchet/KID); with `wells` the well-crop realism metrics."""
        from platesynth.data.layout import IMAGES_DIR
        from platesynth.metrics import dataset_metrics as compute
        from platesynth.metrics.wells import find_dataset_root, well_metrics

        if wells and reference is None:
            raise ParameterError("wells needs a reference (the real plates to compare the wells with)")
        if model is not None and not wells:
            raise ParameterError("model is used by wells only")
        model_dir = read(model, what="model") if model else None
        folder = read(directory, what="directory")
        reference_path = read(reference, what="reference") if reference else None
        target = report_target(save_as)
        count_images(folder, "directory")
        if reference_path is not None:
            count_images(reference_path, "reference")
        def images_of(path: Path | None) -> Path | None:  # a dataset's images/ folder, else the folder itself
            root = find_dataset_root(path) if path is not None else None
            return root / IMAGES_DIR if root is not None else path

        result = compute(images_of(folder), images_of(reference_path), size=(size[1], size[0]) if size else None,
                         frechet=frechet)
        if wells:
            grid = (int(well_grid[0]), int(well_grid[1]))
            result.update(well_metrics(folder, reference_path, size=well_size, grid=grid, model=model_dir,
                                       frechet=frechet))
        metrics = from_result(DatasetMetrics, result)
        save_report(target, "dataset_metrics", {"directory": directory, "reference": reference,
                                                  "size": list(size) if size else None, "frechet": frechet,
                                                  "wells": wells, "well_size": well_size,
                                                  "well_grid": list(well_grid), "model": model}, metrics)
        return _structured(metrics)

    # ---------------------------------------------------------------------------------------------- segmentation

    @tool(annotations=types.ToolAnnotations(read_only_hint=False, destructive_hint=False, idempotent_hint=True))
    @_library_errors
    def train(
        data: Annotated[list[str], Field(min_length=1, description="dataset folders (platesynth layout) to train on")],
        out: Annotated[str, Field(description="model folder to write; the same request again resumes it")],
        mix: Annotated[list[float] | None, Field(description="sampling fraction per dataset (default: by size)")] = None,
        epochs: Annotated[int, Field(ge=1)] = 20,
        steps_per_epoch: Annotated[int, Field(ge=1)] = 50,
        batch_size: Annotated[int, Field(ge=1)] = 4,
        patch: Annotated[tuple[int, int], Field(description="training patch [height, width] in working pixels")] = (256, 256),
        learning_rate: Annotated[float, Field(gt=0)] = 1e-3,
        val_fraction: Annotated[float, Field(ge=0, lt=1)] = 0.1,
        seed: Seed = 0,
        augment: bool = True,
        tune_thresholds: bool = True,
        network: Annotated[
            ModelConfig | None,
            Field(description="the network: architecture, working size, branches (default: the standard model)"),
        ] = None,
        device: Annotated[Literal["auto", "cpu", "cuda"], Field(description="where to train")] = "auto",
        overwrite: Overwrite = False,
        time_limit_seconds: Annotated[
            float | None, Field(gt=0, description="stop the job after this long (at most the server's limit)")
        ] = None,
    ) -> JobStatus:
        """Train the two-branch segmentation model (wells, plaques) on datasets, as a job: returns the job at once;
        follow it with `job_wait`. A stopped training resumes from its last finished epoch when started again."""
        from platesynth.data.layout import list_items
        from platesynth.outputs import claim_output
        from platesynth.segment.model import select_device
        from platesynth.segment.train import TrainConfig
        from platesynth.segment.train import train as run_training

        target = write(out, what="out")
        folders = [read(name, what="data") for name in data]
        if epochs * steps_per_epoch > limits.max_train_steps:
            raise GuardrailError(
                f"epochs x steps_per_epoch = {epochs * steps_per_epoch} optimiser steps, above the limit of "
                f"{limits.max_train_steps} (the server's --max-train-steps)"
            )
        limits.check_images(sum(len(list_items(folder)) for folder in folders), "data")
        select_device(device)
        config = TrainConfig(
            data=[str(f) for f in folders], mix=mix, epochs=epochs, steps_per_epoch=steps_per_epoch,
            batch_size=batch_size, patch=patch, learning_rate=learning_rate, val_fraction=val_fraction, seed=seed,
            augment=augment, tune_thresholds=tune_thresholds,
        )
        claim = claim_output(target, "model", inputs=folders, overwrite=overwrite)
        total = epochs * steps_per_epoch
        arguments = {"data": data, "out": out, "mix": mix, "epochs": epochs, "steps_per_epoch": steps_per_epoch,
                     "batch_size": batch_size, "patch": list(patch), "learning_rate": learning_rate,
                     "val_fraction": val_fraction, "seed": seed, "augment": augment,
                     "tune_thresholds": tune_thresholds, "device": device,
                     "network": network.model_dump(mode="json") if network else None}

        def work(report: Report) -> TrainResult:
            def progress(event: dict[str, Any]) -> None:
                if "loss" in event:
                    done = (event["epoch"] - 1) * steps_per_epoch + event["step"]
                    report(done, total, f"epoch {event['epoch']}/{epochs}, loss {event['loss']:.4f}")
                else:
                    val = "n/a" if event["val_loss"] is None else f"{event['val_loss']:.4f}"
                    report(event["epoch"] * steps_per_epoch, total,
                           f"epoch {event['epoch']} done: train loss {event['train_loss']:.4f}, validation loss {val}")

            report(0, total, "reading the datasets")
            with claim:
                summary = run_training(config, target, network, overwrite=overwrite, device=device,
                                       progress=progress, before_writing=claim.take)
            result = train_result(summary)
            return result.model_copy(update={"model_dir": workspace.relative(target)})

        return jobs.start("train", target, workspace.relative(target), arguments, work, time_limit_seconds)

    def load_network(model: str, device: str) -> tuple[Any, dict[str, tuple[float, float]], Path]:
        from platesynth.segment.model import load_model, select_device

        model_dir = read(model, what="model")
        network = load_model(model_dir, select_device(device))
        return network, network.config.thresholds, model_dir

    Device = Annotated[Literal["auto", "cpu", "cuda"], Field(description="where to run the model")]

    @tool(annotations=types.ToolAnnotations(read_only_hint=False, destructive_hint=False))
    @_library_errors
    def predict(
        images: Annotated[list[str], Field(min_length=1, description="image files or folders of images")],
        model: Annotated[str, Field(description="a model folder written by `train` (or shipped)")],
        out: Annotated[str, Field(description="prediction folder to write")],
        plate: Annotated[int | None, Field(description="wells per plate (default: the model's)")] = None,
        from_below: Annotated[bool, Field(description="plates photographed through their bottom")] = True,
        device: Device = "auto",
        overwrite: Overwrite = False,
    ) -> PredictResult:
        """Predict well and plaque masks and plaques per well (counts.csv; blank for uncountable wells)."""
        import csv

        from platesynth.io import list_images
        from platesynth.outputs import claim_output
        from platesynth.segment.predict import predict_files

        target = write(out, what="out")
        paths: list[Path] = []
        for name in images:
            path = read(name, what="images")
            paths += list_images(path) if path.is_dir() else [path]
        limits.check_images(len(paths), "images")
        network, thresholds, model_dir = load_network(model, device)
        claim = claim_output(target, "prediction", inputs=[*paths, model_dir], overwrite=overwrite)
        with claim:
            table = predict_files(network, paths, target, thresholds, plate, from_below, before_writing=claim.take)
        with open(table, encoding="utf-8", newline="") as handle:
            rows = [{k: (int(v) if k in ("row", "col", "count") and v != "" else (None if v == "" else v))
                     for k, v in row.items()} for row in csv.DictReader(handle)]
        return PredictResult(output=workspace.relative(target), counts_csv=workspace.relative(table),
                             n_images=len(paths), wells=rows)

    @tool(annotations=types.ToolAnnotations(read_only_hint=False, destructive_hint=False))
    @_library_errors
    def evaluate_masks(
        model: Annotated[str, Field(description="a model folder")],
        data: Annotated[str, Field(description="a dataset with true masks (platesynth layout)")],
        tau: Annotated[list[float], Field(min_length=1, description="IoU thresholds in (0, 1]")] = [0.5],  # noqa: B006
        device: Device = "auto",
        save_as: SaveAs = None,
    ) -> Annotated[types.CallToolResult, MaskReport]:
        """Instance masks against the truth, per class (wells, plaques): AP and IoU_R at each tau, over images."""
        from platesynth.data.layout import list_items
        from platesynth.segment.matching import evaluate_masks as evaluate
        from platesynth.segment.predict import predict_image

        if any(not 0 < t <= 1 for t in tau):
            raise ParameterError(f"tau must be in (0, 1], got {', '.join(map(str, tau))}")
        folder = read(data, what="data")
        target = report_target(save_as)
        limits.check_images(len(list_items(folder)), "data")
        network, thresholds, _ = load_network(model, device)
        predictor = functools.partial(predict_image, network, thresholds=thresholds)
        report = from_result(MaskReport, evaluate(predictor, folder, tuple(tau)))
        save_report(target, "evaluate_masks", {"model": model, "data": data, "tau": tau}, report)
        return _structured(report)

    @tool(annotations=types.ToolAnnotations(read_only_hint=False, destructive_hint=False))
    @_library_errors
    def evaluate_counts(
        model: Annotated[str, Field(description="a model folder")],
        images: Annotated[str, Field(description="the folder holding the images the table names")],
        counts: Annotated[str, Field(description="a CSV table image,row,col,well,count (blank: not counted)")],
        plate: Annotated[int | None, Field(description="wells per plate (default: the model's)")] = None,
        from_below: bool = True,
        device: Device = "auto",
        save_as: SaveAs = None,
    ) -> Annotated[types.CallToolResult, CountReport]:
        """Predicted plaques per well against a person's counts: MAE, RMSE, Pearson r, bias, the training-mean
        baseline, and how well uncountable wells are found."""
        import math

        from platesynth.segment.counts import evaluate_counts as evaluate
        from platesynth.segment.predict import predict_image

        folder = read(images, what="images")
        table = read(counts, what="counts")
        target = report_target(save_as)
        count_images(folder, "images")
        network, thresholds, _ = load_network(model, device)
        plate_format = plate or network.config.plate_format
        predictor = functools.partial(predict_image, network, thresholds=thresholds, plate_format=plate_format,
                                      from_below=from_below)
        baseline = network.config.training.get("mean_plaques_per_well")
        baseline = baseline if isinstance(baseline, (int, float)) and math.isfinite(baseline) else None
        report = from_result(CountReport, evaluate(predictor, folder, table, plate_format, baseline))
        save_report(target, "evaluate_counts", {"model": model, "images": images, "counts": counts,
                                                  "plate": plate, "from_below": from_below}, report)
        return _structured(report)

    # ------------------------------------------------------------------------------------------------------ jobs

    JobId = Annotated[str, Field(description="the id a job-starting tool returned")]

    @tool(annotations=types.ToolAnnotations(read_only_hint=True))
    def job_status(job_id: JobId) -> JobStatus:
        """Where a job stands: state, progress (done of total), the latest message, its result or error."""
        return _guarded(lambda: jobs.get(job_id).status())

    @tool(annotations=types.ToolAnnotations(read_only_hint=True))
    async def job_wait(
        job_id: JobId,
        timeout_seconds: Annotated[float, Field(gt=0, le=600, description="wait at most this long")] = 60.0,
        ctx: Context = None,  # type: ignore[assignment]
    ) -> JobStatus:
        """Wait until a job ends or `timeout_seconds` pass, reporting progress meanwhile; returns its status
        (state still 'running' after a timeout: wait again)."""
        job = _guarded(lambda: jobs.get(job_id))
        deadline = time.monotonic() + timeout_seconds
        last: tuple[int, int | None, str] | None = None
        while not job.finished.is_set() and time.monotonic() < deadline:
            now = (job.done, job.total, job.message)
            if now != last and ctx is not None:
                last = now
                try:
                    await ctx.report_progress(job.done, job.total, job.message)
                except Exception:  # noqa: BLE001 -- a client without progress support still gets the status
                    logger.debug("progress notification failed", exc_info=True)
            await anyio.sleep(min(0.1, max(0.0, deadline - time.monotonic())))
        return job.status()

    @tool(annotations=types.ToolAnnotations(read_only_hint=False, destructive_hint=False))
    async def job_cancel(
        job_id: JobId,
        wait_seconds: Annotated[float, Field(ge=0, le=60, description="wait this long for it to stop")] = 10.0,
    ) -> JobStatus:
        """Cancel a running job at its next image or step; what it wrote is kept and resumable."""
        job = _guarded(lambda: jobs.cancel(job_id))
        deadline = time.monotonic() + wait_seconds
        while not job.finished.is_set() and time.monotonic() < deadline:
            await anyio.sleep(0.05)
        return job.status()

    @tool(name="jobs", annotations=types.ToolAnnotations(read_only_hint=True))
    def list_jobs() -> JobList:
        """Every job of this server session, oldest first."""
        return JobList(jobs=[job.status() for job in jobs.all()])

    # ----------------------------------------------------------------------------------------- files and results

    def kind_of(path: Path) -> str | None:
        from platesynth.outputs import folder_kind

        if path.is_dir():
            kind = folder_kind(path)
            return kind if kind not in (None, "other") else None
        if path.suffix == ".json" and path.stat().st_size < limits.max_read_bytes:
            try:
                data = json.loads(path.read_text(encoding="utf-8"))
            except (OSError, ValueError):
                return None
            return "report" if isinstance(data, dict) and "platesynth_report" in data else None
        return None

    @tool(annotations=types.ToolAnnotations(read_only_hint=True))
    @_library_errors
    def list_files(
        folder: Annotated[str, Field(description="a folder in the workspace (or a read-only root)")] = ".",
        limit: Annotated[int, Field(ge=1, le=1000)] = 200,
    ) -> FileList:
        """The files and folders in a folder, with what platesynth wrote there (dataset, model, prediction, report)."""
        path = read(folder, what="folder") if folder not in ("", ".") else workspace.root
        if not path.is_dir():
            raise GuardrailError(f"{folder}: not a folder")
        children = sorted(p for p in path.iterdir() if not p.name.startswith("."))
        folder_name = workspace.relative(path)
        entries = []
        for child in children[:limit]:
            name = child.name if folder_name == "." else f"{folder_name}/{child.name}"
            try:
                real = read(name, what="folder") if child.is_symlink() else child
                is_dir = real.is_dir()
                entries.append(FileEntry(path=name, type="folder" if is_dir else "file", kind=kind_of(real),
                                         bytes=None if is_dir else real.stat().st_size))
            except (GuardrailError, OSError):
                continue  # a link out of the workspace (or a broken one) is not shown
        return FileList(folder=folder_name, entries=entries, truncated=len(children) > limit)

    @tool(annotations=types.ToolAnnotations(read_only_hint=True))
    @_library_errors
    def read_result(path: ReadPath) -> Annotated[types.CallToolResult, ReadResult]:
        """Read a result file: JSON, CSV, YAML, Markdown or text as text; PNG or JPEG as image content."""
        real = read(path, what="path")
        if not real.is_file():
            raise GuardrailError(f"{path}: no such file")
        suffix = real.suffix.lower()
        media = _TEXT_TYPES.get(suffix) or _IMAGE_TYPES.get(suffix)
        if media is None:
            raise GuardrailError(
                f"{path}: only {', '.join(sorted({*_TEXT_TYPES, *_IMAGE_TYPES}))} files are read (masks are TIFF: "
                "use the metrics and evaluation tools)"
            )
        size = real.stat().st_size
        if size > limits.max_read_bytes:
            raise GuardrailError(f"{path}: {size} bytes, above the limit of {limits.max_read_bytes} (the server's --max-read-bytes)")
        data = real.read_bytes()
        if media.startswith("image/"):
            summary = ReadResult(path=path, media_type=media, bytes=size)
            content: list[Any] = [types.ImageContent(type="image", data=base64.b64encode(data).decode("ascii"),
                                                     mime_type=media)]
        else:
            summary = ReadResult(path=path, media_type=media, bytes=size, text=data.decode("utf-8"))
            content = [types.TextContent(type="text", text=summary.text or "")]
        return types.CallToolResult(content=content, structured_content=summary.model_dump(mode="json"))

    # ------------------------------------------------------------------------------------------------- resources

    def discover(kinds: set[str], depth: int = 3) -> list[Path]:
        found = []

        def walk(folder: Path, level: int) -> None:
            try:
                children = sorted(folder.iterdir())
            except OSError:
                return
            for child in children:
                if child.name.startswith(".") or child.name in _SKIPPED_FOLDERS or child.is_symlink():
                    continue
                kind = kind_of(child)
                if kind in kinds or (kind == "demo" and "dataset" in kinds):
                    found.append(child)
                if child.is_dir() and level < depth and kind is None:
                    walk(child, level + 1)

        walk(workspace.root, 1)
        return found

    def index(kind: str) -> str:
        kinds = RESOURCE_KINDS[kind]
        items = [{"path": workspace.relative(p), "uri": f"platesynth://{kind}/{workspace.relative(p)}",
                  "kind": kind_of(p)} for p in discover(kinds)]
        return json.dumps({f"{kind}s": items}, indent=2)

    def resource_path(path: str, kind: str) -> Path:
        try:
            real = read(path, what=kind)
        except GuardrailError as exc:
            raise ResourceError(_one_line(str(exc))) from None
        found = kind_of(real) if real.exists() else None
        wanted = {*RESOURCE_KINDS[kind], "demo"} if kind == "dataset" else RESOURCE_KINDS[kind]
        if found not in wanted:
            raise ResourceError(f"{path}: not a {kind} in the workspace")
        return real

    @server.resource("platesynth://datasets", mime_type="application/json", description="datasets and predictions in the workspace")
    def datasets_index() -> str:
        return index("dataset")

    @server.resource("platesynth://models", mime_type="application/json", description="model folders in the workspace")
    def models_index() -> str:
        return index("model")

    @server.resource("platesynth://reports", mime_type="application/json",
                     description="saved JSON reports and optimisations in the workspace")
    def reports_index() -> str:
        return index("report")

    @server.resource("platesynth://dataset/{+path}", mime_type="application/json",
                     description="a dataset: its manifest (configuration, seed, size, renderer) and its items")
    def dataset_resource(path: str) -> str:
        from platesynth.data.layout import list_items, read_manifest

        real = resource_path(path, "dataset")
        manifest = read_manifest(real)
        items = list_items(real)
        return json.dumps(jsonable({
            "path": workspace.relative(real), "kind": kind_of(real), "n_items": len(items),
            "items": [item.name for item in items[:200]],
            "counts_csv": "counts.csv" if (real / "counts.csv").is_file() else None,
            "manifest": manifest.model_dump(mode="json") if manifest is not None else None,
        }), indent=2)

    @server.resource("platesynth://model/{+path}", mime_type="application/json",
                     description="a model: its configuration (architecture, thresholds, training), training and history")
    def model_resource(path: str) -> str:
        real = resource_path(path, "model")
        parts: dict[str, Any] = {"path": workspace.relative(real)}
        for name in ("config.json", "train.json", "history.json"):
            file = real / name
            if file.is_file() and file.stat().st_size < limits.max_read_bytes:
                parts[name.removesuffix(".json")] = json.loads(file.read_text(encoding="utf-8"))
        return json.dumps(jsonable(parts), indent=2)

    @server.resource("platesynth://report/{+path}", mime_type="application/json",
                     description="a JSON report written by a tool's save_as, or an optimisation's report.json")
    def report_resource(path: str) -> str:
        real = resource_path(path, "report")
        if real.is_dir():  # an optimisation: its report once written, else its settings
            from platesynth.optimise.report import REPORT_JSON, SETTINGS_FILE

            real = real / REPORT_JSON if (real / REPORT_JSON).is_file() else real / SETTINGS_FILE
        return real.read_text(encoding="utf-8")

    def discover_resources() -> list[tuple[str, str]]:
        return [
            (kind, workspace.relative(path))
            for kind, kinds in RESOURCE_KINDS.items()
            for path in discover(kinds)
        ]

    server.discover_resources = discover_resources
    return server


def _structured(model: BaseModel) -> types.CallToolResult:
    """A tool result holding ``model`` as the command line's ``--json`` prints it (metrics not computed left out)."""
    data = dump(model)
    return types.CallToolResult(content=[types.TextContent(type="text", text=json.dumps(data))], structured_content=data)


def _guarded(fn: Callable[[], Any]) -> Any:
    try:
        return fn()
    except GuardrailError as exc:
        raise ToolError(_one_line(str(exc))) from None


def run(workspace: Workspace, limits: Limits, transport: Literal["stdio", "http"] = "stdio", host: str = "127.0.0.1",
        port: int = 8000) -> None:
    """Serve until the client goes (stdio) or the process is stopped (http); running jobs are cancelled at the end."""
    server = build_server(workspace, limits)
    try:
        if transport == "stdio":
            server.run("stdio")
        else:
            server.run("streamable-http", host=host, port=port)  # type: ignore[call-overload]
    finally:
        server.jobs.shutdown()


