"""Which displacement components are held at zero: faces, obstacles, rigid-body modes.

* clamp faces: every component zero on the face's nodes;
* slide faces: the normal component zero;
* obstacles (rigid, frictionless): on every face between an open cell and an
  obstacle cell, the component along that face's normal is zero; the
  tangential ones stay free.  A node touching obstacle faces with different
  normals therefore has all those components fixed;
* whatever rigid-body motion (3 translations + 3 rotations in 3-D, 2 + 1 in
  2-D) the constraints above leave free is removed by pinning single
  components of a few nodes, chosen greedily: a component is pinned only if
  it removes a mode not removed yet.  The candidates are, in this order, the
  mesh node nearest the origin and the nodes nearest the far ends of the x,
  y (and z) axes from it, so that with no other constraint the pins are the
  classic 3-2-1 set: origin (x, y, z), (Lx, 0, 0) (y, z), (0, Ly, 0) (z).
  Such a set is statically determinate: at equilibrium its reactions vanish
  (the internal forces of a free body balance in force and moment), so the
  stress does not depend on which point is pinned, and uniform growth gives
  exactly u = alpha X about the pinned origin.
  This is done per connected piece of the mesh (an obstacle wall can cut
  the domain in two).
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from ..problem import AXES
from .mesh import StructuredMesh


def _face_nodes(mesh: StructuredMesh, axis: int, side: str) -> np.ndarray:
    """Mesh nodes on the domain face x-/x+/... (axis in x, y, z numbering)."""
    index = mesh.node_grid_index()[mesh.ndim - 1 - axis]
    end = 0 if side == "-" else mesh.grid.shape[axis]
    return np.flatnonzero(index == end)


def _obstacle_normals(mesh: StructuredMesh) -> np.ndarray:
    """(grid nodes, ndim) bool: nodes on an open/obstacle face with that face normal."""
    obstacle, d = mesh.obstacle, mesh.ndim
    out = np.zeros(mesh.grid.nodes_shape + (d,), bool)
    for axis in range(d):
        ax = d - 1 - axis  # array axis of this coordinate
        low = [slice(None)] * d
        high = [slice(None)] * d
        low[ax], high[ax] = slice(None, -1), slice(1, None)
        faces = obstacle[tuple(low)] ^ obstacle[tuple(high)]  # face between cell i and i+1 along ax
        # spread each face to its nodes: node plane i+1 along ax, both ends along the other axes
        nodes = np.zeros(mesh.grid.nodes_shape, bool)
        spread = faces
        for other in range(d):
            if other != ax:
                pad_lo = [(0, 0)] * d
                pad_hi = [(0, 0)] * d
                pad_lo[other], pad_hi[other] = (1, 0), (0, 1)
                spread = np.pad(spread, pad_lo) | np.pad(spread, pad_hi)
        target = [slice(None)] * d
        target[ax] = slice(1, -1)
        nodes[tuple(target)] = spread
        out[..., axis] = nodes
    return out.reshape(-1, d)


def boundary_fixed(mesh: StructuredMesh, clamp=(), slide=()) -> np.ndarray:
    """(dofs,) bool: held by clamp and slide faces and by obstacle faces."""
    d = mesh.ndim
    fixed = np.zeros((mesh.n_nodes, d), bool)
    for face in (*clamp, *slide):
        axis = AXES.index(face[0])
        if axis >= d:
            raise ValueError(f"face {face!r} does not exist in a {d}-D grid")
        nodes = _face_nodes(mesh, axis, face[1])
        if face in clamp:
            fixed[nodes, :] = True
        else:
            fixed[nodes, axis] = True
    fixed |= _obstacle_normals(mesh)[mesh.nodes]
    return fixed.ravel()


def rigid_modes(points: np.ndarray) -> np.ndarray:
    """(points * ndim, modes) rigid-body displacements at `points` (translations, then rotations)."""
    n, d = points.shape
    if d == 2:
        x, y = points.T
        modes = np.zeros((n, 2, 3))
        modes[:, 0, 0] = modes[:, 1, 1] = 1.0
        modes[:, 0, 2], modes[:, 1, 2] = -y, x
    else:
        x, y, z = points.T
        modes = np.zeros((n, 3, 6))
        modes[:, [0, 1, 2], [0, 1, 2]] = 1.0
        modes[:, 1, 3], modes[:, 2, 3] = -z, y  # about x
        modes[:, 0, 4], modes[:, 2, 4] = z, -x  # about y
        modes[:, 0, 5], modes[:, 1, 5] = -y, x  # about z
    return modes.reshape(n * d, -1)


def _row_basis(rows: np.ndarray, tol: float) -> np.ndarray:
    """Orthonormal basis of the span of `rows` (k, modes)."""
    if rows.shape[0] == 0:
        return np.zeros((0, rows.shape[1]))
    _, sv, vt = np.linalg.svd(rows, full_matrices=False)
    return vt[sv > tol * max(sv[0], 1.0)]


def pin_rigid_modes(mesh: StructuredMesh, fixed: np.ndarray) -> tuple[np.ndarray, list[tuple[int, int]]]:
    """`fixed` plus the pins removing the remaining rigid-body modes; also the pins as (grid node, comp)."""
    d = mesh.ndim
    fixed = fixed.copy()
    conn = mesh.connectivity
    edges = sp.coo_matrix((np.ones(conn.size), (np.repeat(conn[:, 0], conn.shape[1]), conn.ravel())),
                          shape=(mesh.n_nodes, mesh.n_nodes))
    _, piece = connected_components(edges, directed=False)
    coords = mesh.node_coordinates()
    pins = []
    for label in np.unique(piece):
        nodes = np.flatnonzero(piece == label)
        anchor = nodes[np.argmin(np.linalg.norm(coords[nodes], axis=1))]
        x = (coords[nodes] - coords[anchor]) / mesh.h  # relative, in cells: well-conditioned
        modes = rigid_modes(x).reshape(nodes.size, d, -1)
        held = fixed.reshape(-1, d)[nodes]
        basis = _row_basis(modes[held], 1e-9)
        candidates = [np.flatnonzero(nodes == anchor)[0]]
        for axis in range(d):  # farthest along each axis, nearest to the anchor's line
            far = np.flatnonzero(np.isclose(x[:, axis], x[:, axis].max()))
            candidates.append(far[np.argmin(np.linalg.norm(x[far], axis=1))])
        for local in candidates:
            for comp in range(d):
                if basis.shape[0] == modes.shape[2]:
                    break
                row = modes[local, comp]
                rest = row - basis.T @ (basis @ row)
                if np.linalg.norm(rest) > 1e-9 * max(np.linalg.norm(row), 1.0):
                    basis = np.vstack([basis, rest / np.linalg.norm(rest)])
                    fixed[nodes[local] * d + comp] = True
                    pins.append((int(mesh.nodes[nodes[local]]), comp))
    return fixed, pins
