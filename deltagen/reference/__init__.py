"""The independent numpy implementation that checks the compiled cores, written
from the model (``delta``, ``serial``, ``linear_delta``: the linear delta and the
tripod, ``five_axis``: the 5-axis NC machines), never from the derivation.

``hexapod`` is the hexapod in numpy (homogeneous transforms, SciPy least squares for fk).

May import: ``model``, ``geometry``, the foundation modules.
"""
