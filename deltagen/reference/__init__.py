"""The independent numpy implementation that checks the compiled cores, written
from the model (``delta``, ``serial``, ``five_axis``: the 5-axis NC machines), never from
the derivation.

May import: ``model``, ``geometry``, the foundation modules.
"""
