"""Combined explicit + numerical inverse kinematics: all branches of a 6R elbow arm whose
wrist is *nearly* central (the wrist axes miss one common point by a few centimetres).

This is the last method of the EASY-ROB paper ("Kombination aus explizitem und
numerischem Loesungsverfahren"): a numerical method alone finds one configuration per start,
so for every configuration

1. solve the *nearest central-wrist arm* (the same arm with the wrist offsets set to zero) in
   closed form for that configuration; this is the start value q_ist;
2. refine q_ist by Newton's method on the real arm (q_soll);
3. go on with the next configuration.

Start values (two additions to the paper's step 1): where the central-wrist arm just misses
the pose (the offset changes the reach by up to its length; the elbow's law of cosines has no
real solution), the closed form is clipped onto the nearest real elbow angle instead of
giving up. And the start is improved by ``corrections`` passes of a target correction: with
the current start q, the central-wrist arm is solved again for T' = fk_c(q) fk(q)^-1 T
(fk_c: central-wrist arm, fk: real arm), keeping the branch, which removes the offset's effect
to first order. On 500 random in-limit Puma-with-a4 = 2 cm poses, the original q was among the
valid branches for 470 / 478 / 486 poses with 0 / 1 / 2 passes (default 2), median Newton steps
per valid branch 3 / 2 / 2.

The closed form comes from :func:`deltagen.solve.nearest.closed_form_solver` (structure
``spherical_wrist_6r``), the refinement from :func:`deltagen.solve.numeric.solve`
(damped Newton, ``restarts=0``, started at the branch). Everything is batched: the N poses
times k branches are one Newton batch of N k rows.

``nearest_central_wrist(desc)`` removes the wrist offsets of a 6-joint description:

* standard DH (joint i turns about z_{i-1}; the wrist axes are z3, z4, z5): a4 (distance
  z3-z4, axes 4-5), a5 (distance z4-z5, axes 5-6) and d5 (shift along axis 5 between the
  common normals) are set to 0;
* modified DH (Craig; joint i turns about z_i; wrist axes z4, z5, z6): a of row 5 (a_4,
  axes 4-5), a of row 6 (a_5, axes 5-6) and d of row 5 (d_5) are set to 0.

Everything else (d4, the tool offset along axis 6 (d6), alpha, offsets, limits, base, tool)
is kept. Universal coordinates are not supported (InputError). The result is checked:
:func:`closed_form_solver` must accept it (InputError otherwise).

``solve_all(arm, T)`` returns ``q`` (..., k, n) and ``valid`` (..., k) in the branch order
and with the names of the closed-form solver (``branch_names(arm)``, for a Puma-like arm
``{front|back}_{up|down}_{noflip|flip}``). A branch is valid when Newton converged within
``tol`` (position [m] and rotation [rad] error norms) and the solution lies within the joint
limits (revolute angles are shifted by 2 pi into the limits where that fits, as the analytic
solver does: :func:`deltagen.geometry.limits.fit_limits`). Converged solutions outside the
limits keep their values with valid False; branches without a start (the central-wrist arm
cannot reach the pose) or without convergence are NaN. Newton runs with the limits
unenforced (``respect_limits=False``) so that a branch is not pushed into a different
solution by clamping; the limits are checked afterwards. Two branches can converge to the
same solution near singularities (the wrist flip at q5 ~ 0, the stretched elbow); they are
not merged.

Non-finite or non-rigid targets give NaN / False; nothing raises or warns for unreachable
targets.
"""

from __future__ import annotations

import dataclasses
import weakref

import numpy as np

from deltagen.geometry.limits import fit_limits
from deltagen.inputs import InputError
from deltagen.model.serial import SerialDescription
from deltagen.solve import numeric as ik_numeric
from deltagen.solve.nearest import closed_form_solver

__all__ = ["nearest_central_wrist", "central_solver", "branch_names", "solve_all"]

# (row index, field) of the wrist offsets per convention, 0-based rows of a 6-joint arm
_WRIST_OFFSETS = {
    "standard": ((3, "a"), (4, "a"), (4, "d")),
    "modified": ((4, "a"), (5, "a"), (4, "d")),
}
_SOLVERS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def nearest_central_wrist(desc: SerialDescription) -> SerialDescription:
    """The same 6R arm with the wrist offsets set to zero (module docstring), so that the
    closed-form solver applies. Raises InputError if the arm is not a 6R arm in standard or
    modified DH, or if the closed form still does not apply (e.g. no parallel axes 2, 3)."""
    if not isinstance(desc, SerialDescription):
        raise InputError("nearest_central_wrist needs a SerialDescription")
    if desc.n != 6 or not all(j.revolute for j in desc.joints):
        raise InputError(f"{desc.name}: the combined solution needs a 6R arm")
    if desc.convention not in _WRIST_OFFSETS:
        raise InputError(
            f"{desc.name}: nearest_central_wrist supports standard and modified DH, "
            f"not {desc.convention!r}"
        )
    joints = list(desc.joints)
    for i, field in _WRIST_OFFSETS[desc.convention]:
        joints[i] = dataclasses.replace(joints[i], **{field: 0.0})
    central = dataclasses.replace(
        desc,
        name=f"{desc.name}_central",
        joints=tuple(joints),
        doc=f"{desc.name} with the wrist offsets set to zero",
    )
    if closed_form_solver(central) is None:
        raise InputError(
            f"{desc.name}: no closed form for the arm with a central wrist "
            "(needs axes 2 and 3 parallel, axis 1 not parallel to them)"
        )
    return central


def central_solver(arm):
    """The closed-form solver of the nearest central-wrist arm of ``arm`` (cached per arm)."""
    solver = _SOLVERS.get(arm)
    if solver is None:
        solver = closed_form_solver(nearest_central_wrist(arm.description))
        _SOLVERS[arm] = solver
    return solver


def branch_names(arm) -> tuple:
    """Branch names of :func:`solve_all` (those of the closed-form solver)."""
    return tuple(central_solver(arm).configs)


def _central_starts(solver, arm, T, corrections):
    """(N, k, n) closed-form starts of every branch for poses T (N, 4, 4) (module docstring)."""
    N, k = T.shape[0], len(solver.configs)
    q, _ = solver.closed_form(T[:, :3, :3], T[:, :3, 3])  # clipped, unverified, no limits
    rows = np.arange(k)
    for _ in range(int(corrections)):
        flat = q.reshape(N * k, -1)
        fin = np.all(np.isfinite(flat), axis=1)
        qs = np.where(fin[:, None], flat, 0.0)
        Rc, pc = solver.axes.fk(qs)  # central-wrist arm at q
        Tr, _ = arm._core.fk(np.ascontiguousarray(qs))  # real arm at q
        # T' = fk_central(q) fk_real(q)^-1 T: the pose the central arm must reach so that
        # the real arm reaches T at the same q (to first order in the offset)
        Rr, pr = Tr[:, :3, :3], Tr[:, :3, 3]
        Tt = np.repeat(T, k, axis=0)
        D = Rc @ np.swapaxes(Rr, 1, 2)
        R2 = D @ Tt[:, :3, :3]
        p2 = np.einsum("nij,nj->ni", D, Tt[:, :3, 3] - pr) + pc
        q2, _ = solver.closed_form(R2, p2)  # (N k, k, n): keep own branch
        q2 = q2.reshape(N, k, k, -1)[:, rows, rows]
        ok2 = np.all(np.isfinite(q2), axis=-1) & fin.reshape(N, k)
        q = np.where(ok2[..., None], q2, q)
    return q


def solve_all(arm, T, *, tol=1e-10, max_iter=50, corrections=2, info=False):
    """All branches for poses T (..., 4, 4): q (..., k, n) and valid (..., k).

    arm: a SerialRobot (6R, standard or modified DH, wrist nearly central). tol: Newton's
    tolerance, one value or (position [m], rotation [rad]). max_iter: Newton steps per
    branch. corrections: passes of the target correction of the start (module docstring;
    0 = the plain closed-form start of the seed). ``info=True`` also returns a dict with ``start`` (..., k, n), the closed-form
    start of each branch (NaN where the central-wrist arm has none), and ``iterations``
    (..., k), Newton steps per branch (0 where it was not run).
    """
    if (
        isinstance(corrections, bool)
        or not isinstance(corrections, (int, np.integer))
        or corrections < 0
    ):
        raise InputError(f"corrections must be an integer >= 0, got {corrections!r}")
    solver = central_solver(arm)
    lead, flat, finite, rigid = arm._poses(T)
    good = finite & rigid
    safe = flat.copy()
    safe[~good] = np.eye(4)
    N, k, n = flat.shape[0], len(solver.configs), arm.n
    # 1. the explicit solution of the central-wrist arm, every branch. The elbow's law of
    # cosines is clipped onto the nearest real solution where the central-wrist arm just
    # misses the pose (the offset changes the reach by up to its length), and the limits
    # are not applied (Newton may still land inside them; valid is decided below).
    with np.errstate(all="ignore"):
        q0 = _central_starts(solver, arm, safe, corrections)
    has = np.all(np.isfinite(q0), axis=-1) & good[:, None]
    q0[~has] = np.nan
    # 2. Newton on the real arm from every branch (rows without a start are skipped)
    Tk = np.repeat(safe, k, axis=0)
    res = ik_numeric.solve(
        arm, Tk, q0.reshape(N * k, n), tol=tol, max_iter=max_iter, restarts=0, respect_limits=False
    )
    conv = res.converged.reshape(N, k) & has
    with np.errstate(invalid="ignore"):
        q, inside = fit_limits(res.q.reshape(N, k, n), arm.qlim, [True] * n)
    q[~conv] = np.nan
    valid = conv & inside
    out = (q.reshape(lead + (k, n)), valid.reshape(lead + (k,)))
    if info:
        iters = np.where(has, res.iterations.reshape(N, k), 0)
        return out + (
            {"start": q0.reshape(lead + (k, n)), "iterations": iters.reshape(lead + (k,))},
        )
    return out
