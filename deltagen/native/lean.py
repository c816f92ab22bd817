"""Lean single-row calls into a generated C kernel: the one helper behind every one-pose /
one-state fast path (native.delta.CompiledDelta.single, native.serial.CompiledArm.single*).

A lean call costs little more than the cffi call itself. Measured with callgrind
(instructions per call, Puma 560 fk; the bare cffi call with its kernel is ~3 300, the
kernel ~1 600): the pieces a call can spend on and what this helper does about them

=============================  ======  ==============================================
piece                          instr.  here
=============================  ======  ==============================================
np.empty + ffi.from_buffer     ~5 000  output written into a per-thread cffi buffer,
  of the output                        then one ``view.copy()`` (~2 300): the fresh array
ffi.memmove of a (n,) input    ~1 700  kept (a list slice assignment is ~3 500, from_buffer
                                       ~2 100)
a threading.local attribute      ~580  one access per call (all buffers in one tuple)
shape / dtype / type checks      ~700  ``type(x) is ndarray``, ``x.dtype is f64``,
                                       ``x.shape == (n,)``; finiteness is the kernel's
                                       status (OK only when every output is finite)
=============================  ======  ==============================================

Only what inputs.plain_row accepts takes the lean path: a (n,) float64 ndarray in native
byte order (a non-contiguous view makes memmove raise: general path) or a list/tuple of n
Python floats/ints. Anything else, and every status other than OK, returns None: the
general path then makes its checks and raises its errors, so both paths refuse the same
input the same way. Same C function on the same numbers as the batch path: the same bits.
The buffers are per thread (cffi releases the GIL during the call).

The CPython-extension entry (native/lean_ext.c). Where it builds, the rows-in,
float64-arrays-out forms (every arm's fk, jacobian, mass_matrix, inverse and forward
dynamics; the delta's fk, ik, their rates, jacobian and dynamics) are served by one C
function per kernel instead of the Python code below: the inputs are read in place
through the numpy C API, the kernel writes into the fresh output array, and the checks
above are made in C with the same outcome (accepted: what plain_row accepts, with any
strides; else None, and the general path raises). Callgrind, instructions per call from
Python (README "Dynamics"): Puma 560 inverse_dynamics through SerialRobot 18 278 on the
cffi path below, 5 314 through the extension (pinocchio's rnea on the UR5: 10 088);
tests/native/test_lean_ext.py guards it. One
extension serves every module: it takes the kernel's address. Where it cannot be built
(no Python.h, no compiler) the Python code below serves, unchanged; DELTAGEN_LEAN_EXT=0
(or false, no, off; any case) chooses it too, and a value that is no such flag is an
InputError (deltagen.inputs.env_flag).

More entries of the extension serve the one-pose inverse kinematics: ``pose_kernel``
(checked_pose_call: ik_all of one pose, the pose's finite/rigid check -- solve/ik.py's
rule -- made in C, answered as the caller's IKSolutions), ``newton_kernel`` (the numeric
solver of one target, solve/numeric.py single_solver), ``regular_kernel`` (the cheap test
of ik's singularity check, solve/ik.py singular_one) and ``ik_one_kernel`` (the three in
one call -- the pose's check, the solve, the test -- for ik's numeric requests of one pose,
solve/ik.py IKPlanner.lean_numeric); ``rigid_pose`` is that check alone (solve/ik.py
rigid_one).
"""

from __future__ import annotations

import threading
from pathlib import Path

import numpy as np

from deltagen import status as st
from deltagen.inputs import env_flag, plain_row
from deltagen.native.build import BuildError, load_extension

_F64 = np.dtype(np.float64)


_EXT_LOCK = threading.Lock()
_EXT: list = []  # [module or None] once tried


def extension():
    """The compiled native/lean_ext.c (its ``kernel`` factory), or None where it cannot be
    built or DELTAGEN_LEAN_EXT=0: the Python lean path serves then. Tried once per
    process."""
    if not env_flag("DELTAGEN_LEAN_EXT", True, "off: the Python lean path, no C extension"):
        return None
    if not _EXT:
        with _EXT_LOCK:
            if not _EXT:
                try:
                    module = load_extension(
                        Path(__file__).with_name("lean_ext.c"), "deltagen_lean_ext"
                    )
                except (BuildError, ImportError):
                    module = None  # no headers or compiler: the Python lean path
                _EXT.append(module)
    return _EXT[0]


def _extension_call(ffi, fn, lead, rows, outputs):
    """The C entry of single_call's function, or None when the extension is missing or
    does not serve this form (a pose, flag outputs, > 64 joints, ...)."""
    module = extension()
    if module is None or not outputs or any(ctype != "double" for _, ctype in outputs):
        return None
    widths = [r for r in rows if r != "scalar"]
    scalar = len(rows) - len(widths)
    if not widths or any(not isinstance(w, int) or w != widths[0] for w in widths):
        return None
    if scalar > 1 or (scalar and rows[-1] != "scalar"):
        return None
    if len(lead) == 1 and lead[0] == 1:
        form, geometry, keep = 0, 0, (ffi, fn)
    elif len(lead) == 3 and lead[1] == 1 and lead[2] == widths[0]:
        form, geometry, keep = 1, int(ffi.cast("uintptr_t", lead[0])), (ffi, fn, lead[0])
    elif len(lead) == 2 and lead[1] == 1:  # a struct without an axes count (native/core.py)
        form, geometry, keep = 2, int(ffi.cast("uintptr_t", lead[0])), (ffi, fn, lead[0])
    else:
        return None
    try:
        return module.kernel(
            int(ffi.cast("uintptr_t", fn)),
            form,
            geometry,
            widths[0],
            len(widths),
            scalar,
            tuple(tuple(int(d) for d in shape) for shape, _ in outputs),
            st.OK,
            keep,
        )
    except ValueError:  # a form the C entry does not serve
        return None


def checked_pose_call(ffi, fn, k, n, answers, tolerances, wrap=None):
    """The extension's one-pose ik_all (lean_ext.c ``pose_kernel``) of the generated
    ``fn(rows, T, q, valid, status)``, or None where the extension is missing: call(T) ->
    wrap((q (k, n), valid (k,) bool)) (the tuple itself when wrap is None) for a (4, 4)
    float64 ndarray that is a finite rigid transform by solve/ik.py's check_one_pose rule
    (``tolerances`` = its (rigid, bottom) tolerances), made in C, and a status in
    ``answers``; else None (the general path checks, raises or marks)."""
    module = extension()
    if module is None:
        return None
    rigid_tol, bottom_tol = tolerances
    return module.pose_kernel(
        int(ffi.cast("uintptr_t", fn)),
        int(k),
        int(n),
        tuple(int(a) for a in answers),
        float(rigid_tol),
        float(bottom_tol),
        wrap,
        (ffi, fn),
    )


def row_putter(memmove, n: int):
    """put(buffer, x): copy one row x of n numbers into a double[] cffi buffer when x is
    what inputs.plain_row(x, n) accepts and return True; else False (the general path,
    whose checks decide, takes the call)."""
    ndarray, f64, shape, nbytes = np.ndarray, _F64, (n,), 8 * n

    def put(buffer, x):
        if type(x) is ndarray:
            if x.dtype is not f64 or x.shape != shape:
                return False
            try:
                memmove(buffer, x, nbytes)
            except (TypeError, ValueError, BufferError):  # not contiguous
                return False
            return True
        if not plain_row(x, n):
            return False
        try:
            buffer[0:n] = x
        except (TypeError, ValueError, OverflowError):  # an int beyond float range
            return False
        return True

    return put


def _put_pose(memmove):
    """put(buffer, T) for a (4, 4) float64 pose in native byte order (C-contiguous:
    memmove raises for other layouts). The caller has checked that T is a finite rigid
    transform (SerialRobot._poses' rule); the kernel reads the same 16 numbers as the
    batch path does."""
    ndarray, f64, shape = np.ndarray, _F64, (4, 4)

    def put(buffer, T):
        if type(T) is not ndarray or T.dtype is not f64 or T.shape != shape:
            return False
        try:
            memmove(buffer, T, 128)
        except (TypeError, ValueError, BufferError):  # not contiguous
            return False
        return True

    return put


class _Buffers(threading.local):
    """Per-thread cffi buffers of one lean function: ``b`` = (inputs, outputs, numpy views
    of the outputs, status), one tuple so that a call reads the thread-local once."""

    def __init__(self, ffi, sizes, outputs, leading):
        ins = tuple(ffi.new(f"double[{size}]") for size in sizes)
        outs = tuple(ffi.new(f"{ctype}[{int(np.prod(shape))}]") for shape, ctype in outputs)
        views = tuple(
            np.frombuffer(
                ffi.buffer(o), dtype=np.bool_ if ctype == "uint8_t" else np.float64
            ).reshape(shape)
            for o, (shape, ctype) in zip(outs, outputs)
        )
        self.b = (ins, outs, views, ffi.new("int8_t[1]"))
        self.b1 = (ins[0], outs[0], views[0], self.b[3])  # one input, one output
        self.b2 = (ins[:leading], ins, outs, views, self.b[3])  # rows before a scalar


def single_call(ffi, fn, lead, rows, outputs):
    """A lean function for one row of the C kernel ``fn(*lead, *inputs, *outputs, status)``.

    lead: the leading C arguments (the delta's (geometry, 1, axes), an arm's (1,));
    rows: one entry per input: an int n (a row of n numbers, inputs.plain_row), "pose"
    (a (4, 4) float64 transform the caller has checked, see _put_pose) or "scalar" (a Python float or int >= 0, e.g.
    a payload [kg]); outputs: one (shape, ctype) per output, ctype "double" or "uint8_t"
    (0/1 flags, returned as bool). Returns call(*args) -> a fresh array (one output) or
    a tuple of them, or None when the general path must answer (see the module doc)."""
    fast = _extension_call(ffi, fn, lead, rows, outputs)
    if fast is not None:
        return fast
    memmove, OK = ffi.memmove, st.OK
    sizes = [16 if r == "pose" else 1 if r == "scalar" else r for r in rows]
    buffers = _Buffers(ffi, sizes, outputs, sum(1 for r in rows if r != "scalar"))
    ndarray, f64 = np.ndarray, _F64

    # The common cases are written out below (the leading arguments: an arm's (1,), the
    # delta's (geometry, 1, axes)); where the extension is built it serves them instead.
    if len(rows) == 1 and len(outputs) == 1 and rows[0] not in ("scalar", "pose"):
        # fk, ik, jacobian, mass_matrix, ...
        n = rows[0]
        shape_in, nbytes = (n,), 8 * n
        put = row_putter(memmove, n)

        def one(q):
            x, o, view, status = buffers.b1
            if type(q) is ndarray and q.dtype is f64 and q.shape == shape_in:
                try:
                    memmove(x, q, nbytes)
                except (TypeError, ValueError, BufferError):
                    return None
            elif not put(x, q):
                return None
            fn(*lead, x, o, status)
            return view.copy() if status[0] == OK else None

        return one

    if rows == ["pose"] and len(outputs) == 2:  # ik_all: q and the valid flags
        put_pose = _put_pose(memmove)

        def pose_pair(T):
            (x,), (o1, o2), (v1, v2), status = buffers.b
            if not put_pose(x, T):
                return None
            fn(*lead, x, o1, o2, status)
            return (v1.copy(), v2.copy()) if status[0] == OK else None

        return pose_pair

    if len(lead) == 1 and len(outputs) == 1 and len(set(rows)) == 1 and len(rows) == 3:
        # one-state dynamics of an arm (inverse_dynamics, forward_dynamics), written out
        n = rows[0]
        shape_in, nbytes = (n,), 8 * n
        put = row_putter(memmove, n)

        def three(a, b, c):
            (xa, xb, xc), (o,), (view,), status = buffers.b
            if (
                type(a) is ndarray
                and type(b) is ndarray
                and type(c) is ndarray
                and a.dtype is f64
                and b.dtype is f64
                and c.dtype is f64
                and a.shape == shape_in
                and b.shape == shape_in
                and c.shape == shape_in
            ):
                try:
                    memmove(xa, a, nbytes)
                    memmove(xb, b, nbytes)
                    memmove(xc, c, nbytes)
                except (TypeError, ValueError, BufferError):
                    return None
            elif not (put(xa, a) and put(xb, b) and put(xc, c)):
                return None
            fn(*lead, xa, xb, xc, o, status)
            return view.copy() if status[0] == OK else None

        return three

    def put_scalar(buffer, value):
        kind = type(value)
        if not (kind is float or kind is int) or not value >= 0.0:
            return False
        try:
            buffer[0] = value
        except OverflowError:  # an int too large for a double
            return False
        return True

    numeric_rows = [r for r in rows if r != "scalar"]
    scalar_last = rows[-1] == "scalar" and rows.count("scalar") == 1
    if (
        numeric_rows
        and "pose" not in rows
        and len(set(numeric_rows)) == 1
        and (scalar_last or "scalar" not in rows)
        and len(outputs) <= 3
    ):
        # several rows of one width (the delta's fk_vel, fk_acc; its dynamics with the
        # payload last), written out: no put() call per ndarray row, no generator
        n = numeric_rows[0]
        shape_in, nbytes, count, k = (n,), 8 * n, len(rows), len(outputs)
        put = row_putter(memmove, n)

        def rows_call(*args):
            row_ins, ins, outs, views, status = buffers.b2
            if len(args) != count:
                return None
            for buffer, x in zip(row_ins, args):  # the rows; the scalar, if any, below
                if type(x) is ndarray and x.dtype is f64 and x.shape == shape_in:
                    try:
                        memmove(buffer, x, nbytes)
                    except (TypeError, ValueError, BufferError):
                        return None
                elif not put(buffer, x):
                    return None
            if scalar_last and not put_scalar(ins[-1], args[-1]):
                return None
            fn(*lead, *ins, *outs, status)
            if status[0] != OK:
                return None
            if k == 1:
                return views[0].copy()
            if k == 2:
                return views[0].copy(), views[1].copy()
            return views[0].copy(), views[1].copy(), views[2].copy()

        return rows_call

    putters = [
        _put_pose(memmove)
        if r == "pose"
        else put_scalar
        if r == "scalar"
        else row_putter(memmove, r)
        for r in rows
    ]
    count = len(rows)

    def call(*args):
        ins, outs, views, status = buffers.b
        if len(args) != count:
            return None
        for put, buffer, x in zip(putters, ins, args):
            if not put(buffer, x):
                return None
        fn(*lead, *ins, *outs, status)
        if status[0] != OK:
            return None
        if len(views) == 1:
            return views[0].copy()
        return tuple(v.copy() for v in views)

    return call
