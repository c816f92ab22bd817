"""What the compiled cores of the families with a parameter struct share (CompiledDelta,
CompiledTrilateration, CompiledFiveAxis, CompiledHexapod): the generated module loaded
(``build.load``), its struct filled from the family's parameter table and checked
(``manifest.fill_struct``), the kernels' ports from the module's manifest, a batch split
across threads (``parallel.run_batch``) and the one-pose lean path of a kernel
(``lean.single_call``). Every kernel takes ``(geometry, rows, *leading, *inputs, *outputs,
status)``; ``leading`` is the delta's axes count, empty for the others."""

from __future__ import annotations

from typing import Any

from deltagen.native.build import load
from deltagen.native.lean import single_call
from deltagen.native.manifest import (
    fill_struct,
    kernels,
    output_widths,
    point_shape,
    reshape_outputs,
)
from deltagen.native.parallel import run_batch


class CompiledCore:
    """The module ``base_name`` (generated/<base_name>.{c,h,cdef.h,kernels.json}) with C
    prefix ``prefix``, its struct ``struct`` filled from ``table`` (model/parameters.py) for
    ``model``; ``threads`` None: DELTAGEN_THREADS or every core (native.parallel)."""

    def __init__(
        self, base_name: str, prefix: str, struct: str, table: tuple, model: Any, threads=None
    ) -> None:
        self.threads = threads
        module = load(base_name, prefix)
        self._ffi, self._lib = module.ffi, module.lib
        self._kernels: dict[str, dict] = kernels(base_name)  # ports and widths, by kernel
        self._geometry = fill_struct(self._ffi, struct, table, model)

    def _fn(self, name: str) -> Any:
        return getattr(self._lib, self._kernels[name]["function"])

    def _single(self, name: str, rows: list | None = None, leading: tuple = ()) -> Any:
        """The lean function for one pose of kernel ``name`` (native.lean.single_call: None
        from it where the general path must answer); ``rows``: one entry per input (None:
        each input port's width from the manifest)."""
        entry = self._kernels[name]
        if rows is None:
            rows = [port["width"] for port in entry["inputs"]]
        outputs = [(point_shape(port), port["ctype"]) for port in entry["outputs"]]
        return single_call(self._ffi, self._fn(name), (self._geometry, 1, *leading), rows, outputs)

    def _run(self, name: str, inputs: list, axes: int | None = None) -> tuple:
        """(*outputs, status) of kernel ``name`` over the batch, split into row chunks across
        threads (native.parallel); inputs are (N, ...) C-contiguous; the outputs' widths are
        the manifest's (an "axes" port: ``axes``, then passed as the leading argument), a
        matrix output reshaped to (N, rows, columns)."""
        entry = self._kernels[name]
        *outs, status = run_batch(
            self._ffi,
            self._fn(name),
            self._geometry,
            inputs,
            output_widths(entry, axes),
            self.threads,
            leading=() if axes is None else (axes,),
        )
        return (*reshape_outputs(entry, outs), status)
