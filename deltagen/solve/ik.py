"""The inverse-kinematics planner of a serial arm: which method answers ``ik`` and
``ik_all`` (the generated C closed form, the numpy closed form, the closed form of the
reversed chain, the combined method, the general 6R solver, the numeric solver), the lean
one-pose paths, the capabilities of the arm those choices read (made once, on first use),
and why a target has no solution (the error path). ``deltagen.api.serial.SerialRobot``
keeps the argument checks, the error modes and the shaping, and builds one ``IKPlanner``
per arm (docs/architecture.md, "Where the IK policy lives").

The planner reads the arm duck-typed (its description, its batched core ``_core`` and its
one-configuration Jacobian path): the solvers of this package take the same arm.
"""

from __future__ import annotations

import math
import warnings
from functools import cached_property
from typing import Any, NamedTuple

import numpy as np

from deltagen.errors import (
    GeometryError,
    IncompleteSolutionsWarning,
    SingularityError,
    UnreachableError,
    rows_text,
)
from deltagen.geometry.limits import wrap_to_pi
from deltagen.inputs import InputError, as_float_array
from deltagen.status import SINGULAR_TOL

BoolArray = np.ndarray
FloatArray = np.ndarray
_EYE3 = np.eye(3)
_F64 = np.dtype(np.float64)  # native byte order

#: ik_all's methods and ik's
ALL_METHODS = ("auto", "closed_form", "complete", "combined")
IK_METHODS = ("auto", "analytic", "numeric")


class IKSolutions(tuple):
    """What ik_all returns: unpacks as ``q, valid`` (also ``.q``, ``.valid``), and
    ``.complete``: True when the method used finds every solution of the arm, so that a pose
    without a valid one is unreachable within the joint limits (SerialRobot.ik_all).
    ``IKSolutions.of(q, valid, complete)`` makes one; ``complete`` is a class attribute of
    the two subclasses, so that no Python ``__new__`` runs on the one-pose path (a third of
    its Python time)."""

    complete: bool = False

    @staticmethod
    def of(q: FloatArray, valid: BoolArray, complete: bool) -> IKSolutions:
        return (_CompleteIKSolutions if complete else _IncompleteIKSolutions)((q, valid))

    @property
    def q(self) -> FloatArray:
        return self[0]

    @property
    def valid(self) -> BoolArray:
        return self[1]


class _CompleteIKSolutions(IKSolutions):
    complete = True


class _IncompleteIKSolutions(IKSolutions):
    complete = False


_BOTTOM = np.array([0.0, 0.0, 0.0, 1.0])
_RIGID_TOL, _BOTTOM_TOL = 1e-6, 1e-12  # check_poses: what counts as a rigid transform
#: The cheap lower bound sqrt(det G) / |J|_F^m of sigma_min / sigma_max for a Jacobian that is
#: not square (G its m x m Gram matrix) clears a row as not singular only above this, far
#: above SINGULAR_TOL: G's rounding (~ eps sigma_max^2 on its eigenvalues, a few 1e-16)
#: could lift a ratio below SINGULAR_TOL = 1e-9 to ~1e-8 but not to 1e-6; rows below it
#: get the SVD.
GRAM_TOL = 1e-6


try:  # np.linalg.det's LAPACK gufunc without its errstate context (a third of the cost
    # of one-pose ik's singularity check; J is finite there, its status was OK)
    from numpy.linalg import _umath_linalg

    def _det(J):
        return _umath_linalg.det(J, signature="d->d")

    if _det(np.eye(2)) != 1.0:  # pragma: no cover - a private module that changed
        raise ImportError("numpy.linalg._umath_linalg.det is not the determinant")
except Exception:  # pragma: no cover - a numpy without the module, or with another one
    _det = np.linalg.det


def bound_clears(J):
    """True where a cheap lower bound of sigma_min / sigma_max of J (..., r, c) already
    clears J as not singular (IKPlanner.singular_rows and singular_one; the rows it does not
    clear get the SVD). For square J, |det J| / |J|_F^n <= sigma_min / |J|_F <= sigma_min /
    sigma_max (det J is the product of the singular values, each <= sigma_max <= |J|_F),
    held against SINGULAR_TOL; for J that is not square, sqrt(det G) / |J|_F^m with G the
    m x m Gram matrix (J J^T or J^T J, m = min(r, c)), held against GRAM_TOL. The strict >
    leaves a zero J to the SVD. native/lean_ext.c regular_call is the C form of the square
    case (det from the runtime's LU)."""
    if J.ndim == 2:  # one pose: a quarter of the cost of the stacked forms below
        (rows, cols), norm, Jt = J.shape, math.sqrt(float(np.vdot(J, J))), J.T
    else:
        rows, cols = J.shape[-2:]
        norm, Jt = np.linalg.norm(J, axis=(-2, -1)), np.swapaxes(J, -1, -2)
    if rows == cols:
        return abs(_det(J)) > SINGULAR_TOL * norm**rows
    # sqrt(det G) > GRAM_TOL |J|_F^m squared: no square root (nor its warning) of a det G
    # that rounding made negative, which fails the test as it should
    return _det(J @ Jt if rows < cols else Jt @ J) > (GRAM_TOL * norm ** min(rows, cols)) ** 2


def check_one_pose(v):
    """(finite, rigid) of one pose given as its 16 entries (row by row, a Python list):
    check_poses' rule for a batch, in Python floats (a few us instead of ~20)."""
    if not all(map(math.isfinite, v)):
        return False, False
    a, b, c, _, d, e, f, _, g, h, i, _, w, x, y, z = v
    tol, bottom = _RIGID_TOL, _BOTTOM_TOL
    rigid = (
        abs(a * a + b * b + c * c - 1.0) < tol
        and abs(d * d + e * e + f * f - 1.0) < tol
        and abs(g * g + h * h + i * i - 1.0) < tol
        and abs(a * d + b * e + c * f) < tol
        and abs(a * g + b * h + c * i) < tol
        and abs(d * g + e * h + f * i) < tol
        and abs(w) < bottom
        and abs(x) < bottom
        and abs(y) < bottom
        and abs(z - 1.0) < bottom
    )
    return True, rigid


_RIGID_C: list = []  # [lean_ext.rigid_pose or None] once tried


def rigid_one(T: np.ndarray) -> bool:
    """check_one_pose(T)[1] for one (4, 4) float64 ndarray T: the same rule, made in C by
    the lean extension where it builds (native/lean_ext.c rigid_pose, ~0.1 us instead of
    ~1 us), else in Python floats."""
    if not _RIGID_C:
        from deltagen.native.lean import extension

        module = extension()
        _RIGID_C.append(None if module is None else module.rigid_pose)
    rigid_c = _RIGID_C[0]
    if rigid_c is not None:
        rigid = rigid_c(T, _RIGID_TOL, _BOTTOM_TOL)
        if rigid is not None:
            return rigid
    return check_one_pose(T.ravel().tolist())[1]


def check_poses(T, name="T"):
    """The one check of target poses (every ik / ik_all call, single pose or batch):
    (lead, flat (N, 4, 4), finite (N,), rigid (N,)). rigid: finite, the rotation block
    orthonormal (|R R^T - I| < 1e-6 entrywise) and the bottom row 0 0 0 1 to 1e-12.
    One pose is checked with Python floats (the same rule, a tenth of the time)."""
    if type(T) is np.ndarray and T.shape == (4, 4) and T.dtype.char == "d":
        arr = np.ascontiguousarray(T)
    else:
        arr = as_float_array(T, name, "(..., 4, 4)")
        if arr.ndim < 2 or arr.shape[-2:] != (4, 4):
            raise InputError(f"{name} must have shape (..., 4, 4), got {arr.shape}")
    lead = arr.shape[:-2]
    flat = arr.reshape(-1, 4, 4)  # C-contiguous
    if flat.shape[0] == 1:
        finite, rigid = check_one_pose(flat.ravel().tolist())
        return lead, flat, np.array([finite]), np.array([rigid])
    m = np.ascontiguousarray(flat.reshape(-1, 16).T)  # (16, N): contiguous columns
    finite = np.isfinite(m).all(axis=0)
    # R R^T entry by entry on columns of the batch (its 6 distinct entries: the (i, j)
    # and (j, i) sums are the same products in the same order): a batched 3 x 3 matmul
    # was ~0.7 us per pose, a third of the UR5's whole ik_all
    rows = [[m[4 * i + k] for k in range(3)] for i in range(3)]
    with np.errstate(all="ignore"):
        rigid = (np.abs(m[12:] - _BOTTOM[:, None]) < _BOTTOM_TOL).all(axis=0)
        for i in range(3):
            for j in range(i, 3):
                a, b = rows[i], rows[j]
                g = a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
                rigid &= np.abs(g - _EYE3[i, j]) < _RIGID_TOL
    return lead, flat, finite, rigid & finite


def raise_bad_poses(finite, rigid, name="T"):
    """InputError naming the rows of T that are not finite, or not rigid transforms."""
    nonfinite = np.flatnonzero(~finite)
    if nonfinite.size:
        raise InputError(
            f"{name} contains NaN or infinite values in rows {rows_text(nonfinite)}",
            nonfinite,
        )
    bad = np.flatnonzero(~rigid)
    if bad.size:
        raise InputError(
            f"{name} is not a rigid transform (rotation block not orthonormal, or bottom "
            f"row not [0, 0, 0, 1]) in rows {rows_text(bad)}",
            bad,
        )


class IKResult(NamedTuple):
    """ik's batch answer (IKPlanner.solve): q (N, n) (NaN where not valid), valid (N,),
    cause (the error naming each unsolved row's cause, when asked for and some row is
    unsolved; else None) and complete (the method used finds every solution: the closed
    forms; ik_all's answer says it in IKSolutions.complete)."""

    q: FloatArray
    valid: BoolArray
    cause: Exception | None
    complete: bool


def _plain_request(
    config: Any, q0: Any, method: Any, errors: Any, singular: Any, options: Any
) -> bool:
    """An ik request the one-call numeric path may serve (IKPlanner.remember / remembered):
    no config, q0 or options, and method, errors, singular plain str (their own hash and
    equality, so a remembered request cannot be matched by a look-alike)."""
    return (
        config is None
        and q0 is None
        and not options
        and type(method) is str
        and type(errors) is str
        and type(singular) is str
    )


class IKPlanner:
    """The choice of inverse-kinematics method of one serial arm, made once per arm
    (SerialRobot builds it): ``ik_all`` and ``solve_all`` (ik_all's paths), ``solve`` (ik's
    batch path) and ``one`` (ik's lean one-pose paths). The capabilities those choices read
    are attributes, each made on first use: ``analytic`` (the closed form or None),
    ``combined`` (the combined method's module or None), ``general`` ((eliminations,
    complete) of the general 6R solver or None), ``reach``, ``z_only`` and
    ``partial_mask``; the one-pose paths made on the way are ``ik_all_single`` (the C
    closed form's), ``ik_all_checked`` (the same with the pose's check in C),
    ``general_single`` (the complete solver's: None not made yet, False
    none), ``numeric_solver`` and ``numeric_lean`` (the numeric solver's whole one-pose
    path in one C call, for the requests in ``lean_requests``)."""

    def __init__(self, arm: Any) -> None:
        self.arm = arm
        self.core = arm._core
        self.description = arm.description
        self.n = arm.n
        self.name = arm.name
        self.backend = arm.backend
        self.jacobian_single = arm._jacobian_single  # None: the batched Jacobian
        compiled = arm.backend == "compiled"
        self.ik_all_single: Any = None  # made by ik_all when the arm has a C closed form
        # with it, where the C extension builds: ik_all(T) of one (4, 4) float64 pose
        # (methods "auto" and "closed_form") as one C call, the pose checked in C; None
        # for any other input (native.serial.CompiledArm.checked_ik_all)
        self.ik_all_checked: Any = None
        self.general_single: Any = None if compiled else False  # numpy engine: general path
        self.numeric_solver: Any = None  # the C numeric solver's one-pose path
        self.mid_range: Any = None  # the numeric solver's default start (n,)
        # the numeric ik of one pose in one C call, per ``singular`` (lean_numeric; None:
        # it does not serve this arm), and the requests (method, errors, singular) of ik,
        # without config, q0 or options, that it answers: accepted once by SerialRobot.ik's
        # checks (remember), so a later call with the same arguments goes straight to it
        self.numeric_lean: dict[str, Any] = {}
        self.lean_requests: dict[tuple[str, str, str], Any] = {}
        self.reversed: Any = None  # the reversed chain's arm (a closed form solved backwards)
        # ik_all: whether each method used so far is complete (warned once where it is not)
        self.completeness: dict[str, bool] = {}

    def configs(self) -> tuple[str, ...]:
        """Branch names of ik_all ((), if the arm has none): the closed form's, or for a
        6R arm whose wrist axes nearly meet, those of its nearest central-wrist arm."""
        return self.config_names

    @cached_property
    def config_names(self) -> tuple[str, ...]:
        """configs(), made once (the arm's closed form and combined method do not change)."""
        solver = self.analytic
        if solver is not None:
            return tuple(solver.configs)
        combined = self.combined
        return () if combined is None else combined.branch_names(self.arm)

    @cached_property
    def analytic(self) -> Any:
        """The closed form of deltagen.solve.analytic for this arm's structure (or its nearest
        exact arm's, deltagen.solve.nearest), else None."""
        from deltagen.solve.nearest import closed_form_solver

        return closed_form_solver(self.description)

    @cached_property
    def combined(self) -> Any:
        """deltagen.solve.combined when it applies to this arm, else None."""
        from deltagen.solve import combined as ik_combined

        try:
            ik_combined.nearest_central_wrist(self.description)
        except (InputError, GeometryError):
            return None
        return ik_combined

    @cached_property
    def general(self) -> Any:
        """(eliminations, complete) of deltagen.solve.general6r for a 6R arm, else None."""
        if self.n == 6 and all(j.revolute for j in self.description.joints):
            from deltagen.solve import general6r

            return general6r.eliminations(self.description)
        return None

    def all_method(self, method: str) -> str | None:
        """The path ik_all(T, method) takes on this arm: "closed_form", "complete" or
        "combined" (None: no method applies, ik_all refuses). "auto" is the closed form
        where the structure has one; else, for a 6R arm, the general solver when one of its
        eliminations is regular or the combined method does not apply; else the combined
        method."""
        if method != "auto":
            return method
        if self.analytic is not None:
            return "closed_form"
        general, combined = self.general, self.combined
        if general is not None and (general[1] or combined is None):
            return "complete"
        return "combined" if combined is not None else None

    def ik_all(self, T: Any, method: str = "auto") -> IKSolutions:
        """SerialRobot.ik_all (its docstring states the methods and ``complete``): the
        solutions, and the IncompleteSolutionsWarning once per method where the method
        used may miss solutions."""
        one = self.ik_all_checked  # one pose, the closed form's whole call in C (else None)
        if one is not None and (method == "auto" or method == "closed_form"):
            solutions = one(T)  # None: not one finite rigid (4, 4) float64 pose, or INVALID
            if solutions is not None:
                return solutions
        q, valid = self.solve_all(T, method)
        complete = self.completeness.get(method)
        if complete is None:
            complete = self.completeness[method] = self._ik_all_complete(method)
            if not complete:
                self._warn_incomplete(method)
        return IKSolutions.of(q, valid, complete)

    def _warn_incomplete(self, method: str) -> None:
        """The IncompleteSolutionsWarning of ik_all (stacklevel: the caller of
        SerialRobot.ik_all)."""
        why = (
            "the combined method (the nearest central-wrist arm's branches, refined by "
            "Newton) may miss solutions"
            if method == "combined" or (method == "auto" and self.combined is not None)
            else "the general 6R solver's eliminations are singular for this arm (no "
            "closed form either): its answer is a best effort"
        )
        warnings.warn(
            f"ik_all of {self.name} (method={method!r}) is not complete: {why}; a pose "
            "without a valid solution may still be reachable (result.complete is False)",
            IncompleteSolutionsWarning,
            stacklevel=4,
        )

    def _ik_all_complete(self, method: str) -> bool:
        """Whether ik_all's ``method`` finds every solution of this arm (ik_all's docstring):
        the same choice of path as _ik_all's."""
        if method == "combined":
            return False
        solver = self.analytic
        if solver is not None and method in ("auto", "closed_form"):
            return True
        # "complete", or "auto" without a closed form: the general solver, complete when its
        # elimination is regular (else its best effort, or the combined method)
        general = self.general
        return general is not None and bool(general[1])

    def solve_all(self, T: Any, method: str) -> tuple[FloatArray, BoolArray]:
        """ik_all's (q, valid) by ``method`` (the choice of path: ik_all's docstring)."""
        one = self.general_single
        if (
            one
            and type(T) is np.ndarray
            and T.shape == (4, 4)
            and T.dtype is _F64
            and (method == "complete" or (method == "auto" and one.auto))
            and rigid_one(T)
        ):  # one pose, complete solver: one C call (general6r.single), after check_poses' rule
            return one(T if T.flags.c_contiguous else np.ascontiguousarray(T))
        if method not in ALL_METHODS:
            raise InputError(
                f'method must be "auto", "closed_form", "complete" or "combined", got {method!r}'
            )
        solver = self.analytic
        if method == "auto" and solver is None and self.all_method("auto") == "complete":
            method = "complete"
        if method == "complete":
            general = self.general
            if general is None:
                raise InputError(f"{self.name}: the complete solver needs a 6R arm")
            from deltagen.solve import general6r

            if one is None and general[1]:  # made once: the fast path above from now on
                made = general6r.single(self.arm, general[0])
                self.general_single = made if made is not None else False
                if made is not None:
                    made.auto = solver is None  # "auto" is "complete" here (checked above)
                    if type(T) is np.ndarray and T.shape == (4, 4) and T.dtype is _F64:
                        return self.solve_all(T, method)
            lead, flat, finite, rigid = check_poses(T)
            safe = flat.copy()
            safe[~rigid] = np.eye(4)
            extra = None
            if not general[1] and self.combined is not None:
                # an incomplete (singular-pencil) elimination: the combined method's
                # branches join the candidates
                extra = self.combined.solve_all(self.arm, safe)[0]
            q, valid = general6r.solve(self.arm, safe, general[0], extra=extra)
            q[~rigid], valid[~rigid] = np.nan, False
            k = q.shape[1]
            return q.reshape(lead + (k, self.n)), valid.reshape(lead + (k,))
        if method == "combined":
            if self.combined is None:
                raise InputError(f"{self.name}: the combined method does not apply")
            lead, flat, finite, rigid = check_poses(T)
            return self.solve_rows(lead, flat, rigid, None, self.combined)
        if method == "closed_form" and solver is None:
            raise InputError(f"{self.name} has no closed-form inverse")
        combined = self.combined if solver is None else None
        if solver is None and combined is None:
            raise InputError(f"{self.name} has no closed-form inverse; use ik(T, method='numeric')")
        single = self.ik_all_single
        if single is not None and type(T) is np.ndarray and T.shape == (4, 4) and T.dtype is _F64:
            # one pose: the lean path, after the same check as check_poses'
            if rigid_one(T):
                result = single(T)
                if result is not None:
                    return result
        lead, flat, finite, rigid = check_poses(T)  # every call, whichever path follows
        if single is not None and flat.shape[0] == 1 and rigid[0]:
            result = single(flat[0])
            if result is not None:
                q1, valid1 = result
                return q1.reshape(lead + q1.shape), valid1.reshape(lead + valid1.shape)
        return self.solve_rows(lead, flat, rigid, solver, combined)

    def reversed_arm(self, solver: Any) -> Any:
        """The reversed chain (model/structure.py reversed_description) as an arm of this
        backend, made once: its compiled closed form serves ik_all (built on first use)."""
        if self.reversed is None:
            self.reversed = type(self.arm)(
                solver.reversed_description, self.backend, threads=self.arm.threads
            )
        return self.reversed

    def solve_rows(self, lead, flat, good, solver, combined):
        """ik_all's general path for checked poses (good: finite rigid rows)."""
        bad = ~good
        safe = flat.copy()
        safe[bad] = np.eye(4)
        k = len(self.configs())
        from deltagen.solve.analytic import ReversedSolver, invert

        if isinstance(solver, ReversedSolver) and self.backend == "compiled":
            # solved backwards: the reversed chain's own compiled closed form for T^-1
            back = self.reversed_arm(solver)
            q, valid = back.ik_planner.solve_all(invert(safe), "closed_form")
            q = np.ascontiguousarray(q[..., ::-1])
        elif solver is not None and self.backend == "compiled" and self.core.has_ik_all:
            q, valid, _ = self.core.ik_all(safe, k)  # the generated C (ik_kernel.py)
            if self.ik_all_single is None:
                self.ik_all_single = self.core.single_ik_all(k)
                # the whole one-pose call in C, check_one_pose's rule included (a closed
                # form: complete); ik_all calls it first
                self.ik_all_checked = self.core.checked_ik_all(
                    k, (_RIGID_TOL, _BOTTOM_TOL), _CompleteIKSolutions
                )
        elif solver is not None:
            q, valid = solver.solve(safe)
        else:  # explicit start from the nearest central-wrist arm, refined by Newton
            assert combined is not None  # solver is None here, so combined is not
            q, valid = combined.solve_all(self.arm, safe)
        q[bad], valid[bad] = np.nan, False
        return q.reshape(lead + (k, self.n)), valid.reshape(lead + (k,))

    def choose(self, method: str, config: Any, options: dict[str, Any]) -> tuple[bool, Any]:
        """ik's method for ``method`` (checked: "auto", "analytic" or "numeric"), after
        checking that ``config`` and ``options`` apply to it: (analytic: the closed form's
        branches, else the numeric solver; the numeric options checked by
        deltagen.solve.numeric.check_options, or None)."""
        configs = self.configs()
        if method == "analytic" and not configs:
            raise InputError(f"{self.name} has no closed-form inverse; use method='numeric'")
        analytic = method == "analytic" or (method == "auto" and bool(configs))
        if config is not None:
            if not analytic:
                raise InputError(
                    f"config picks a closed-form branch; it does not apply to the numeric "
                    f"method ({self.name}, method={method!r}; give q0 to choose the start)"
                )
            if not isinstance(config, str) or config not in configs:
                raise InputError(f"unknown configuration {config!r}; {self.name} has {configs}")
        if options:
            from deltagen.solve import numeric as ik_numeric

            unknown = sorted(set(options) - set(ik_numeric.OPTIONS))
        else:
            unknown = []
        if unknown:
            raise InputError(
                f"ik got unknown option(s) {', '.join(unknown)}; it takes config, q0, method, "
                f"errors, singular and, for method='numeric', {', '.join(ik_numeric.OPTIONS)}"
            )
        checked = None
        if analytic:
            if options:
                raise InputError(
                    f"option(s) {', '.join(sorted(options))} apply to method='numeric' only; "
                    f"this call uses {self.name}'s closed form (method={method!r})"
                )
        else:
            # max_iter >= 1 here; no options: the defaults, which pass
            checked = ik_numeric.check_options(self.arm, **options) if options else None
        return analytic, checked

    # -- ik -------------------------------------------------------------------------

    def solve(self, flat, good, start, analytic, config, singular, options, explain):
        """ik's batch path for checked targets flat (N, 4, 4) (good: the rows to solve,
        finite rigid poses with a finite start) and start rows (N, n) or None, by the method
        SerialRobot._ik_request chose (``analytic``: the closed form's branches, else the
        numeric solver). ``explain``: name each unsolved row's cause (errors="raise")."""
        complete = bool(analytic and self.analytic is not None)
        if analytic:
            q_all, valid_all = self.solve_rows(
                (flat.shape[0],), flat, good, self.analytic, self.combined
            )
            q, ok = self.pick_branch(q_all, valid_all, config, start)
        else:
            from deltagen.solve import numeric as ik_numeric

            if start is None:
                start = self.start(None, (flat.shape[0],))
            with np.errstate(all="ignore"):  # huge targets: the distances overflow to inf
                dist, reach = self.reach_of(flat)
            good = good & ~(dist > reach)  # beyond the reach: no attempt (and no restarts)
            q = np.full((flat.shape[0], self.n), np.nan)
            ok = np.zeros(flat.shape[0], dtype=bool)
            if np.any(good):  # only these rows: a placeholder target would cost its restarts
                result = ik_numeric.solve(self.arm, flat[good], start[good], **options)
                q[good], ok[good] = result.q, result.converged
            unfit = np.zeros_like(ok)
            if "mask" not in options and self.partial_mask and np.any(ok):
                # the default mask of an arm with fewer than 6 joints matches what it can
                # move; a target it cannot take in the other components (a tilted SCARA
                # tool) is not reached: no solution here (mask= asks for the fit)
                unfit[ok] = ~self.reaches_fully(q[ok], flat[ok])
                ok = ok & ~unfit
        q = q.copy()
        q[~ok] = np.nan
        if singular == "raise" and np.any(ok):
            at_singularity = np.zeros_like(ok)
            at_singularity[ok] = self.singular_rows(q[ok])
            if np.any(at_singularity):
                if explain:
                    bad = np.flatnonzero(at_singularity)
                    cause = SingularityError(
                        f"the target is at a singularity of {self.name} (sigma_min/sigma_max "
                        f"< {SINGULAR_TOL:g}; the solution is not unique) in rows "
                        f"{rows_text(bad)}; singular='allow' returns one of its solutions",
                        bad,
                    )
                    return IKResult(q, ok & ~at_singularity, cause, complete)
                ok = ok & ~at_singularity
                q[at_singularity] = np.nan
        cause = None
        if explain and not np.all(ok):
            bad = np.flatnonzero(~ok)
            unfit_rows = None if analytic else np.flatnonzero(unfit)
            cause = self.unsolved(flat, bad, analytic, config, options, unfit_rows)
        return IKResult(q, ok, cause, complete)

    # -- why a target has no solution (errors="raise" only: the error path) -------------

    @cached_property
    def partial_mask(self) -> bool:
        """True when the numeric solver's default mask leaves pose components out (arms
        with fewer than 6 joints): its solutions are then checked against the whole pose."""
        from deltagen.solve.numeric import default_mask

        return not bool(default_mask(self.arm).all())

    def reaches_fully(self, q, T, tol=1e-8):
        """Rows where fk(q) is the whole target pose T: position within tol [m], rotation
        within tol [rad] (the closed form's tolerance, analytic.AnalyticSolver.solve)."""
        from deltagen.solve.numeric import pose_error

        Tq, _ = self.core.fk(np.ascontiguousarray(q))
        err = pose_error(Tq, T)
        return (np.linalg.norm(err[:, :3], axis=1) <= tol) & (
            np.linalg.norm(err[:, 3:], axis=1) <= tol
        )

    def unsolved(self, flat, bad, analytic, config, options, unfit=None):
        """UnreachableError for the unsolved rows ``bad`` of finite rigid targets, naming
        each row's cause: out of reach, an orientation this structure cannot reach, a
        solution only outside the joint limits, or (numeric) no convergence."""

        with np.errstate(all="ignore"):  # huge targets: the distances overflow to inf
            return self.unsolved_rows(flat[bad], bad, analytic, config, options, unfit)

    def unsolved_rows(self, T, bad, analytic, config, options, unfit):
        cause = np.full(bad.size, "", dtype=object)
        dist, reach = self.reach_of(T)
        far = dist > reach
        tilt = self.tilt_of(T)
        solver = self.analytic if analytic else None
        if solver is not None:
            with np.errstate(all="ignore"):
                _, free = solver.solve(T, limits=False)
                _, within = solver.solve(T)
            k = None if config is None else self.configs().index(config)
            sel = slice(None) if k is None else k
            exists = np.asarray(free[:, sel]).reshape(bad.size, -1).any(axis=1)
            other = within.any(axis=1) & (k is not None)
            cause[exists] = "its solution lies outside the joint limits"
            cause[~exists & other] = f"no solution in configuration {config!r} (others exist)"
            oriented = np.zeros(bad.size, dtype=bool)
            if solver.detected.position_only_ok:
                _, pos = solver.solve(T, limits=False, position_only=True)
                oriented = pos.any(axis=1)
            cause[(cause == "") & tilt & ~far] = "orientation not reachable: tilted"
            cause[(cause == "") & oriented & ~far] = "orientation not reachable"
        elif not analytic:
            from deltagen.solve.numeric import DEFAULTS

            max_iter = options.get("max_iter", DEFAULTS["max_iter"])
            restarts = options.get("restarts", DEFAULTS["restarts"])
            fitted = np.isin(bad, unfit) if unfit is not None else np.zeros(bad.size, bool)
            cause[fitted & tilt] = "orientation not reachable: tilted"
            cause[fitted & ~tilt] = "pose not reachable: fitted"
            cause[~fitted] = (
                f"no convergence in max_iter={max_iter} steps and restarts={restarts} "
                "(a target outside the joint limits or a poor start; try restarts= or "
                "another q0)"
            )
        cause[far] = "out of reach"
        cause[cause == ""] = (
            "out of reach"
            if solver is not None
            else "no solution found (out of reach or outside the joint limits)"
        )
        parts = []
        for text in dict.fromkeys(cause):
            rows = bad[cause == text]
            if text == "out of reach":
                sub = far[cause == text]
                detail = (
                    f" (the tool point is up to {float(np.max(dist[cause == text])):.4g} m "
                    f"from the base; {self.name} reaches at most {reach:.4g} m)"
                    if np.any(sub)
                    else " (no closed-form solution)"
                )
                text = text + detail
            elif text == "orientation not reachable: tilted":
                text = (
                    f"orientation not reachable by this structure ({self.name} turns the "
                    "tool about the base z axis only; the target's tool axis is tilted)"
                )
            elif text == "pose not reachable: fitted":
                text = (
                    f"pose not reachable by this structure ({self.name} matches the "
                    "components it can move, but not the whole target; mask= asks for "
                    "that fit)"
                )
            elif text == "orientation not reachable":
                text = (
                    f"orientation not reachable by this structure ({self.name} cannot reach "
                    "the target's rotation at that position; the position alone is reachable)"
                )
            parts.append(f"{text} in rows {rows_text(rows)}")
        return UnreachableError(f"ik of {self.name} has no solution: " + "; ".join(parts), bad)

    @cached_property
    def reach(self) -> float:
        """The arm's reach [m]: for arms of revolute joints only the distance between
        consecutive joint frames is constant, so their sum bounds it; otherwise inf."""
        reach = np.inf
        if all(j.revolute for j in self.description.joints):
            F, _ = self.core.frames(np.zeros((1, self.n)))
            o = F[0, :, :3, 3]
            reach = float(np.sum(np.linalg.norm(np.diff(o, axis=0), axis=1)))
            reach = reach * (1 + 1e-9) + 1e-12
        return reach

    def reach_of(self, T):
        """(distance of each target's tool point from the base origin, the arm's reach)."""
        base_origin = self.description.base[:3, 3]
        return np.linalg.norm(T[:, :3, 3] - base_origin, axis=1), self.reach

    @cached_property
    def z_only(self) -> Any:
        """R0 (tool rotation at q = 0) if every reachable tool rotation is Rz(a) R0 (the
        SCARAs, the planar arms: checked at fixed sample configurations), else None."""
        rng = np.random.default_rng(7)
        qs = np.vstack([np.zeros(self.n), rng.uniform(-2.0, 2.0, (8, self.n))])
        R, _ = self.core.fk(np.ascontiguousarray(qs))
        R = R[:, :3, :3]
        Rrel = R @ R[0].T
        z_only = np.all(np.abs(Rrel[:, 2, 2] - 1.0) < 1e-9)
        return R[0].copy() if z_only else None

    def tilt_of(self, T):
        """Rows of T whose rotation this arm cannot reach by turning about z (only for the
        arms of z_only; False elsewhere)."""
        R0 = self.z_only
        if R0 is None:
            return np.zeros(T.shape[0], dtype=bool)
        Rrel = T[:, :3, :3] @ R0.T
        return np.linalg.norm(Rrel[:, :, 2] - [0.0, 0.0, 1.0], axis=1) > 1e-8

    def one(self, T, config, q0a, analytic, errors, singular, options):
        """ik's lean paths for one checked rigid pose T (4, 4) C-contiguous: the C closed
        form's branch, or the C numeric solver (every attempt in C) -- ik's result, or None
        when the general path must answer (it then raises or reports the errors)."""
        if analytic:
            if errors == "raise" and q0a is None and self.ik_all_single is not None:
                q = self.closed_form_one(T, config)
                if q is not None and (singular == "allow" or not self.singular_one(q)):
                    return q
            return None
        if not (
            self.backend == "compiled"
            and (not options or options.keys() <= {"restarts", "seed"})
            and (q0a is None or (q0a.shape == (self.n,) and all(map(math.isfinite, q0a.tolist()))))
        ):
            return None
        q = self.numeric_one(T, q0a, options)
        if q is None:
            return None
        if self.partial_mask and not self.reaches_fully(q[None], T[None])[0]:
            return None  # the general path names the pose the arm cannot take
        if singular == "allow" or not self.singular_one(q):
            return q if errors == "raise" else (q, np.array(True))
        return None

    def singular_rows(self, q):
        """Rows of finite q (M, n) whose Jacobian is singular: sigma_min / sigma_max <
        SINGULAR_TOL. Only rows that bound_clears does not clear need the SVD."""
        J, _ = self.core.jacobian(np.ascontiguousarray(q, dtype=float))
        with np.errstate(all="ignore"):
            check = ~bound_clears(J)
        singular = np.zeros(J.shape[0], dtype=bool)
        if np.any(check):
            sv = np.linalg.svd(J[check], compute_uv=False)
            singular[check] = ~(sv[:, -1] >= SINGULAR_TOL * sv[:, 0])
        return singular

    def numeric_one(self, T, q0, options):
        """Fast path of the numerical ik for one checked target T (4, 4) and q0 None or a
        finite (n,) array (ik_numeric.single_solver), with the checked options (at most
        ``restarts`` and ``seed``; the solver's defaults are numeric.DEFAULTS'): q, or None
        when the general path must answer (the first attempt did not converge: restarts and
        errors are its)."""
        solver = self.single_numeric()
        start = self.mid_range if q0 is None else np.ascontiguousarray(q0)
        if not options:
            return solver(T, start)
        given = {"restarts": int(options["restarts"])} if "restarts" in options else {}
        if "seed" in options:
            given["seed"] = options["seed"]
        return solver(T, start, **given)

    def single_numeric(self) -> Any:
        """The C numeric solver's one-pose path (ik_numeric.single_solver; the compiled
        backend) and its default start ``mid_range``, made on first use."""
        solver = self.numeric_solver
        if solver is None:
            from deltagen.solve.numeric import single_solver

            solver = self.numeric_solver = single_solver(self.arm)
            self.mid_range = np.ascontiguousarray(self.start(None, (1,))[0])
        return solver

    def one_plain(
        self,
        T: Any,
        config: Any,
        q0a: Any,
        analytic: bool,
        errors: str,
        singular: str,
        options: Any,
    ) -> tuple[Any, bool]:
        """:meth:`one` for one pose as a plain C-ordered (4, 4) float64 array that passes
        check_poses' rule in Python floats (rigid_one). (q, True): answered; (None, True):
        such a pose the lean paths left to the general one (which checks T itself and must
        not try one() again); (None, False): not such a pose."""
        if not (
            type(T) is np.ndarray
            and T.dtype is _F64
            and T.shape == (4, 4)
            and T.flags.c_contiguous
            and rigid_one(T)
        ):
            return None, False
        return self.one(T, config, q0a, analytic, errors, singular, options), True

    def remembered(
        self, T: Any, config: Any, q0: Any, method: Any, errors: Any, singular: Any, options: Any
    ) -> tuple[Any, bool]:
        """SerialRobot.ik's first try: a request its checks accepted before (:meth:`remember`)
        answered for one (4, 4) float64 pose by one C call (:meth:`lean_numeric`: the
        pose's check, the numeric solve, the cheap singularity test; the same bits as
        :meth:`one`). (q, True): answered; (None, True): this path had the pose and did
        not answer it (not rigid, no convergence: the general path must not try it
        again); (None, False): not such a request or pose."""
        if not _plain_request(config, q0, method, errors, singular, options):
            return None, False
        lean = self.lean_requests.get((method, errors, singular))
        if lean is None:
            return None, False
        q = lean(T)  # False: not such a pose, the other paths take it
        if type(q) is np.ndarray:
            return q, True
        if q is False:
            return None, False
        if q is not None and not self.singular_one(q[0]):
            return q[0], True  # solved; not cleared by the cheap test, by the SVD
        return None, True

    def remember(
        self,
        config: Any,
        q0: Any,
        method: Any,
        errors: Any,
        singular: Any,
        options: Any,
        analytic: bool,
    ) -> None:
        """Note a request of ik that its checks accepted: where it is plain (no config, q0
        or options, str arguments with their own hash and equality) and answered by the
        numeric method, lean_requests maps it to lean_numeric(singular) for errors="raise"
        (None otherwise: the usual path), so that SerialRobot.ik answers the same request
        for one plain pose in one C call (:meth:`remembered`)."""
        if not analytic and _plain_request(config, q0, method, errors, singular, options):
            key = (method, errors, singular)
            if key not in self.lean_requests:
                lean = self.lean_numeric(singular) if errors == "raise" else None
                self.lean_requests[key] = lean

    def lean_numeric(self, singular: str) -> Any:
        """one()'s numeric path for q0 None, no options and errors="raise" as one C call
        (native/lean_ext.c ik_one_kernel): ``call(T)`` with T a (4, 4) float64 array makes
        rigid_one's check, numeric_one's solve from mid_range and, for singular="raise",
        singular_one's cheap C test, with the same functions on the same numbers (the same
        bits), and returns q (solved, cleared), (q,) (solved, not cleared by the cheap test:
        singular_one decides), None (not a finite rigid pose, or no convergence: the
        general path answers) or False (T is not one (4, 4) float64 array: the other paths
        take it). None instead of the callable where one() would not take that
        path alone: the numpy backend, no extension, a default mask that leaves components
        out (reaches_fully decides), no C test of a square Jacobian for singular="raise"."""
        if singular in self.numeric_lean:
            return self.numeric_lean[singular]
        lean = None
        regular = self.regular_single if singular == "raise" else None
        if (
            self.backend == "compiled"
            and not self.partial_mask
            and (singular == "allow" or regular is not None)
        ):
            solver = self.single_numeric()
            if solver.lean is not None:  # made by the extension: it is there
                from deltagen.native.lean import extension

                lean = extension().ik_one_kernel(
                    solver.lean, regular, self.mid_range, _RIGID_TOL, _BOTTOM_TOL
                )
        self.numeric_lean[singular] = lean
        return lean

    @cached_property
    def regular_single(self) -> Any:
        """The C form of singular_one's cheap test for a square Jacobian (native.serial
        CompiledArm.single_regular), or None."""
        make = getattr(self.core, "single_regular", None)
        return make(SINGULAR_TOL) if make is not None and self.n == 6 else None

    def singular_one(self, q):
        """singular_rows for one configuration, lean (the single-pose fast path)."""
        regular = self.regular_single
        if regular is not None:
            cleared = regular(q)  # |det J| >= SINGULAR_TOL |J|_F^6, in C
            if cleared is True:
                return False
            if cleared is False:
                return bool(self.singular_rows(q[None])[0])
        J = self.jacobian_single(q)
        if J is not None and bound_clears(J):
            return False
        return bool(self.singular_rows(q[None])[0])

    def closed_form_one(self, T, config):
        """Fast path of ik for one checked pose with a C closed form (config checked by
        _ik_request): q, or None when the general path must answer (it raises the errors)."""
        result = self.ik_all_single(T)
        if result is None:
            return None
        q_all, valid = result
        k = int(valid.argmax()) if config is None else self.analytic.configs.index(config)
        return q_all[k] if valid[k] else None

    def start(self, q0, lead):
        """(N, n) start rows for targets of leading shape ``lead``: q0 (checked by
        _ik_request) broadcast against it, or the middle of the joint ranges (0 where a
        range is unbounded)."""
        count = int(np.prod(lead))
        if q0 is None:
            lim = self.description.qlim
            bounded = np.isfinite(lim).all(axis=1)
            mid = np.where(bounded, np.where(bounded[:, None], lim, 0.0).mean(axis=1), 0.0)
            return np.tile(mid, (count, 1))
        try:
            start = np.broadcast_to(q0, tuple(lead) + (self.n,))
        except ValueError:
            raise InputError(
                f"q0 of shape {q0.shape} does not broadcast to the targets' leading shape "
                f"{tuple(lead)}"
            ) from None
        return np.ascontiguousarray(start.reshape(count, self.n))

    def pick_branch(self, q_all, valid_all, config, start):
        """The branch of each row: ``config`` (checked by _ik_request), else the valid
        branch nearest the start rows (N, n), else the first valid one."""
        configs = self.configs()
        rows = np.arange(q_all.shape[0])
        if config is not None:
            k = configs.index(config)
            return q_all[:, k], valid_all[:, k]
        if start is not None:
            d = wrap_to_pi(q_all - start[:, None, :])
            revolute = np.array([j.revolute for j in self.description.joints])
            d = np.where(revolute, d, q_all - start[:, None, :])
            dist = np.where(
                valid_all, np.linalg.norm(np.nan_to_num(d, nan=np.inf), axis=-1), np.inf
            )
            k = np.argmin(dist, axis=1)
        else:
            k = np.argmax(valid_all, axis=1)
        return q_all[rows, k], valid_all[rows, k]
