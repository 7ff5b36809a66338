"""The kind of a mesh is decided in one place (``mesh/kinds.py``): no other module of the
package sniffs a mesh's class (``isinstance`` against the mesh classes, ``hasattr`` or
``getattr`` of ``tets``) or its plane (``.is_planar``), except the few named here with
their reason; and the rule there is one for every object (a file's cells, our meshes,
meshio). Of the front ends (``cli/``, ``filters/``) only those named ask a decider: the
verbs decide for the others."""

from __future__ import annotations

import ast
from collections import Counter

import meshio
import numpy as np
import pytest
from cell_meshes import planar, rotation
from test_architecture import ROOT

from meshopt_toolkit.cells.registry import KINDS
from meshopt_toolkit.io.cells import CellMesh
from meshopt_toolkit.mesh import SurfaceMesh, TetMesh, TriangleMesh
from meshopt_toolkit.mesh.kinds import (KIND_NAMES, PLANAR, SURFACE, TETS, cells_kind,
                                        mesh_kind)
from meshopt_toolkit.pipeline.document import MESH_KINDS
from meshopt_toolkit.pipeline.document import kind_of as document_kind

MESH_CLASSES = {"PlanarMesh", "TriangleMesh", "SurfaceMesh", "TetMesh"}
SNIFFED_ATTRIBUTES = {"tets", "is_planar"}

#: the modules that may sniff, with how many sites each, and why
ALLOWED = {
    "mesh/kinds.py": (4, "the decider"),
    "mesh/core.py": (1, "as_planar: a PlanarMesh is its own view"),
    "io/__init__.py": (1, "save: the argument's type (WriteError)"),
    "io/workpiece.py": (1, "an assert on the plane view's type"),
    "penalties/penalty.py": (1, "the argument's type (TypeError)"),
    "motion/planar/scalar_morph.py": (1, "the arguments' type (InvalidMeshError)"),
}


#: the functions that decide a mesh's kind (``mesh/kinds.py``, and the registry and the
#: document over it)
DECIDERS = {"cells_kind", "mesh_kind", "class_kind", "is_tets", "is_surface", "kind_of"}

#: the front ends (``cli/``, ``filters/``) that ask a decider, with why; the verbs decide
#: for the rest (``meshopt move`` and the move filter hand their file to ``mt.move``'s
#: ``motion/moved_file.py``)
FRONT_ENDS_DECIDING = {
    "cli/_common.py": "load_workpiece: a planar operation names the kind it refuses",
    "cli/_info_cells.py": "info: the kind is what it prints",
    "cli/info.py": "info: the kind is what it prints",
    "cli/morph.py": "the target file read as the source's kind",
    "cli/optimize.py": "optimize: planar and tet files read differently",
    "filters/compute_scalar_by_shape_quality_per_face.py": "per face or per tet",
    "filters/generate_geodesic_morph.py": "the frames stored per kind",
    "filters/load_mesh.py": "the summary counts tets or triangles",
}


def _name(node) -> str | None:
    return node.id if isinstance(node, ast.Name) else \
        node.attr if isinstance(node, ast.Attribute) else None


def sniffing_sites(source: str) -> list[int]:
    """Line numbers where ``source`` decides a mesh's kind itself."""
    lines = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Call) and _name(node.func) == "isinstance" and len(node.args) == 2:
            what = node.args[1]
            names = {_name(e) for e in (what.elts if isinstance(what, ast.Tuple) else [what])}
            if names & MESH_CLASSES:
                lines.append(node.lineno)
        elif isinstance(node, ast.Call) and _name(node.func) in ("hasattr", "getattr") and \
                len(node.args) >= 2 and isinstance(node.args[1], ast.Constant) and \
                node.args[1].value in SNIFFED_ATTRIBUTES:
            lines.append(node.lineno)
        elif isinstance(node, ast.Attribute) and node.attr == "is_planar":
            lines.append(node.lineno)
    return sorted(lines)


def test_the_sniffing_finder_sees_each_way_of_sniffing():
    code = ("a = isinstance(m, TetMesh)\nb = isinstance(m, (int, mesh.SurfaceMesh))\n"
            "c = hasattr(m, 'tets')\nd = m.is_planar\ne = isinstance(m, MeshEntry)\n"
            "f = hasattr(m, 'refactorize')\ng = getattr(m, 'tets', None)\n")
    assert sniffing_sites(code) == [1, 2, 3, 4, 7]


def test_only_the_allowed_modules_decide_a_mesh_s_kind():
    found = Counter()
    where = {}
    for path in sorted(ROOT.rglob("*.py")):
        rel = path.relative_to(ROOT).as_posix()
        sites = sniffing_sites(path.read_text(encoding="utf-8"))
        if sites:
            found[rel] = len(sites)
            where[rel] = sites
    extra = {f"{rel}:{where[rel]}" for rel, n in found.items()
             if n > ALLOWED.get(rel, (0, ""))[0]}
    assert not extra, f"decide the kind with meshopt_toolkit.mesh.kinds: {sorted(extra)}"
    # the list stays exact: a module that stopped sniffing leaves it
    assert {rel: n for rel, n in found.items()} == {rel: n for rel, (n, _) in ALLOWED.items()}


def deciding_sites(source: str) -> list[int]:
    """Line numbers where ``source`` calls or imports a kind decider."""
    lines = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Call) and _name(node.func) in DECIDERS:
            lines.append(node.lineno)
        elif isinstance(node, ast.ImportFrom) and {a.name for a in node.names} & DECIDERS:
            lines.append(node.lineno)
    return sorted(lines)


def test_the_decider_finder_sees_calls_and_imports():
    code = ("from ..mesh.kinds import TETS, cells_kind\nk = cells_kind(c)\n"
            "t = kinds.is_tets(m)\nfrom ..mesh.kinds import PLANAR\nx = kind(m)\n")
    assert deciding_sites(code) == [1, 2, 3]


def test_the_front_ends_leave_the_kind_to_the_verbs():
    found = {}
    for folder in ("cli", "filters"):
        for path in sorted((ROOT / folder).glob("*.py")):
            if deciding_sites(path.read_text(encoding="utf-8")):
                found[path.relative_to(ROOT).as_posix()] = True
    assert set(found) == set(FRONT_ENDS_DECIDING), \
        f"let the verb decide the kind: {sorted(set(found) - set(FRONT_ENDS_DECIDING))}"
    for moving in ("cli/move.py", "filters/apply_coord_prescribed_motion.py"):
        assert moving not in FRONT_ENDS_DECIDING


def test_every_layer_names_the_kinds_alike():
    assert tuple(KINDS) == KIND_NAMES == MESH_KINDS == (PLANAR, SURFACE, TETS)


def _tilted(seed: int, bump: float):
    """The planar grid turned by a random rotation in space, lifted by ``bump`` along
    the normal of its plane at the centre vertices."""
    P, T = planar(seed=seed)
    X = np.column_stack([P, bump * P[:, 0] * (1 - P[:, 0]) * P[:, 1] * (1 - P[:, 1])])
    R = rotation(KINDS[TETS], seed)
    return X @ R.T + np.random.default_rng(seed).uniform(-5, 5, 3), T


@pytest.mark.parametrize("seed", range(6))
def test_triangles_on_any_plane_are_planar_for_every_reader_of_a_file(seed):
    for bump, kind in ((0.0, PLANAR), (0.5, SURFACE)):
        X, T = _tilted(seed, bump)
        cm = CellMesh(X, [("triangle", T)])
        assert cells_kind(cm) == kind
        assert mesh_kind(TriangleMesh(X, T)) == document_kind(TriangleMesh(X, T)) == kind
        # the caller's choice of object wins
        assert mesh_kind(SurfaceMesh(X, T)) == SURFACE
        # a meshio object is handed back at its own coordinates: planar only in them
        assert mesh_kind(meshio.Mesh(X, [("triangle", T)])) == SURFACE
        assert mesh_kind(meshio.Mesh(X[:, :2], [("triangle", T)])) == PLANAR


def test_tetrahedra_decide_whatever_is_beside_them():
    X = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
    C = np.array([[0, 1, 2, 3]])
    cm = CellMesh(X, [("triangle", C[:, :3]), ("tetra", C)])
    assert cells_kind(cm) == TETS == mesh_kind(TetMesh(X, C))
    assert mesh_kind(meshio.Mesh(X, [("triangle", C[:, :3]), ("tetra", C)])) == TETS
