"""The rotary delta robot of the 2008 report (seed 000): description, derivation,
reference, and the Python API."""
