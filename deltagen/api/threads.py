"""The ``threads`` property every robot class with a compiled core shares (DeltaRobot,
SerialRobot, LinearDelta, Tripod, FiveAxisMachine, Hexapod): one copy of its check and its doc."""

from __future__ import annotations

from typing import Any

from deltagen.native.parallel import check_threads


class ThreadsProperty:
    """Mixin: ``threads`` read from ``self._threads`` and, when set, checked and handed to
    ``self._core`` (whose batched calls split their rows across that many threads)."""

    _threads: int | None
    _core: Any

    @property
    def threads(self) -> int | None:
        """Threads a batched call may use (compiled backend; batches of at least 2 x
        native.parallel.MIN_ROWS_PER_THREAD rows are split into row chunks): a positive
        integer, or None for DELTAGEN_THREADS, else every available core. Results do not
        depend on it (bit for bit)."""
        return self._threads

    @threads.setter
    def threads(self, threads: int | None) -> None:
        self._threads = check_threads(threads)
        self._core.threads = self._threads
