"""The group path's elements: refinement, verification, closure and upsampling (ALGORITHM §5 step 5).

Two stages, so that every cluster can be checked cheaply and only the distinct elements pay for the
exact measure:

- **Coarse** (:class:`CoarseElements`): in the coarse basis and on sample vertices, each candidate
  is refined (:func:`zoomout`, or fixed-size spectral ICP), screened by the cheap distortion of
  :meth:`Geometry.distortion_at`, and merged with an element it duplicates; the set is then closed
  under composition and what closure adds goes through the same screen.
- **Exact** (:func:`upsample_elements`): each distinct element is grown to the refined basis,
  every vertex is mapped, and the distortion ``|d(g(s), g(x)) - d(s, x)|`` is measured from 10
  spread sources ``s`` to the score samples ``x`` (10 heat solves per element). A coarse duplicate
  kept as an alternative that the refined basis tells apart from every element joins as one more;
  the vertex maps are then closed under composition, each new product measured the same way.
  :func:`point_map_distortions` measures kept elements again as vertex-to-point maps (where the
  group path asks: a half of the group standing apart from the rest), without the rounding of each
  image to a vertex that a triangulation no symmetry preserves puts into every element.

The cheap screen uses only the distance fields of the invariant points ``P``: the mean over
``p in P`` and the score samples ``x`` of ``|d(pi(p), g(x)) - d(p, x)| - off(p)`` (clamped at 0),
plus a quarter of the mean ``off``, where ``pi(p)`` is the point of ``P`` nearest to ``g(p)`` and
``off(p) = d(g(p), pi(p))``. ``P`` is invariant, so for an exact symmetry ``pi(p) = g(p)`` and this is
0; the ``off`` discount (triangle inequality) keeps points of ``P`` placed slightly asymmetrically
(flat extrema) from counting. Distortions are in EPS_KLC units.
"""
from __future__ import annotations

import warnings
from typing import NamedTuple

import numpy as np
import torch
from torch import Tensor

from ..geodesics import GeodesicSolver
from ..groups.algebra import DEFAULT_TOL, _rel_dist, closure
from ..maps import TwoLevelSearch, p2p_to_fmap
from ..procrustes import block_procrustes, block_project
from ..refine import zoomout_symmetry
from ..sampling import farthest_point_sampling
from ..spectrum import Spectrum, full_bands
from ..units import EPS_KLC
from ..vertex_to_point import vertex_faces, vertex_to_point
from .config import GroupConfig

__all__ = ["Geometry", "CoarseElement", "CoarseElements", "Element", "upsample_elements", "point_map_distortions",
           "batched_icp", "zoomout"]


def image_gaps(verts: Tensor, images: Tensor, query: Tensor) -> Tensor:
    """[G] mean distance between the points ``query [S']`` and each row of ``images [G, S']``
    (vertex ids, images of the same samples), on ``verts [V, 3]``: how far apart two maps land."""
    return (verts[images] - verts[query][None]).norm(dim=-1).mean(-1)


#: two maps are one element when their images of the score samples lie closer than this, on
#: average (KLC radii): the same-map test of every stage here
SAME_MAP_GAP = 0.5


class CoarseElement(NamedTuple):
    """An element verified in the coarse basis."""

    fmap: Tensor       # [k0, k0]
    images: Tensor     # [S'] images of the score samples
    distortion: float  # the cheap screen's distortion


class Element(NamedTuple):
    """An element in the refined basis, measured exactly."""

    fmap: Tensor       # [K, K]
    p2p: Tensor        # [V]
    distortion: float  # exact distortion


class Geometry:
    """What verification and refinement need, computed once per shape.

    Attributes:
        evecs, mass: the basis; verts: [V, 3] unit-area positions (tensor).
        samples: [S] well-spread sample vertices; score_samples: the first 200 of them.
        points: [n] the invariant points; dist_points: [n, V] their distance fields.
    """

    def __init__(self, verts_unit: np.ndarray, spectrum: Spectrum, points: np.ndarray,
                 dist_points: Tensor, n_samples: int, faces=None):
        self.evecs, self.mass = spectrum.evecs, spectrum.mass
        V = self.evecs.shape[0]
        self.verts = torch.as_tensor(verts_unit)
        # farthest points among a regular subset of the vertices (4 per sample): the same spread at
        # a fraction of the cost of running over every vertex
        sub = torch.arange(0, V, max(1, V // (4 * n_samples)))
        self.samples = sub[farthest_point_sampling(self.verts[sub], min(n_samples, len(sub)))]  # [S]
        self.score_samples = self.samples[: min(200, len(self.samples))]
        self.points = torch.as_tensor(points)
        self.dist_points = dist_points  # [n, V]
        # two-level vertex maps: the map on the samples, carried to every vertex by continuity
        # (cells: the nearest sample in space; ~2 Voronoi cells of a sample searched per vertex)
        from scipy.spatial import cKDTree

        _, ns = cKDTree(verts_unit[self.samples.numpy()]).query(verts_unit)
        c = min(max(2 * V // max(len(self.samples), 1), 12), V)
        self.search = TwoLevelSearch(verts_unit, self.evecs, self.samples, torch.as_tensor(np.asarray(ns)), c)
        self.faces = None if faces is None else torch.as_tensor(np.asarray(faces), dtype=torch.long)
        self.vf = None if faces is None else vertex_faces(self.faces, V)

    def p2p(self, C: Tensor, at: Tensor | None = None) -> Tensor:
        """Vertex map of C [k, k] at the vertices ``at`` (default all): ``maps.TwoLevelSearch``."""
        return self.search(C, at)

    def points_of(self, C: Tensor, at: Tensor, nearest: Tensor) -> tuple[Tensor, Tensor]:
        """Images of the vertices ``at`` under ``C [k, k]`` as points of triangles
        (``vertex_to_point``; ``nearest``: their vertex map): (tri [N, 3], bary [N, 3]). Needs the
        faces the geometry was built with."""
        if self.faces is None:
            raise ValueError("points_of needs the mesh's faces: Geometry(..., faces=...)")
        E = self.evecs[:, : C.shape[-1]]
        return vertex_to_point(E, self.faces, self.vf, E[at] @ C, nearest)

    def screen(self, C: Tensor) -> tuple[float, Tensor]:
        """The cheap screen of a matrix ``C [k, k]``: (its distortion, the images ``[S']`` of the
        score samples)."""
        n = len(self.points)
        img = self.p2p(C, torch.cat([self.points, self.score_samples]))
        return self.distortion_at(img[:n], img[n:]), img[n:]

    def distortion_at(self, gp: Tensor, gx: Tensor) -> float:
        """The cheap screen's distortion from the images ``gp`` of the points and ``gx`` of the
        score samples (see the module docstring)."""
        D = self.dist_points  # [n, V]
        pi = D[:, gp].argmin(0)  # [n] point nearest to g(p)
        off = D[pi, gp]  # [n] how far g(p) lands from the point of P standing for it
        # |d(pi(p), g(x)) - d(g(p), g(x))| <= off(p) (triangle inequality): discount that much, so
        # that points of P placed slightly asymmetrically (flat extrema) do not count as distortion
        dev = ((D[pi][:, gx] - D[:, self.score_samples]).abs() - off[:, None]).clamp_min(0).mean()
        return float((dev + 0.25 * off.mean()) / EPS_KLC)


def zoomout(geo: Geometry, C0: Tensor, bands: list[range], k_final: int, step: int = 4,
            n_iter_end: int = 3, block: bool = True) -> Tensor:
    """Block-orthogonal ZoomOut (``refine.zoomout_symmetry``) from samples to samples; with
    ``block=False`` the full orthogonal matrix (ZoomOut's own), for the maps of a near-isometry
    that mixes eigenfunctions of different bands (``group_path``'s merged attempt)."""
    return zoomout_symmetry(C0, geo.evecs, geo.mass, bands, k_final, step=step, samples=geo.samples,
                            targets=geo.samples, block=block, n_iter_end=n_iter_end)


def batched_icp(C: Tensor, E_src: Tensor, E_tgt: Tensor, bands: list[range], n_iter: int = 2,
                chunk: int = 128) -> Tensor:
    """A few spectral ICP steps on many candidates at once.

    Each step maps the source rows to their nearest target rows (``E_src @ C``), then solves the block
    Procrustes ``E_src @ C ≈ E_tgt[nn]`` (transposed: ``C.T @ E_src.T ≈ E_tgt[nn].T``). Candidates of
    one symmetry found from different point tuples then agree closely, so that mean shift merges them.

    Args:
        C: [B, k, k]; E_src: [S, k] rows of sample vertices; E_tgt: [T, k] rows of target vertices
            (a superset of the sources' images); bands: covering ``0..k-1``.

    Returns:
        [B, k, k] block-orthogonal.
    """
    out = []
    Et = E_tgt.float()
    sq = Et.square().sum(-1)
    for Cb in C.split(chunk):
        for _ in range(n_iter):
            Q = (E_src @ Cb).float()  # [b, S, k]
            nn = (sq[None, None] - 2 * Q @ Et.mT).argmin(-1)  # [b, S]
            Cb = block_procrustes(E_src.mT.expand(len(Cb), -1, -1), E_tgt[nn].mT, bands).mT
        out.append(Cb)
    return torch.cat(out)


class CoarseElements:
    """The elements verified in the coarse basis, identity first; :meth:`add` refines (block by
    block, or with ``block=False`` as full orthogonal matrices: :func:`zoomout`), screens and
    deduplicates a candidate, :meth:`close` adds what composition implies.

    Two versions of one symmetry can pass the same-map test (their images within half a KLC radius
    of each other) and still differ where it matters: on a thin part, one may swap the part's two
    faces. The cheap screen cannot always tell which is right, so the duplicates that differ
    materially from the element kept (mean image gap at least ``cfg.alternative_gap`` radii) are
    kept as its *alternatives* (at most ``cfg.n_alternatives``, least distorted first), for
    :func:`upsample_elements` to measure exactly.

    Attributes:
        elements: the accepted :class:`CoarseElement` s.
        alternatives: element index -> its alternative :class:`CoarseElement` s.
        trace: (distortion, index of the element it duplicates or -1) per candidate added.
        rejected: distortions of the candidates rejected by the screen.
        near_misses: rejected candidates within ``cfg.near_miss_ratio`` of the screen, not the same
            map as an element or as one another (least distorted first, at most
            ``cfg.n_near_misses``): the coarse basis can distort an element that its exact map
            does not (the cap swaps of a strongly bent slab read 0.26-0.30 coarse, 0.09 exact);
            :func:`upsample_elements` measures them exactly.
    """

    def __init__(self, geo: Geometry, bands0: list[range], k0: int, cfg: GroupConfig, block: bool = True):
        self.geo, self.bands0, self.k0, self.cfg, self.block = geo, bands0, k0, cfg, block
        eye0 = torch.eye(k0, dtype=geo.evecs.dtype)
        self.elements = [CoarseElement(eye0, geo.score_samples.clone(), 0.0)]
        self.alternatives: dict[int, list[CoarseElement]] = {}
        self.trace: list[tuple[float, int]] = []
        self.rejected: list[float] = []
        self.near_misses: list[CoarseElement] = []

    def image_gap(self, a: Tensor, b: Tensor) -> float:
        """Mean distance (unit-area shape) between two image sets of the score samples."""
        return float(image_gaps(self.geo.verts, a[None], b)[0])

    def _keep_alternative(self, j: int, alt: CoarseElement) -> None:
        """Keep ``alt`` as an alternative of element ``j`` when it differs from it materially (an
        alternative of the identity can only be another element: :func:`upsample_elements`)."""
        if self.cfg.n_alternatives <= 0:
            return
        if self.image_gap(alt.images, self.elements[j].images) < self.cfg.alternative_gap * EPS_KLC:
            return
        alts = sorted(self.alternatives.get(j, []) + [alt], key=lambda e: e.distortion)
        self.alternatives[j] = alts[:self.cfg.n_alternatives]

    def _keep_near_miss(self, e: CoarseElement) -> None:
        """Keep a rejected candidate as a near miss unless it duplicates an element, or a near miss
        that distorts less (one that distorts more it replaces)."""
        if self.cfg.n_near_misses <= 0 or self.duplicate_of(e.images, e.fmap) >= 0:
            return
        same = [i for i, o in enumerate(self.near_misses)
                if self.image_gap(o.images, e.images) < SAME_MAP_GAP * EPS_KLC]
        if same and self.near_misses[same[0]].distortion <= e.distortion:
            return
        kept = [o for i, o in enumerate(self.near_misses) if i not in same] + [e]
        self.near_misses = sorted(kept, key=lambda o: o.distortion)[:self.cfg.n_near_misses]

    def duplicate_of(self, images: Tensor, C0: Tensor, same_gap: float = SAME_MAP_GAP) -> int:
        """An accepted element with the same images (mean gap < ``same_gap`` eps) or matrix (< DEFAULT_TOL)."""
        gap = image_gaps(self.geo.verts, torch.stack([e.images for e in self.elements]), images)  # [G]
        j = int(gap.argmin())
        if float(gap[j]) < same_gap * EPS_KLC:
            return j
        # maps can differ where an element is ill-pinned; the matrices then still agree
        d = _rel_dist(C0[None], torch.stack([e.fmap for e in self.elements]))[0]
        return int(d.argmin()) if float(d.min()) < DEFAULT_TOL else -1

    def add(self, C0: Tensor, same_gap: float = SAME_MAP_GAP) -> bool:
        """Refine a coarse candidate, screen it, and keep it unless it duplicates an element (images
        within ``same_gap`` KLC radii; where it is better than the element it duplicates, it takes
        that element's place)."""
        geo = self.geo
        if self.cfg.refine == "icp":  # paper §4.1 step 3: fixed-size spectral ICP on the samples
            E_s = geo.evecs[geo.samples, :self.k0]
            C0 = batched_icp(C0[None], E_s, E_s, self.bands0, n_iter=10)[0]
        else:
            C0 = zoomout(geo, C0, self.bands0, self.k0, block=self.block)
        dst, img = geo.screen(C0)
        rejected = dst > self.cfg.max_distortion
        j = -1 if rejected else self.duplicate_of(img, C0, same_gap)
        self.trace.append((round(dst, 3), j))
        if rejected:
            self.rejected.append(round(dst, 3))
            if dst <= self.cfg.near_miss_ratio * self.cfg.max_distortion:
                self._keep_near_miss(CoarseElement(C0, img, dst))
            return False
        if j >= 0:
            new = CoarseElement(C0, img, dst)
            if dst < self.elements[j].distortion:
                new, self.elements[j] = self.elements[j], new
                self.alternatives[j] = [a for a in self.alternatives.get(j, [])
                                        if self.image_gap(a.images, img)
                                        >= self.cfg.alternative_gap * EPS_KLC]
            self._keep_alternative(j, new)
            return False
        self.elements.append(CoarseElement(C0, img, dst))
        return True

    def close(self, rounds: int = 3) -> bool:
        """Add what composition implies (``groups.closure``), refined and screened like the rest.

        Returns:
            whether the set ended closed: the last closure ran to the end (within its
            ``max_order``) and added nothing that survived the screen. A round cut at ``max_order``
            is no failure where a later round closes the set (noisy products of a 20-element
            set can outnumber ``2 G + 8`` before they are screened), so ``closure``'s own warning
            is left to the caller, once, from this flag.
        """
        closed = False
        for _ in range(rounds):
            factors = self.factors()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                cl = closure(torch.stack([self.elements[i].fmap for i in factors]), tol=DEFAULT_TOL,
                             max_order=2 * len(self.elements) + 8)
            new = cl.fmaps[cl.added]
            # every product is tried (a list, not a short-circuiting generator)
            # a product of two coarse maps carries the errors of both: the same map within twice the gap
            if len(new) == 0 or not any([self.add(block_project(Cn, self.bands0), 2 * SAME_MAP_GAP)
                                         for Cn in new]):
                # products with the held-back elements are left to the exact maps
                closed = cl.converged and len(factors) == len(self.elements)
                break
        return closed

    def factors(self) -> list[int]:
        """The elements the coarse closure composes: all, but those an order of magnitude more
        distorted than the typical element (:func:`far_above` the median non-identity distortion,
        :data:`HELD_RATIO`). A spurious element just
        under the screen would otherwise bring its whole coset through the screen with it (each
        product as distorted as itself), and the closure would refine hundreds of products; held
        back, it is measured exactly like the rest, and where it holds, the exact vertex maps close
        its coset (:func:`upsample_elements` with ``close``)."""
        d = [e.distortion for e in self.elements[1:]]
        if len(d) < 3:
            return list(range(len(self.elements)))
        typical = float(np.median(d))
        return [0] + [i for i, x in enumerate(d, 1) if not far_above(x, typical, HELD_RATIO)]


#: :meth:`CoarseElements.factors`: elements :func:`far_above` this many times the median are held back
HELD_RATIO = 10.0
#: :func:`far_above`: no distortion (KLC radii) below this is an outlier, and no reference counts
#: below OUTLIER_FLOOR (near-exact elements differ by the mesh's noise, not by symmetry)
OUTLIER_MIN_DISTORTION = 0.1
OUTLIER_FLOOR = 0.01


def far_above(distortion: float, reference: float, ratio: float) -> bool:
    """Whether a distortion (KLC radii) stands out from a reference one: above
    :data:`OUTLIER_MIN_DISTORTION` and ``ratio`` times the reference (at least :data:`OUTLIER_FLOOR`).
    The elements of one exact group share the mesh's discretisation, so their distortions are of one
    size; one far above the rest is a near-symmetry or a spurious element."""
    return distortion > OUTLIER_MIN_DISTORTION and distortion > ratio * max(reference, OUTLIER_FLOOR)


#: An element whose exact distortion is at most this share of ``max_distortion`` is kept as it is:
#: its alternatives (:class:`CoarseElements`) are not measured (exact symmetries read ~0.001 of it).
EXACT_ENOUGH = 0.1
#: sources of the exact measure (the first N_SOURCES samples), and of the vertex-to-point measure
#: (:class:`_SourcePool`: one in each of their cells among the first SOURCE_POOL score samples)
N_SOURCES, SOURCE_POOL = 10, 40


class Upsampled(NamedTuple):
    """What :func:`upsample_elements` returns."""

    elements: list[Element]  # the elements kept, identity first
    rejected: list[float]    # the rejected elements' distortions
    closed: bool             # whether the vertex maps are closed under composition, where checked


def upsample_elements(coarse: list[CoarseElement], geo: Geometry, solver: GeodesicSolver,
                      bands: list[range], k0: int, kf: int, max_distortion: float,
                      alternatives: dict[int, list[CoarseElement]] | None = None,
                      close: bool = False, near_misses: list[CoarseElement] = (),
                      block: bool = True) -> Upsampled:
    """Grow the coarse elements to ``kf``, map every vertex and measure each exactly.

    An element that upsampling made worse than ``max_distortion`` falls back to its verified coarse
    map (its matrix in the refined basis then comes from that map). Each of an element's
    ``alternatives`` (:class:`CoarseElements`) is grown and measured too (unless the element already
    distorts by at most ``EXACT_ENOUGH * max_distortion``), and replaces the element where it
    distorts less; the products that a replaced element takes part in are then re-made from
    it (:func:`_remake_products`), since the element they were closed from was the wrong version.
    An alternative, or one of the screen's ``near_misses`` (:class:`CoarseElements`), that is within
    ``max_distortion`` and not the same map as any element once refined is an element of its own
    (:meth:`_Maps.add_distinct`); the vertex maps are then closed under composition (:meth:`_Maps.close`),
    as they are with ``close`` (the coarse closure did not end closed: its matrices may have been
    too crude to compose where the exact maps are not). Elements still above ``max_distortion``
    are dropped, the identity never. With ``block=False`` the refined matrices are full orthogonal
    ones (:func:`zoomout`), not projected onto the bands.
    """
    src = geo.samples[:N_SOURCES].numpy()
    D_src = torch.as_tensor(np.asarray(solver.distances_from(src)))[:, geo.score_samples]

    def exact_distortion(p2p: Tensor) -> float:
        g = p2p.numpy()
        D_img = torch.as_tensor(np.asarray(solver.distances_from(g[src])))[:, p2p[geo.score_samples]]
        return float((D_img - D_src).abs().mean() / EPS_KLC)

    def from_map(p2p: Tensor) -> Element:
        """The element of a vertex map: its block-projected matrix in the refined basis."""
        Cf = block_project(p2p_to_fmap(p2p, geo.evecs[:, :kf], geo.mass),
                           [b for b in bands if b.stop <= kf] if block else full_bands(kf))
        return Element(Cf, p2p, exact_distortion(p2p))

    def grown(e: CoarseElement, screen: bool = False) -> Element | None:
        """``e`` in the refined basis, measured exactly; with ``screen``, None where the cheap
        screen, on the refined map, already rejects it."""
        Cf = e.fmap if kf == k0 else zoomout(geo, e.fmap, bands, kf, step=6, n_iter_end=2, block=block)
        if screen and geo.screen(Cf)[0] > max_distortion:
            return None
        p2p = geo.p2p(Cf)
        return Element(Cf, p2p, exact_distortion(p2p))

    V = geo.evecs.shape[0]
    eye0 = torch.eye(k0, dtype=geo.evecs.dtype)
    final: list[Element] = []
    for e in coarse:
        if e.distortion == 0.0 and float((e.fmap - eye0).abs().max()) == 0.0:
            final.append(Element(torch.eye(kf, dtype=geo.evecs.dtype), torch.arange(V), 0.0))
        else:
            final.append(grown(e))
    for i, e in enumerate(final):
        if e.distortion > max_distortion and coarse[i].distortion <= max_distortion and kf != k0:
            final[i] = from_map(geo.p2p(coarse[i].fmap))
    replaced: list[int] = []
    distinct: list[Element] = []
    for i, alts in sorted((alternatives or {}).items()):
        exact = final[i].distortion <= EXACT_ENOUGH * max_distortion
        if exact and i != 0:  # nothing left to gain
            continue
        for a in alts:
            alt = grown(a)
            if i != 0 and alt.distortion < final[i].distortion:
                final[i] = alt
                if i not in replaced:
                    replaced.append(i)
            else:
                distinct.append(alt)
    if replaced:
        _remake_products(final, replaced, geo, from_map)
    distinct += [alt for alt in (grown(e, screen=True) for e in near_misses) if alt is not None]
    rejected = [round(e.distortion, 3) for e in final if e.distortion > max_distortion]
    final = [e for i, e in enumerate(final) if e.distortion <= max_distortion or i == 0]
    maps = _Maps(final, geo)
    added = maps.add_distinct(distinct, max_distortion)
    # two coarse elements that upsampled onto one map leave the coarse closure's count short of
    # the group's: the exact maps close what is missing (a remeshed thin star: 31 of 32)
    closed = maps.close(from_map, max_distortion) if added or close or maps.has_duplicates() else True
    return Upsampled(final, rejected, closed)


def point_map_distortions(elements: list[Element], geo: Geometry, solver: GeodesicSolver) -> list[Element]:
    """The elements with each distortion the smaller of its vertex map's and its vertex-to-point
    map's (:class:`_SourcePool`); the identity as it is. Unchanged without faces.

    A vertex map rounds each image to a vertex: on a triangulation that no symmetry preserves (a
    remesh, a scan) that costs an exact element about 0.04 KLC radii at 3000 vertices, the same in
    every element, and hides a near-symmetry a few times above it. As points of triangles the
    exact elements of remeshed solids read 0.012-0.018 (``scripts/vertex_rounding_table.py``)."""
    if geo.faces is None or len(elements) < 2:
        return elements
    pool = _SourcePool(geo, solver)
    return [e if i == 0 else e._replace(distortion=min(e.distortion, pool.distortion(e.p2p, e.fmap)))
            for i, e in enumerate(elements)]


class _SourcePool:
    """The kept elements' distortion as vertex-to-point maps, on the score samples ``S'``.

    Sources: among the first ``SOURCE_POOL`` score samples, one in each cell of the first
    ``N_SOURCES`` (farthest-point, so the sources stay as spread), the one whose image lands
    nearest a vertex (largest barycentric coordinate of its vertex-to-point image,
    ``Geometry.points_of``); its image is that vertex. Targets at their points, the distances
    interpolated in their triangles; one heat solve per source."""

    def __init__(self, geo: Geometry, solver: GeodesicSolver):
        self.geo, self.solver = geo, solver
        S = geo.score_samples
        self.P = min(SOURCE_POOL, len(S))
        self.D = torch.as_tensor(np.asarray(solver.distances_from(S[:self.P].numpy())))[:, S]  # [P, S']
        x = geo.verts[S[:self.P]]
        self.cell = torch.cdist(x, x[:N_SOURCES]).argmin(1)  # [P]

    def distortion(self, p2p: Tensor, C: Tensor) -> float:
        S = self.geo.score_samples
        tri, bary = self.geo.points_of(C, S, p2p[S])
        near = bary[:self.P].max(1).values
        idx = torch.argsort(self.cell.to(near.dtype) * 2 - near)  # by cell, nearest a vertex first
        c = self.cell[idx]
        pick = idx[torch.cat([torch.ones(1, dtype=torch.bool), c[1:] != c[:-1]])]  # one per cell
        src_img = tri[pick, bary[pick].argmax(1)]
        D_img = torch.as_tensor(np.asarray(self.solver.distances_from(src_img.numpy())))  # [N_SOURCES, V]
        D_img = (D_img[:, tri] * bary.to(D_img.dtype)).sum(-1)  # [N_SOURCES, S'] at the image points
        return float((D_img - self.D[pick]).abs().mean() / EPS_KLC)


class _Maps:
    """The exact elements (a list it appends to in place) with their images of the score samples
    kept in step, for the same-map test of the elements that upsampling adds."""

    def __init__(self, elements: list[Element], geo: Geometry):
        self.elements, self.geo = elements, geo
        self.images = torch.stack([e.p2p[geo.score_samples] for e in elements])  # [G, S']

    def is_new(self, p2p: Tensor) -> bool:
        """Whether ``p2p`` lands, on the score samples, at least ``SAME_MAP_GAP`` KLC radii (mean)
        from every element's images: the coarse stage's same-map test, on exact maps."""
        gap = image_gaps(self.geo.verts, self.images, p2p[self.geo.score_samples])
        return float(gap.min()) >= SAME_MAP_GAP * EPS_KLC

    def has_duplicates(self) -> bool:
        """Whether two elements are the same map (the same-map test of :meth:`is_new`)."""
        for i in range(1, len(self.images)):
            gap = image_gaps(self.geo.verts, self.images[:i], self.images[i])
            if float(gap.min()) < SAME_MAP_GAP * EPS_KLC:
                return True
        return False

    def append(self, e: Element) -> None:
        self.elements.append(e)
        self.images = torch.cat([self.images, e.p2p[self.geo.score_samples][None]])

    def add_distinct(self, candidates: list[Element], max_distortion: float) -> bool:
        """Append the candidates that upsampling made into elements of their own.

        A coarse duplicate can be a *different* element whose coarse map was too crude to tell:
        on a bent thin slab the coarse maps of the cap-swapping elements keep most samples on their
        own cap, so they read as the non-swapping ones, and only the refined basis resolves the
        swap. Such a candidate, within ``max_distortion`` and not the same map as any element, joins
        the elements; one that is the same map (a thin part's two faces swapped, under the same-map
        test) does not.

        Returns:
            whether any was appended.
        """
        added = False
        for e in sorted(candidates, key=lambda e: e.distortion):
            if e.distortion <= max_distortion and self.is_new(e.p2p):
                self.append(e)
                added = True
        return added

    def close(self, from_map, max_distortion: float) -> bool:
        """Close the elements under composition of their vertex maps: every product that is not
        the same map as an element, measured exactly (``from_map``) and kept within
        ``max_distortion``. Bounded by :data:`CLOSE_ROUNDS` rounds and ``2 G + 8`` elements
        (``G`` the count it started from).

        Returns:
            whether the last round found every product among the elements (or rejected it).
        """
        most = 2 * len(self.elements) + 8
        for _ in range(CLOSE_ROUNDS):
            grew, cut = False, False
            for a in list(self.elements[1:]):
                for b in list(self.elements[1:]):
                    prod = a.p2p[b.p2p]
                    if not self.is_new(prod):
                        continue
                    if len(self.elements) >= most:
                        cut = True
                        continue
                    cand = from_map(prod)
                    if cand.distortion <= max_distortion:
                        self.append(cand)
                        grew = True
            if not grew:
                return not cut
        return False


#: most composition rounds of :meth:`_Maps.close`
CLOSE_ROUNDS = 3


def _remake_products(final: list[Element], replaced: list[int], geo: Geometry, from_map) -> None:
    """For each replaced element ``a`` and every other element ``b``, the products ``a∘b`` and
    ``b∘a`` (vertex maps composed): where one is the same map as an element ``c`` (mean image gap on
    the score samples under half a KLC radius) and distorts less than it, it replaces ``c``
    (in place). Only products that name an element already found are made: no element is added."""
    S = geo.score_samples
    images = torch.stack([e.p2p[S] for e in final])  # [G, S'], kept in step with ``final``
    for i in replaced:
        a = final[i].p2p
        for j in range(1, len(final)):
            if j == i:
                continue
            for prod in (a[final[j].p2p], final[j].p2p[a]):
                gap = image_gaps(geo.verts, images, prod[S])  # [G]
                c = int(gap.argmin())
                if c in (0, i) or float(gap[c]) >= SAME_MAP_GAP * EPS_KLC:
                    continue
                cand = from_map(prod)
                if cand.distortion < final[c].distortion:
                    final[c] = cand
                    images[c] = prod[S]
