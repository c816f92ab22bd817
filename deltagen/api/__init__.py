"""The public robot classes: ``DeltaRobot`` (``delta``) and ``SerialRobot``
(``serial``): input checking, errors, dispatch to the compiled or the reference backend;
``coupled`` (``CoupledArm``, a serial arm with URDF ``<mimic>`` joints, in its independent
variables); ``validity`` (the finite-output rule at the API: which rows are valid and what an
INVALID row's error says); ``hints`` (the type aliases of the public API);
``workspace`` (the numbers of robot.workspace) and ``sweep`` (deltagen.sweep, on Dask);
``linear_delta`` (``LinearDelta`` and ``Tripod``, the three-sphere machines).

``hexapod`` (``Hexapod``, the Stewart-Gough platform: ik, fk by damped Newton in C,
Jacobian, rates, leg forces, joint limits, workspace grids).

``five_axis`` (``FiveAxisMachine``, the 5-axis NC machines).

``threads`` (``ThreadsProperty``: the ``threads`` property the classes with a compiled core
share).

``base`` (``RobotFamily``: what the robot families share -- backend and threads checks,
``from_toml`` / ``default``, ``with_backend``, the errors-mode shaping ``_finish``, the
one-pose lean path, ``ReferenceCore``); ``serial_dynamics`` (SerialRobot's dynamics
methods); ``bundled`` (the bundled arms' names and descriptions). SerialRobot keeps the
argument checks, error modes and shaping of ik / ik_all; the choice of method is
``deltagen.solve.ik``'s. ``coupled.load_urdf_arm`` is the one URDF loader (plain or coupled
arm); ``serial`` imports ``coupled``, never the reverse.

May import: ``solve``, ``plan``, and everything below them.
"""
