"""Cell kinds: triangles in the plane (:mod:`.planar`), triangles in space
(:mod:`.surface`) and tetrahedra (:mod:`.tetrahedra`) behind one interface
(:class:`.base.CellKind`); :func:`.registry.kind_of` decides a mesh's kind.

Nothing is imported here: the distortions' metrics import :mod:`.base` alone.
"""
