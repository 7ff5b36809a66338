"""A pipeline checks every step against the kind of mesh it will get (planar, a surface
in 3D, tetrahedra) before any step runs, for every input file; ``--dry-run`` reports a
step that does not fit as a failure with its one-line reason."""

from __future__ import annotations

import json

import numpy as np
import pytest
from test_cli_names_file import _cube_tets

from meshopt_toolkit import data_path
from meshopt_toolkit.batch.file_job import RunOptions, run_file
from meshopt_toolkit.cli import main
from meshopt_toolkit.errors import FilterError
from meshopt_toolkit.filters.apply_coord_prescribed_motion import PrescribedMotion
from meshopt_toolkit.io import save_cells
from meshopt_toolkit.io.cells import CellMesh
from meshopt_toolkit.pipeline import (MESH_KINDS, PLANAR, SURFACE, TETS, Document, Filter,
                                      FilterRegistry, Pipeline, registry)
from meshopt_toolkit.pipeline.document import kind_of

trimesh = pytest.importorskip("trimesh")

MOVE = {"name": "apply_coord_prescribed_motion", "params": {"map": "x + 0.01*z; y; z"}}
PLANAR_STEP = {"name": "apply_coord_quality_preserving_deformation",
               "params": {"displacement": "v.npy"}}
SMOOTH = {"name": "apply_coord_laplacian_smoothing", "params": {"stepsmoothnum": 1}}
PLANAR_ONLY = ("step 2 (apply_coord_quality_preserving_deformation): supports planar triangle "
               "meshes; the current mesh is {}")


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("kinds")
    P, T = _cube_tets(4)
    save_cells(CellMesh(P, [("tetra", T)]), d / "cube.msh")
    trimesh.creation.icosphere(subdivisions=1).export(d / "sphere.obj")
    (d / "disc.msh").write_bytes(data_path("disc_25.msh").read_bytes())
    np.save(d / "v.npy", np.zeros((_planar().n_vertices, 2)))  # the planar step's velocity
    (d / "late.json").write_text(json.dumps({"filters": [MOVE, PLANAR_STEP]}))
    return d


@pytest.fixture
def no_move(monkeypatch):
    """The move filter's work, counted: a refused pipeline must not start it."""
    calls = []
    monkeypatch.setattr(PrescribedMotion, "apply", lambda self, doc, **kw: calls.append(kw))
    return calls


@pytest.mark.parametrize("mesh,kind", [("cube.msh", "a tetrahedral mesh"),
                                       ("sphere.obj", "a triangle surface in 3D")])
@pytest.mark.parametrize("dry_run", [True, False])
def test_a_step_that_needs_another_kind_fails_before_any_work(files, tmp_path, no_move, mesh,
                                                              kind, dry_run):
    rec = run_file(Pipeline.from_dict({"filters": [MOVE, PLANAR_STEP]}), files / mesh, tmp_path,
                   options=RunOptions(dry_run=dry_run))
    assert rec["status"] == "failed" and rec["error"] == PLANAR_ONLY.format(kind)
    assert no_move == [] and not list(tmp_path.iterdir())


def test_dry_run_counts_each_file_that_does_not_fit(files, capsys):
    late = files / "late.json"
    assert main(["run", str(late), *(str(files / m) for m in ("cube.msh", "sphere.obj",
                                                              "disc.msh")), "--dry-run",
                 "--allow-read", str(files)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    errors = [ln for ln in err if ": error: " in ln]
    assert errors == [f"meshopt run: error: {files / m}: {late}: " + PLANAR_ONLY.format(k)
                      for m, k in (("cube.msh", "a tetrahedral mesh"),
                                   ("sphere.obj", "a triangle surface in 3D"))]
    assert err[-1].startswith("meshopt run: dry run: 1 checked, 2 failed, nothing written")


def test_the_run_refuses_the_tet_file_at_once(files, tmp_path, capsys, no_move):
    out = tmp_path / "out"
    assert main(["run", str(files / "late.json"), str(files / "cube.msh"), "-o", str(out)]) == 1
    err = capsys.readouterr().err
    assert PLANAR_ONLY.format("a tetrahedral mesh") in err and str(files / "cube.msh") in err
    assert no_move == [] and not [p for p in out.rglob("*") if p.is_file()
                                  and not p.name.startswith(".")]  # the batch's journal


def test_a_meshlab_step_keeps_the_kind(files, tmp_path):
    """A MeshLab step on a surface leaves a surface: the planar step after it is refused
    before the MeshLab step runs."""
    pytest.importorskip("pymeshlab")
    rec = run_file({"filters": [SMOOTH, PLANAR_STEP]}, files / "sphere.obj", tmp_path,
                   options=RunOptions(dry_run=True))
    assert rec["error"] == PLANAR_ONLY.format("a triangle surface in 3D")


def test_the_kind_after_a_load_is_checked_once_it_is_read(files, tmp_path):
    """``load_mesh`` says only running it tells the kind: the dry run cannot refuse the
    planar step after it, the run refuses it once the tets are read, before it runs."""
    data = {"filters": [{"name": "load_mesh", "params": {"path": str(files / "cube.msh")}},
                        PLANAR_STEP]}
    pipeline = Pipeline.from_dict(data)
    doc = Document()
    doc.dry_run = True
    pipeline.check_kinds(doc, pipeline.validate())  # no mesh yet: nothing to refuse
    doc = Document([_planar()])
    doc.dry_run = True
    pipeline.check(doc)  # the load's result is unknown (and a tet file is read for its size)
    doc.dry_run = False
    with pytest.raises(FilterError, match=r"step 2 \(apply_coord_quality_preserving_"
                                          r"deformation\): supports planar triangle meshes; "
                                          r"the current mesh is a tetrahedral mesh"):
        pipeline.run(doc)
    assert len(doc.entries) == 2 and kind_of(doc.mesh) == TETS and doc.results[0]["loaded"]


def _planar():
    from meshopt_toolkit.io import load

    return load(data_path("disc_25.msh")).as_planar()


def test_kind_of_each_mesh(files):
    from meshopt_toolkit.io import load_cells
    from meshopt_toolkit.mesh import TriangleMesh

    assert kind_of(load_cells(files / "cube.msh").to_tet_mesh()) == TETS
    assert kind_of(_planar()) == PLANAR
    P = _planar().points
    turned = np.column_stack([P[:, 0], P[:, 1] * 0.6, P[:, 1] * 0.8])  # a tilted plane
    assert kind_of(TriangleMesh(turned, _planar().triangles)) == PLANAR
    s = trimesh.creation.icosphere(subdivisions=1)
    assert kind_of(TriangleMesh(np.array(s.vertices), np.array(s.faces))) == SURFACE


def test_every_builtin_declares_its_kinds():
    declared = {cls.name: set(cls.kinds) for cls in registry if cls.origin == "builtin"}
    assert declared["apply_coord_shape_optimization"] == {PLANAR, TETS}
    assert declared["apply_coord_quality_preserving_deformation"] == {PLANAR}
    assert declared["apply_coord_prescribed_motion"] == set(MESH_KINDS)
    assert declared["compute_scalar_by_shape_quality_per_face"] == {PLANAR, SURFACE}
    assert all(kinds and kinds <= set(MESH_KINDS) for kinds in declared.values())
    assert registry.get("save_mesh").spec()["kinds"] == list(MESH_KINDS)


def test_a_filter_with_an_unknown_kind_is_refused():
    class Volumes(Filter):
        name = "test_volumes"
        label = "Test Volumes"
        description = "Takes a kind that does not exist."
        kinds = ("hexahedra",)

    with pytest.raises(FilterError, match="kinds must be some of planar triangles, surface "
                                          "triangles, tetrahedra"):
        FilterRegistry(builtin_package=None, group=None).register(Volumes)
