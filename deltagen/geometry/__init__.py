"""Small shared math, one copy of each piece: rotations (Euler angles after Vukobratovic,
rpy, skew, exp/log, quaternions and slerp), the 2 pi joint-limit fit and its tolerance, and
the common-point test of joint axes.

May import: numpy and the foundation modules only.
"""
