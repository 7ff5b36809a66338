"""Mesh file I/O: one module per format behind an extension registry."""
