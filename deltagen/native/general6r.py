"""The compiled eigen step of the general 6R inverse kinematics (deltagen/solve/general6r.py):
one arm-independent cffi module of hand-written C (codegen/runtime/deltagen_general6r.c and
deltagen_eigen.c: a Hessenberg + Francis double-shift QR eigen-solver), built once per
machine into the build cache (native/build.py: keyed, locked, verified) and shared by every
arm -- no compile per arm, so a newly loaded arm pays nothing for it.

The module's own translation unit is a stub (written into the cache): build.load compiles a
<name>.c/.h/.cdef.h triple and the runtime C they include; the declarations come from the
runtime header's ``cffi: begin``/``end`` part.
"""

from __future__ import annotations

import os
import threading

import numpy as np

from deltagen.native.build import BuildError, load, usable_cache_dir

__all__ = ["Arm", "available", "eigen", "eigvals", "finish"]

_NAME = "deltagen_general6r_core"
_STUB = {
    ".h": '/* stub: the general 6R eigen step lives in the runtime */\n#include "deltagen_general6r.h"\n',
    ".c": f'#include "{_NAME}.h"\n',
    ".cdef.h": "\n",
}
_LOCK = threading.Lock()
_MODULE: list = []


def _module():
    if _MODULE:
        return _MODULE[0]
    with _LOCK:
        if not _MODULE:
            folder = usable_cache_dir() / "general6r_src"
            folder.mkdir(exist_ok=True)
            for ext, text in _STUB.items():
                path = folder / f"{_NAME}{ext}"
                if not path.is_file() or path.read_text() != text:
                    # atomic: another process may be reading it (os.replace)
                    tmp = path.with_name(f"{path.name}.{os.getpid()}.tmp")
                    tmp.write_text(text)
                    os.replace(tmp, path)
            _MODULE.append(load(_NAME, "deltagen_general6r", folder))
    return _MODULE[0]


_FAILED: list = []


def available() -> bool:
    """True when the module builds (a C compiler) or is in the cache; a failed build is
    not retried in this process (the numpy engine serves)."""
    if _MODULE:
        return True
    if _FAILED:
        return False
    try:
        _module()
    except BuildError:
        _FAILED.append(True)
        return False
    return True


def _ptr(ffi, a, kind="double *"):
    return ffi.cast(kind, ffi.from_buffer(a))


def eigvals(A):
    """Eigenvalues (count, n) complex and status (count,) of real matrices A (count, n, n),
    n <= 64, by deltagen_eigvals_batch (NaN where status != 0)."""
    mod = _module()
    A = np.array(A, dtype=np.float64, order="C", copy=True)
    count, n = A.shape[0], A.shape[1]
    wr, wi = np.empty((count, n)), np.empty((count, n))
    status = np.empty(count, dtype=np.int32)
    ffi = mod.ffi
    mod.lib.deltagen_eigvals_batch(
        _ptr(ffi, A), count, n, _ptr(ffi, wr), _ptr(ffi, wi), _ptr(ffi, status, "int *")
    )
    return wr + 1j * wi, status


def eigen(M, cond_limit: float, imag_tol: float, start):
    """deltagen_general6r_eigen on M (N, 3, 12, 12): (status (N,), nreal (N,), x (N, 24),
    V (N, 24, 12)) (the header documents each)."""
    mod = _module()
    M = np.ascontiguousarray(M, dtype=np.float64)
    start = np.ascontiguousarray(start, dtype=np.float64)
    N = M.shape[0]
    status = np.empty(N, dtype=np.int32)
    nreal = np.empty(N, dtype=np.int32)
    x = np.empty((N, 24))
    V = np.empty((N, 24, 12))
    ffi = mod.ffi
    mod.lib.deltagen_general6r_eigen(
        _ptr(ffi, M),
        N,
        float(cond_limit),
        float(imag_tol),
        _ptr(ffi, start),
        _ptr(ffi, status, "int *"),
        _ptr(ffi, nreal, "int *"),
        _ptr(ffi, x),
        _ptr(ffi, V),
    )
    return status, nreal, x, V


class Arm:
    """The per-arm data of one arrangement (deltagen_general6r_arm, the header documents
    each field), packed once; ``starts`` runs deltagen_general6r_starts with it."""

    def __init__(
        self,
        *,
        T0inv,
        w,
        o,
        order,
        shift,
        reverse,
        left_mode,
        left_fixed,
        delta,
        B2inv,
        B3inv,
        half3,
    ):
        mod = _module()
        self._ffi, self._lib = mod.ffi, mod.lib
        self.struct = self._ffi.new("deltagen_general6r_arm *")
        st = self.struct
        for name, value, size in (
            ("T0inv", T0inv, 16),
            ("w", w, 18),
            ("o", o, 18),
            ("left_fixed", left_fixed, 378),
            ("delta", delta, 3),
            ("B2inv", B2inv, 81),
            ("B3inv", B3inv, 729),
            ("half3", half3, 729),
        ):
            flat = np.ascontiguousarray(value, dtype=np.float64).reshape(-1)
            if flat.size != size:
                raise ValueError(f"{name}: {flat.size} values, expected {size}")
            self._ffi.memmove(getattr(st, name), self._ffi.from_buffer(flat), 8 * size)
        for j in range(6):
            st.order[j] = int(order[j])
        st.shift, st.reverse, st.left_mode = int(shift), int(reverse), int(left_mode)

    def starts(self, T, cond_limit: float, imag_tol: float, start):
        """(q (N, 16, 6), margin (N,), status (N,)) for tool poses T (N, 4, 4)."""
        T = np.ascontiguousarray(T, dtype=np.float64)
        start = np.ascontiguousarray(start, dtype=np.float64)
        N = T.shape[0]
        q = np.empty((N, 16, 6))
        margin = np.empty(N)
        status = np.empty(N, dtype=np.int32)
        ffi = self._ffi
        self._lib.deltagen_general6r_starts(
            _ptr(ffi, T),
            N,
            self.struct,
            float(cond_limit),
            float(imag_tol),
            _ptr(ffi, start),
            _ptr(ffi, q),
            _ptr(ffi, margin),
            _ptr(ffi, status, "int *"),
        )
        return q, margin, status

    def solver(self, cond_limit: float, imag_tol: float, start, newton, qlim, limits: bool):
        """A one-call solve (deltagen_general6r_solve) with everything but the poses packed
        once: ``call(T (N, 4, 4) float64 C-contiguous)`` -> (q (N, 16, 6), valid (N, 16)
        bool, status (N,)). ``newton``: (function address, options address, limits (6, 2)
        or None, keep-alive) of the arm's Newton kernel (numeric.polisher's ``kernel``);
        ``qlim`` (6, 2): the limits of the fit."""
        ffi, lib = self._ffi, self._lib
        fn_addr, opt_addr, newton_qlim, keep = newton
        fn = ffi.cast("deltagen_general6r_newton_fn", fn_addr)
        opts = ffi.cast("const struct deltagen_ik_options *", opt_addr)
        start = np.ascontiguousarray(start, dtype=np.float64)
        qlim = np.ascontiguousarray(qlim, dtype=np.float64)
        if qlim.shape != (6, 2):
            raise ValueError(f"qlim: shape {qlim.shape}, expected (6, 2)")
        nq = ffi.NULL
        if newton_qlim is not None:
            newton_qlim = np.ascontiguousarray(newton_qlim, dtype=np.float64)
            nq = ffi.cast("double *", ffi.from_buffer(newton_qlim))
        p_start = ffi.cast("double *", ffi.from_buffer(start))
        p_qlim = ffi.cast("double *", ffi.from_buffer(qlim))
        struct, run = self.struct, lib.deltagen_general6r_solve
        cond_limit, imag_tol, lim = float(cond_limit), float(imag_tol), int(bool(limits))
        fb = ffi.from_buffer
        empty = np.empty

        def call(T):
            N = T.shape[0]
            q = empty((N, 16, 6))
            valid = empty((N, 16), dtype=np.bool_)
            found = empty(N, dtype=np.int32)
            status = empty(N, dtype=np.int32)
            run(
                fb("double[]", T),
                N,
                struct,
                cond_limit,
                imag_tol,
                p_start,
                fn,
                opts,
                nq,
                p_qlim,
                lim,
                fb("double[]", q, require_writable=True),
                fb("unsigned char[]", valid, require_writable=True),
                fb("int[]", found, require_writable=True),
                fb("int[]", status, require_writable=True),
            )
            return q, valid, status

        call.keep = (keep, start, qlim, newton_qlim, fn, opts)  # alive with the closure
        return call


def finish(qs, conv, qlim, limits: bool):
    """deltagen_general6r_finish: (q (N, 16, 6), valid (N, 16) bool, found (N,)) from
    Newton's results qs (N, S, 6) and their convergence conv (N, S)."""
    mod = _module()
    ffi = mod.ffi
    qs = np.ascontiguousarray(qs, dtype=np.float64)
    conv = np.ascontiguousarray(conv, dtype=np.uint8)
    qlim = np.ascontiguousarray(qlim, dtype=np.float64)
    N, S = conv.shape
    q = np.empty((N, 16, 6))
    valid = np.empty((N, 16), dtype=np.uint8)
    found = np.empty(N, dtype=np.int32)
    fitted = np.empty((N, S, 6))
    mod.lib.deltagen_general6r_finish(
        _ptr(ffi, qs),
        _ptr(ffi, conv, "unsigned char *"),
        N,
        S,
        _ptr(ffi, qlim),
        int(bool(limits)),
        _ptr(ffi, fitted),
        _ptr(ffi, q),
        _ptr(ffi, valid, "unsigned char *"),
        _ptr(ffi, found, "int *"),
    )
    return q, valid.view(bool), found
