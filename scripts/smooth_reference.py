#!/usr/bin/env python3
"""Smooth-geometry references for the curved primitives (issue 19): the same shapes as
`src/shape/primitives.rs`, meshed by gmsh as their true curved solids (no voxels), solved with
quadratic tetrahedra (scikit-fem, curved 10-node tets) and SciPy's shift-invert eigsh, at two
mesh sizes so the convergence shows.

Units are the FEM's reference units (E = 1, rho = 1, lengths in voxels at scale 1), so the
eigenvalues compare directly with `ModeBasis` eigenvalues of the rasterised primitive.

Run through scripts/smooth-reference.sh (it makes the venv); writes JSON to stdout:
    {"bowl:d=16,wall=2": {"nu": 0.2, "levels": [{"h": 2.0, "dofs": N, "eigenvalues": [...]}, ...]}}
Not a test dependency: the tests read the committed tests/data/smooth_references.json.
"""

import json
import math
import sys
import tempfile

import gmsh
import numpy as np
from scipy.sparse.linalg import eigsh
from skfem import Basis, BilinearForm, ElementTetP2, ElementVector, MeshTet2, asm
from skfem.helpers import dot
from skfem.models.elasticity import lame_parameters, linear_elasticity

MODES = 16


def revolve_profile(occ, pts):
    """A solid of revolution about z from a closed (r, z) polygon of straight and spline
    pieces: pts is a list of segments, each a list of (r, z) points (2 points: a line)."""
    curves = []
    point_tags = {}

    def tag(p):
        key = (round(p[0], 12), round(p[1], 12))
        if key not in point_tags:
            point_tags[key] = occ.addPoint(p[0], 0.0, p[1])
        return point_tags[key]

    for seg in pts:
        tags = [tag(p) for p in seg]
        if len(tags) == 2:
            curves.append(occ.addLine(tags[0], tags[1]))
        else:
            curves.append(occ.addSpline(tags))
    loop = occ.addCurveLoop(curves)
    surf = occ.addPlaneSurface([loop])
    out = occ.revolve([(2, surf)], 0, 0, 0, 0, 0, 1, 2 * math.pi)
    return [e for e in out if e[0] == 3]


def build(occ, name, p):
    """Adds the primitive `name` with parameters p (voxels at scale 1), centred on the z axis
    with its lowest point at z = 0, as gmsh OCC volumes."""
    if name == "sphere":
        r = p["d"] / 2
        return [(3, occ.addSphere(0, 0, r, r))]
    if name == "cylinder":
        return [(3, occ.addCylinder(0, 0, 0, 0, 0, p["h"], p["d"] / 2))]
    if name == "tube":
        r, w, h = p["d"] / 2, p["wall"], p["h"]
        o = occ.addCylinder(0, 0, 0, 0, 0, h, r)
        i = occ.addCylinder(0, 0, -1, 0, 0, h + 2, r - w)
        return occ.cut([(3, o)], [(3, i)])[0]
    if name == "cup":
        r, w, h = p["d"] / 2, p["wall"], p["h"]
        o = occ.addCylinder(0, 0, 0, 0, 0, h, r)
        i = occ.addCylinder(0, 0, w, 0, 0, h, r - w)
        return occ.cut([(3, o)], [(3, i)])[0]
    if name == "bowl":
        r, w = p["d"] / 2, p["wall"]
        top = round(p["d"] / 2)
        o = occ.addSphere(0, 0, top, r)
        i = occ.addSphere(0, 0, top, r - w)
        shell = occ.cut([(3, o)], [(3, i)])[0]
        lid = occ.addBox(-r - 1, -r - 1, top, 2 * r + 2, 2 * r + 2, r + 1)
        return occ.cut(shell, [(3, lid)])[0]
    if name == "bell":
        big_r, h, w = p["d"] / 2, p["h"], p["wall"]

        def outer(z):
            return big_r * (0.55 + 0.45 * (1 - z / h) ** 2)

        n = 24
        outer_pts = [(outer(h * k / n), h * k / n) for k in range(n + 1)]
        zc = h - w
        inner_pts = [(outer(zc * k / n) - w, zc * k / n) for k in range(n + 1)]
        segs = [
            outer_pts,  # mouth (z = 0) up to the crown top
            [(outer(h), h), (0.0, h)],
            [(0.0, h), (0.0, zc)],
            [(0.0, zc), (outer(zc) - w, zc)],
            list(reversed(inner_pts)),
            [(outer(0) - w, 0.0), (outer(0), 0.0)],
        ]
        return revolve_profile(occ, segs)
    raise ValueError(name)


def mesh(name, p, h):
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.model.add(name)
    build(gmsh.model.occ, name, p)
    gmsh.model.occ.synchronize()
    gmsh.option.setNumber("Mesh.MeshSizeMax", h)
    gmsh.option.setNumber("Mesh.MeshSizeMin", h / 3)
    gmsh.option.setNumber("Mesh.ElementOrder", 2)
    gmsh.option.setNumber("Mesh.HighOrderOptimize", 1)
    gmsh.model.mesh.generate(3)
    with tempfile.NamedTemporaryFile(suffix=".msh", delete=False) as f:
        path = f.name
    gmsh.option.setNumber("Mesh.MshFileVersion", 2.2)
    gmsh.write(path)
    gmsh.finalize()
    return MeshTet2.load(path)


def solve(m, nu):
    e = ElementVector(ElementTetP2())
    basis = Basis(m, e, intorder=4)
    lam, mu = lame_parameters(1.0, nu)
    k = asm(linear_elasticity(lam, mu), basis)

    @BilinearForm
    def mass(u, v, _):
        return dot(u, v)

    mm = asm(mass, basis)
    # Shift below zero so K - sigma M is definite; the 6 rigid modes come out near 0.
    scale = k.diagonal().mean() / mm.diagonal().mean()
    vals = eigsh(k, k=MODES + 6, M=mm, sigma=-1e-3 * scale, which="LM",
                 return_eigenvectors=False)
    vals = np.sort(vals)
    return k.shape[0], [float(v) for v in vals[6:]]


def main():
    # (spec, parameters, nu, mesh sizes coarse -> fine)
    cases = [
        ("bowl:d=16,wall=2", "bowl", {"d": 16, "wall": 2}, [1.0, 0.75, 0.55]),
        ("bowl:d=32,wall=2", "bowl", {"d": 32, "wall": 2}, [1.4, 1.0, 0.8]),
        ("sphere:d=16", "sphere", {"d": 16}, [2.5, 1.8]),
        ("cylinder:d=16,h=32", "cylinder", {"d": 16, "h": 32}, [3.0, 2.2]),
        ("tube:d=16,h=32,wall=2", "tube", {"d": 16, "h": 32, "wall": 2}, [1.1, 0.8]),
        ("cup:d=16,h=20,wall=2", "cup", {"d": 16, "h": 20, "wall": 2}, [1.1, 0.8]),
        ("bell:d=24,h=24,wall=2", "bell", {"d": 24, "h": 24, "wall": 2}, [1.6, 1.1]),
    ]
    only = set(sys.argv[1:])
    nu = 0.2  # glass (presets/materials/glass.toml)
    out = {}
    for spec, name, p, sizes in cases:
        if only and spec not in only:
            continue
        levels = []
        for h in sizes:
            m = mesh(name, p, h)
            dofs, vals = solve(m, nu)
            levels.append({"h": h, "dofs": dofs, "eigenvalues": vals})
            print(f"{spec} h={h} dofs={dofs} first={vals[:4]}", file=sys.stderr, flush=True)
        out[spec] = {"nu": nu, "levels": levels}
    json.dump(out, sys.stdout, indent=1)
    print()


if __name__ == "__main__":
    main()
