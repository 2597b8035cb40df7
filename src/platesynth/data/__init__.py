"""Datasets on disk: writing (resumable, atomic, on any executor), reading back, counts and COCO annotations."""

from platesynth.data.batch import (
    BatchSummary,
    ItemRecord,
    build_manifest,
    item_seed,
    render_dataset,
    render_item,
    rerender,
)
from platesynth.data.executor import DaskExecutor, ProcessExecutor, SerialExecutor, make_executor
from platesynth.data.layout import (
    DatasetItem,
    Manifest,
    WellCount,
    list_items,
    load_item,
    read_counts_csv,
    read_manifest,
    read_params,
)

__all__ = [
    "BatchSummary",
    "DaskExecutor",
    "DatasetItem",
    "ItemRecord",
    "Manifest",
    "ProcessExecutor",
    "SerialExecutor",
    "WellCount",
    "build_manifest",
    "item_seed",
    "list_items",
    "load_item",
    "make_executor",
    "read_counts_csv",
    "read_manifest",
    "read_params",
    "render_dataset",
    "render_item",
    "rerender",
]
