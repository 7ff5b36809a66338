"""``meshopt optimize`` on the 2D benchmarks' meshes (a hole in an 8 × 8 plate, a body in
a 6 × 4 box) refuses bad problems in one line naming the file and the flag, exit 1,
before anything is written."""

from __future__ import annotations

import pytest

from meshopt_toolkit.cli import main
from meshopt_toolkit.shape.cases import ellipse_in_box


@pytest.fixture(scope="module")
def meshes(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("bad2d")
    return {"plate": ellipse_in_box(tmp / "plate.msh", (0.5, 0.5), (8, 8), 2.0,
                                    refine_near=0.4, inner="hole"),
            "body": ellipse_in_box(tmp / "body.msh", (0.5, 0.5), (6, 4), 2.0,
                                   refine_near=0.4, inner="body")}


STOKES = ["--pde", "stokes", "--objective", "dissipation"]
ELASTICITY = ["--pde", "elasticity", "--objective", "compliance"]


@pytest.mark.parametrize("case, args, words", [
    # Stokes without velocities, or with none that moves anything
    ("body", [*STOKES, "--move", "body", "--keep-volume"], "--dirichlet"),
    ("body", [*STOKES, "--dirichlet", "outer=0,0", "--move", "body"], "is 0"),
    ("body", [*STOKES, "--dirichlet", "body=0,0", "--dirichlet", "outer=0,0"], "is 0"),
    # unknown groups, wherever a group is named
    ("body", [*STOKES, "--dirichlet", "nobody=1,0"], "nobody"),
    ("body", [*STOKES, "--dirichlet", "body=1,0", "--move", "nobody"], "nobody"),
    ("body", [*STOKES, "--dirichlet", "body=1,0", "--fixed", "nobody"], "nobody"),
    ("plate", [*ELASTICITY, "--stress", "nohole=2,1,0"], "nohole"),
    ("plate", [*ELASTICITY, "--stress", "outer=2,1,0", "--clamped", "nowhere"], "nowhere"),
    # vectors and stresses with the wrong number of components
    ("plate", [*ELASTICITY, "--stress", "outer=2,1"], "3 components"),
    ("plate", [*ELASTICITY, "--stress", "outer=2,1,0,5", "--move", "hole"], "3 components"),
    ("body", [*STOKES, "--dirichlet", "body=1"], "2 components"),
    ("body", [*STOKES, "--dirichlet", "body=1,0,0"], "2 components"),
    # constraints that cannot hold
    ("plate", [*ELASTICITY, "--stress", "outer=2,1,0", "--fixed", "outer,hole",
               "--keep-area"], "cannot hold"),
    ("body", [*STOKES, "--dirichlet", "body=1,0", "--keep-barycenter"], "--move"),
    ("body", [*STOKES, "--dirichlet", "body=1,0", "--move", "body", "--fixed", "body",
              "--keep-barycenter"], "--move"),
])
def test_bad_problem_is_one_line_naming_file_and_flag(case, args, words, meshes, tmp_path,
                                                      capsys):
    path = meshes[case]
    out = tmp_path / "out"
    assert main(["optimize", str(path), *args, "-o", str(out)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and words in err and path.name in err, err
    assert "Traceback" not in err and not out.exists()
