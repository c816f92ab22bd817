"""Small shared math, one copy of each piece: ``rotations`` (Euler angles after
Vukobratovic, rpy, skew, exp/log, quaternions and slerp), ``limits`` (the 2 pi joint-limit
fit and its tolerance) and ``axes`` (the parallel and common-point tests of joint axes).

May import: numpy and the foundation modules only.
"""
