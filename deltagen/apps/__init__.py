"""The CLI's jobs: ``generate``, ``validate`` (the delta report's trajectory),
``demos``, ``workspace`` (PNG slices and the 3D page of robot.workspace),
``sweep`` (the CSV and Pareto plot of deltagen.sweep), ``kinematics`` (``fk`` and ``ik``
of one pose or a batch), ``tables`` (the one CSV/NPY reader and writer of batches, columns
by name), ``dynamics`` (motor sizing along a trajectory), ``calibrate`` (a built delta's
geometry from measured pairs), ``export`` (a self-contained C package for a controller) and
``plotting`` (the one module that imports matplotlib); ``hexapod`` (`deltagen fk|ik|workspace|export`
of a hexapod robot file); ``robots`` is the one loader every
command takes its robot from (the kind decided from the file, the URDF options).

``deltagen bench`` is the ``bench`` package (throughput and one-pose latency, one
measure-and-render path: each section declares what it times, one engine runs, records and
renders it; its own docstring names its modules: the sections, the engine, the timers, the
peer libraries, IK, general 6R, the other families, load, ``--compare`` and the report).

May import: anything of deltagen except ``cli``.
"""
