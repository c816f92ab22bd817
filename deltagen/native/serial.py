"""The compiled backend of a serial arm: its generated C module via cffi. A bundled robot's
module is the checked-in generated/serial_<name>.c (-O3), loaded once it is in the build
cache (`deltagen generate <name>`, or any complete build of it, puts it there); any other
description is rendered into the build cache under a key of its content (a changed file
never loads a stale module). An arm whose complete module is not built yet, bundled or
not, starts from the parts of it that its calls need (CompiledArm: the "first" part, then
each other part on its first call), which a cold load compiles sooner."""

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
from deltagen.derive.serial.parts import PARTS
from deltagen.errors import ManifestError
from deltagen.native.build import is_built, load, usable_cache_dir
from deltagen.native.lean import checked_pose_call, single_call
from deltagen.native.manifest import kernels, output_widths, point_shape, reshape_outputs
from deltagen.native.parallel import check_rc, run_rows
from deltagen.paths import generated_dir


def source_dir(desc, render: bool = True, part: str = "all") -> Path | None:
    """generated/ when it holds this description's checked-in module (bundled robots; kept
    current by `deltagen generate --check`), else a cache folder keyed by the description,
    the part and the generator, rendered on first use (None instead when ``render`` is
    false and it has not been rendered yet). ``part``: "all" (every kernel) or one part of
    a new arm's module (derive.serial.parts.PARTS; codegen.serial.arm_sources), never
    checked in."""
    name = base_name(desc)
    if part == "all":
        header = generated_dir() / f"{name}.h"
        stamp = f"Description fingerprint: {description_fingerprint(desc)}"
        if header.is_file() and stamp in header.read_text():
            return generated_dir()
    tag = "" if part == "all" else part + "\0"
    key = hashlib.sha256((tag + desc.key() + generator_fingerprint()).encode()).hexdigest()[:16]
    label = "" if part == "all" else part + "_"
    folder = usable_cache_dir() / "sources" / f"{name}_{label}{key}"
    if not (folder / f"{name}.cdef.h").is_file():
        if not render:
            return None
        folder.mkdir(parents=True, exist_ok=True)
        sources = arm_sources(desc, part)
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


def module_ready(desc, part: str = "all") -> bool:
    """True when the description's module (or ``part`` of it) loads without SymPy or a
    compiler: checked in under generated/, or rendered and compiled into the cache before."""
    folder = source_dir(desc, render=False, part=part)
    return folder is not None and is_built(
        base_name(desc), c_prefix(desc), folder, _opt(folder), part=part
    )


def _load(desc, part: str = "all"):
    folder = source_dir(desc, part=part)
    assert folder is not None
    return load(base_name(desc), c_prefix(desc), folder, _opt(folder), part=part)


def _ports(desc, part: str = "all") -> dict:
    """{kernel: manifest entry} of the module (or part) :func:`_load` loads: the ports of its
    kernels (the <name>.kernels.json beside its C, native.manifest)."""
    folder = source_dir(desc, part=part)
    assert folder is not None
    return kernels(base_name(desc), folder)


def complete_module(desc):
    """The description's module with every kernel (kinematics, ik_all, dynamics when it has
    inertials), built if needed: what `deltagen generate ROBOT_FILE` leaves in the cache."""
    return _load(desc)


# the part of a new arm's module (derive.serial.parts.PARTS) that holds each kernel the
# first-load module leaves out; forward_dynamics is the C wrapper of the "mass" part
_PART_OF = {
    kernel: part for part, kernels in PARTS.items() if part != "first" for kernel in kernels
}
_PART_OF["forward_dynamics"] = "mass"


class CompiledArm:
    """Batched calls into an arm's C module; q is (N, n) C-contiguous float64."""

    def __init__(self, desc, threads=None):
        self.desc = desc
        self.threads = threads  # None: DELTAGEN_THREADS or every core (native.parallel)
        self._prefix = c_prefix(desc)  # of the C functions: deltagen_<name>
        # An arm whose module is not built yet (a new URDF or robot file) starts from the
        # kernels most calls need (fk, frames, jacobian, fk_jacobian, ik_newton: the
        # "first" part); the other parts (derive.serial.parts.PARTS) are derived and
        # compiled on the first call of one of their kernels, each alone (part_module):
        # "later" (jacobian_dot and the closed-form ik_all: SymPy and the compiler spend
        # half of a UR5's cold load on it), "dynamics" (inverse dynamics and g), "mass" (M,
        # h and the forward dynamics) and "coriolis". No part derives or compiles another's kernels. Every part's
        # kernels come from the same derivation code as the complete module's: same C
        # text per kernel, same results. A complete module built before (`deltagen
        # generate`, a bundled robot) is loaded at once and serves every kernel.
        self._lock = threading.Lock()
        self._parts: dict[str, Any] = {}
        # {kernel: manifest entry} of every module loaded so far (its ports and widths)
        self._kernels: dict[str, dict] = {}
        self._kinematics_desc = desc.without_inertia() if desc.has_inertia else desc
        if module_ready(desc):
            module = _load(desc)
            self._kernels.update(_ports(desc))
            self._parts = dict.fromkeys(("later", "dynamics", "mass", "coriolis"), module)
            if not desc.has_inertia:
                for part in ("dynamics", "mass", "coriolis"):
                    del self._parts[part]
        elif desc.has_inertia and module_ready(self._kinematics_desc):
            module = self._parts["later"] = _load(self._kinematics_desc)
            self._kernels.update(_ports(self._kinematics_desc))
        else:
            module = _load(self._kinematics_desc, part="first")
            self._kernels.update(_ports(self._kinematics_desc, part="first"))
        self._ffi, self._lib = module.ffi, module.lib
        self._module_file = getattr(module, "__file__", None)  # single_regular's LU
        self._ik_newton = getattr(self._lib, f"{self._prefix}_ik_newton")

    def _run(self, name, inputs):
        """Call <prefix>_<name> on the input rows: one output per port of the kernel's
        manifest entry ((N, width), a matrix port reshaped to (N, *matrix); a flag port
        uint8), then the status. The rows are split into chunks across threads
        (native.parallel)."""
        n = inputs[0].shape[0]
        ffi, fn = self.c_function(name)
        entry = self._kernels[name]
        fb = ffi.from_buffer
        kinds = [w if isinstance(w, tuple) else (w, "double") for w in output_widths(entry)]
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

        check_rc(run_rows(n, self.threads, call))
        return (*reshape_outputs(entry, outs), status)

    def fk(self, q):
        """T (N, 4, 4) and the status."""
        return self._run("fk", [q])

    def frames(self, q):
        """Every link frame (N, n + 2, 4, 4), base to tool, and the status."""
        return self._run("frames", [q])

    def jacobian(self, q):
        """J (N, 6, n) and the status."""
        return self._run("jacobian", [q])

    def fk_jacobian(self, q):
        """T (N, 4, 4) and J (N, 6, n) from one evaluation, and the status."""
        return self._run("fk_jacobian", [q])

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
        return self._run("jacobian_dot", [q, qd])

    # -- dynamics (arms with inertial parameters; the API checks has_inertia first) ------

    def part_module(self, part: str):
        """The module holding ``part``'s kernels (derive.serial.parts.PARTS: "later",
        "dynamics", "mass" or "coriolis"): the complete module when it was loaded at first, else
        that part alone, loaded from the cache or rendered and compiled on first use."""
        module = self._parts.get(part)
        if module is None:
            with self._lock:
                module = self._parts.get(part)
                if module is None:
                    desc = self._kinematics_desc if part == "later" else self.desc
                    module = _load(desc, part=part)
                    self._kernels.update(_ports(desc, part=part))
                    self._parts[part] = module
        return module

    def load_dynamics(self):
        """The module of inverse_dynamics and gravity_torque, built on first use for a new
        arm (the complete module when it was built before)."""
        return self.part_module("dynamics")

    def load_kinematics(self):
        """The module of jacobian_dot and ik_all, built on first use for a new arm."""
        return self.part_module("later")

    @property
    def dynamics_loaded(self) -> bool:
        return "dynamics" in self._parts

    def kernel(self, name: str) -> dict:
        """The manifest entry of kernel ``name`` (native.manifest.kernels: C function, ports
        with width, C type, unit and matrix shape), from the module that has it (a new
        arm's part is built on first use): for callers that time or drive the C directly."""
        self.c_function(name)
        return self._kernels[name]

    def c_function(self, name: str):
        """(ffi, function) of the generated C function <prefix>_<name>, from the module
        that has it (for callers that time or drive the C directly)."""
        part = _PART_OF.get(name)
        module = self.part_module(part) if part else None
        ffi, lib = (module.ffi, module.lib) if module else (self._ffi, self._lib)
        return ffi, getattr(lib, f"{self._prefix}_{name}")

    def inverse_dynamics(self, q, qd, qdd):
        return self._run("inverse_dynamics", [q, qd, qdd])

    def nonlinear_effects(self, q, qd):
        return self._run("nonlinear_effects", [q, qd])

    def gravity_torque(self, q):
        return self._run("gravity_torque", [q])

    def mass_matrix(self, q):
        """M (N, n, n) and the status."""
        return self._run("mass_matrix", [q])

    def coriolis(self, q, qd):
        """C (N, n, n) and the status."""
        return self._run("coriolis", [q, qd])

    def forward_dynamics(self, q, qd, tau):
        return self._run("forward_dynamics", [q, qd, tau])

    def _single(self, name, module=None, rows=None):
        """The lean one-point call (native.lean) of kernel ``name`` of ``module`` (None: the
        module loaded first): input rows and output shapes from its manifest entry
        (``rows``: native.lean's kinds instead)."""
        ffi, lib = (self._ffi, self._lib) if module is None else (module.ffi, module.lib)
        entry = self._kernels[name]
        rows = rows or [port["width"] for port in entry["inputs"]]
        outputs = [(point_shape(port), port["ctype"]) for port in entry["outputs"]]
        return single_call(ffi, getattr(lib, entry["function"]), (1,), rows, outputs)

    def single_dynamics(self, name):
        """Lean path (native.lean) for one state of inverse_dynamics or forward_dynamics:
        three rows of n numbers (inputs.plain_row) in, the (n,) result out, or None when
        the general path must handle the call (other inputs, a status other than OK)."""
        return self._single(name, self.part_module(_PART_OF[name]))

    def single_mass_matrix(self):
        """Lean path of mass_matrix for one q (inputs.plain_row): M (n, n), or None when the
        general path must handle the call."""
        return self._single("mass_matrix", self.part_module("mass"))

    @property
    def has_ik_all(self) -> bool:
        """True when the arm's C has a closed-form ik_all (asking builds the complete
        kinematics module of a new arm: whether a closed form exists is found by deriving
        it)."""
        return hasattr(self.load_kinematics().lib, f"{self._prefix}_ik_all")

    def _check_branches(self, k: int) -> None:
        """ik_all's callers name its branch count k: the manifest's must be the same."""
        found = self._kernels["ik_all"]["outputs"][0]["matrix"][0]
        if found != k:
            raise ManifestError(f"ik_all of {self.desc.name} has {found} branches, not {k}")

    def ik_all(self, T, k):
        """Every closed-form branch (generated ik_all): T (N, 4, 4) C-contiguous ->
        q (N, k, n), valid (N, k) bool, status (N,)."""
        self.load_kinematics()
        self._check_branches(k)
        q, valid, status = self._run("ik_all", [T.reshape(-1, 16)])
        return q, valid != 0, status

    def single_ik_all(self, k):
        """Lean path of ik_all for one pose: a (4, 4) C-contiguous float64 array with the
        bottom row 0 0 0 1 (the caller has checked that it is a finite rigid transform) in,
        fresh (q (k, n), valid (k,) bool) out, or None when the general path must handle the
        call (other inputs; a status other than OK)."""
        if not self.has_ik_all:
            return None
        self._check_branches(k)
        return self._single("ik_all", self.load_kinematics(), rows=["pose"])

    def checked_ik_all(self, k, tolerances, wrap=None):
        """ik_all of one pose through the C extension (native.lean.checked_pose_call), the
        pose's check made in C: a (4, 4) float64 ndarray in, wrap((q (k, n), valid (k,)))
        out for a finite rigid transform (solve/ik.py's rule, ``tolerances`` its (rigid,
        bottom) tolerances) whose status is OK or UNREACHABLE (the batch path's outputs for
        such a row, as they stand); None for anything else (the general path answers). None
        instead of the callable where the arm has no C closed form or the extension is
        missing."""
        if not self.has_ik_all:
            return None
        self._check_branches(k)
        module = self.load_kinematics()
        entry = self._kernels["ik_all"]
        k_q, n_q = point_shape(entry["outputs"][0])  # q (k, n), the manifest's
        return checked_pose_call(
            module.ffi,
            getattr(module.lib, entry["function"]),
            k_q,
            n_q,
            (st.OK, st.UNREACHABLE),
            tolerances,
            wrap,
        )

    def single_regular(self, tol):
        """The cheap test of ik's singularity check for one configuration of an arm whose
        Jacobian is square (native.lean_ext regular_kernel: the generated Jacobian and the
        runtime's deltagen_lu of this module, in C): call(q) -> True (|det J| >= tol
        |J|_F^n: not singular), False (the caller's SVD decides) or None (other inputs, a
        status other than OK). None instead of the callable where the Jacobian is not
        square, the extension is missing or the module does not export deltagen_lu."""
        import ctypes

        from deltagen.native.lean import extension

        module = extension()
        if module is None or self._module_file is None or self.desc.n != 6:
            return None
        try:
            shared = ctypes.CDLL(self._module_file)
            lu = ctypes.cast(shared.deltagen_lu, ctypes.c_void_p).value
        except (OSError, AttributeError):
            return None
        jacobian = getattr(self._lib, self._kernels["jacobian"]["function"])
        return module.regular_kernel(
            int(self._ffi.cast("uintptr_t", jacobian)),
            int(lu),
            self.desc.n,
            float(tol),
            st.OK,
            (self._ffi, self._lib, jacobian, shared),
        )

    def single(self, name):
        """Lean path (native.lean) for one configuration of fk or jacobian: what
        inputs.plain_row(q, n) accepts in (a (n,) float64 array in native byte order, or a
        list/tuple of n Python floats/ints), a fresh result array out, or None when the
        general path must handle the call (other inputs, whose checks it makes, or a status
        other than OK: the kernel's status is OK only when every output is finite,
        deltagen/status.py). Same C function, same numbers as the batch path."""
        return self._single(name)
