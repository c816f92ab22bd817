"""matplotlib, an optional dependency (the ``plot`` extra): the one place that imports it.

``deltagen validate`` and ``deltagen demo`` draw their figures through :func:`pyplot`;
without matplotlib they stop with :data:`HINT` instead of a traceback (the CLI prints a
``DeltagenError`` as one line and exits 2).
"""

from __future__ import annotations

from types import ModuleType

from deltagen.errors import DeltagenError

HINT = "matplotlib is needed for plots: pip install 'deltagen[plot]'"


class PlottingUnavailable(DeltagenError, ImportError):
    """matplotlib is not installed."""


def pyplot() -> ModuleType:
    """``matplotlib.pyplot`` on the file-only Agg backend; PlottingUnavailable if absent."""
    try:
        import matplotlib
    except ImportError as exc:
        raise PlottingUnavailable(HINT) from exc
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt
