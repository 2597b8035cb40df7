"""The study's tables: datasets (size, realism, diversity), wells and plaques, as Markdown, CSV and JSON.

Each table has one row per arm and one column per metric; an arm with several seeds shows the mean ± the sample
standard deviation over its replicates (the CSV has both, the JSON every replicate's value too). A column no arm
has a value for (e.g. the Inception FID without its weights, AP on real masks without real masks) is left out.
"""

from __future__ import annotations

import csv
import io
import math
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from platesynth.io import write_json, write_text

TABLES_DIR = "tables"
TABLE_NAMES = ("datasets", "wells", "plaques")


def _get(record: dict[str, Any] | None, *path: str) -> float | None:
    """``record[path[0]][path[1]]...`` as a finite float, else None (missing, null, not finite)."""
    value: Any = record
    for part in path:
        if not isinstance(value, dict):
            return None
        if part == "@tau":  # the first threshold evaluated
            part = next(iter(value), "")
        value = value.get(part)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        return None
    return float(value)


def _wells_found(replicate: dict[str, Any]) -> float | None:
    counts = (replicate.get("evaluate") or {}).get("counts")
    if not counts or not counts.get("n_wells"):
        return None
    return 1.0 - counts["n_wells_not_detected"] / counts["n_wells"]


@dataclass(frozen=True)
class Column:
    """A metric column: its key, header, whether lower or higher is better, and how to read it from a replicate."""

    key: str
    header: str
    better: str  # "lower" or "higher" (or "" where neither, e.g. a bias)
    read: Callable[[dict[str, Any]], float | None]
    digits: int = 3


def _at(stage: str, *path: str) -> Callable[[dict[str, Any]], float | None]:
    return lambda replicate: _get(replicate.get(stage), *path)


COLUMNS: dict[str, tuple[Column, ...]] = {
    "datasets": (
        Column("n_images", "images", "higher", _at("measure", "n_images"), 0),
        Column("fd_alexnet", "FD AlexNet", "lower", _at("measure", "fd_alexnet"), 1),
        Column("fid_inception", "FID Inception", "lower", _at("measure", "fid_inception"), 1),
        Column("kid_alexnet", "KID AlexNet", "lower", _at("measure", "kid_alexnet")),
        Column("dnf", "dNf", "lower", _at("measure", "dnf")),
        Column("entropy_matched", "entropy (bits, size-matched)", "higher", _at("measure", "entropy_matched")),
        Column("brightness_variability", "brightness var.", "higher", _at("measure", "brightness_variability"), 1),
        Column("fd_wells", "FD wells", "lower", _at("measure", "fd_wells"), 1),
        Column("dnf_wells", "dNf wells", "lower", _at("measure", "dnf_wells")),
    ),
    "wells": (
        Column("ap_wells_test", "AP wells (test)", "higher", _at("evaluate", "test", "wells", "@tau", "ap_mean")),
        Column("iou_r_wells_test", "IoU_R wells (test)", "higher",
               _at("evaluate", "test", "wells", "@tau", "iou_r_mean")),
        Column("ap_wells_real", "AP wells (real)", "higher",
               _at("evaluate", "real_masks", "wells", "@tau", "ap_mean")),
        Column("iou_r_wells_real", "IoU_R wells (real)", "higher",
               _at("evaluate", "real_masks", "wells", "@tau", "iou_r_mean")),
        Column("wells_found_real", "wells found (real)", "higher", _wells_found),
    ),
    "plaques": (
        Column("count_mae", "count MAE (real)", "lower", _at("evaluate", "counts", "mae"), 2),
        Column("count_rmse", "count RMSE (real)", "lower", _at("evaluate", "counts", "rmse"), 2),
        Column("count_r", "Pearson r (real)", "higher", _at("evaluate", "counts", "pearson_r")),
        Column("count_bias", "bias (real)", "", _at("evaluate", "counts", "bias"), 2),
        Column("ap_plaques_test", "AP plaques (test)", "higher",
               _at("evaluate", "test", "plaques", "@tau", "ap_mean")),
        Column("iou_r_plaques_test", "IoU_R plaques (test)", "higher",
               _at("evaluate", "test", "plaques", "@tau", "iou_r_mean")),
        Column("ap_plaques_real", "AP plaques (real)", "higher",
               _at("evaluate", "real_masks", "plaques", "@tau", "ap_mean")),
        Column("iou_r_plaques_real", "IoU_R plaques (real)", "higher",
               _at("evaluate", "real_masks", "plaques", "@tau", "iou_r_mean")),
    ),
}
"""Every table's possible columns, in order."""

TITLES = {
    "datasets": "Datasets: size, realism against the reference photos, diversity",
    "wells": "Wells: segmentation on the rendered test set (and real masks), wells found on the real photos",
    "plaques": "Plaques: counts per well against a person's on the real photos; segmentation on the test set",
}


def _summary(values: list[float | None]) -> dict[str, Any]:
    present = [v for v in values if v is not None]
    if not present:
        return {"mean": None, "sd": None, "n": 0, "values": values}
    mean = sum(present) / len(present)
    sd = math.sqrt(sum((v - mean) ** 2 for v in present) / (len(present) - 1)) if len(present) > 1 else None
    return {"mean": mean, "sd": sd, "n": len(present), "values": values}


def build_tables(results: dict[str, Any]) -> dict[str, Any]:
    """The three tables from what ``results.json`` holds (:func:`platesynth.study.run.run_study`).

    Returns
    -------
    dict
        ``{name: {"title", "columns": [{"key", "header", "better", "digits"}], "rows": [{"arm", "label", "kind",
        "seeds", "values": {key: {"mean", "sd", "n", "values"}}}]}}``.
    """
    tables = {}
    for name, columns in COLUMNS.items():
        rows = []
        for arm in results["arms"]:
            replicates = arm["replicates"]
            values = {c.key: _summary([c.read(r) for r in replicates]) for c in columns}
            rows.append({"arm": arm["name"], "label": arm["label"], "kind": arm["kind"],
                         "seeds": [r["seed"] for r in replicates], "values": values})
        kept = [c for c in columns if any(row["values"][c.key]["n"] for row in rows)]
        for row in rows:
            row["values"] = {c.key: row["values"][c.key] for c in kept}
        tables[name] = {
            "title": TITLES[name],
            "columns": [{"key": c.key, "header": c.header, "better": c.better, "digits": c.digits} for c in kept],
            "rows": rows,
        }
    return tables


def cell(summary: dict[str, Any], digits: int) -> str:
    """``"12.3 ± 0.4"`` (sd over seeds where there are several), ``"12.3"``, or ``"–"`` without a value."""
    if summary["mean"] is None:
        return "–"
    text = f"{summary['mean']:.{digits}f}"
    if summary["sd"] is not None:
        text += f" ± {summary['sd']:.{digits}f}"
    return text


def _arrow(better: str) -> str:
    return {"lower": " ↓", "higher": " ↑"}.get(better, "")


def to_markdown(table: dict[str, Any]) -> str:
    """A Markdown table (arrows say whether lower or higher is better)."""
    headers = ["arm", "seeds", *(c["header"] + _arrow(c["better"]) for c in table["columns"])]
    lines = [f"**{table['title']}**", "", "| " + " | ".join(headers) + " |",
             "|" + "|".join(["---"] * 2 + ["---:"] * len(table["columns"])) + "|"]
    for row in table["rows"]:
        cells = [row["label"], str(len(row["seeds"])),
                 *(cell(row["values"][c["key"]], c["digits"]) for c in table["columns"])]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def to_csv(table: dict[str, Any]) -> str:
    """CSV: arm, label, seeds, then per metric its mean and ``_sd`` (empty where undefined)."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    keys = [c["key"] for c in table["columns"]]
    writer.writerow(["arm", "label", "seeds", *(name for key in keys for name in (key, f"{key}_sd"))])
    for row in table["rows"]:
        numbers = []
        for key in keys:
            summary = row["values"][key]
            numbers += ["" if summary["mean"] is None else repr(summary["mean"]),
                        "" if summary["sd"] is None else repr(summary["sd"])]
        writer.writerow([row["arm"], row["label"], " ".join(map(str, row["seeds"])), *numbers])
    return buffer.getvalue()


def write_tables(out: str | os.PathLike, tables: dict[str, Any]) -> list[str]:
    """Write every table as ``tables/NAME.md``, ``.csv`` and ``.json`` and all of them as ``tables/tables.md``;
    returns the paths written, relative to ``out``."""
    folder = Path(out) / TABLES_DIR
    written = []
    for name, table in tables.items():
        for suffix, text in (("md", to_markdown(table)), ("csv", to_csv(table))):
            write_text(folder / f"{name}.{suffix}", text)
            written.append(f"{TABLES_DIR}/{name}.{suffix}")
        write_json(folder / f"{name}.json", table)
        written.append(f"{TABLES_DIR}/{name}.json")
    write_text(folder / "tables.md", "\n".join(to_markdown(tables[name]) for name in tables))
    written.append(f"{TABLES_DIR}/tables.md")
    return written
