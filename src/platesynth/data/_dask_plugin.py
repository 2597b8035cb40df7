"""The Dask worker plugin behind ``DaskExecutor(setup=...)`` (a module of its own: dask is optional)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from distributed import WorkerPlugin


class SetupPlugin(WorkerPlugin):
    """Calls ``setup()`` once on every worker of the cluster, present and future."""

    def __init__(self, setup: Callable[[], None]) -> None:
        self._setup = setup

    def setup(self, worker: Any) -> None:
        self._setup()
