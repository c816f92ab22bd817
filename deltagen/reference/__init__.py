"""The independent numpy implementation that checks the compiled cores, written
from the model (``delta``, ``serial``), never from the derivation.

``hexapod`` is the hexapod in numpy (homogeneous transforms, SciPy least squares for fk).

May import: ``model``, ``geometry``, the foundation modules.
"""
