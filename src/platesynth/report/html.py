"""One self-contained HTML page for a study, a dataset or an optimisation run.

The page is static and opens offline: every picture is inside it (renders and photos as base64 JPEG, plots as
base64 SVG or PNG), its style is inline, it has no script and names no external address. Mask outlines are shown
on demand by a checkbox (CSS only). What it shows:

- a **study** (:mod:`platesynth.study`): synthetic samples of every rendered arm beside the reference photos, the
  tables, the radar charts, predicted against counted plaques per well (a scatter) and the worst wells with their
  crops (the model's plaques outlined);
- a **dataset** (``platesynth render``): its samples (beside ``reference`` photos where given), what was rendered
  (the manifest) and the plaques per well;
- an **optimisation run** (``platesynth optimise``): the evaluation of start and best on the fit and check photos,
  the best trials, the history and importance plots, the contact sheet.
"""

from __future__ import annotations

import base64
import csv
import html
import io
import json
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from platesynth import __version__
from platesynth.errors import DatasetError, PlatesynthError
from platesynth.outputs import REPORT_GENERATOR, claim_output, file_kind, folder_kind

REPORT_NAME = "report.html"
THUMB_WIDTH = 320
SAMPLES = 6
"""Samples of each rendered set, and real photos, shown."""
JPEG_QUALITY = 85
WELL_OUTLINE = (0, 229, 255)
PLAQUE_OUTLINE = (255, 215, 0)
KINDS = ("study", "dataset", "optimisation")

STYLE = """
body{font-family:system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;margin:0;background:#fafafa;color:#222}
header{background:#263238;color:#fff;padding:14px 24px}header h1{margin:0;font-size:22px}
header p{margin:4px 0 0;color:#cfd8dc;font-size:13px}
main{padding:8px 24px 40px}section{margin:18px 0}h2{font-size:18px;border-bottom:1px solid #ccc;padding-bottom:4px}
h3{font-size:15px;margin:12px 0 6px}
.toggle{position:sticky;top:0;background:#fafafa;padding:8px 0;z-index:1;font-size:14px}
.grid{display:flex;flex-wrap:wrap;gap:8px}
figure{margin:0;background:#fff;border:1px solid #ddd;padding:4px}
figure img{display:block;max-width:320px;height:auto}
figcaption{font-size:12px;color:#555;max-width:320px;overflow-wrap:anywhere}
.outlined{display:none}
#outlines:checked ~ section .outlined{display:block}#outlines:checked ~ section .plain{display:none}
table{border-collapse:collapse;margin:6px 0 14px;font-size:13px;background:#fff}
th,td{border:1px solid #ccc;padding:3px 8px}td.num{text-align:right;font-variant-numeric:tabular-nums}
th{background:#eceff1}caption{text-align:left;font-weight:600;padding:4px 0}
.plot{max-width:100%;height:auto;background:#fff;border:1px solid #ddd}
.note{color:#666;font-size:13px}.crop img{max-width:128px}.crop figcaption{max-width:128px}
"""


# --- pictures -----------------------------------------------------------------------------------------------------


def data_uri(data: bytes, mime: str) -> str:
    """``data:MIME;base64,...``: a picture inside the page."""
    return f"data:{mime};base64,{base64.b64encode(data).decode('ascii')}"


def jpeg_uri(image: np.ndarray, width: int | None = THUMB_WIDTH) -> str:
    """An RGB image, shrunk to ``width`` pixels (never enlarged), as a JPEG data URI."""
    from PIL import Image

    picture = Image.fromarray(np.asarray(image, np.uint8)).convert("RGB")
    if width is not None and picture.width > width:
        picture = picture.resize((width, max(1, round(picture.height * width / picture.width))),
                                 Image.Resampling.LANCZOS)
    buffer = io.BytesIO()
    picture.save(buffer, format="JPEG", quality=JPEG_QUALITY)
    return data_uri(buffer.getvalue(), "image/jpeg")


def file_uri(path: Path) -> str:
    """A PNG, JPEG or SVG file as a data URI."""
    mime = {".png": "image/png", ".jpg": "image/jpeg", ".jpeg": "image/jpeg", ".svg": "image/svg+xml"}[path.suffix.lower()]
    return data_uri(path.read_bytes(), mime)


def figure_uri(figure: Any) -> str:
    """A matplotlib figure as an SVG data URI (the figure is closed)."""
    import matplotlib.pyplot as plt

    buffer = io.BytesIO()
    figure.savefig(buffer, format="svg", metadata={"Date": None})
    plt.close(figure)
    return data_uri(buffer.getvalue(), "image/svg+xml")


def outlined(image: np.ndarray, wells: np.ndarray, plaques: np.ndarray, width: int = THUMB_WIDTH) -> tuple[str, str]:
    """A thumbnail of an image, plain and with its wells and plaques outlined (masks shrunk nearest-neighbour)."""
    from PIL import Image
    from skimage.segmentation import find_boundaries

    height = max(1, round(image.shape[0] * min(1.0, width / image.shape[1])))
    width = min(width, image.shape[1])
    small = np.asarray(Image.fromarray(np.asarray(image, np.uint8)).convert("RGB").resize((width, height),
                                                                                          Image.Resampling.LANCZOS))
    shrink = (np.arange(height) * image.shape[0] // height)[:, None], (np.arange(width) * image.shape[1] // width)[None]
    drawn = small.copy()
    drawn[find_boundaries(wells[shrink], mode="inner")] = WELL_OUTLINE
    drawn[find_boundaries(plaques[shrink], mode="inner")] = PLAQUE_OUTLINE
    return jpeg_uri(small, None), jpeg_uri(drawn, None)


# --- HTML pieces --------------------------------------------------------------------------------------------------


def esc(value: Any) -> str:
    """Text for the page, escaped."""
    return html.escape(str(value), quote=True)


def tile(plain: str, caption: str, outlines: str | None = None) -> str:
    """A figure with a picture (and its outlined version, shown by the checkbox) and a caption."""
    if outlines is None:
        return f'<figure><img src="{plain}" alt="{esc(caption)}"><figcaption>{esc(caption)}</figcaption></figure>'
    return (f'<figure><img class="plain" src="{plain}" alt="{esc(caption)}">'
            f'<img class="outlined" src="{outlines}" alt="{esc(caption)} with mask outlines">'
            f"<figcaption>{esc(caption)}</figcaption></figure>")


def html_table(headers: Sequence[str], rows: Sequence[Sequence[Any]], caption: str | None = None,
               numeric_from: int = 1) -> str:
    """A plain HTML table; cells from column ``numeric_from`` on are right-aligned."""
    head = "".join(f"<th>{esc(h)}</th>" for h in headers)
    body = "".join(
        "<tr>" + "".join(f'<td class="num">{esc(c)}</td>' if i >= numeric_from else f"<td>{esc(c)}</td>"
                         for i, c in enumerate(row)) + "</tr>"
        for row in rows
    )
    title = f"<caption>{esc(caption)}</caption>" if caption else ""
    return f"<table>{title}<thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def _number(value: Any, digits: int = 4) -> str:
    if value is None or value == "":
        return "–"
    if isinstance(value, float):
        return f"{value:.{digits}g}"
    return str(value)


def dataset_samples(dataset: Path, count: int = SAMPLES) -> list[str]:
    """Tiles of a dataset's first images, with their mask outlines on demand."""
    from platesynth.data.layout import list_items, load_item

    tiles = []
    for item in list_items(dataset)[:count]:
        image, wells, plaques = load_item(item)
        plain, drawn = outlined(image, wells, plaques)
        tiles.append(tile(plain, item.image_path.name, drawn))
    return tiles


def photo_samples(folder: Path, count: int = SAMPLES) -> list[str]:
    """Tiles of the first photos of a folder."""
    from platesynth.io import list_images, read_image

    return [tile(jpeg_uri(read_image(path)), path.name) for path in list_images(folder)[:count]]


def page(title: str, subtitle: str, sections: Sequence[str]) -> str:
    """The whole page: head with the generator mark and the style, the outline checkbox (where there are mask
    outlines to show), the sections."""
    toggle = ('<input type="checkbox" id="outlines"><label class="toggle" for="outlines">show mask outlines '
              "(wells cyan, plaques yellow)</label>\n") if any('class="outlined"' in s for s in sections) else ""
    return (
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
        f"{REPORT_GENERATOR}\n<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n"
        f"<title>{esc(title)}</title>\n<style>{STYLE}</style>\n</head>\n<body>\n"
        f"<header><h1>{esc(title)}</h1><p>{esc(subtitle)}</p></header>\n<main>\n{toggle}"
        + "\n".join(sections) + "\n</main>\n</body>\n</html>\n"
    )


def section(title: str, body: str, anchor: str) -> str:
    """A titled section."""
    return f'<section id="{esc(anchor)}"><h2>{esc(title)}</h2>{body}</section>'


# --- a study ------------------------------------------------------------------------------------------------------


def _study_table(table: dict[str, Any]) -> str:
    from platesynth.study.tables import cell

    arrows = {"lower": " ↓", "higher": " ↑"}
    headers = ["arm", "seeds", *(c["header"] + arrows.get(c["better"], "") for c in table["columns"])]
    rows = [[row["label"], len(row["seeds"]), *(cell(row["values"][c["key"]], c["digits"]) for c in table["columns"])]
            for row in table["rows"]]
    return html_table(headers, rows, table["title"])


def _count_rows(directory: Path, results: dict[str, Any]) -> dict[str, list[dict[str, str]]]:
    """Per arm, the per-well tables of its evaluations (every replicate), as read from their ``wells.csv``."""
    from platesynth.study.cache import stage_dir

    rows: dict[str, list[dict[str, str]]] = {}
    for arm in results["arms"]:
        for replicate in arm["replicates"]:
            counts = (replicate.get("evaluate") or {}).get("counts")
            if not counts:
                continue
            path = stage_dir(directory, "evaluate", replicate["keys"]["evaluate"]) / counts["table"]
            if path.is_file():
                with path.open(encoding="utf-8", newline="") as handle:
                    rows.setdefault(arm["label"], []).extend(csv.DictReader(handle))
    return rows


def scatter_uri(rows: dict[str, list[dict[str, str]]]) -> str | None:
    """Predicted against counted plaques per well, one colour per arm, with the diagonal; None without wells."""
    if not any(w.get("count") not in ("", None) for wells in rows.values() for w in wells):
        return None
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, ax = plt.subplots(figsize=(6.0, 5.0), dpi=100)
    top = 1.0
    for label, wells in rows.items():
        scored = [(float(w["count"]), float(w["predicted"])) for w in wells if w.get("count") not in ("", None)]
        if not scored:
            continue
        counted, predicted = zip(*scored)
        top = max(top, *counted, *predicted)
        ax.scatter(counted, predicted, s=14, alpha=0.6, label=f"{label} ({len(scored)} wells)")
    ax.plot([0, top], [0, top], color="#888", linewidth=1, linestyle="--", label="predicted = counted")
    ax.set_xlabel("plaques counted by a person")
    ax.set_ylabel("plaques predicted")
    ax.set_title("plaques per well on the real photos")
    ax.legend(fontsize=8)
    figure.tight_layout()
    return figure_uri(figure)


def training_uri(directory: Path, results: dict[str, Any]) -> str | None:
    """Training and validation loss per epoch of every arm's first replicate; None without any history."""
    from platesynth.study.cache import load_result

    histories = {}
    for arm in results["arms"]:
        stored = load_result(directory, "train", arm["replicates"][0]["keys"]["train"])
        if stored and stored.get("history"):
            histories[arm["label"]] = stored["history"]
    if not histories:
        return None
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, ax = plt.subplots(figsize=(6.4, 3.8), dpi=100)
    for number, (label, history) in enumerate(histories.items()):
        colour = f"C{number % 10}"
        epochs = [h["epoch"] for h in history]
        ax.plot(epochs, [h["train_loss"] for h in history], color=colour, linestyle="--", linewidth=1)
        if any(h.get("val_loss") is not None for h in history):
            ax.plot(epochs, [h.get("val_loss") for h in history], color=colour, marker="o", markersize=3, label=label)
        else:
            ax.plot([], [], color=colour, label=label)
    ax.set_xlabel("epoch")
    ax.set_ylabel("loss (dashed: training, solid: validation)")
    ax.legend(fontsize=8)
    figure.tight_layout()
    return figure_uri(figure)


def _worst_wells(directory: Path, results: dict[str, Any]) -> str:
    from platesynth.study.cache import stage_dir

    parts = []
    for arm in results["arms"]:
        replicate = arm["replicates"][0]
        counts = (replicate.get("evaluate") or {}).get("counts")
        if not counts or not counts.get("worst"):
            continue
        folder = stage_dir(directory, "evaluate", replicate["keys"]["evaluate"])
        tiles = []
        for well in counts["worst"]:
            caption = (f"{well['image']} {well['well']}: counted {well['count']}, predicted {well['predicted']}"
                       + ("" if well.get("detected", True) else " (well not found)"))
            crop = folder / well["crop"] if well.get("crop") else None
            if crop is not None and crop.is_file():
                tiles.append(tile(file_uri(crop), caption).replace("<figure>", '<figure class="crop">', 1))
            else:
                tiles.append(f'<figure class="crop"><figcaption>{esc(caption)}</figcaption></figure>')
        parts.append(f"<h3>{esc(arm['label'])} (seed {replicate['seed']})</h3><div class=\"grid\">{''.join(tiles)}</div>")
    if not parts:
        return '<p class="note">No counts were evaluated (the study names no evaluation.counts).</p>'
    return ('<p class="note">The wells with the largest |predicted − counted|, the model\'s plaques outlined in '
            "yellow.</p>" + "".join(parts))


def study_report(directory: Path) -> tuple[str, str, list[str]]:
    """Title, subtitle and sections of a study's page."""
    from platesynth.study.run import RESULTS_FILE, SETTINGS_FILE
    from platesynth.study.stages import DATA_DIR
    from platesynth.study.tables import TABLE_NAMES, TABLES_DIR

    results_path = directory / RESULTS_FILE
    if not results_path.is_file():
        raise DatasetError(f"{directory}: no {RESULTS_FILE}: the study has not finished a run yet; run platesynth study")
    results = json.loads(results_path.read_text(encoding="utf-8"))
    spec = json.loads((directory / SETTINGS_FILE).read_text(encoding="utf-8")).get("spec", {})
    sections = []
    samples = []
    reference = spec.get("reference")
    if reference and Path(reference).is_dir():
        samples.append(f"<h3>real photos ({esc(reference)})</h3><div class=\"grid\">"
                       f"{''.join(photo_samples(Path(reference)))}</div>")
    for arm in results["arms"]:
        replicate = arm["replicates"][0]
        if arm["kind"] != "rendered" or not replicate.get("render"):
            continue
        from platesynth.study.cache import stage_dir

        dataset = stage_dir(directory, "render", replicate["keys"]["render"]) / DATA_DIR
        samples.append(f"<h3>{esc(arm['label'])} (seed {replicate['seed']}, {esc(arm['preset'] or arm['config'])})</h3>"
                       f"<div class=\"grid\">{''.join(dataset_samples(dataset))}</div>")
    sections.append(section("Samples: synthetic beside real", "".join(samples), "samples"))
    tables = [json.loads((directory / TABLES_DIR / f"{name}.json").read_text(encoding="utf-8"))
              for name in TABLE_NAMES if (directory / TABLES_DIR / f"{name}.json").is_file()]
    sections.append(section("Tables", "".join(_study_table(t) for t in tables)
                            + '<p class="note">Mean ± sd over an arm\'s seeds; ↓ lower is better, ↑ higher.</p>',
                            "tables"))
    charts = [f'<img class="plot" src="{file_uri(directory / name)}" alt="{name}">'
              for name in ("radar_wells.svg", "radar_plaques.svg") if (directory / name).is_file()]
    sections.append(section("Radar charts", "".join(charts) or '<p class="note">No radar chart (too few axes).</p>',
                            "radar"))
    scatter = scatter_uri(_count_rows(directory, results))
    sections.append(section("Plaques per well: predicted against counted",
                            f'<img class="plot" src="{scatter}" alt="scatter of predicted against counted plaques">'
                            if scatter else '<p class="note">No counts evaluated.</p>', "counts"))
    sections.append(section("Worst wells", _worst_wells(directory, results), "worst"))
    timing = []
    for arm in results["arms"]:
        spent = [[r.get("seconds", {}).get(kind) for r in arm["replicates"]] for kind in ("render", "measure", "train",
                                                                                         "evaluate")]
        timing.append([arm["label"], len(arm["replicates"]),
                       *(f"{sum(v for v in values if v is not None):.0f}" if any(v is not None for v in values)
                         else "–" for values in spent)])
    sections.append(section("Time spent (seconds of each stage, summed over seeds)",
                            html_table(["arm", "seeds", "render", "measure", "train", "evaluate"], timing), "time"))
    losses = training_uri(directory, results)
    if losses:
        sections.append(section("Training", f'<img class="plot" src="{losses}" alt="losses per epoch">', "training"))
    notes = sorted({f"{arm['label']}: {note}" for arm in results["arms"] for replicate in arm["replicates"]
                    for stage in ("measure", "evaluate") for note in ((replicate.get(stage) or {}).get("notes") or [])})
    failed = [f"{arm['label']} (seed {r['seed']}): {stage} not done" for arm in results["arms"]
              for r in arm["replicates"] for stage, key in r["keys"].items() if key is not None and r.get(stage) is None]
    if notes or failed:
        items = "".join(f"<li>{esc(line)}</li>" for line in [*failed, *notes])
        sections.append(section("Notes", f"<ul class=\"note\">{items}</ul>", "notes"))
    n_replicates = sum(len(arm["replicates"]) for arm in results["arms"])
    subtitle = (f"{spec.get('description') or 'study'} ({len(results['arms'])} arms, {n_replicates} runs; "
                f"platesynth {results['platesynth_version']})")
    return f"platesynth study {spec.get('name', directory.name)}", subtitle, sections


# --- a dataset ----------------------------------------------------------------------------------------------------


def count_histogram_uri(counts: list[int]) -> str:
    """A histogram of plaques per well."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, ax = plt.subplots(figsize=(6.0, 3.4), dpi=100)
    ax.hist(counts, bins=min(40, max(5, len(set(counts)))), color="#546e7a")
    ax.set_xlabel("plaques per well")
    ax.set_ylabel("wells")
    figure.tight_layout()
    return figure_uri(figure)


def dataset_report(directory: Path, reference: Path | None = None) -> tuple[str, str, list[str]]:
    """Title, subtitle and sections of a rendered dataset's page."""
    from platesynth.data.layout import read_counts_csv, read_manifest

    manifest = read_manifest(directory)
    if manifest is None:
        raise DatasetError(f"{directory}: no manifest.json: not a rendered dataset")
    samples = []
    if reference is not None:
        samples.append(f"<h3>real photos ({esc(reference)})</h3><div class=\"grid\">{''.join(photo_samples(reference))}</div>")
    samples.append(f"<h3>{esc(directory.name)}</h3><div class=\"grid\">{''.join(dataset_samples(directory))}</div>")
    sections = [section("Samples", "".join(samples), "samples")]
    rows = [["preset", manifest.preset or "–"], ["configuration file", manifest.config_file or "–"],
            ["overrides", json.dumps(manifest.overrides) if manifest.overrides else "–"], ["seed", manifest.seed],
            ["images", manifest.count], ["size", f"{manifest.size[0]}x{manifest.size[1]}"],
            ["renderer", json.dumps(manifest.renderer)], ["failed", len(manifest.failed)],
            ["platesynth", manifest.platesynth_version]]
    sections.append(section("What was rendered", html_table(["field", "value"], rows, numeric_from=9), "manifest"))
    counts_path = directory / "counts.csv"
    if counts_path.is_file():
        records = read_counts_csv(counts_path)
        counted = [r.count for r in records if r.count is not None]
        if counted:
            stats = [["wells", len(records)], ["countable wells", len(counted)], ["plaques", sum(counted)],
                     ["mean per countable well", f"{np.mean(counted):.2f}"], ["median", f"{np.median(counted):g}"],
                     ["max", max(counted)], ["wells without plaques", sum(c == 0 for c in counted)]]
            body = html_table(["", "value"], stats) + f'<img class="plot" src="{count_histogram_uri(counted)}" alt="histogram">'
            sections.append(section("Plaques per well", body, "counts"))
    return f"platesynth dataset {directory.name}", f"dataset; platesynth {__version__}", sections


# --- an optimisation run ------------------------------------------------------------------------------------------


def optimisation_report(directory: Path) -> tuple[str, str, list[str]]:
    """Title, subtitle and sections of an optimisation run's page (``platesynth optimise``)."""
    from platesynth.optimise import report as files

    sections = []
    report_path = directory / files.REPORT_JSON
    report = json.loads(report_path.read_text(encoding="utf-8")) if report_path.is_file() else None
    if report is not None:
        parts = [f"<p>best trial {esc(report['best_trial'])} of {esc(report['n_trials'])} "
                 f"({esc(report['n_failed'])} failed), from {esc(report['start'])}; {esc(report['eval_count'])} fresh "
                 "renders per configuration.</p>"]
        for part, table in report.get("evaluation", {}).items():
            terms = sorted({key for row in table.values() for key in row if key not in ("objective", "error")})
            rows = [[name, _number(row.get("objective")), *(_number(row.get(t)) for t in terms)]
                    for name, row in table.items()]
            parts.append(html_table(["configuration", "objective", *terms], rows,
                                    f"{part} photos ({len(report['split'].get(part, []))})"))
        sections.append(section("Evaluation of start and best", "".join(parts), "evaluation"))
    else:
        sections.append(section("Evaluation", '<p class="note">No report.json yet: the run has not finished.</p>',
                                "evaluation"))
    trials_path = directory / files.TRIALS_JSON
    if trials_path.is_file():
        trials = json.loads(trials_path.read_text(encoding="utf-8"))
        finished = sorted((t for t in trials if t.get("objective") is not None), key=lambda t: t["objective"])[:10]
        from platesynth.optimise import TERMS

        terms = [t for t in TERMS if any(row.get(t) is not None for row in finished)]
        rows = [[t["number"], _number(t["objective"]), *(_number(t.get(term)) for term in terms), t.get("state", "")]
                for t in finished]
        sections.append(section(f"Best trials ({len(trials)} in all)",
                                html_table(["trial", "objective", *terms, "state"], rows, numeric_from=0), "trials"))
    plots = [(files.HISTORY_PLOT, "history of the objective"), (files.IMPORTANCE_PLOT, "parameter importances"),
             (files.PARETO_PLOT, "Pareto front"), (files.CONTACT_SHEET, "best renders (top) and check photos")]
    images = [f'<figure><img class="plot" src="{file_uri(directory / name)}" alt="{esc(text)}">'
              f"<figcaption>{esc(text)}</figcaption></figure>" for name, text in plots if (directory / name).is_file()]
    sections.append(section("Optimisation history", "".join(images) or '<p class="note">No plots yet.</p>', "history"))
    return f"platesynth optimisation {directory.name}", f"optimisation run; platesynth {__version__}", sections


# --- the page -----------------------------------------------------------------------------------------------------


def report_kind(directory: str | os.PathLike) -> str:
    """Which report a folder gets: ``study``, ``dataset`` or ``optimisation``.

    Raises
    ------
    DatasetError
        For a missing folder or one that holds none of them.
    """
    directory = Path(directory)
    if not directory.is_dir():
        raise DatasetError(f"{directory}: no such folder")
    kind = folder_kind(directory)
    if kind == "demo":
        kind = "dataset"
    if kind not in KINDS:
        raise DatasetError(f"{directory}: holds no study, rendered dataset or optimisation run to report on")
    return kind


def build_report(directory: str | os.PathLike, reference: str | os.PathLike | None = None) -> str:
    """The HTML page of a study, a dataset or an optimisation run (see the module docstring).

    Parameters
    ----------
    directory : the folder to report on.
    reference : real photos shown beside a dataset's samples (a study names its own).

    Raises
    ------
    DatasetError, EmptyDatasetError, ImageReadError
        For a folder that holds nothing to report on, or unreadable files in it (named).
    """
    from platesynth.study.run import require

    directory = Path(directory)
    kind = report_kind(directory)
    require("matplotlib", "study", "platesynth report")
    try:
        if kind == "study":
            title, subtitle, sections = study_report(directory)
        elif kind == "dataset":
            title, subtitle, sections = dataset_report(directory, Path(reference) if reference else None)
        else:
            title, subtitle, sections = optimisation_report(directory)
    except (ValueError, KeyError, TypeError) as exc:
        if isinstance(exc, PlatesynthError):
            raise
        raise DatasetError(f"{directory}: cannot read its results ({type(exc).__name__}: {exc})") from None
    return page(title, subtitle, sections)


def write_report(directory: str | os.PathLike, out: str | os.PathLike | None = None, *,
                 reference: str | os.PathLike | None = None, overwrite: bool = False) -> Path:
    """Write the page of :func:`build_report` to ``out`` (default ``DIRECTORY/report.html``); returns its path.

    An earlier report at ``out`` is replaced; another existing file is refused unless ``overwrite``.

    Raises
    ------
    OutputError
        Where ``out`` may not be written.
    """
    from platesynth.io import write_text

    directory = Path(directory)
    out = Path(out) if out is not None else directory / REPORT_NAME
    report_kind(directory)
    own = file_kind(out) == "report"  # its own earlier page, also inside the folder it reports on
    claim = claim_output(out, "report", inputs=[reference], overwrite=overwrite or own)
    text = build_report(directory, reference)
    with claim:
        claim.take()
        write_text(out, text)
    return out
