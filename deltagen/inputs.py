"""Checking and normalising arguments: any real numeric dtype or memory layout in,
C-contiguous float64 out; clear errors for everything else. Also the checks every stage
shares for a single number (Python or numpy scalars alike, never a bool), for the
environment variables (integers and on/off flags, one message style), and the resource
bounds: a memory budget that large grids and batches are checked against before they are
allocated, and input files read only as regular files of bounded size.

Resource bounds (environment variables, sizes in bytes with an optional K, M, G or T
suffix, 1024-based):

* ``DELTAGEN_MAX_MEMORY``: the memory one deltagen call may plan to allocate (a voxel grid,
  a sweep's design table); default half the memory available when the process starts
  (``MemAvailable`` of /proc/meminfo, else the physical memory), at least 256 MiB.
* ``DELTAGEN_MAX_INPUT``: the largest input file (``--input``, measurements, robot files);
  default 1 GiB or a quarter of ``DELTAGEN_MAX_MEMORY``, the smaller.
"""

from __future__ import annotations

import math
import numbers
import os
import re
import stat
from pathlib import Path

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
    if isinstance(value, np.ma.MaskedArray):
        # np.asarray would drop the mask and compute the masked entries as numbers
        raise InputError(
            f"{name} is a masked array: deltagen does not honour masks; pass "
            f"{name}.filled(np.nan) (masked rows become invalid) or the unmasked rows "
            f"({name}.compressed() or a boolean selection)"
        )
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


# -- single numbers -------------------------------------------------------------------------


def is_real(value) -> bool:
    """A real number: Python int/float or numpy integer/floating scalar, never a bool."""
    return isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))


def is_integer(value) -> bool:
    """An integer: Python int or numpy integer scalar, never a bool."""
    return isinstance(value, numbers.Integral) and not isinstance(value, (bool, np.bool_))


def check_real(
    value,
    name: str,
    *,
    low: float | None = None,
    high: float | None = None,
    low_open: bool = False,
    unit: str = "",
) -> float:
    """``value`` as a finite float in [low, high] (``low_open``: low excluded); InputError
    naming ``name`` otherwise."""
    unit_text = f" [{unit}]" if unit else ""
    if not is_real(value):
        raise InputError(f"{name} must be a real number{unit_text}, got {value!r}")
    number = float(value)
    if not math.isfinite(number):
        raise InputError(f"{name} must be finite{unit_text}, got {value!r}")
    if low is not None and (number < low or (low_open and number == low)):
        relation = ">" if low_open else ">="
        raise InputError(f"{name} must be {relation} {low:g}{unit_text}, got {value!r}")
    if high is not None and number > high:
        raise InputError(f"{name} must be <= {high:g}{unit_text}, got {value!r}")
    return number


def check_integer(value, name: str, *, low: int | None = None, high: int | None = None) -> int:
    """``value`` as an int in [low, high]; InputError naming ``name`` otherwise."""
    if not is_integer(value):
        raise InputError(f"{name} must be an integer, got {value!r}")
    number = int(value)
    if low is not None and number < low:
        raise InputError(f"{name} must be an integer >= {low}, got {value!r}")
    if high is not None and number > high:
        raise InputError(f"{name} must be an integer <= {high}, got {value!r}")
    return number


# -- environment variables ------------------------------------------------------------------

_TRUE = ("1", "true", "yes", "on")
_FALSE = ("0", "false", "no", "off")


def env_positive_int(name: str, meaning: str, unset: str) -> int | None:
    """The positive integer in environment variable ``name``, or None when it is unset or
    empty. InputError for anything else (``meaning``: what the number is; ``unset``: what
    happens without it), e.g. "DELTAGEN_THREADS must be a positive integer (the threads a
    batched call may use), got 'abc'; unset it to use every available core"."""
    text = os.environ.get(name)
    if text is None or text.strip() == "":
        return None
    raw = text.strip()
    value = int(raw, 10) if re.fullmatch(r"\+?[0-9]+", raw) else 0
    if value < 1:
        raise InputError(
            f"{name} must be a positive integer ({meaning}), got {text!r}; unset it to {unset}"
        )
    return value


def env_flag(name: str, default: bool, meaning: str) -> bool:
    """On/off environment variable: 1/true/yes/on or 0/false/no/off (any case, surrounding
    blanks ignored); ``default`` when unset or empty; InputError for anything else."""
    text = os.environ.get(name)
    if text is None or text.strip() == "":
        return default
    word = text.strip().lower()
    if word in _TRUE:
        return True
    if word in _FALSE:
        return False
    raise InputError(
        f"{name} must be one of {', '.join(_TRUE + _FALSE)} (any case; {meaning}), got "
        f"{text!r}; unset it for the default ({'on' if default else 'off'})"
    )


# -- resource bounds ------------------------------------------------------------------------

_SIZE = re.compile(r"\s*([0-9]+(?:\.[0-9]*)?(?:e[0-9]+)?)\s*([kmgt]?)(?:i?b)?\s*", re.IGNORECASE)
_UNITS = {"": 1, "k": 1 << 10, "m": 1 << 20, "g": 1 << 30, "t": 1 << 40}
_MIN_MEMORY = 256 << 20


def size_text(nbytes: float) -> str:
    """A byte count for a message: '7.28 TiB', '512 MiB', '130 B'."""
    value = float(nbytes)
    for unit in ("B", "KiB", "MiB", "GiB", "TiB", "PiB"):
        if value < 1024.0 or unit == "PiB":
            return f"{value:.0f} {unit}" if unit == "B" else f"{value:.3g} {unit}"
        value /= 1024.0
    return f"{value:.3g} EiB"  # pragma: no cover


def _env_size(name: str) -> int | None:
    text = os.environ.get(name)
    if text is None or text.strip() == "":
        return None
    match = _SIZE.fullmatch(text)
    value = float(match.group(1)) * _UNITS[match.group(2).lower()] if match else 0.0
    if not (math.isfinite(value) and value >= 1):
        raise InputError(
            f"{name} must be a size in bytes with an optional K, M, G or T suffix (e.g. 4G), "
            f"got {text!r}; unset it for the default"
        )
    return int(value)


def _available_memory() -> int:
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (AttributeError, OSError, ValueError):
        return 4 << 30


def memory_limit() -> int:
    """Bytes one call may plan to allocate: DELTAGEN_MAX_MEMORY (module docstring), else
    half the available memory (at least 256 MiB)."""
    given = _env_size("DELTAGEN_MAX_MEMORY")
    if given is not None:
        return given
    return max(_available_memory() // 2, _MIN_MEMORY)


def input_limit() -> int:
    """The largest input file [bytes]: DELTAGEN_MAX_INPUT, else min(1 GiB, memory_limit/4)."""
    given = _env_size("DELTAGEN_MAX_INPUT")
    if given is not None:
        return given
    return min(1 << 30, memory_limit() // 4)


def check_memory(nbytes: float, what: str, option: str) -> None:
    """Refuse (InputError) a plan that needs more than memory_limit(): ``what`` is the
    allocation ("a workspace grid of 1.2e10 voxels"), ``option`` the setting that sizes it
    and how to shrink it ("--step / step: a larger voxel edge")."""
    limit = memory_limit()
    if not nbytes <= limit:  # also NaN / inf
        raise InputError(
            f"{what} needs about {size_text(nbytes)} of memory, more than the "
            f"{size_text(limit)} allowed; {option} (or raise DELTAGEN_MAX_MEMORY, now "
            f"{os.environ.get('DELTAGEN_MAX_MEMORY') or 'half the available memory'})"
        )


def read_regular_file(path, what: str = "input file") -> bytes:
    """The bytes of ``path``, a regular file of at most input_limit() bytes; InputError
    naming the path for a directory, a FIFO, a device, a socket, a file that is too large
    or one that cannot be read (never reads an endless stream such as /dev/zero)."""
    path = Path(path)
    limit = input_limit()
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except IsADirectoryError:
        raise InputError(f"{what} {path}: is a directory, not a file") from None
    except OSError as exc:
        raise InputError(f"cannot read {what} {path}: {exc.strerror or exc}") from None
    try:
        info = os.fstat(fd)
        if stat.S_ISDIR(info.st_mode):
            raise InputError(f"{what} {path}: is a directory, not a file")
        if not stat.S_ISREG(info.st_mode):
            kind = (
                "a FIFO (named pipe)"
                if stat.S_ISFIFO(info.st_mode)
                else "a device"
                if stat.S_ISCHR(info.st_mode) or stat.S_ISBLK(info.st_mode)
                else "a socket"
                if stat.S_ISSOCK(info.st_mode)
                else "not a regular file"
            )
            raise InputError(
                f"{what} {path}: is {kind}; deltagen reads regular files only (save the "
                "stream to a file first)"
            )
        if info.st_size > limit:
            raise InputError(
                f"{what} {path}: {size_text(info.st_size)}, larger than the "
                f"{size_text(limit)} allowed (raise DELTAGEN_MAX_INPUT to read it)"
            )
        chunks = []
        total = 0
        while True:
            chunk = os.read(fd, 1 << 20)
            if not chunk:
                break
            total += len(chunk)
            if total > limit:  # the file grew while being read
                raise InputError(
                    f"{what} {path}: larger than the {size_text(limit)} allowed (raise "
                    "DELTAGEN_MAX_INPUT to read it)"
                )
            chunks.append(chunk)
        return b"".join(chunks)
    except OSError as exc:
        raise InputError(f"cannot read {what} {path}: {exc.strerror or exc}") from None
    finally:
        os.close(fd)
