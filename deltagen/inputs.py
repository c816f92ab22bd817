"""Checking and normalising array arguments: any real numeric dtype or memory layout in,
C-contiguous float64 out; clear errors for everything else."""

from __future__ import annotations

import numbers

import numpy as np

from deltagen.errors import DeltagenError


class InputError(DeltagenError, ValueError):
    """An argument of the wrong type, shape or value."""


def as_float_array(value, name: str) -> np.ndarray:
    try:
        arr = np.asarray(value)
    except Exception as exc:  # ragged lists, exotic objects
        raise InputError(f"{name} is not an array of numbers: {exc}") from None
    if arr.dtype == object:
        # Lists mixing ints and floats land here: accept real numbers only (no strings,
        # None or bools, which a float conversion would silently turn into numbers).
        for element in arr.flat:
            if isinstance(element, (bool, np.bool_)) or not isinstance(
                element, (numbers.Real, np.number)
            ):
                raise InputError(
                    f"{name} must be numeric, got a non-numeric element {element!r} of type "
                    f"{type(element).__name__}"
                )
        arr = arr.astype(np.float64)
    if arr.dtype.kind == "b" or arr.dtype.kind not in "iuf":
        raise InputError(f"{name} must have a real numeric dtype, got {arr.dtype}")
    if arr.ndim == 0:
        raise InputError(f"{name} must be an array of shape (..., 3 or 4), got () (a scalar)")
    return np.ascontiguousarray(arr, dtype=np.float64)


def as_rows(value, name: str, widths=(3, 4)) -> np.ndarray:
    """(..., w) with w in ``widths`` -> float64 array of the same shape."""
    arr = as_float_array(value, name)
    if arr.ndim == 0 or arr.shape[-1] not in widths:
        allowed = " or ".join(str(w) for w in widths)
        raise InputError(f"{name} must have shape (..., {allowed}), got {arr.shape}")
    return arr


def broadcast_rows(arrays: dict, widths=(3, 4)) -> tuple[tuple, int, list]:
    """Broadcast several (..., w) arrays of one width to common leading dims.

    Returns (leading shape, width, [flattened (N, w) C-contiguous arrays]).
    """
    checked = {name: as_rows(v, name, widths) for name, v in arrays.items()}
    shapes = {name: a.shape for name, a in checked.items()}
    width_set = {a.shape[-1] for a in checked.values()}
    if len(width_set) != 1:
        raise InputError(f"arguments must have the same number of columns, got {shapes}")
    (width,) = width_set
    try:
        lead = np.broadcast_shapes(*(a.shape[:-1] for a in checked.values()))
    except ValueError:
        raise InputError(f"argument shapes do not broadcast: {shapes}") from None
    flat = [
        np.ascontiguousarray(np.broadcast_to(a, lead + (width,)).reshape(-1, width))
        for a in checked.values()
    ]
    return lead, width, flat


def check_errors_mode(errors: str) -> str:
    if errors not in ("raise", "nan"):
        raise InputError(f'errors must be "raise" or "nan", got {errors!r}')
    return errors


def plain_pose(T) -> bool:
    """True for what the single-pose fast paths take: a (4, 4) C-contiguous float64 array
    whose bottom row is exactly 0 0 0 1 (anything else goes the general, checking path)."""
    return (
        type(T) is np.ndarray
        and T.shape == (4, 4)
        and T.dtype.char == "d"
        and T.flags.c_contiguous
        and T[3].tolist() == [0.0, 0.0, 0.0, 1.0]
    )
