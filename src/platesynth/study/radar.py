"""Radar charts of the arms, for wells and for plaques (matplotlib, written as SVG and PNG).

Each axis is one metric, scaled across the arms so that the best arm sits at 1 and the worst at
:data:`FLOOR` (lower-is-better metrics reversed); an axis on which all arms are equal puts them all at 1. The axes:
the dataset's size, realism (FD AlexNet, FD of the well crops, dNf) and diversity (size-matched entropy), then the
task's figures (wells: AP and IoU_R; plaques: AP, IoU_R, count MAE and Pearson r). Axes without values are left out;
a chart needs at least three.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

FLOOR = 0.15
"""Where the worst arm of an axis sits (not 0, so that its polygon stays visible)."""
DATASET_AXES = (("datasets", "n_images", "size"), ("datasets", "fd_alexnet", "realism\n(FD)"),
                ("datasets", "fd_wells", "well realism\n(FD wells)"), ("datasets", "dnf", "naturalness\n(dNf)"),
                ("datasets", "entropy_matched", "diversity\n(entropy)"))
AXES = {
    "wells": (*DATASET_AXES, ("wells", "ap_wells_test", "AP wells"), ("wells", "iou_r_wells_test", "IoU_R wells"),
              ("wells", "ap_wells_real", "AP wells\n(real)"), ("wells", "wells_found_real", "wells found\n(real)")),
    "plaques": (*DATASET_AXES, ("plaques", "ap_plaques_test", "AP plaques"),
                ("plaques", "iou_r_plaques_test", "IoU_R plaques"), ("plaques", "ap_plaques_real", "AP plaques\n(real)"),
                ("plaques", "count_mae", "count MAE\n(real)"), ("plaques", "count_r", "count r\n(real)")),
}
MIN_AXES = 3


def radar_data(tables: dict[str, Any], chart: str) -> dict[str, Any]:
    """The scaled values behind a chart: ``{"axes": [labels], "arms": {label: [0..1 per axis]}, "raw": {...}}``.

    Arms without a value on an axis get None there (drawn at 0).
    """
    axes, columns = [], []
    for table_name, key, label in AXES[chart]:
        table = tables.get(table_name)
        column = next((c for c in table["columns"] if c["key"] == key), None) if table else None
        if column is None:
            continue
        values = {row["label"]: row["values"][key]["mean"] for row in table["rows"]}
        if sum(v is not None for v in values.values()) == 0:
            continue
        axes.append(label)
        columns.append((column["better"], values))
    labels = [row["label"] for row in tables["datasets"]["rows"]] if "datasets" in tables else []
    scaled: dict[str, list[float | None]] = {label: [] for label in labels}
    raw: dict[str, list[float | None]] = {label: [] for label in labels}
    for better, values in columns:
        present = [v for v in values.values() if v is not None]
        low, high = min(present), max(present)
        for label in labels:
            value = values.get(label)
            raw[label].append(value)
            if value is None:
                scaled[label].append(None)
            elif high == low:
                scaled[label].append(1.0)
            else:
                share = (value - low) / (high - low)
                share = 1 - share if better == "lower" else share
                scaled[label].append(FLOOR + (1 - FLOOR) * share)
    return {"axes": axes, "arms": scaled, "raw": raw}


def draw_radar(data: dict[str, Any], title: str) -> Any:
    """A matplotlib figure of one radar chart (one closed polygon per arm)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    axes = data["axes"]
    angles = [2 * math.pi * i / len(axes) for i in range(len(axes))]
    figure = plt.figure(figsize=(6.4, 5.6), dpi=100)
    ax = figure.add_subplot(projection="polar")
    ax.set_theta_offset(math.pi / 2)
    ax.set_theta_direction(-1)
    for label, values in data["arms"].items():
        points = [v if v is not None else 0.0 for v in values]
        ax.plot([*angles, angles[0]], [*points, points[0]], linewidth=1.6, label=label)
        ax.fill([*angles, angles[0]], [*points, points[0]], alpha=0.08)
    ax.set_xticks(angles)
    ax.set_xticklabels(axes, fontsize=8)
    ax.set_ylim(0, 1.05)
    ax.set_yticks([0.25, 0.5, 0.75, 1.0])
    ax.set_yticklabels([])
    ax.set_title(title, fontsize=11, pad=18)
    ax.legend(loc="upper right", bbox_to_anchor=(1.32, 1.12), fontsize=8, frameon=False)
    figure.tight_layout()
    return figure


def write_radars(out: str | os.PathLike, tables: dict[str, Any]) -> tuple[list[str], list[str]]:
    """Write ``radar_wells`` and ``radar_plaques`` (``.svg``, ``.png``, and the scaled values as ``.json``).

    Returns
    -------
    written : paths relative to ``out``.
    notes : charts left out and why.
    """
    import matplotlib.pyplot as plt

    from platesynth.io import atomic_path, write_json

    written, notes = [], []
    for chart in AXES:
        data = radar_data(tables, chart)
        if len(data["axes"]) < MIN_AXES:
            notes.append(f"radar_{chart} left out: {len(data['axes'])} axes with values (needs {MIN_AXES})")
            continue
        figure = draw_radar(data, f"{chart}: arms scaled per axis (1 = best)")
        for suffix in ("svg", "png"):
            path = Path(out) / f"radar_{chart}.{suffix}"
            with atomic_path(path) as tmp:
                figure.savefig(tmp, format=suffix, metadata={"Date": None} if suffix == "svg" else None)
            written.append(path.name)
        plt.close(figure)
        write_json(Path(out) / f"radar_{chart}.json", data)
        written.append(f"radar_{chart}.json")
    return written, notes
