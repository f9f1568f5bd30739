"""Which displacement components are held at zero: faces, obstacles, rigid-body modes.

* clamp faces: every component zero on the face's nodes;
* slide faces: the normal component zero;
* obstacles (rigid, frictionless): on every face between an open cell and an
  obstacle cell, the component along that face's normal is zero; the
  tangential ones stay free.  A node touching obstacle faces with different
  normals therefore has all those components held;
* whatever rigid-body motion (3 translations + 3 rotations in 3-D, 2 + 1 in
  2-D) the constraints above leave free is removed by pinning single
  components of a few nodes, chosen greedily: a component is pinned only if
  it removes a mode not removed yet.  The candidates are an anchor node and
  the nodes farthest from it along the x, y (and z) axes, so that with no
  other constraint the pins are a 3-2-1 set: anchor (x, y, z), a node along
  x (y, z), a node along y (z).  Such a set is statically determinate: at
  equilibrium its reactions vanish (the internal forces of a free body
  balance in force and moment), so the stress does not depend on which
  points are pinned; the displacements differ by a rigid-body motion.
  This is done per connected piece of the mesh (an obstacle wall can cut
  the domain in two).

Where the pins go matters to the solver, not to the answer.  Pinned in the
void (the domain's corner), a dense body floats on the void's residual
stiffness: its rigid motions become the softest modes of the tangent
(by seven orders of magnitude, docs/mechanics.md), and as their stiffness
depends on the body's prestress as much as on the void, a preconditioner
built from one tangent misjudges them in the next and Newton stalls
(docs/mechanics.md).  So `pin_rigid_modes` takes an optional node
stiffness and pins inside the stiffest part: anchor at the stiff node
nearest the stiffness-weighted centroid, axis nodes the stiff nodes
farthest from it along the anchor's grid lines.  The displacement reported
is still the one pinned at the domain corner (`gauge`): a rigid-body
motion apart, exactly for infinitesimal rotations.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from ..problem import AXES, face_problem
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


def boundary_held(mesh: StructuredMesh, clamp=(), slide=()) -> np.ndarray:
    """(dofs,) bool: held by clamp and slide faces and by obstacle faces."""
    d = mesh.ndim
    constrained = np.zeros((mesh.n_nodes, d), bool)
    for face in (*clamp, *slide):
        problem = face_problem(face, d)
        if problem:
            raise ValueError(problem)
        axis = AXES.index(face[0])
        nodes = _face_nodes(mesh, axis, face[1])
        if face in clamp:
            constrained[nodes, :] = True
        else:
            constrained[nodes, axis] = True
    constrained |= _obstacle_normals(mesh)[mesh.nodes]
    return constrained.ravel()


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


def pin_rigid_modes(mesh: StructuredMesh, constrained: np.ndarray,
                    stiffness: np.ndarray | None = None) -> tuple[np.ndarray, list[tuple[int, int]]]:
    """`constrained` plus the pins removing the remaining rigid-body modes; also the pins as (mesh node, comp).

    stiffness: per mesh node (e.g. `node_stiffness`); None pins at the domain's corner (the origin)."""
    d = mesh.ndim
    constrained = constrained.copy()
    piece = pieces(mesh)
    coords = mesh.node_coordinates()
    pins = []
    for label in np.unique(piece):
        nodes = np.flatnonzero(piece == label)
        if stiffness is None:
            pool, anchor = nodes, nodes[np.argmin(np.linalg.norm(coords[nodes], axis=1))]
        else:  # the stiff nodes of this piece; anchor nearest their weighted centroid
            s = stiffness[nodes]
            pool = nodes[s >= 0.5 * s.max()]
            centre = (coords[pool] * stiffness[pool, None]).sum(axis=0) / stiffness[pool].sum()
            anchor = pool[np.argmin(np.linalg.norm(coords[pool] - centre, axis=1))]
        x = (coords[nodes] - coords[anchor]) / mesh.h  # relative, in cells: well-conditioned
        modes = rigid_modes(x).reshape(nodes.size, d, -1)
        held = constrained.reshape(-1, d)[nodes]
        basis = _row_basis(modes[held], 1e-9)
        local = np.flatnonzero(np.isin(nodes, pool))
        candidates = [np.flatnonzero(nodes == anchor)[0]]
        for axis in range(d):  # the pool node farthest from the anchor along each axis, nearest its line
            reach = np.abs(x[local, axis]) - 1e-3 * np.linalg.norm(np.delete(x[local], axis, axis=1), axis=1)
            candidates.append(local[np.argmax(reach)])
        for index in candidates:
            for comp in range(d):
                if basis.shape[0] == modes.shape[2]:
                    break
                row = modes[index, comp]
                rest = row - basis.T @ (basis @ row)
                if np.linalg.norm(rest) > 1e-9 * max(np.linalg.norm(row), 1.0):
                    basis = np.vstack([basis, rest / np.linalg.norm(rest)])
                    constrained[nodes[index] * d + comp] = True
                    pins.append((int(nodes[index]), comp))
    return constrained, pins


def pieces(mesh: StructuredMesh) -> np.ndarray:
    """Per mesh node, the label of its connected piece of the mesh."""
    conn = mesh.connectivity
    edges = sp.coo_matrix((np.ones(conn.size), (np.repeat(conn[:, 0], conn.shape[1]), conn.ravel())),
                          shape=(mesh.n_nodes, mesh.n_nodes))
    return connected_components(edges, directed=False)[1]


def pins_are_stiff(pins: list[tuple[int, int]], stiffness: np.ndarray, piece: np.ndarray) -> bool:
    """Every pinned node at least half as stiff as the stiffest node of its piece."""
    return all(stiffness[node] >= 0.5 * stiffness[piece == piece[node]].max() for node, _ in pins)


def node_stiffness(mesh: StructuredMesh, weight: np.ndarray) -> np.ndarray:
    """Per mesh node, the mean stiffness weight w of the elements around it."""
    conn = mesh.connectivity
    total = np.bincount(conn.ravel(), weights=np.repeat(weight, conn.shape[1]), minlength=mesh.n_nodes)
    return total / np.bincount(conn.ravel(), minlength=mesh.n_nodes)


def gauge(mesh: StructuredMesh, u: np.ndarray, constrained: np.ndarray, pins: list[tuple[int, int]]) -> np.ndarray:
    """u minus the rigid-body motion that is zero at the held dofs and equals u at `pins`.

    The same equilibrium pinned elsewhere (exact for infinitesimal rotations:
    the rigid modes are linearised)."""
    if not pins:
        return u
    d = mesh.ndim
    coords = mesh.node_coordinates()
    modes = rigid_modes((coords - coords.mean(axis=0)) / mesh.h)
    rows = np.array([node * d + comp for node, comp in pins])
    held = np.flatnonzero(constrained)
    held = held[~np.isin(held, rows)]
    system = np.vstack([modes[held], modes[rows]])
    target = np.concatenate([np.zeros(held.size), u[rows]])
    coefficients = np.linalg.lstsq(system, target, rcond=None)[0]
    return u - modes @ coefficients


def body_modes(mesh: StructuredMesh, dense: np.ndarray, constrained: np.ndarray) -> np.ndarray:
    """Orthonormal rigid-body modes of each connected dense body, zero elsewhere and at constrained dofs.

    `dense` marks elements (e.g. phi > 1/2).  A body that touches no
    constraint floats in the void, held only by its residual stiffness: its
    rigid motions are the softest modes of the tangent, which a Krylov solve
    stopped on the residual leaves unconverged; `preconditioners.Deflated`
    can solve in their span exactly (`Settings.deflate`; with the pins inside
    the biofilm it did not pay, docs/mechanics.md).  Bodies held by
    constraints get modes too: harmless."""
    d, conn = mesh.ndim, mesh.connectivity
    elements = np.flatnonzero(dense)
    if elements.size == 0:
        return np.zeros((mesh.n_dofs, 0))
    incidence = sp.csr_matrix((np.ones(elements.size * conn.shape[1]),
                               (np.repeat(np.arange(elements.size), conn.shape[1]), conn[elements].ravel())),
                              shape=(elements.size, mesh.n_nodes))
    count, label = connected_components(incidence @ incidence.T, directed=False)
    coords = mesh.node_coordinates()
    columns = []
    for body in range(count):
        nodes = np.unique(conn[elements[label == body]])
        modes = np.zeros((mesh.n_nodes, d, 3 * (d - 1)))
        modes[nodes] = rigid_modes((coords[nodes] - coords[nodes].mean(axis=0)) / mesh.h).reshape(nodes.size, d, -1)
        columns.append(modes.reshape(mesh.n_dofs, -1))
    Z = np.hstack(columns)
    Z[constrained] = 0.0
    q, r = np.linalg.qr(Z)
    return q[:, np.abs(np.diag(r)) > 1e-10 * np.abs(np.diag(r)).max()]
