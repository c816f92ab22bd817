"""The independent numpy implementation that checks the compiled cores, written
from the model (``delta``, ``serial``), never from the derivation.

May import: ``model``, ``geometry``, the foundation modules.
"""
