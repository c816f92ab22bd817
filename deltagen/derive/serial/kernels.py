"""The batched kernels of one serial arm: fk (T, 4x4 row-major), frames (every link frame),
jacobian (geometric, base frame, 6 x n row-major), fk_jacobian (T and the Jacobian from one
shared CSE: the evaluation of one Newton step of the compiled IK solver) and jacobian_dot
(dJ/dt along qd).

Status: INVALID for a non-finite input, and (codegen.lowering.guard_outputs, for every
kernel) for finite inputs whose outputs are not finite (e.g. a prismatic q of 1e308, rates
of 1e200: the arithmetic overflows); the row's outputs are then NaN. Otherwise OK."""

from __future__ import annotations

import sympy as sp

from deltagen import status as st
from deltagen.derive.functions import AllFinite
from deltagen.derive.kernel import Angle, Kernel, Port, Stage
from deltagen.derive.serial.chain import Chain
from deltagen.derive.serial.ik_closed_form import ik_kernel

invalid = sp.Symbol("invalid")


def _masked(prefix, values, bad):
    outs = [sp.Symbol(f"out_{prefix}{k}", real=True) for k in range(len(values))]
    return tuple(outs), tuple(
        (o, sp.Piecewise((sp.nan, bad), (v, True))) for o, v in zip(outs, values)
    )


def _flags(symbols):
    return Stage("status flag: a non-finite input", ((invalid, sp.Not(AllFinite(*symbols))),))


def _status():
    return sp.Piecewise((st.INVALID, invalid), (st.OK, True))


class ArmKernels:
    """Builds the kernels of ``desc`` (a SerialDescription) from one Chain derivation."""

    def __init__(self, desc):
        self.desc = desc
        self.chain = Chain(desc)
        sym = self.chain.sym
        self.angles = tuple(
            Angle(sym.q[i], sym.cos[i], sym.sin[i]) for i, j in enumerate(desc.joints) if j.revolute
        )
        n = desc.n
        self.q_port = Port("q", sym.q, f"joint coordinates q_1..q_{n} [rad or m]", "rad|m", width=n)
        self.qd_port = Port(
            "qd", sym.qd, f"joint rates qdot_1..qdot_{n} [rad/s or m/s]", "rad/s|m/s", width=n
        )

    def _kernel(self, name, doc, inputs, outputs, stages):
        return Kernel(
            name=name,
            doc=doc,
            inputs=inputs,
            outputs=outputs,
            stages=tuple(stages),
            status=_status(),
            angles=self.angles,
            status_doc="OK; INVALID (a non-finite input; the row's outputs are NaN)",
        )

    def fk(self) -> Kernel:
        c = self.chain
        values = [c.T[r, k] for r in range(4) for k in range(4)]
        outs, stage = _masked("T", values, invalid)
        return self._kernel(
            "fk",
            f"Forward kinematics: q -> tool pose T = base A_1 ... A_{self.desc.n} tool "
            "(4x4 homogeneous, row-major; position in m).",
            (self.q_port,),
            (Port("T", outs, "tool pose, 4x4 row-major [rotation | position m]", "m", width=16),),
            [*c.stages, _flags(c.sym.q), Stage("outputs (NaN on invalid rows)", stage)],
        )

    def frames(self) -> Kernel:
        c = self.chain
        values = [F[r, k] for F in c.frames for r in range(4) for k in range(4)]
        outs, stage = _masked("F", values, invalid)
        count = len(c.frames)
        return self._kernel(
            "frames",
            f"Every frame of the arm: base, F_1 ... F_{self.desc.n}, tool "
            f"({count} 4x4 row-major matrices per point), for drawing the arm.",
            (self.q_port,),
            (
                Port(
                    "F",
                    outs,
                    f"{count} frames x 4x4 row-major, base to tool",
                    "m",
                    width=16 * count,
                ),
            ),
            [*c.stages, _flags(c.sym.q), Stage("outputs (NaN on invalid rows)", stage)],
        )

    def _jacobian_stage(self):
        J = self.chain.jacobian()
        n = self.desc.n
        Js = sp.Matrix(6, n, lambda r, k: sp.Symbol(f"J{r + 1}_{k + 1}", real=True))
        assignments = []
        for r in range(6):
            for k in range(n):
                assignments.append((Js[r, k], J[r, k]))
        return Js, Stage(
            "geometric Jacobian: revolute [w x (p - o); w], prismatic [w; 0]", tuple(assignments)
        )

    def jacobian(self) -> Kernel:
        c, n = self.chain, self.desc.n
        Js, stage = self._jacobian_stage()
        outs, out_stage = _masked("J", list(Js), invalid)
        return self._kernel(
            "jacobian",
            "Geometric Jacobian of the tool point in the base frame: rows vx vy vz "
            f"wx wy wz, 6 x {n} row-major (twist = J qdot).",
            (self.q_port,),
            (
                Port(
                    "J",
                    outs,
                    f"6 x {n} row-major [m/rad, 1 (prismatic) | rad/rad]",
                    "-",
                    width=6 * n,
                ),
            ),
            [*c.stages, stage, _flags(c.sym.q), Stage("outputs (NaN on invalid rows)", out_stage)],
        )

    def fk_jacobian(self) -> Kernel:
        """T and J of the same q in one pass: the chain's stages, and so their common
        subexpressions, are shared (what a Newton step needs)."""
        c, n = self.chain, self.desc.n
        values = [c.T[r, k] for r in range(4) for k in range(4)]
        t_outs, t_stage = _masked("T", values, invalid)
        Js, stage = self._jacobian_stage()
        j_outs, j_stage = _masked("J", list(Js), invalid)
        return self._kernel(
            "fk_jacobian",
            f"Tool pose and geometric Jacobian together (one shared evaluation): "
            f"T as in fk, J as in jacobian (6 x {n} row-major, base frame).",
            (self.q_port,),
            (
                Port(
                    "T", t_outs, "tool pose, 4x4 row-major [rotation | position m]", "m", width=16
                ),
                Port(
                    "J",
                    j_outs,
                    f"6 x {n} row-major [m/rad, 1 (prismatic) | rad/rad]",
                    "-",
                    width=6 * n,
                ),
            ),
            [
                *c.stages,
                stage,
                _flags(c.sym.q),
                Stage("outputs (NaN on invalid rows)", t_stage + j_stage),
            ],
        )

    def jacobian_dot(self) -> Kernel:
        c, n = self.chain, self.desc.n
        Js, stage = self._jacobian_stage()
        Jd = c.jacobian_dot(Js)
        Jds = sp.Matrix(6, n, lambda r, k: sp.Symbol(f"Jd{r + 1}_{k + 1}", real=True))
        jd_stage = Stage(
            "dJ/dt along qdot: axis rates Omega x w, point velocities",
            tuple((Jds[r, k], Jd[r, k]) for r in range(6) for k in range(n)),
        )
        outs, out_stage = _masked("Jd", list(Jds), invalid)
        return self._kernel(
            "jacobian_dot",
            f"Time derivative of the geometric Jacobian along qdot, 6 x {n} "
            "row-major: tool acceleration = J qddot + Jdot qdot.",
            (self.q_port, self.qd_port),
            (Port("Jd", outs, f"6 x {n} row-major, per second", "-", width=6 * n),),
            [
                *c.stages,
                stage,
                jd_stage,
                _flags((*c.sym.q, *c.sym.qd)),
                Stage("outputs (NaN on invalid rows)", out_stage),
            ],
        )

    def ik_all(self) -> Kernel | None:
        """Every closed-form IK branch in C, for the structures ik_kernel supports."""
        return ik_kernel(self.desc, self.chain)

    def all(self):
        kernels = [
            self.fk(),
            self.frames(),
            self.jacobian(),
            self.fk_jacobian(),
            self.jacobian_dot(),
        ]
        ik = self.ik_all()
        return tuple(kernels + ([ik] if ik is not None else []))
