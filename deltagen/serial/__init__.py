"""Serial arms: Denavit-Hartenberg (standard and modified) and EASY-ROB universal
coordinates; description, derivation, reference and the Python API."""
