"""The growth mechanics written with scikit-fem's own forms: the reference for `solver/mechanics/assembly.py`.

The same discrete problem as the project's assembler (paper 2.1, 2.3.1, 3; docs/model.md, departures
3, 4, 5 and 10), set up the way scikit-fem's nearly-incompressible hyperelasticity example
(its ex36.py) sets up its own: a mixed displacement/pressure formulation, one
`LinearForm` / `BilinearForm` per block, and the pressure block eliminated afterwards (paper
Table 1, step 7, the Schur complement).

    mesh      `MeshHex` / `MeshQuad` on the grid's nodes, obstacle cells removed
    u         `ElementVector(ElementHex1())` (`ElementQuad1` in 2-D): trilinear (bilinear) displacement
    p         `ElementHex0` (`ElementQuad0`): one Cauchy pressure per element (Q1/P0, the paper's H1P0)
    per cell  w = eps + (1 - eps) phi^2 (departure 5) and Jg = (1 + alpha)^3 (Fg = (1 + alpha) I,
              departure 3), both as P0 fields
    points    2 x 2 (x 2) Gauss points (`intorder=2`)

With F = I + grad u, J = det F, G = F^-T and I1 = F : F (+ 1 in plane strain, where F_zz = 1),
J^(-2/3) I1 = tr C~e (Eq. 1; Fg is spherical), the perturbed Lagrangian of the constraint Eq. 15
(departure 4) per unit reference volume is

    Pi(u, p) = Jg w mu/2 (J^(-2/3) I1 - 3) + p (J - Jg) - Jg p^2 / (2 w kappa),

the first term Eq. 20's mechanical energy with tr C~e.  Stationary in the element's p:
p = w kappa (Theta - 1), Theta = int J / (Jg V), and put back, Pi is the project's
Jg V w kappa/2 (Theta - 1)^2 per element.  Its blocks (Eq. 26, with s = Jg w mu J^(-2/3)):

    R_u  = int P : grad v,         P = s (F - I1/3 G) + p J G       (first Piola-Kirchhoff stress)
    K_uu = int dP[grad du] : grad v                                  (p held)
    K_up = int q J G : grad v
    R_p  = int (J - Jg) q - int Jg p q / (w kappa) = B - M p         (M diagonal: P0)

so p = M^-1 B, the condensed residual is R_u and the condensed tangent K_uu + K_up M^-1 K_up^T.
dP[A] is derived here from P (`piola_derivative_terms`), not taken from `solver.mechanics.material`.

Every pointwise quantity is computed once per evaluation and handed to the forms in `w`: scikit-fem
calls a bilinear form once per pair of local basis functions (576 times for a hexahedron).

Round-off: `magnitudes` assembles the same sums with every factor replaced by its absolute value
(and every sign by +), which bounds the round-off of either assembler: a sum of products computed in
floating point is within n u sum |terms| of the exact one (u = 2^-53, n the roundings along the way;
Higham, Accuracy and Stability of Numerical Algorithms, 2nd ed., section 3.1).  `roundings` counts them.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from skfem import (
    Basis,
    BilinearForm,
    ElementHex0,
    ElementHex1,
    ElementQuad0,
    ElementQuad1,
    ElementVector,
    Functional,
    LinearForm,
    MeshHex,
    MeshQuad,
    asm,
)
from skfem.helpers import ddot, det, grad, inv, transpose

from solver.problem import AXES

UNIT_ROUNDOFF = np.finfo(float).eps / 2
CHAIN = 120  # roundings along the longest computation of one entry by one assembler, 3-D (below)
MAP = 64  # roundings of a basis gradient per cell of distance from the origin (below)


def roundings(shape: tuple[int, ...]) -> int:
    """How many unit round-offs of its own scale two correct assemblers may differ by in any entry.

    CHAIN: F = I + a sum of 8 products (9), det F (8), G = cof F / det F (12), J^(-2/3) (3), I1 (9),
    s and the stress or dP[A] terms (<= 12), the sum over 8 points x 3 components (24), the condensed
    term's h and its product (<= 30), the sum over the 8 elements at a node (8): < 120.
    MAP: scikit-fem takes each element's gradients from its isoparametric map, whose Jacobian
    sum_a x_a dN^_a/dxi (8 terms, |x_a| up to n h, |dN^| <= 1/2) rounds relative to the coordinates:
    up to 64 n u of the gradient, n cells from the origin (the project's gradients are one element's
    at the origin, the same for all).  Twice for two assemblers, twice again for the conditioning of F
    (|grad u| <= 0.2 in the tests: cond F < 1.6)."""
    return 4 * (CHAIN + MAP * max(shape))


@dataclass
class OracleEvaluation:
    """Residual, tangent, element pressure and energy, in the oracle's dof and element numbering."""

    residual: np.ndarray
    tangent: sp.csr_matrix | None
    pressure: np.ndarray  # (elements,) p = w kappa (Theta - 1)
    energy: float


# -- pointwise pieces: plain arrays (components first, then elements, points), as scikit-fem's helpers ---

def kinematics(grad_u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """F = I + grad u, G = F^-T, J = det F, I1 = F : F, the last with F_zz = 1 in plane strain (2-D)."""
    d = grad_u.shape[0]
    F = np.array(grad_u, dtype=float)
    for i in range(d):
        F[i, i] += 1.0
    return F, transpose(inv(F)), det(F), ddot(F, F) + (3 - d)


def first_piola_terms(F, G, J, I1, s, p) -> list[tuple[int, np.ndarray]]:
    """P = s (F - I1/3 G) + p J G as (sign, term) pairs (Table 1, step 2, pulled back: P = J sigma F^-T)."""
    return [(1, s * F), (-1, s * I1 / 3 * G), (1, p * J * G)]


def piola_derivative_terms(F, G, J, I1, s, p, A) -> list[tuple[int, np.ndarray]]:
    """dP[A], the derivative of `first_piola_terms` at fixed p in the direction A = grad du, as (sign, term).

    dJ = J G : A,  dG = -G A^T G,  dI1 = 2 F : A,  ds = -2/3 s G : A, so
    dP = ds (F - I1/3 G) + s (A - dI1/3 G - I1/3 dG) + p (dJ G + J dG)."""
    GA, FA = ddot(G, A), ddot(F, A)
    GAtG = np.einsum("ij...,kj...,kl...->il...", G, A, G)
    return [(-1, 2 / 3 * s * GA * F), (1, 2 / 9 * s * I1 * GA * G), (1, s * A), (-1, 2 / 3 * s * FA * G),
            (1, s * I1 / 3 * GAtG), (1, p * J * GA * G), (-1, p * J * GAtG)]


def energy_terms(J, I1, Jg, w, mu, kappa, p) -> list[tuple[int, np.ndarray]]:
    """Pi(u, p) per unit reference volume as (sign, term): Eq. 20's tr C~e energy plus the constraint Eq. 15."""
    return [(1, Jg * w * mu / 2 * J ** (-2 / 3) * I1), (-1, 3 * Jg * w * mu / 2), (1, p * J),
            (-1, p * Jg), (-1, Jg * p**2 / (2 * w * kappa))]


def signed(terms) -> np.ndarray:
    return sum(sign * term for sign, term in terms)


def magnitude(terms) -> np.ndarray:
    """The terms' sum with every sign +: evaluated at absolute values, the round-off scale of `signed`."""
    return sum(term for _, term in terms)


# -- forms -------------------------------------------------------------------------------------------

@LinearForm
def internal_force(v, w):
    return ddot(w.P, grad(v))


@LinearForm
def internal_force_magnitude(v, w):
    return ddot(w.P, np.abs(grad(v)))


@BilinearForm
def material_tangent(du, v, w):
    return ddot(signed(piola_derivative_terms(w.F, w.G, w.J, w.I1, w.s, w.p, grad(du))), grad(v))


@BilinearForm
def material_tangent_magnitude(du, v, w):
    return ddot(magnitude(piola_derivative_terms(w.F, w.G, w.J, w.I1, w.s, w.p, np.abs(grad(du)))),
                np.abs(grad(v)))


@BilinearForm
def pressure_coupling(q, v, w):
    return q * ddot(w.JG, grad(v))


@BilinearForm
def pressure_coupling_magnitude(q, v, w):
    return q * ddot(w.JG, np.abs(grad(v)))


@LinearForm
def volume_change(q, w):
    return (w.J - w.Jg) * q


@BilinearForm
def compliance(p, q, w):
    return w.Jg / w.stiffness * p * q


@Functional
def energy_density(w):
    return signed(energy_terms(w.J, w.I1, w.Jg, w.weight, w.mu, w.kappa, w.p))


@Functional
def energy_magnitude(w):
    return magnitude(energy_terms(w.J, w.I1, w.Jg, w.weight, w.mu, w.kappa, w.p))


# -- mesh --------------------------------------------------------------------------------------------

def element_cells(mesh, shape: tuple[int, ...], h: float) -> np.ndarray:
    """The grid cell (FiPy index, x fastest) of every element, from its centroid."""
    index = np.floor(mesh.p[:, mesh.t].mean(axis=1) / h).astype(int)  # (x, y[, z], elements)
    return np.ravel_multi_index(tuple(index[::-1]), tuple(reversed(shape)))


def grid_mesh(shape: tuple[int, ...], h: float, obstacle: np.ndarray | None = None):
    """`MeshHex` (`MeshQuad`) of the grid's open cells; obstacle in the grid's cell layout ([z,] y, x)."""
    mesh = (MeshHex if len(shape) == 3 else MeshQuad).init_tensor(*[np.arange(n + 1) * h for n in shape])
    if obstacle is not None and np.any(obstacle):
        closed = np.asarray(obstacle, bool).ravel()[element_cells(mesh, shape, h)]
        mesh = mesh.remove_elements(np.flatnonzero(closed))
    return mesh


class MechanicsOracle:
    """The mixed u/p problem on a grid of `shape` cells (x, y[, z]) of edge h, assembled by scikit-fem."""

    def __init__(self, shape: tuple[int, ...], h: float, obstacle: np.ndarray | None = None):
        self.shape, self.h, self.d = tuple(shape), float(h), len(shape)
        self.mesh = grid_mesh(self.shape, self.h, obstacle)
        q1, p0 = (ElementHex1(), ElementHex0()) if self.d == 3 else (ElementQuad1(), ElementQuad0())
        self.u_basis = Basis(self.mesh, ElementVector(q1), intorder=2)
        self.p_basis = self.u_basis.with_element(p0)
        self.cells = element_cells(self.mesh, self.shape, self.h)

    # -- numbering --------------------------------------------------------------------------------
    def dofs_at(self, points: np.ndarray) -> np.ndarray:
        """(points, d) oracle dofs of the mesh nodes at `points` (points, d in x, y[, z])."""
        nodes = np.rint(self.mesh.p / self.h).astype(int)
        lookup = -np.ones(tuple(n + 1 for n in self.shape), int)
        lookup[tuple(nodes)] = np.arange(nodes.shape[1])
        node = lookup[tuple(np.rint(np.asarray(points).T / self.h).astype(int))]
        if np.any(node < 0):
            raise ValueError("a point is not a node of the oracle's mesh")
        return self.u_basis.nodal_dofs[:, node].T

    def cell_field(self, values: np.ndarray) -> np.ndarray:
        """Values per grid cell ([z,] y, x) as a P0 field at the points: (elements, points)."""
        dofs = np.zeros(self.p_basis.N)
        dofs[self.p_basis.element_dofs[0]] = np.asarray(values, float).ravel()[self.cells]
        return np.asarray(self.p_basis.interpolate(dofs))

    def held(self, clamp=(), slide=()) -> np.ndarray:
        """(dofs,) bool: all components on clamp faces, the normal one on slide faces and on every obstacle face.

        Faces are the mesh's facets: a boundary facet not on the domain's boundary is an obstacle's."""
        mesh, d = self.mesh, self.d
        corners = mesh.p[:, mesh.facets]  # (d, facet nodes, facets)
        normal = np.argmin(np.ptp(corners, axis=1), axis=0)  # the axis along which a facet is flat
        at = corners[normal, 0, np.arange(corners.shape[2])]
        size = np.array(self.shape)[normal] * self.h
        outer = np.isclose(at, 0.0) | np.isclose(at, size)
        held = np.zeros(self.u_basis.N, bool)
        facets = mesh.boundary_facets()
        for axis in range(d):
            obstacle_faces = facets[(normal[facets] == axis) & ~outer[facets]]
            held[self.u_basis.get_dofs(obstacle_faces).all(f"u^{axis + 1}")] = True
        for face in (*clamp, *slide):
            axis = AXES.index(face[0])
            side = np.isclose(at, 0.0 if face[1] == "-" else size)
            dofs = self.u_basis.get_dofs(facets[(normal[facets] == axis) & side[facets]])
            held[dofs.all() if face in clamp else dofs.all(f"u^{axis + 1}")] = True
        return held

    # -- assembly ---------------------------------------------------------------------------------
    def state(self, u, phi, alpha, mu, kappa, residual_stiffness) -> dict:
        """Everything the forms need at the points, with p the element pressure M^-1 B."""
        weight = self.cell_field(residual_stiffness + (1 - residual_stiffness) * np.asarray(phi, float) ** 2)
        Jg = self.cell_field((1 + np.asarray(alpha, float)) ** 3)
        F, G, J, I1 = kinematics(grad(self.u_basis.interpolate(u)))
        stiffness = weight * kappa
        M = asm(compliance, self.p_basis, Jg=Jg, stiffness=stiffness).diagonal()
        p_dofs = asm(volume_change, self.p_basis, J=J, Jg=Jg) / M
        p = np.asarray(self.p_basis.interpolate(p_dofs))
        return dict(F=F, G=G, J=J, I1=I1, Jg=Jg, weight=weight, stiffness=stiffness, M=M, p_dofs=p_dofs, p=p,
                    s=Jg * weight * mu * J ** (-2 / 3), mu=mu, kappa=kappa)

    def evaluate(self, u, phi, alpha, mu, kappa, residual_stiffness, held=None, tangent=True) -> OracleEvaluation:
        """Condensed residual and tangent at u (oracle numbering), held dofs with identity rows and columns."""
        st = self.state(u, phi, alpha, mu, kappa, residual_stiffness)
        P = signed(first_piola_terms(st["F"], st["G"], st["J"], st["I1"], st["s"], st["p"]))
        R = asm(internal_force, self.u_basis, P=P)
        K = None
        if tangent:
            K_uu = asm(material_tangent, self.u_basis, **pick(st, "F", "G", "J", "I1", "s", "p"))
            K_up = asm(pressure_coupling, self.p_basis, self.u_basis, JG=st["J"] * st["G"])
            K = (K_uu + K_up @ sp.diags(1 / st["M"]) @ K_up.T).tocsr()
        energy = asm(energy_density, self.u_basis, **pick(st, "J", "I1", "Jg", "weight", "mu", "kappa", "p"))
        R, K = hold(R, K, held)
        return OracleEvaluation(R, K, st["p_dofs"][self.p_basis.element_dofs[0]], float(energy))

    def magnitudes(self, u, phi, alpha, mu, kappa, residual_stiffness, held=None) -> OracleEvaluation:
        """The same sums over absolute values (module docstring): the scale of round-off in each entry.

        The element pressure p = w kappa (Theta - 1) is computed from Theta ~ 1, so its round-off is
        relative to w kappa (Theta + 1) <= 2 w kappa + |p|, which stands in for |p|."""
        st = self.state(u, phi, alpha, mu, kappa, residual_stiffness)
        F, G, J, I1, s = np.abs(st["F"]), np.abs(st["G"]), st["J"], st["I1"], st["s"]
        p = 2 * st["stiffness"] + np.abs(st["p"])
        R = asm(internal_force_magnitude, self.u_basis, P=magnitude(first_piola_terms(F, G, J, I1, s, p)))
        K_uu = asm(material_tangent_magnitude, self.u_basis, F=F, G=G, J=J, I1=I1, s=s, p=p)
        K_up = asm(pressure_coupling_magnitude, self.p_basis, self.u_basis, JG=J * G)
        K = (K_uu + K_up @ sp.diags(1 / st["M"]) @ K_up.T).tocsr()
        energy = asm(energy_magnitude, self.u_basis, J=J, I1=I1, Jg=st["Jg"], weight=st["weight"], mu=mu,
                     kappa=kappa, p=p)
        R, K = hold(R, K, held)
        return OracleEvaluation(R, K, p[:, 0], float(energy))


def pick(state: dict, *names: str) -> dict:
    return {name: state[name] for name in names}


def hold(R: np.ndarray, K: sp.spmatrix | None, held: np.ndarray | None):
    """Held dofs: residual zero, identity rows and columns (the project's convention, symmetric)."""
    if held is None or not np.any(held):
        return R, K
    R = np.where(held, 0.0, R)
    if K is not None:
        free = sp.diags((~held).astype(float))
        K = (free @ K @ free + sp.diags(held.astype(float))).tocsr()
    return R, K


def roundoff_ratio(project, oracle, scale) -> float:
    """max |project - oracle| / (u * scale) over entries: how many unit round-offs of its own scale apart.

    Arrays or sparse matrices (then over the difference's nonzeros); an entry whose scale is zero
    must agree exactly (else inf)."""
    if sp.issparse(project) or sp.issparse(oracle):
        difference = sp.coo_matrix(sp.csr_matrix(project) - sp.csr_matrix(oracle))
        scale = np.asarray(sp.csr_matrix(scale)[difference.row, difference.col]).ravel()
        difference = np.abs(difference.data)
    else:
        difference = np.abs(np.asarray(project, float) - np.asarray(oracle, float))
        scale = np.asarray(scale, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(difference == 0, 0.0, difference / (UNIT_ROUNDOFF * scale))
    return float(ratio.max(initial=0.0))
