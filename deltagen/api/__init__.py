"""The public robot classes: ``DeltaRobot`` (``delta``) and ``SerialRobot``
(``serial``): input checking, errors, dispatch to the compiled or the reference backend;
``workspace`` (the numbers of robot.workspace) and ``sweep`` (deltagen.sweep, on Dask).

May import: ``solve``, ``plan``, and everything below them.
"""
