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

__all__ = ["icosphere", "radial_surface", "mirror_blob", "star_prism", "ngon_prism", "table",
           "propeller", "asymmetric", "ellipsoid", "true_symmetries", "symmetry_maps", "SHAPES"]


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


def propeller(subdivisions: int = 4, blades: int = 3, twist: float = 1.2) -> tuple[np.ndarray, np.ndarray]:
    """C_blades (rotations only): ``blades`` blades twisted along z, so no mirror survives."""
    def r(u):
        phi, z = _angles(u)
        return 0.7 + 0.45 * np.exp(3 * (np.cos(blades * phi + twist * z * np.pi) - 1)) + 0.15 * z
    return radial_surface(r, subdivisions)


def asymmetric(subdivisions: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """Trivial group: bumps of different sizes at generic places."""
    centers = [[0.7, 0.2, 0.5], [-0.3, 0.8, 0.1], [0.1, -0.6, 0.7], [0.4, -0.2, -0.9], [-0.8, -0.4, -0.3]]
    heights = [0.9, 0.6, 0.45, 0.3, 0.7]
    return radial_surface(lambda u: 1 + _bumps(u, centers, heights), subdivisions, (1.0, 1.15, 0.85))


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


def symmetry_maps(verts: np.ndarray, mats: list[np.ndarray]) -> np.ndarray:
    """[G, V] vertex maps of Euclidean symmetries: the nearest vertex to each transformed vertex."""
    tree = cKDTree(verts)
    return np.stack([tree.query(verts @ R.T)[1] for R in mats]).astype(np.int64)


SHAPES = {"mirror_blob": mirror_blob, "star_prism": star_prism, "ngon_prism": ngon_prism,
          "table": table, "propeller": propeller, "asymmetric": asymmetric, "ellipsoid": ellipsoid}
