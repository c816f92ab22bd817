"""The batched kernels of one serial arm: fk (T, 4x4 row-major), frames (every link frame),
jacobian (geometric, base frame, 6 x n row-major), fk_jacobian (T and the Jacobian from one
shared CSE: the evaluation of one Newton step of the compiled IK solver) and jacobian_dot
(dJ/dt along qd); for arms with inertial parameters also the dynamics (dynamics.py):
inverse_dynamics, mass_matrix, gravity_torque, coriolis and nonlinear_effects (the
forward dynamics is a C wrapper of the last two and the runtime's Cholesky solver).

Status: INVALID for a non-finite input, and (codegen.lowering.guard_outputs, for every
kernel) for finite inputs whose outputs are not finite (e.g. a prismatic q of 1e308, rates
of 1e200: the arithmetic overflows); the row's outputs are then NaN. Otherwise OK."""

from __future__ import annotations

import sympy as sp

from deltagen import status as st
from deltagen.derive.functions import AllFinite
from deltagen.derive.kernel import Angle, Kernel, Port, Stage
from deltagen.derive.serial.chain import Chain
from deltagen.derive.serial.dynamics import Dynamics
from deltagen.derive.serial.ik_closed_form import ik_kernel
from deltagen.derive.serial.parts import PARTS

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
            (
                Port(
                    "T",
                    outs,
                    "tool pose, 4x4 row-major [rotation | position m]",
                    "m",
                    width=16,
                    matrix=(4, 4),
                ),
            ),
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
                    matrix=(count, 4, 4),
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
                    matrix=(6, n),
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
                    "T",
                    t_outs,
                    "tool pose, 4x4 row-major [rotation | position m]",
                    "m",
                    width=16,
                    matrix=(4, 4),
                ),
                Port(
                    "J",
                    j_outs,
                    f"6 x {n} row-major [m/rad, 1 (prismatic) | rad/rad]",
                    "-",
                    width=6 * n,
                    matrix=(6, n),
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
            (Port("Jd", outs, f"6 x {n} row-major, per second", "-", width=6 * n, matrix=(6, n)),),
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

    # -- dynamics (arms with inertial parameters) -----------------------------------

    def _dynamics(self) -> Dynamics:
        if not hasattr(self, "_dyn"):
            self._dyn = Dynamics(self.desc, self.chain.sym)
        return self._dyn

    def _dynamics_kernel(self, name, doc, inputs, port, values, assignments):
        """A kernel whose outputs are ``values`` (a list, row-major; entries that are the
        same object as an earlier entry reuse its symbol, e.g. the mirrored half of M).
        INVALID when an input or an output is not finite (e.g. an overflow at huge rates)."""
        raw, raw_assign, seen = [], [], {}
        for k, value in enumerate(values):
            key = id(value)
            if key in seen:
                raw.append(seen[key])
                continue
            sym = sp.Symbol(f"{port[0]}_{k}", real=True)
            raw_assign.append((sym, value))
            raw.append(sym)
            seen[key] = sym
        inputs_symbols = [s for p in inputs for s in p.symbols]
        unique = list(dict.fromkeys(raw))
        flag = Stage(
            "status flag: a non-finite input or result",
            ((invalid, sp.Not(AllFinite(*inputs_symbols, *unique))),),
        )
        outs, out_stage = _masked(port[0], raw, invalid)
        return Kernel(
            name=name,
            doc=doc,
            inputs=inputs,
            outputs=(
                Port(
                    port[0],
                    outs,
                    port[1],
                    port[2],
                    width=len(values),
                    matrix=port[3] if len(port) > 3 else None,
                ),
            ),
            stages=(
                Stage(
                    "recursive Newton-Euler passes (derive/serial/dynamics.py)", tuple(assignments)
                ),
                Stage("results", tuple(raw_assign)),
                flag,
                Stage("outputs (NaN on invalid rows)", out_stage),
            ),
            status=_status(),
            angles=self.angles,
            status_doc="OK; INVALID (a non-finite input or result; the row's outputs are NaN)",
        )

    def _qdd_port(self):
        n = self.desc.n
        return Port(
            "qdd",
            self._dynamics().qdd,
            f"joint accelerations qddot_1..qddot_{n} [rad/s^2 or m/s^2]",
            "rad/s^2|m/s^2",
            width=n,
        )

    def _tau_doc(self):
        return f"joint torques tau_1..tau_{self.desc.n} [N m (revolute) or N (prismatic)]"

    def inverse_dynamics(self) -> Kernel:
        tau, assignments = self._dynamics().inverse_dynamics()
        return self._dynamics_kernel(
            "inverse_dynamics",
            "Inverse dynamics: tau = M(q) qdd + C(q, qd) qd + g(q) + armature qdd + viscous qd "
            "+ Coulomb(sign qd), by the recursive Newton-Euler algorithm (gravity of the "
            "description, base frame).",
            (self.q_port, self.qd_port, self._qdd_port()),
            ("tau", self._tau_doc(), "N m|N"),
            tau,
            assignments,
        )

    def nonlinear_effects(self) -> Kernel:
        h, assignments = self._dynamics().nonlinear_effects()
        return self._dynamics_kernel(
            "nonlinear_effects",
            "Nonlinear effects h = C(q, qd) qd + g(q) + friction: the joint torques at qdd = 0 "
            "(what forward_dynamics subtracts).",
            (self.q_port, self.qd_port),
            ("h", self._tau_doc(), "N m|N"),
            h,
            assignments,
        )

    def gravity_torque(self) -> Kernel:
        g, assignments = self._dynamics().gravity_torque()
        return self._dynamics_kernel(
            "gravity_torque",
            "Gravity torque g(q): the joint torques that hold the arm still against gravity.",
            (self.q_port,),
            ("g", self._tau_doc(), "N m|N"),
            g,
            assignments,
        )

    def mass_matrix(self) -> Kernel:
        n = self.desc.n
        M, assignments = self._dynamics().mass_matrix()
        return self._dynamics_kernel(
            "mass_matrix",
            f"Joint-space inertia matrix M(q), {n} x {n} row-major, symmetric, with the "
            "armature (reflected motor inertia) on the diagonal; one RNEA pass per column "
            "(qdd = e_j, no velocity, no gravity).",
            (self.q_port,),
            ("M", f"{n} x {n} row-major [kg m^2 | kg m | kg]", "kg m^2|kg", (n, n)),
            [M[r][c] for r in range(n) for c in range(n)],
            assignments,
        )

    def coriolis(self) -> Kernel:
        n = self.desc.n
        C, assignments = self._dynamics().coriolis()
        return self._dynamics_kernel(
            "coriolis",
            f"Coriolis matrix C(q, qd), {n} x {n} row-major, in the Christoffel form "
            "(C qd: Coriolis and centrifugal torques; Mdot - 2C skew-symmetric); column j is "
            "the bilinear RNEA of (qd, e_j).",
            (self.q_port, self.qd_port),
            ("C", f"{n} x {n} row-major [kg m^2/s | ...]", "kg m^2/s", (n, n)),
            [C[r][c] for r in range(n) for c in range(n)],
            assignments,
        )

    def dynamics(self) -> tuple:
        if not self.desc.has_inertia:
            return ()
        return (
            self.inverse_dynamics(),
            self.mass_matrix(),
            self.gravity_torque(),
            self.coriolis(),
            self.nonlinear_effects(),
        )

    def first(self) -> tuple:
        """The kernels a new arm loads with (fk, frames, jacobian, fk_jacobian: what the
        numerical IK and the single calls use); jacobian_dot, ik_all and the dynamics are
        rendered and compiled on their first use (native/serial.py)."""
        return self.part("first")

    def part(self, part: str) -> tuple:
        """The kernels of one part of the module (PARTS): only they are derived."""
        if part == "all":
            return self.all()
        kernels = [getattr(self, name)() for name in PARTS[part]]
        return tuple(k for k in kernels if k is not None)

    def all(self):
        kernels = [
            self.fk(),
            self.frames(),
            self.jacobian(),
            self.fk_jacobian(),
            self.jacobian_dot(),
        ]
        ik = self.ik_all()
        return tuple(kernels + ([ik] if ik is not None else []) + list(self.dynamics()))
