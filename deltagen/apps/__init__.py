"""The CLI's jobs: ``generate``, ``validate`` (the delta report's trajectory),
``demos``, ``bench``, ``workspace`` (PNG slices and the 3D page of robot.workspace),
``sweep`` (the CSV and Pareto plot of deltagen.sweep), ``kinematics`` (``fk`` and ``ik``
of one pose or a batch) and ``tables`` (the one CSV/NPY reader and writer of batches, columns by name).

May import: anything of deltagen except ``cli``.
"""
