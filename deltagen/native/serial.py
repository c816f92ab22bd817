"""The compiled backend of a serial arm: its generated C module via cffi. Bundled robots
use the checked-in generated/serial_<name>.c; any other description is rendered into the
build cache under a key of its content (a changed file never loads a stale module)."""

from __future__ import annotations

import hashlib
import os
import threading
from pathlib import Path
from typing import Any

import numpy as np

from deltagen import status as st
from deltagen.codegen.serial import (
    arm_sources,
    base_name,
    c_prefix,
    description_fingerprint,
    generator_fingerprint,
)
from deltagen.inputs import plain_pose, plain_row
from deltagen.native.build import is_built, load, usable_cache_dir
from deltagen.native.parallel import run_rows
from deltagen.paths import generated_dir


def source_dir(desc, render: bool = True) -> Path | None:
    """generated/ when it holds this description's checked-in module (bundled robots; kept
    current by `deltagen generate --check`), else a cache folder keyed by the description
    and the generator, rendered on first use (None instead when ``render`` is false and it
    has not been rendered yet)."""
    name = base_name(desc)
    header = generated_dir() / f"{name}.h"
    stamp = f"Description fingerprint: {description_fingerprint(desc)}"
    if header.is_file() and stamp in header.read_text():
        return generated_dir()
    key = hashlib.sha256((desc.key() + generator_fingerprint()).encode()).hexdigest()[:16]
    folder = usable_cache_dir() / "sources" / f"{name}_{key}"
    if not (folder / f"{name}.cdef.h").is_file():
        if not render:
            return None
        folder.mkdir(parents=True, exist_ok=True)
        sources = arm_sources(desc)
        # the .cdef.h marks a complete folder, so it is written last
        for file_name in sorted(sources, key=lambda f: f.endswith(".cdef.h")):
            tmp = folder / f".{file_name}.{os.getpid()}.{threading.get_ident()}.tmp"
            tmp.write_text(sources[file_name])
            tmp.replace(folder / file_name)
    return folder


def _opt(folder: Path) -> str:
    """The optimisation level of a module: -O3 for the checked-in ones (generated/), -O2 for
    those rendered at run time (a new URDF or robot file): less than half the compile time
    of a cold load, the same results bit for bit and the same speed (native/build.py,
    OPT_LEVELS)."""
    return "-O3" if folder == generated_dir() else "-O2"


def module_ready(desc) -> bool:
    """True when the description's module loads without SymPy or a compiler: checked in
    under generated/, or rendered and compiled into the cache before."""
    folder = source_dir(desc, render=False)
    return folder is not None and is_built(base_name(desc), c_prefix(desc), folder, _opt(folder))


def _load(desc):
    folder = source_dir(desc)
    assert folder is not None
    return load(base_name(desc), c_prefix(desc), folder, _opt(folder))


# kernels only the full module has
_DYNAMICS = frozenset(
    (
        "inverse_dynamics",
        "nonlinear_effects",
        "gravity_torque",
        "mass_matrix",
        "coriolis",
        "forward_dynamics",
    )
)


class _Scratch(threading.local):
    """Per-thread buffers for single-pose calls (cffi releases the GIL during calls)."""

    def __init__(self, ffi, n):
        self.q = ffi.new(f"double[{n}]")
        self.T = ffi.new("double[16]")
        self.J = ffi.new(f"double[{6 * n}]")
        self.status = ffi.new("int8_t[1]")
        self.T_np = np.frombuffer(ffi.buffer(self.T), dtype=np.float64).reshape(4, 4)
        self.J_np = np.frombuffer(ffi.buffer(self.J), dtype=np.float64).reshape(6, n)
        self.ik_q = self.ik_valid = None  # ik_all buffers, made on first use

    def make_ik_buffers(self, ffi, k, n):
        self.ik_q = ffi.new(f"double[{k * n}]")
        self.ik_valid = ffi.new(f"uint8_t[{k}]")
        self.ik_q_np = np.frombuffer(ffi.buffer(self.ik_q), dtype=np.float64).reshape(k, n)
        self.ik_valid_np = np.frombuffer(ffi.buffer(self.ik_valid), dtype=np.uint8)


class _DynamicsScratch(threading.local):
    """Per-thread buffers of the single-state dynamics calls (three inputs, one output)."""

    def __init__(self, ffi, n, out_size=None):
        self.a, self.b, self.c = (ffi.new(f"double[{n}]") for _ in range(3))
        self.out = ffi.new(f"double[{out_size or n}]")
        self.status = ffi.new("int8_t[1]")
        self.out_np = np.frombuffer(ffi.buffer(self.out), dtype=np.float64)


class CompiledArm:
    """Batched calls into an arm's C module; q is (N, n) C-contiguous float64."""

    def __init__(self, desc, threads=None):
        self.desc = desc
        self.threads = threads  # None: DELTAGEN_THREADS or every core (native.parallel)
        self._prefix = c_prefix(desc)  # of the C functions: deltagen_<name>
        # An arm with inertials whose module is not built yet (a new URDF or robot file)
        # starts from its kinematics alone: deriving and compiling the dynamics is most of
        # a cold load, so they are made on the first dynamics call (load_dynamics). The
        # kinematic kernels of both modules come from the same derivation: same results.
        self._dynamics_lock = threading.Lock()
        self._dynamics: Any = None
        if desc.has_inertia and not module_ready(desc):
            module = _load(desc.without_inertia())
        else:
            module = _load(desc)
            self._dynamics = module if desc.has_inertia else None
        self._ffi, self._lib = module.ffi, module.lib
        self._scratch = _Scratch(self._ffi, desc.n)
        self._ik_newton = getattr(self._lib, f"{self._prefix}_ik_newton")

    def _run(self, name, inputs, *widths):
        """Call <prefix>_<name> on the input rows: one (N, width) output per width, then
        the status. A width may be (width, "uint8_t") for a flag output. The rows are split
        into chunks across threads (native.parallel)."""
        n = inputs[0].shape[0]
        ffi, fn = self.c_function(name)
        fb = ffi.from_buffer
        kinds = [w if isinstance(w, tuple) else (w, "double") for w in widths]
        outs = [
            np.empty((n, width), dtype=np.uint8 if ctype == "uint8_t" else np.float64)
            for width, ctype in kinds
        ]
        status = np.empty(n, dtype=np.int8)
        ctypes = [f"{ctype}[]" for _, ctype in kinds]

        def call(lo, hi):
            return fn(
                hi - lo,
                *(fb("double[]", a[lo:hi]) for a in inputs),
                *(fb(c, out[lo:hi], require_writable=True) for out, c in zip(outs, ctypes)),
                fb("int8_t[]", status[lo:hi], require_writable=True),
            )

        rc = run_rows(n, self.threads, call)
        if rc != 0:
            raise RuntimeError(f"C core rejected its arguments (rc={rc})")
        return (*outs, status)

    def fk(self, q):
        T, status = self._run("fk", [q], 16)
        return T.reshape(-1, 4, 4), status

    def frames(self, q):
        count = self.desc.n + 2
        F, status = self._run("frames", [q], 16 * count)
        return F.reshape(-1, count, 4, 4), status

    def jacobian(self, q):
        J, status = self._run("jacobian", [q], 6 * self.desc.n)
        return J.reshape(-1, 6, self.desc.n), status

    def fk_jacobian(self, q):
        """T (N, 4, 4) and J (N, 6, n) from one evaluation, and the status."""
        n = self.desc.n
        T, J, status = self._run("fk_jacobian", [q], 16, 6 * n)
        return T.reshape(-1, 4, 4), J.reshape(-1, 6, n), status

    def ik_options(self, **fields):
        """A filled deltagen_ik_options struct (cffi-owned) for :meth:`ik_newton`: one
        keyword per field of the struct, which is declared once, in the runtime's C header
        (codegen/runtime/deltagen_ik_newton.h); integers and flags are converted."""
        types = dict(self._ffi.typeof("deltagen_ik_options").fields)
        if set(fields) != set(types):
            raise TypeError(
                f"ik_options needs exactly the fields {sorted(types)}; missing "
                f"{sorted(set(types) - set(fields))}, unknown "
                f"{sorted(set(fields) - set(types))}"
            )
        values = {}
        for name, value in fields.items():
            ctype = types[name].type
            if ctype.kind == "array":  # the mask: 0/1 flags
                values[name] = [int(bool(v)) for v in value]
            elif ctype.cname.startswith(("int", "uint")):
                values[name] = int(value)
            else:
                values[name] = float(value)
        return self._ffi.new("deltagen_ik_options *", values)

    def ik_newton(self, options, T, q0, qlim=None):
        """One damped Newton attempt per target in C (<prefix>_ik_newton).

        options: from :meth:`ik_options`; T (N, 4, 4) and q0 (N, n) float64 C-contiguous;
        qlim (n, 2) or None. Returns q (N, n), err_p (N), err_r (N), iterations (N) int32,
        status (N) int8 (OK converged, UNREACHABLE not converged, INVALID non-finite row)."""
        N, n = q0.shape[0], self.desc.n
        fb = self._ffi.from_buffer
        q = np.empty((N, n))
        err_p, err_r = np.empty(N), np.empty(N)
        iterations = np.empty(N, dtype=np.int32)
        status = np.empty(N, dtype=np.int8)
        lim = self._ffi.NULL if qlim is None else fb("double[]", qlim)
        fn = self._ik_newton

        def call(lo, hi):  # rows are independent: a chunk's rows get the same answers
            return fn(
                hi - lo,
                options,
                fb("double[]", T[lo:hi]),
                fb("double[]", q0[lo:hi]),
                lim,
                fb("double[]", q[lo:hi], require_writable=True),
                fb("double[]", err_p[lo:hi], require_writable=True),
                fb("double[]", err_r[lo:hi], require_writable=True),
                fb("int32_t[]", iterations[lo:hi], require_writable=True),
                fb("int8_t[]", status[lo:hi], require_writable=True),
            )

        rc = run_rows(N, self.threads, call)
        if rc != 0:
            raise RuntimeError(f"C core rejected the IK arguments (rc={rc})")
        return q, err_p, err_r, iterations, status

    def jacobian_dot(self, q, qd):
        Jd, status = self._run("jacobian_dot", [q, qd], 6 * self.desc.n)
        return Jd.reshape(-1, 6, self.desc.n), status

    # -- dynamics (arms with inertial parameters; the API checks has_inertia first) ------

    def load_dynamics(self):
        """The full module (kinematics and dynamics), rendered and compiled on first use
        when the arm started from its kinematics alone."""
        if self._dynamics is None:
            with self._dynamics_lock:
                if self._dynamics is None:
                    self._dynamics = _load(self.desc)
        return self._dynamics

    @property
    def dynamics_loaded(self) -> bool:
        return self._dynamics is not None

    def c_function(self, name: str):
        """(ffi, function) of the generated C function <prefix>_<name>, from the module
        that has it (for callers that time or drive the C directly)."""
        module = self.load_dynamics() if name in _DYNAMICS else None
        ffi, lib = (module.ffi, module.lib) if module else (self._ffi, self._lib)
        return ffi, getattr(lib, f"{self._prefix}_{name}")

    def inverse_dynamics(self, q, qd, qdd):
        return self._run("inverse_dynamics", [q, qd, qdd], self.desc.n)

    def nonlinear_effects(self, q, qd):
        return self._run("nonlinear_effects", [q, qd], self.desc.n)

    def gravity_torque(self, q):
        return self._run("gravity_torque", [q], self.desc.n)

    def mass_matrix(self, q):
        n = self.desc.n
        M, status = self._run("mass_matrix", [q], n * n)
        return M.reshape(-1, n, n), status

    def coriolis(self, q, qd):
        n = self.desc.n
        C, status = self._run("coriolis", [q, qd], n * n)
        return C.reshape(-1, n, n), status

    def forward_dynamics(self, q, qd, tau):
        return self._run("forward_dynamics", [q, qd, tau], self.desc.n)

    def single_dynamics(self, name):
        """Fast path for one state of inverse_dynamics or forward_dynamics (three (n,)
        C-contiguous float64 arrays): the (n,) result, or None when the general path must
        handle the call (other inputs, a status other than OK)."""
        module = self.load_dynamics()
        fn = getattr(module.lib, f"{self._prefix}_{name}")
        scratch = _DynamicsScratch(module.ffi, self.desc.n)
        n, nbytes = self.desc.n, 8 * self.desc.n
        memmove = module.ffi.memmove
        ndarray, OK = np.ndarray, st.OK

        def plain(x):
            return (
                type(x) is ndarray
                and x.shape == (n,)
                and x.dtype.char == "d"
                and x.flags.c_contiguous
            )

        def call(a, b, c):
            if not (plain(a) and plain(b) and plain(c)):
                return None
            sc = scratch
            memmove(sc.a, a, nbytes)
            memmove(sc.b, b, nbytes)
            memmove(sc.c, c, nbytes)
            fn(1, sc.a, sc.b, sc.c, sc.out, sc.status)
            if sc.status[0] != OK:
                return None
            return sc.out_np.copy()

        return call

    def single_mass_matrix(self):
        """Fast path of mass_matrix for one (n,) C-contiguous float64 q: M (n, n), or None
        when the general path must handle the call."""
        module = self.load_dynamics()
        fn = getattr(module.lib, f"{self._prefix}_mass_matrix")
        scratch = _DynamicsScratch(module.ffi, self.desc.n, self.desc.n**2)
        n, nbytes = self.desc.n, 8 * self.desc.n
        memmove = module.ffi.memmove
        ndarray, OK = np.ndarray, st.OK

        def call(q):
            if not (
                type(q) is ndarray
                and q.shape == (n,)
                and q.dtype.char == "d"
                and q.flags.c_contiguous
            ):
                return None
            sc = scratch
            memmove(sc.a, q, nbytes)
            fn(1, sc.a, sc.out, sc.status)
            if sc.status[0] != OK:
                return None
            return sc.out_np.reshape(n, n).copy()

        return call

    @property
    def has_ik_all(self) -> bool:
        return hasattr(self._lib, f"{self._prefix}_ik_all")

    def ik_all(self, T, k):
        """Every closed-form branch (generated ik_all): T (N, 4, 4) C-contiguous ->
        q (N, k, n), valid (N, k) bool, status (N,)."""
        q, valid, status = self._run("ik_all", [T.reshape(-1, 16)], k * self.desc.n, (k, "uint8_t"))
        return q.reshape(-1, k, self.desc.n), valid != 0, status

    def single_ik_all(self, k):
        """Lean path of ik_all for one pose: a (4, 4) C-contiguous float64 array with the
        bottom row 0 0 0 1 (the caller has checked that it is a finite rigid transform) in,
        fresh (q (k, n), valid (k,) bool) out, or None when the general path must handle the
        call (other inputs; a status other than OK)."""
        if not self.has_ik_all:
            return None
        fn = getattr(self._lib, f"{self._prefix}_ik_all")
        scratch, memmove, fb, n = (
            self._scratch,
            self._ffi.memmove,
            self._ffi.from_buffer,
            self.desc.n,
        )
        empty, OK = np.empty, st.OK

        def call(T):
            if not plain_pose(T):
                return None
            sc = scratch
            memmove(sc.T, T, 128)
            q = empty((k, n))
            valid = empty(k, dtype=np.bool_)  # the kernel writes uint8 flags, 1 or 0
            status = sc.status
            fn(
                1,
                sc.T,
                fb("double[]", q, require_writable=True),
                fb("uint8_t[]", valid, require_writable=True),
                status,
            )
            return (q, valid) if status[0] == OK else None

        return call

    def single(self, name):
        """Lean path for one configuration of fk or jacobian: what inputs.plain_row(q, n)
        accepts in (a (n,) float64 array in native byte order -- a non-contiguous view makes
        memmove raise -- or a list/tuple of n Python floats/ints), a fresh result array out,
        or None when the general path must handle the call (other inputs, whose checks it
        makes, or a status other than OK: the kernel's status is OK only when every output is
        finite, deltagen/status.py). Same C function, same numbers as the batch path."""
        fn = getattr(self._lib, f"{self._prefix}_{name}")
        scratch, memmove, fb, n = (
            self._scratch,
            self._ffi.memmove,
            self._ffi.from_buffer,
            self.desc.n,
        )
        ndarray, f64, empty, OK = np.ndarray, np.dtype(np.float64), np.empty, st.OK
        shape_in, nbytes = (n,), 8 * n
        shape = (4, 4) if name == "fk" else (6, n)

        def call(q):
            sc = scratch
            buffer = sc.q
            if type(q) is ndarray:
                if q.shape != shape_in or q.dtype is not f64:
                    return None
                try:
                    memmove(buffer, q, nbytes)
                except (TypeError, ValueError, BufferError):
                    return None
            elif plain_row(q, n):
                try:
                    buffer[0:n] = q
                except (TypeError, ValueError, OverflowError):
                    return None
            else:
                return None
            out = empty(shape)
            status = sc.status
            fn(1, buffer, fb("double[]", out, require_writable=True), status)
            return out if status[0] == OK else None

        return call
