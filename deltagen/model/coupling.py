"""Joint couplings (URDF ``<mimic>``): q_j = m_j q_i + c_j.

A coupled chain has n physical joints but only k < n independent variables. A
:class:`Coupling` holds the affine map from the independent vector r (k,) to the full joint
vector q (n,) of the chain's description (model/serial.py)::

    q = E r + c        E (n, k), c (n,)

Row j of E is the unit vector of r's entry for an independent joint, and m_j times the row
of the joint it mimics for a coupled one (a mimic of a mimic is resolved to its independent
joint: q_j = m_j (m_i q_k + c_i) + c_j). Then, by the chain rule and virtual work,

    J_r = J E                         (base-frame Jacobian of the reduced chain)
    Jdot_r(r, rd) = Jdot(q, E rd) E
    tau_r = E^T tau(q, E rd, E rdd),  M_r = E^T M E,  g_r = E^T g

(the generalised forces of the independent variables).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from deltagen.errors import GeometryError


@dataclass(frozen=True, eq=False)
class Coupling:
    """q = E r + c (module docstring). ``independent`` are the indices (0-based, in the full
    chain) of the joints whose values r holds, in chain order."""

    matrix: npt.NDArray[np.float64]  # E (n, k)
    offset: npt.NDArray[np.float64]  # c (n,) [rad or m]
    independent: tuple[int, ...]

    @property
    def n(self) -> int:
        """Number of physical joints."""
        return int(self.matrix.shape[0])

    @property
    def k(self) -> int:
        """Number of independent variables."""
        return int(self.matrix.shape[1])

    def expand(self, r: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        """q (..., n) of r (..., k)."""
        return np.asarray(r @ self.matrix.T + self.offset, dtype=np.float64)

    def expand_rate(self, rd: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        """qd (..., n) of rd (..., k) (also for accelerations)."""
        return np.asarray(rd @ self.matrix.T, dtype=np.float64)

    @classmethod
    def from_mimics(
        cls, names: Sequence[str], mimics: Mapping[str, tuple[str, float, float]]
    ) -> Coupling:
        """The coupling of a chain of joints ``names`` (chain order) where ``mimics`` maps a
        coupled joint's name to (mimicked joint's name, multiplier, offset). A mimicked joint
        must be one of ``names``; cycles are refused."""
        index = {name: i for i, name in enumerate(names)}
        for name, (target, _, _) in mimics.items():
            if target not in index:
                raise GeometryError(
                    f"joint {name!r}: <mimic joint={target!r}> names a joint that is not a "
                    f"movable joint of the chain ({', '.join(names)})"
                )
        independent = tuple(i for i, name in enumerate(names) if name not in mimics)
        if not independent:
            raise GeometryError("every joint of the chain mimics another (a cycle)")
        column = {i: c for c, i in enumerate(independent)}
        n, k = len(names), len(independent)
        E = np.zeros((n, k))
        c = np.zeros(n)
        for j, name in enumerate(names):
            m, off, seen, at = 1.0, 0.0, [name], name
            while at in mimics:  # q_at = mult q_target + offset
                target, mult, offset = mimics[at]
                m, off = m * mult, off + m * offset
                if target in seen:
                    raise GeometryError(f"mimic joints form a cycle: {' -> '.join(seen)}")
                seen.append(target)
                at = target
            E[j, column[index[at]]] = m
            c[j] = off
        E.flags.writeable = False
        c.flags.writeable = False
        return cls(matrix=E, offset=c, independent=independent)
