"""The public robot classes: ``DeltaRobot`` (``delta``) and ``SerialRobot``
(``serial``): input checking, errors, dispatch to the compiled or the reference backend.

May import: ``solve``, ``plan``, and everything below them.
"""
