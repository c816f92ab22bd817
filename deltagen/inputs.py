"""Checking and normalising array arguments: any real numeric dtype or memory layout in,
C-contiguous float64 out; clear errors for everything else."""

from __future__ import annotations

import numbers

import numpy as np

from deltagen.errors import DeltagenError


class InputError(DeltagenError, ValueError):
    """An argument of the wrong type, shape or value."""


def _holds_bool(value) -> bool:
    """True if a (nested) list/tuple holds a Python or numpy bool anywhere: numpy would turn
    [True, 0.5] into the numbers [1.0, 0.5] without a word, so such lists are refused."""
    for element in value:
        if isinstance(element, (bool, np.bool_)):
            return True
        if isinstance(element, (list, tuple)) and _holds_bool(element):
            return True
    return False


def as_float_array(value, name: str, shape: str = "(..., 3 or 4)") -> np.ndarray:
    """value as a C-contiguous float64 array; ``shape`` words the expected shape for the
    message about a scalar (e.g. "(..., 6)" for a 6-joint arm)."""
    try:
        arr = np.asarray(value)
    except Exception as exc:  # ragged lists, exotic objects
        raise InputError(f"{name} is not an array of numbers: {exc}") from None
    if isinstance(value, (list, tuple)) and arr.dtype.kind in "iuf" and _holds_bool(value):
        raise InputError(f"{name} must be numeric, got a bool element (True/False)")
    if arr.dtype == object:
        # Lists mixing ints and floats land here: accept real numbers only (no strings,
        # None or bools, which a float conversion would silently turn into numbers).
        for element in arr.flat:
            if isinstance(element, (bool, np.bool_)) or not isinstance(
                element, (numbers.Real, np.integer, np.floating)
            ):
                raise InputError(
                    f"{name} must be numeric, got a non-numeric element {element!r} of type "
                    f"{type(element).__name__}"
                )
        try:
            arr = arr.astype(np.float64)
        except (OverflowError, ValueError, TypeError) as exc:  # e.g. an int beyond float range
            raise InputError(f"{name} holds a number that is not a float64: {exc}") from None
    if arr.dtype.kind == "b" or arr.dtype.kind not in "iuf":
        raise InputError(f"{name} must have a real numeric dtype, got {arr.dtype}")
    if arr.ndim == 0:
        raise InputError(f"{name} must be an array of shape {shape}, got () (a scalar)")
    return np.ascontiguousarray(arr, dtype=np.float64)


def as_rows(value, name: str, widths=(3, 4)) -> np.ndarray:
    """(..., w) with w in ``widths`` -> float64 array of the same shape."""
    allowed = " or ".join(str(w) for w in widths)
    arr = as_float_array(value, name, f"(..., {allowed})")
    if arr.ndim == 0 or arr.shape[-1] not in widths:
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
    if not isinstance(errors, str) or errors not in ("raise", "nan"):
        raise InputError(f'errors must be "raise" or "nan", got {errors!r}')
    return errors


def plain_row(value, n: int) -> bool:
    """True for what the single-row fast paths may take without the general checks: a (n,)
    float64 ndarray, or a list/tuple of n Python floats/ints (no bools, no other number
    types). Anything else goes the general path, whose checks (as_float_array) decide; the
    fast paths therefore accept nothing the general path would refuse. Finiteness is left
    to the kernel's status (INVALID sends the call to the general path, which raises)."""
    kind = type(value)
    if kind is np.ndarray:
        return value.shape == (n,) and value.dtype.char == "d"
    if (kind is list or kind is tuple) and len(value) == n:
        for element in value:
            if type(element) is not float and type(element) is not int:
                return False
        return True
    return False
