"""Symbolic rigid-body dynamics of a serial arm: the recursive Newton-Euler algorithm (RNEA)
in link frames, with the arm's numbers compiled in (exact zeros fold away before CSE).

Notation (Craig, "Introduction to Robotics", ch. 6; Luh, Walker & Paul 1980): link frame i
is the frame after A_i (model/serial.py), in which link i's centre of mass r_i, inertia I_i
(about the COM) and mass m_i are given. R_i is the rotation of A_i (frame i in frame i-1),
p_i its translation. A_i = P_i Mot_i(q_i) Post_i splits each link transform into the part
before the joint's motion, the motion (Rot or Trans along the joint axis) and a constant
part after it; so in frame i the joint axis is the constant z_i = Post_R^T e_axis and a
point on it is u_i = -Post_R^T Post_p (both exact numbers); in frame i-1 that point is s_i,
the translation of P_i (fixed in link i-1 for a revolute joint). a_i is the acceleration of
origin i: in standard DH it is rigid with link i but off joint i's axis (Corke's p*), in
modified DH it lies on the axis (u_i = 0: Craig's recursion).

Forward pass (base frame 0 = the description's base; omega_0 = omegad_0 = 0, and the base
accelerates with a_0 = -g, R_base^T applied, which adds gravity to every link):

    omega_i  = R_i^T omega_{i-1} + z_i qd_i                                   (revolute)
    omegad_i = R_i^T omegad_{i-1} + (R_i^T omega_{i-1}) x z_i qd_i + z_i qdd_i (revolute)
    revolute:  a_i = R_i^T (a_{i-1} + omegad_{i-1} x s_i + omega_{i-1} x (omega_{i-1} x s_i))
                     + omegad_i x (-u_i) + omega_i x (omega_i x (-u_i))
    prismatic: a_i = R_i^T (a_{i-1} + omegad_{i-1} x p_i + omega_{i-1} x (omega_{i-1} x p_i))
                     + 2 omega_i x z_i qd_i + z_i qdd_i
    a_ci     = a_i + omegad_i x r_i + omega_i x (omega_i x r_i)
    F_i = m_i a_ci,   N_i = I_i omegad_i + omega_i x I_i omega_i

Backward pass (forces and moments on link i about the origin of frame i, in frame i):

    f_i = R_{i+1} f_{i+1} + F_i
    n_i = N_i + R_{i+1} n_{i+1} + r_i x F_i + p_{i+1} x R_{i+1} f_{i+1}
    tau_i = z_i . (n_i - u_i x f_i)   (revolute: the moment about a point on the axis)
    tau_i = z_i . f_i                 (prismatic)

One routine serves every quantity, with the velocity terms written **bilinearly** in two
velocity vectors u, v (each product of two velocities, e.g. omega x (omega x r), becomes its
symmetrised form 1/2 (omega_u x (omega_v x r) + omega_v x (omega_u x r))):

* inverse dynamics: u = v = qd, qdd, gravity; plus armature_i qdd_i and friction;
* gravity torque: u = v = 0, qdd = 0, gravity;
* mass matrix column j: u = v = 0, qdd = e_j, no gravity (plus the armature on the diagonal);
* Coriolis matrix column j: u = qd, v = e_j, qdd = 0, no gravity. The velocity terms of the
  RNEA are the quadratic form h(qd) = Gamma(qd, qd) of the symmetric bilinear form of the
  Christoffel symbols of the first kind, Gamma_k(x, y) = sum_ij c_ijk x_i y_j; polarisation
  gives Gamma(qd, e_j) = C(qd) e_j exactly, so C is the Christoffel matrix (the one with
  Mdot - 2C skew-symmetric).
"""

from __future__ import annotations

import sympy as sp

from deltagen.derive.serial.chain import (
    ArmSymbols,
    cos_sin,
    exact_angle,
    exact_length,
    link_transform,
    numeric_matrix,
    rot,
    trans,
)

HALF = sp.Rational(1, 2)


def _number(value: float) -> sp.Expr:
    return exact_length(float(value))


def post_transform(desc, i: int) -> sp.Matrix:
    """Post_i: the constant part of A_i after the joint's motion (module docstring)."""
    j = desc.joints[i]
    if desc.convention == "universal":
        return (
            trans(exact_length(j.tx), exact_length(j.ty), exact_length(j.tz))
            * rot("x", *cos_sin(exact_angle(j.rx)))
            * rot("y", *cos_sin(exact_angle(j.ry)))
            * rot("z", *cos_sin(exact_angle(j.rz)))
        )
    if desc.convention == "standard":
        # revolute: Rot_z(q) | Trans_z(d) Trans_x(a) Rot_x(alpha);
        # prismatic: Rot_z(theta) Trans_z(q) | Trans_x(a) Rot_x(alpha)
        tz = trans(z=exact_length(j.d)) if j.revolute else sp.eye(4)
        return tz * trans(x=exact_length(j.a)) * rot("x", *cos_sin(exact_angle(j.alpha)))
    # modified: Rot_x(alpha) Trans_x(a) Rot_z(q) | Trans_z(d)  (prismatic: nothing after)
    return trans(z=exact_length(j.d)) if j.revolute else sp.eye(4)


def _cross(a, b) -> sp.Matrix:
    return sp.Matrix(
        [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    )


def _zero(v) -> bool:
    return all(x == 0 for x in v)


class Velocities:
    """A pair of velocity-like vectors (the u and v terms); ``same`` when u is v."""

    def __init__(self, u, v, same):
        self.u, self.v, self.same = u, v, same

    def cross(self, other: Velocities) -> sp.Matrix:
        """Symmetrised self x other: 1/2 (self_u x other_v + self_v x other_u)."""
        if self.same and other.same:
            return _cross(self.u, other.u)
        return HALF * (_cross(self.u, other.v) + _cross(self.v, other.u))

    def double_cross(self, r) -> sp.Matrix:
        """Symmetrised w x (w x r)."""
        if self.same:
            return _cross(self.u, _cross(self.u, r))
        return HALF * (_cross(self.u, _cross(self.v, r)) + _cross(self.v, _cross(self.u, r)))

    def gyroscopic(self, inertia) -> sp.Matrix:
        """Symmetrised w x I w."""
        if self.same:
            return _cross(self.u, inertia * self.u)
        return HALF * (_cross(self.u, inertia * self.v) + _cross(self.v, inertia * self.u))


class Dynamics:
    """The staged RNEA passes of one arm (``desc`` must carry inertial parameters)."""

    def __init__(self, desc, sym: ArmSymbols | None = None):
        desc.require_inertia()
        self.desc = desc
        n = desc.n
        self.sym = sym or ArmSymbols(n)
        self.qdd = sp.symbols(f"qdd1:{n + 1}", real=True)
        self.R, self.p, self.z, self.u_axis, self.s = [], [], [], [], []
        for i in range(n):
            A, P, axis = link_transform(desc, i, self.sym)
            self.s.append(P[:3, 3].applyfunc(sp.expand))  # constant for a revolute joint
            self.R.append(A[:3, :3].applyfunc(sp.expand))
            self.p.append(A[:3, 3].applyfunc(sp.expand))
            post = post_transform(desc, i)
            # the motion axis; minus it for a reversed joint (sign -1: it moves by -q)
            e = sp.Matrix([int(desc.joints[i].sign) if axis == k else 0 for k in "xyz"])
            Rt = post[:3, :3].T
            self.z.append((Rt * e).applyfunc(sp.expand))
            self.u_axis.append((-Rt * post[:3, 3]).applyfunc(sp.expand))
        self.mass, self.com, self.inertia = [], [], []
        for j in desc.joints:
            inertial = j.inertial
            self.mass.append(_number(inertial.mass))
            self.com.append(sp.Matrix([_number(c) for c in inertial.com]))
            tensor = inertial.inertia_matrix
            self.inertia.append(sp.Matrix(3, 3, [_number(x) for x in tensor.ravel()]))
        base_R = numeric_matrix(desc.base)[:3, :3]
        self.gravity0 = (-base_R.T * sp.Matrix([_number(g) for g in desc.gravity])).applyfunc(
            sp.expand
        )

    def _name(self, assignments, name, vector) -> sp.Matrix:
        """Symbols for the non-trivial entries of ``vector`` (constants and bare symbols are
        kept as they are); their assignments go to ``assignments``."""
        out = []
        for k, value in enumerate(vector):
            value = sp.expand(value)
            if not value.free_symbols or value.is_Symbol or (-value).is_Symbol:
                out.append(value)
            else:
                s = sp.Symbol(f"{name}_{'xyz'[k]}", real=True)
                assignments.append((s, value))
                out.append(s)
        return sp.Matrix(out)

    def rnea(self, tag: str, u, v, qdd, gravity: bool):
        """(tau expressions (n), Stage): the rigid-body joint forces of the bilinear RNEA
        (module docstring) for velocity vectors u, v (v is u: the plain RNEA), joint
        accelerations qdd and gravity on or off. u, v, qdd: sequences of n SymPy values."""
        desc, n = self.desc, self.desc.n
        out: list = []
        name = lambda what, i: f"{tag}_{what}{i + 1}"  # noqa: E731
        zero = sp.zeros(3, 1)
        w = Velocities(zero, zero, u is v)
        wd = zero
        a = self.gravity0 if gravity else zero
        forces, moments = [], []
        for i, joint in enumerate(desc.joints):
            Rt, p, z = self.R[i].T, self.p[i], self.z[i]
            w_in = Velocities(Rt * w.u, Rt * w.v, w.same)
            if joint.revolute:
                # the joint point s_i (fixed in link i-1), then origin i, rigid in link i at
                # -u_i from it
                s = self.s[i]
                a_joint = Rt * (a + _cross(wd, s) + w.double_cross(s))
                zu, zv = z * u[i], z * v[i]
                wd = Rt * wd + w_in.cross(Velocities(zu, zv, w.same)) + z * qdd[i]
                wu = self._name(out, name("wu", i), w_in.u + zu)
                wv = wu if w.same else self._name(out, name("wv", i), w_in.v + zv)
                w = Velocities(wu, wv, w.same)
                wd = self._name(out, name("wd", i), wd)
                back = -self.u_axis[i]
                a = self._name(out, name("a", i), a_joint + _cross(wd, back) + w.double_cross(back))
            else:
                # origin i slides along the axis relative to link i-1: carried acceleration,
                # Coriolis 2 omega_i x z_i qd_i (bilinear) and the sliding acceleration
                a_carried = Rt * (a + _cross(wd, p) + w.double_cross(p))
                wd = self._name(out, name("wd", i), Rt * wd)
                wu = self._name(out, name("wu", i), w_in.u)
                wv = wu if w.same else self._name(out, name("wv", i), w_in.v)
                w = Velocities(wu, wv, w.same)
                a = a_carried + 2 * w.cross(Velocities(z * u[i], z * v[i], w.same)) + z * qdd[i]
                a = self._name(out, name("a", i), a)
            m, r, inertia = self.mass[i], self.com[i], self.inertia[i]
            a_c = a + _cross(wd, r) + w.double_cross(r)
            F = self._name(out, name("F", i), m * a_c)
            N = self._name(out, name("N", i), inertia * wd + w.gyroscopic(inertia))
            forces.append(F)
            moments.append((N, r, F))
        tau = [sp.S.Zero] * n
        f_next = n_next = zero
        for i in reversed(range(n)):
            N, r, F = moments[i]
            if i + 1 < n:
                Rn, pn = self.R[i + 1], self.p[i + 1]
                f_carried = Rn * f_next
                n_carried = Rn * n_next + _cross(pn, f_carried)
            else:
                f_carried = n_carried = zero
            f = self._name(out, name("f", i), F + f_carried)
            nm = self._name(out, name("n", i), N + n_carried + _cross(r, F))
            z = self.z[i]
            if desc.joints[i].revolute:
                tau[i] = sp.expand((z.T * (nm - _cross(self.u_axis[i], f)))[0])
            else:
                tau[i] = sp.expand((z.T * f)[0])
            f_next, n_next = f, nm
        return tau, out

    def friction(self, i: int, qd_i) -> sp.Expr:
        """viscous_i qd_i + (Tc+_i if qd_i > 0, Tc-_i if qd_i < 0, else 0): branch-free in C
        (a select on doubles), exact zero when the joint has no friction."""
        inertial = self.desc.joints[i].inertial
        value = _number(inertial.viscous) * qd_i
        plus, minus = inertial.coulomb
        if plus or minus:
            value += sp.Piecewise(
                (_number(plus), qd_i > 0), (_number(minus), qd_i < 0), (sp.S.Zero, True)
            )
        return value

    def armature(self, i: int) -> sp.Expr:
        return _number(self.desc.joints[i].inertial.armature)

    # -- the quantities --------------------------------------------------------------

    def inverse_dynamics(self):
        """(tau (n), assignments): full inverse dynamics."""
        qd = list(self.sym.qd)
        tau, out = self.rnea("id", qd, qd, list(self.qdd), gravity=True)
        return [
            t + self.armature(i) * self.qdd[i] + self.friction(i, qd[i]) for i, t in enumerate(tau)
        ], out

    def nonlinear_effects(self):
        """(h (n), assignments): tau at qdd = 0 (Coriolis, centrifugal, gravity, friction)."""
        qd = list(self.sym.qd)
        zeros = [sp.S.Zero] * self.desc.n
        tau, out = self.rnea("h", qd, qd, zeros, gravity=True)
        return [t + self.friction(i, qd[i]) for i, t in enumerate(tau)], out

    def gravity_torque(self):
        zeros = [sp.S.Zero] * self.desc.n
        return self.rnea("g", zeros, zeros, zeros, gravity=True)

    def mass_matrix(self):
        """(M (n x n) with M[r][c] for r >= c computed and mirrored, assignments)."""
        n = self.desc.n
        zeros = [sp.S.Zero] * n
        columns, out = self._unit_columns("M", lambda e: (zeros, zeros, e))
        M = [[sp.S.Zero] * n for _ in range(n)]
        for c, col in enumerate(columns):
            for r in range(c, n):
                M[r][c] = col[r] + (self.armature(r) if r == c else 0)
        for r in range(n):
            for c in range(r + 1, n):
                M[r][c] = M[c][r]
        return M, out

    def coriolis(self):
        """(C (n x n) Christoffel form, C[r][c] = Gamma_r(qd, e_c), assignments)."""
        n = self.desc.n
        qd = list(self.sym.qd)
        zeros = [sp.S.Zero] * n
        columns, out = self._unit_columns("C", lambda e: (qd, e, zeros))
        return [[columns[c][r] for c in range(n)] for r in range(n)], out

    def _unit_columns(self, tag: str, states):
        """The columns of an n x n matrix of the RNEA (M, C): column c is one pass without
        gravity on ``states(e_c)`` = (u, v, qdd), the unit vector e_c in the place that
        selects it; the passes are tagged <tag>1 .. <tag>n. (columns, assignments)."""
        n = self.desc.n
        columns: list = []
        out: list = []
        for c in range(n):
            e = [sp.S.One if k == c else sp.S.Zero for k in range(n)]
            col, stage = self.rnea(f"{tag}{c + 1}", *states(e), gravity=False)
            out += stage
            columns.append(col)
        return columns, out
