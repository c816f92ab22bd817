"""Machines whose direct kinematics is the intersection of three spheres, like the rotary
delta's (derive/delta/fk.py, whose ``intersection_stages`` they reuse: one copy of the
math): the linear delta (three vertical towers, Klipper's ``delta`` kinematics) and the
tripod of LinuxCNC's ``tripodkins`` (three struts of variable length to one point).
``symbols`` (their geometry and joint symbols), ``rates`` (velocity and acceleration
level, derived by differentiating the sphere constraints) and ``kernels`` (the batched
kernels of both modules).
"""
