"""The independent numpy implementation that checks the compiled cores, written
from the model (``delta``, ``serial``, ``linear_delta``: the linear delta and the
tripod), never from the derivation.

May import: ``model``, ``geometry``, the foundation modules.
"""
