"""Shapes built in code with known symmetry groups: the demo shape and the test corpus.

Every shape is a star-shaped surface ``x = r(u) u`` over a subdivided icosphere (``u`` a unit
direction), so its symmetry group is exactly the group under which the radius function ``r`` is
invariant (up to the icosphere's triangulation, which is itself symmetric under the coordinate
mirrors). Each builder returns ``(verts [V, 3] float64, faces [F, 3] int64)`` numpy arrays; the true
symmetries of a shape are the Euclidean maps listed by :func:`true_symmetries`, turned into vertex
maps by nearest neighbour.

Shapes and their groups (Schoenflies names as used by :mod:`symtorch.groups`):

=================  ==========  ===================================================================
builder            group       what it looks like
=================  ==========  ===================================================================
``mirror_blob``    C2 (Cs)     a bumpy, stretched ball with bumps in mirror pairs about x = 0
``star_prism``     D5h (20)    a rounded five-pointed star slab
``ngon_prism``     Dnh (4n)    a rounded regular n-gon slab
``table``          C4v (8)     a square slab with four legs below
``propeller``      C3 (3)      three twisted blades: rotations, no reflection
``asymmetric``     trivial     a ball with bumps at generic places
``ellipsoid``      continuous  an ellipsoid of revolution about z
=================  ==========  ===================================================================
"""
from __future__ import annotations

import math

import numpy as np
import trimesh
from scipy.spatial import cKDTree

__all__ = ["icosphere", "radial_surface", "outline_prism", "mirror_blob", "star_prism", "ngon_prism", "table",
           "propeller", "asymmetric", "ellipsoid", "true_symmetries", "symmetry_maps", "SHAPES",
           "polar_prism", "polar_prism_symmetries"]


def icosphere(subdivisions: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """Unit icosphere: (verts [V, 3], faces [F, 3]); V = 10 * 4**subdivisions + 2."""
    m = trimesh.creation.icosphere(subdivisions=subdivisions)
    return np.asarray(m.vertices, dtype=np.float64), np.asarray(m.faces, dtype=np.int64)


def radial_surface(radius, subdivisions: int = 3, stretch=(1.0, 1.0, 1.0)) -> tuple[np.ndarray, np.ndarray]:
    """The surface ``u -> radius(u) * u * stretch`` over an icosphere; ``radius`` maps [V, 3] -> [V]."""
    u, f = icosphere(subdivisions)
    r = np.asarray(radius(u), dtype=np.float64)
    return u * r[:, None] * np.asarray(stretch, dtype=np.float64), f


def _bumps(u: np.ndarray, centers, heights, width: float = 0.08) -> np.ndarray:
    c = np.asarray(centers, dtype=np.float64)
    c = c / np.linalg.norm(c, axis=1, keepdims=True)
    return sum(h * np.exp(-np.sum((u - ci) ** 2, 1) / width) for ci, h in zip(c, heights))


def _angles(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Azimuth about z and height z of unit directions."""
    return np.arctan2(u[:, 1], u[:, 0]), u[:, 2]


def mirror_blob(subdivisions: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """C2 (one reflection, x -> -x): a bumpy, anisotropically stretched ball. The default demo shape."""
    centers = [[0.6, 0.6, 0.5], [-0.6, 0.6, 0.5], [0, -0.7, 0.7], [0.5, -0.3, -0.8], [-0.5, -0.3, -0.8]]
    heights = [0.9, 0.9, 0.6, 0.4, 0.4]
    return radial_surface(lambda u: 1 + _bumps(u, centers, heights), subdivisions, (1.0, 1.2, 0.9))


def _slab(u: np.ndarray, profile: np.ndarray, thickness: float) -> np.ndarray:
    """Radius of a rounded slab: in-plane extent ``profile`` (per direction), half-height ``thickness``."""
    _, z = _angles(u)
    rho = np.sqrt(np.maximum(1 - z ** 2, 0))
    # superellipse-like blend between the rim (rho) and the caps (z): flat top and bottom
    p = 6.0
    return 1.0 / ((rho / profile) ** p + (np.abs(z) / thickness) ** p) ** (1 / p)


def star_prism(subdivisions: int = 4, points: int = 5, depth: float = 0.45,
               thickness: float = 0.35) -> tuple[np.ndarray, np.ndarray]:
    """D_{points}h (4 * points elements): a rounded star slab with ``points`` arms."""
    def r(u):
        phi, _ = _angles(u)
        return _slab(u, 1 - depth * (0.5 - 0.5 * np.cos(points * phi)), thickness)
    return radial_surface(r, subdivisions)


def ngon_prism(n: int = 6, subdivisions: int = 4, thickness: float = 0.45) -> tuple[np.ndarray, np.ndarray]:
    """D_nh (4n elements): a rounded regular n-gon slab (a star with shallow arms)."""
    return star_prism(subdivisions, points=n, depth=0.15, thickness=thickness)


def table(subdivisions: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """C4v (8 elements: 4 rotations about z, 4 vertical mirrors): a square top, four legs below."""
    def r(u):
        phi, z = _angles(u)
        top = _slab(u, 1 - 0.12 * (0.5 - 0.5 * np.cos(4 * phi)), 0.3)
        legs = _bumps(u, [[math.cos(a), math.sin(a), -1.1] for a in np.pi / 4 + np.arange(4) * np.pi / 2],
                      [0.9] * 4, width=0.05)
        return top + legs
    return radial_surface(r, subdivisions)


def propeller(subdivisions: int = 4, blades: int = 3, twist: float = 1.2,
              hub: float = 0.8) -> tuple[np.ndarray, np.ndarray]:
    """C_blades (rotations only): ``blades`` blades twisted along z, so no mirror survives.

    ``hub`` is the height of a round bump on the top pole. Without it the half-turns about the
    horizontal axes, ``(phi, z) -> (-phi, -z)``, which keep the twist ``blades * phi + twist * z * pi``,
    are intrinsic near-isometries (geodesic distortion ~0.11 eps on a subdivision-4 mesh, as low as
    the true rotations), and the intrinsic group is D_blades; the hub makes top and bottom differ.
    """
    def r(u):
        phi, z = _angles(u)
        return (0.7 + 0.45 * np.exp(3 * (np.cos(blades * phi + twist * z * np.pi) - 1)) + 0.15 * z
                + _bumps(u, [[0.0, 0.0, 1.0]], [hub], width=0.1))
    return radial_surface(r, subdivisions)


def asymmetric(subdivisions: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """Trivial group: a lopsided body (low-order terms with no common symmetry) with bumps of
    different sizes at generic places. Bumps alone on a symmetric ellipsoid are not enough: a
    reflection of the body is then a near-isometry everywhere but at the bumps."""
    centers = [[0.7, 0.2, 0.5], [-0.3, 0.8, 0.1], [0.1, -0.6, 0.7], [0.4, -0.2, -0.9], [-0.8, -0.4, -0.3]]
    heights = [0.9, 0.6, 0.45, 0.3, 0.7]

    def r(u):
        x, y, z = u.T
        body = 1 + 0.35 * x * y + 0.3 * z ** 3 + 0.25 * x + 0.2 * y * z - 0.15 * x * z
        return body + _bumps(u, centers, heights)
    return radial_surface(r, subdivisions, (1.0, 1.15, 0.85))


def ellipsoid(subdivisions: int = 3, axes=(1.0, 1.0, 1.6)) -> tuple[np.ndarray, np.ndarray]:
    """Continuous symmetry (rotations about z): an ellipsoid of revolution."""
    return radial_surface(lambda u: np.ones(len(u)), subdivisions, axes)


def _rot_z(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def _mirror(normal) -> np.ndarray:
    n = np.asarray(normal, dtype=np.float64)
    n = n / np.linalg.norm(n)
    return np.eye(3) - 2 * np.outer(n, n)


def _dihedral(n: int, horizontal_mirror: bool, vertical_mirrors: bool, phase: float = 0.0) -> list[np.ndarray]:
    rots = [_rot_z(2 * math.pi * j / n) for j in range(n)]
    mats = list(rots)
    if vertical_mirrors:  # mirror planes containing z, one through each arm (arm at angle phase)
        mats += [_mirror([-math.sin(phase + math.pi * j / n), math.cos(phase + math.pi * j / n), 0])
                 for j in range(n)]
    if horizontal_mirror:
        sh = _mirror([0, 0, 1])
        mats += [sh @ m for m in mats]
    return mats


def true_symmetries(name: str) -> list[np.ndarray]:
    """The Euclidean symmetries [3, 3] of a builder's shape (default parameters), identity first."""
    if name == "mirror_blob":
        return [np.eye(3), _mirror([1, 0, 0])]
    if name == "star_prism":
        return _dihedral(5, True, True)
    if name == "ngon_prism":
        return _dihedral(6, True, True)
    if name == "table":
        return _dihedral(4, False, True)
    if name == "propeller":
        return _dihedral(3, False, False)
    if name == "asymmetric":
        return [np.eye(3)]
    raise ValueError(f"no finite symmetry list for shape {name!r}")


def symmetry_maps(verts: np.ndarray, rigid: list[np.ndarray]) -> np.ndarray:
    """[G, V] vertex maps of Euclidean symmetries: the nearest vertex to each transformed vertex.

    Args:
        verts: [V, 3]; rigid: [3, 3] orthogonal matrices ``R``, acting as ``verts @ R.T``.
    """
    tree = cKDTree(verts)
    return np.stack([tree.query(verts @ R.T)[1] for R in rigid]).astype(np.int64)


SHAPES = {"mirror_blob": mirror_blob, "star_prism": star_prism, "ngon_prism": ngon_prism,
          "table": table, "propeller": propeller, "asymmetric": asymmetric, "ellipsoid": ellipsoid}


# ------------------------------------------------------------------ exactly symmetric polar meshes
def _polygon(n: int, segments: int, radius: float = 1.0) -> np.ndarray:
    """[n * segments, 2] points of a regular n-gon (a corner at angle 0), each side cut evenly."""
    corners = radius * np.stack([np.cos(2 * np.pi * np.arange(n + 1) / n),
                                 np.sin(2 * np.pi * np.arange(n + 1) / n)], 1)
    t = np.arange(segments)[:, None] / segments
    return np.concatenate([(1 - t) * corners[j] + t * corners[j + 1] for j in range(n)])


def _quad_strip(lo: np.ndarray, hi: np.ndarray, verts: list, faces: list, flip: bool) -> None:
    """Triangulate the closed strip between two rings of vertex ids with one centre vertex per quad.

    The centre vertex (mean of the quad's corners) makes the four triangles of each quad invariant
    under the mirrors of the strip, which a diagonal split would break.
    """
    N = len(lo)
    for k in range(N):
        a, b, d, e = lo[k], lo[(k + 1) % N], hi[(k + 1) % N], hi[k]
        c = len(verts)
        verts.append((verts[a] + verts[b] + verts[d] + verts[e]) / 4)
        tris = [(a, b, c), (b, d, c), (d, e, c), (e, a, c)]
        faces += [t[::-1] for t in tris] if flip else tris


def outline_prism(poly: np.ndarray, height: float, rings: int = 5,
                  cap_rings: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """A closed prism over a star-shaped outline ``poly [N, 2]`` (about the origin, counter-clockwise):
    ``rings`` levels of the outline joined by quads with a centre vertex, and caps of ``cap_rings``
    shrunken copies of the outline with a fan around the centre. Any symmetry of the outline (and the
    top/bottom swap) maps the vertex set and the faces onto themselves. Outward-oriented, closed.

    Returns:
        (verts [V, 3] float64, faces [F, 3] int64).
    """
    N = len(poly)
    z = height * (np.arange(rings) / (rings - 1) - 0.5)
    verts: list = [np.array([x, y, zr]) for zr in z for x, y in poly]
    faces: list = []
    side = np.arange(rings * N).reshape(rings, N)
    for r in range(rings - 1):
        _quad_strip(side[r], side[r + 1], verts, faces, flip=False)
    for zc, outer, top in ((z[-1], side[-1], True), (z[0], side[0], False)):
        inner = None
        for c in range(cap_rings - 1, 0, -1):  # shrunken boundaries, outside in
            ring = np.arange(len(verts), len(verts) + N)
            verts += [np.array([x, y, zc]) for x, y in poly * c / cap_rings]
            _quad_strip(ring, outer if inner is None else inner, verts, faces, flip=top)
            inner = ring
        last = outer if inner is None else inner
        centre = len(verts)
        verts.append(np.array([0.0, 0.0, zc]))
        for k in range(N):
            a, b = last[k], last[(k + 1) % N]
            faces.append((centre, a, b) if top else (centre, b, a))
    return np.asarray(verts, dtype=np.float64), np.asarray(faces, dtype=np.int64)


def polar_prism(n: int = 6, segments: int = 3, rings: int = 6, cap_rings: int = 4,
                height: float = 0.8, radius: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """D_nh (4n elements), exactly: a closed regular n-gon prism whose triangulation has the symmetry.

    The side is ``rings`` levels of the n-gon boundary (each side cut into ``segments``), joined by
    quads with a centre vertex; each cap is ``cap_rings`` shrunken copies of the boundary joined the
    same way, and a fan around the cap centre. Every rotation by ``2 pi / n`` about z, every vertical
    mirror through a corner or a side midpoint, and the top/bottom swap map the vertex set and the
    faces onto themselves, so the cotangent Laplacian commutes with D_nh and its eigenvalues have the
    exact multiplicities 1 or 2 of the irreducible representations (the ``ngon_prism`` builder is
    only symmetric up to its icosphere triangulation). Corners at angles ``2 pi j / n``, matching
    ``_dihedral(n, True, True)``. Outward-oriented, closed, genus 0.

    Returns:
        (verts [V, 3] float64, faces [F, 3] int64).
    """
    if n < 3 or segments < 1 or rings < 2 or cap_rings < 1:
        raise ValueError(f"need n >= 3, segments >= 1, rings >= 2, cap_rings >= 1, got n={n}, "
                         f"segments={segments}, rings={rings}, cap_rings={cap_rings}")
    poly = _polygon(n, segments, radius)  # [N, 2]
    return outline_prism(poly, height, rings, cap_rings)


def polar_prism_symmetries(n: int = 6) -> list[np.ndarray]:
    """The 4n Euclidean symmetries [3, 3] of :func:`polar_prism` (any size parameters), identity first:
    n rotations, n vertical mirrors, then the same composed with the top/bottom swap."""
    return _dihedral(n, True, True)


SHAPES["polar_prism"] = polar_prism
