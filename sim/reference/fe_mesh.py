"""The mesh of the axisymmetric FE (:mod:`.fe`) and what every material field solved on it shares: the skfem basis,
the stiffness's geometric parts, the condensed sparse structure, the constrained dofs and the hats' surface loads.
Built once per geometry (:func:`build_mesh`); a field's stiffness is then assembled from its Lame constants alone.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from palpate.core.errors import ValidationError
from palpate.sim.reference.sample import AxisymmetricSample


@dataclass(frozen=True)
class FEMesh:
    """What a mesh gives every material field solved on it: the skfem basis, the stiffness's two geometric parts
    (per element, (E, 18, 18): K_e = lam_e A_e + mu_e B_e, lam and mu being constant on an element), where each
    condensed local entry lands in the free dofs' CSC matrix, the constrained dofs and the surface loads of the hats.

    Each element's two interior (bubble) dofs couple to nothing outside it and carry no load, so they are condensed
    out element by element (static condensation) before the global solve: a quarter fewer unknowns to factorise,
    the same answer to rounding; they are recovered from the element's other dofs where the energy needs them.

    Attributes:
        basis: skfem basis (vector Q2). centroid_r, centroid_depth: each element's centroid, m, (E,).
        lam_part, mu_part: (E, 18, 18), A and B above (local dofs 16 and 17 the bubble's).
        element_dofs: (E, 18) global dofs of each element.
        free: (f,) the free dofs but the bubbles'; at: (N,) each dof's index among them (-1: fixed or a bubble).
        kept: (k,) flat indices (into E * 16 * 16) of the condensed local entries between two free dofs; slot: (k,)
            the position of each in the CSC data; indices, indptr: the CSC structure (f x f).
        r_top: the hats' vertices, m; loads: (f, hats) consistent loads of unit hat pressures on the free dofs;
        vertex: (hats,) each hat vertex's vertical dof among the free ones.
    """

    basis: object
    centroid_r: np.ndarray
    centroid_depth: np.ndarray
    lam_part: np.ndarray
    mu_part: np.ndarray
    element_dofs: np.ndarray
    free: np.ndarray
    at: np.ndarray
    kept: np.ndarray
    slot: np.ndarray
    indices: np.ndarray
    indptr: np.ndarray
    r_top: np.ndarray
    loads: np.ndarray
    vertex: np.ndarray

    def local_stiffness(self, lam: np.ndarray, mu: np.ndarray) -> np.ndarray:
        """Each element's stiffness (E, 18, 18) for per-element Lame constants ``lam``, ``mu`` (Pa, (E,))."""
        local = self.lam_part * lam[:, None, None]
        local += self.mu_part * mu[:, None, None]
        return local

    def stiffness(self, lam: np.ndarray, mu: np.ndarray, local: np.ndarray | None = None):
        """The free dofs' condensed stiffness (CSC) for per-element Lame constants ``lam``, ``mu`` (Pa, (E,)), and
        the bubbles' recovery (E, 2, 16): bubble dofs = -recovery @ the element's other dofs. ``local``: their
        :meth:`local_stiffness` if the caller has it."""
        from scipy.sparse import csc_matrix

        local = self.local_stiffness(lam, mu) if local is None else local
        recovery = np.linalg.solve(local[:, 16:, 16:], local[:, 16:, :16])
        condensed = local[:, :16, :16] - np.matmul(local[:, :16, 16:], recovery)
        data = np.bincount(self.slot, weights=condensed.ravel()[self.kept], minlength=len(self.indices))
        n = len(self.free)
        return csc_matrix((data, self.indices, self.indptr), shape=(n, n)), recovery

    def element_energy(self, local: np.ndarray, u: np.ndarray, recovery: np.ndarray) -> np.ndarray:
        """Twice the strain energy in each element (only shares are used) of displacement ``u`` (all dofs; the
        bubbles' are recovered with ``recovery`` from :meth:`stiffness`), ``local`` the elements'
        :meth:`local_stiffness`."""
        ue = u[self.element_dofs]
        ue[:, 16:] = -np.einsum("ebj,ej->eb", recovery, ue[:, :16])
        return np.einsum("ei,eij,ej->e", ue, local, ue)


def stiffness_parts(basis) -> tuple[np.ndarray, np.ndarray]:
    """The axisymmetric stiffness's parts A and B, (E, 18, 18), such that lam_e A_e + mu_e B_e is element e's
    stiffness for Lame constants constant on it: the bilinear form lam tr(e_u) tr(e_v) + 2 mu (e_u : e_v over the
    normal strains e_rr, e_zz, e_tt = u_r / r) + mu g_u g_v (g the engineering shear), weighted by r, as skfem's
    BilinearForm would assemble it, but all 18 x 18 local pairs in batched matrix products instead of one Python
    call per pair (equal to ~1e-16)."""
    r = basis.global_coordinates()[0]  # (elements, quadrature points), m
    phi = [b[0] for b in basis.basis]  # each local basis function at every element's quadrature points
    grad = np.stack([p.grad for p in phi])  # (18, 2, 2, E, Q)
    normal = np.stack([grad[:, 0, 0], grad[:, 1, 1], np.stack([p[0] for p in phi]) / r], axis=1)
    trace = normal.sum(axis=1)  # (18, E, Q)
    shear = grad[:, 0, 1] + grad[:, 1, 0]
    w = basis.dx * r  # (E, Q)
    tw = (trace * w[None]).transpose(1, 0, 2)  # (E, 18, Q)
    lam_part = np.matmul(tw, trace.transpose(1, 2, 0))
    # the mu part: 2 (normal strains) + 1 (shear), summed over quadrature points and strain components at once
    right = np.concatenate([normal, shear[:, None]], axis=1)  # (18, 4, E, Q)
    left = right * (np.array([2.0, 2.0, 2.0, 1.0])[None, :, None, None] * w[None, None])
    e = len(w)
    mu_part = np.matmul(left.transpose(2, 0, 1, 3).reshape(e, len(phi), -1),
                        right.transpose(2, 1, 3, 0).reshape(e, -1, len(phi)))
    return lam_part, mu_part


def assemble_stiffness(basis, lam: np.ndarray, mu: np.ndarray):
    """The axisymmetric stiffness matrix (CSR, every dof) for per-element Lame constants ``lam``, ``mu`` (Pa)."""
    from scipy.sparse import coo_matrix

    lam_part, mu_part = stiffness_parts(basis)
    local = lam_part * lam[:, None, None] + mu_part * mu[:, None, None]
    dofs = basis.element_dofs.T  # (E, 18)
    rows = np.broadcast_to(dofs[:, :, None], local.shape).ravel()
    cols = np.broadcast_to(dofs[:, None, :], local.shape).ravel()
    return coo_matrix((local.ravel(), (rows, cols)), shape=(basis.N, basis.N)).tocsr()


def build_mesh(sample: AxisymmetricSample, r_nodes: np.ndarray, z_nodes: np.ndarray, width: float, wide: bool,
          reach: float) -> FEMesh:
    """The mesh of nodes ``r_nodes`` x ``z_nodes`` (m) and what every field solved on it shares (:class:`FEMesh`):
    the axis, the base (bonded or frictionless) and, for a wide sample, a roller at ``width`` m constrained; hats
    on the top vertices out to ``reach`` m."""
    from skfem import Basis, ElementQuad2, ElementVector, MeshQuad1

    top = float(z_nodes[-1])
    # mesh coordinates: x = r, y = height above the base (depth = top - y)
    mesh = MeshQuad1.init_tensor(r_nodes, np.sort(top - z_nodes))
    basis = Basis(mesh, ElementVector(ElementQuad2()), intorder=4)
    centroid = mesh.p[:, mesh.t].mean(axis=1)
    locs = basis.doflocs
    dofs = basis.get_dofs()
    ur, uz = dofs.all("u^1"), dofs.all("u^2")
    n = basis.N
    fixed = [ur[np.isclose(locs[0, ur], 0.0)]]
    bottom = np.isclose(locs[1], 0.0)
    fixed.append(uz[bottom[uz]])
    if sample.base == "bonded":
        fixed.append(ur[bottom[ur]])
    if wide:
        fixed.append(ur[np.isclose(locs[0, ur], width)])
    element_dofs = np.ascontiguousarray(basis.element_dofs.T)  # (E, 18), the bubble's last
    fixed = np.unique(np.concatenate(fixed + [element_dofs[:, 16:].ravel()]))  # bubbles: condensed, not solved
    free = np.setdiff1d(np.arange(n), fixed)
    at = -np.ones(n, dtype=int)
    at[free] = np.arange(len(free))
    # where each condensed local entry between two free dofs lands in their CSC matrix (column-major keys)
    outer = element_dofs[:, :16]
    rows = at[np.broadcast_to(outer[:, :, None], (len(outer), 16, 16))].ravel()
    cols = at[np.broadcast_to(outer[:, None, :], (len(outer), 16, 16))].ravel()
    kept = np.flatnonzero((rows >= 0) & (cols >= 0))
    keys, slot = _unique_inverse(cols[kept].astype(np.int64) * len(free) + rows[kept])
    indptr = np.searchsorted(keys // len(free), np.arange(len(free) + 1))
    on_top = uz[np.isclose(locs[1, uz], top)]
    r_top = r_nodes[r_nodes <= reach + 1e-12]
    if len(r_top) < 4:
        raise ValidationError("fe_press: fewer than 4 surface vertices under the contact; raise the refinement")
    loads = _hat_loads(r_top, locs[0, on_top], on_top, n)[free]
    vertex = np.array([at[on_top[np.argmin(np.abs(locs[0, on_top] - rv))]] for rv in r_top])
    lam_part, mu_part = stiffness_parts(basis)
    mesh = FEMesh(basis=basis, centroid_r=centroid[0], centroid_depth=top - centroid[1], lam_part=lam_part,
                 mu_part=mu_part, element_dofs=element_dofs, free=free, at=at, kept=kept, slot=slot.reshape(-1),
                 indices=(keys % len(free)).astype(np.int32), indptr=indptr.astype(np.int32), r_top=r_top,
                 loads=loads, vertex=vertex)
    for value in vars(mesh).values():
        if isinstance(value, np.ndarray):
            value.setflags(write=False)  # one mesh serves every field and every caller that keeps it
    return mesh


def _unique_inverse(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``np.unique(keys, return_inverse=True)`` for integer keys, by a stable argsort: an element's keys come in
    sorted runs, which a stable sort merges in a third of the time of unique's own sort."""
    order = np.argsort(keys, kind="stable")
    ordered = keys[order]
    first = np.empty(len(keys), dtype=bool)
    first[:1] = True
    np.not_equal(ordered[1:], ordered[:-1], out=first[1:])
    inverse = np.empty(len(keys), dtype=np.intp)
    inverse[order] = np.cumsum(first) - 1
    return ordered[first], inverse


def _hat_loads(r_top: np.ndarray, dof_r: np.ndarray, dof_index: np.ndarray, n_dofs: int) -> np.ndarray:
    """Consistent nodal loads (n_dofs, hats) of unit hat pressures on the top vertices r_top (downward, z up)."""
    xg, wg = np.polynomial.legendre.leggauss(6)
    s = 0.5 * (xg + 1.0)
    shape = (2 * (s - 0.5) * (s - 1), 4 * s * (1 - s), 2 * s * (s - 0.5))  # Q2 trace: vertex, midside, vertex
    hats = (1.0 - s, s)
    lookup = {round(float(v), 13): int(i) for v, i in zip(dof_r, dof_index, strict=True)}
    loads = np.zeros((n_dofs, len(r_top)))
    for e in range(len(r_top) - 1):
        r0, r1 = r_top[e], r_top[e + 1]
        rq = r0 + (r1 - r0) * s
        wq = wg * 0.5 * (r1 - r0) * rq
        nodes = [lookup[round(float(r0), 13)], lookup[round(0.5 * float(r0 + r1), 13)], lookup[round(float(r1), 13)]]
        for a, node in enumerate(nodes):
            for b, hat in enumerate((e, e + 1)):
                loads[node, hat] -= np.sum(shape[a] * hats[b] * wq)
    return loads
