"""The package's version: the package root, the kernels' source digest (`_jit`) and a map's
provenance read it here, so no module below the root imports the root."""
__version__ = "0.1.0"
