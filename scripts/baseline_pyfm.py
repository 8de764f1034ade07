"""Peer baseline: intrinsic reflection of a mesh by pyFM functional maps with an orientation term + ZoomOut.

Method (Ren, Poulenard, Wonka & Ovsjanikov, "Continuous and Orientation-preserving Correspondences
via Functional Maps", SIGGRAPH Asia 2018, orientation term; Melzi et al., "ZoomOut", SIGGRAPH Asia 2019),
as packaged by pyFM (``pip install pyfmaps``):

1. ``mesh1`` = the mesh; ``mesh2`` = the same mesh mirrored (``x -> -x``) with its faces reversed so
   its normals point outward again. Both are area-normalised and centred.
2. WKS descriptors, a functional map of size ``k_fit`` with descriptor preservation, Laplacian
   commutativity, descriptor commutativity and the orientation term, then ZoomOut up to ``k_final``.
3. The point map ``mesh2 -> mesh1`` is read as vertex indices, i.e. as a self-map of the mesh.

Orientation, pinned (measured, see the report): with the mirrored copy's faces reversed, the map we
want, ``i -> mirror(g(i))``, *preserves* orientation (a reflection composed with a reflection), while
the trivial index map ``i -> mirror(i)`` reverses it. So the mirrored set-up needs
``orient_reversing=False``; ``orient_reversing=True`` returns the identity. The equivalent set-up
without a mirror (``mirror=False``: a self-map of the mesh onto itself) needs ``orient_reversing=True``.
Both give the same map on FAUST.

The mirror is an isometry, so the mirrored copy has exactly the same Laplacian; ``reuse_spectrum``
copies it instead of solving the eigenproblem twice.

Usage: ``python scripts/baseline_pyfm.py path/to/mesh.off`` prints timings and writes nothing.
"""
from __future__ import annotations

import argparse
import time

import numpy as np


def pyfm_reflection(verts, faces, *, k_fit: int = 20, k_final: int = 100, n_descr: int = 100,
                    subsample_step: int = 2, mirror: bool = True, reuse_spectrum: bool = True,
                    w_descr: float = 1.0, w_lap: float = 1e-1, w_dcomm: float = 1.0,
                    w_orient: float = 1.0, zoomout_step: int = 5, timings: dict | None = None,
                    verbose: bool = False) -> np.ndarray:
    """Orientation-reversing self-map of a mesh by pyFM (see the module docstring).

    Args:
        verts: [V, 3] vertex positions (numpy or torch).
        faces: [F, 3] triangles.
        k_fit: size of the optimised functional map (pyFM's README uses 30; 20 here).
        k_final: size after ZoomOut (``k_fit + nit * zoomout_step``; rounded down to a whole step).
        n_descr: number of WKS energies; ``subsample_step`` keeps every n-th (README: 100 and 2).
        mirror: map onto a mirrored copy (True) or onto the mesh itself (False).
        reuse_spectrum: copy the Laplacian spectrum to the mirrored copy instead of recomputing it.
        w_descr, w_lap, w_dcomm, w_orient: energy weights (pyFM README values).
        zoomout_step: ZoomOut dimension increase per iteration.
        timings: if a dict is given, stage times in seconds are stored in it.
        verbose: let pyFM print.

    Returns:
        [V] int64 self-map: entry i is the vertex of the mesh that vertex i's mirror image maps to,
        the image of i under the detected reflection.
    """
    try:
        from pyFM.functional import FunctionalMapping
        from pyFM.mesh import TriMesh
    except ImportError as err:  # pragma: no cover
        raise ImportError("the pyFM baseline needs pyFM: pip install pyfmaps") from err

    if hasattr(verts, "detach"):
        verts, faces = verts.detach().cpu().numpy(), faces.detach().cpu().numpy()
    verts = np.asarray(verts, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    t = {}
    t0 = time.perf_counter()
    nit = max((k_final - k_fit) // zoomout_step, 0)
    k_process = max(k_fit + nit * zoomout_step, n_descr)

    mesh1 = TriMesh(verts, faces, area_normalize=True, center=True)
    mesh1.process(k_process, verbose=verbose)
    if mirror:
        mesh2 = TriMesh(verts * np.array([-1.0, 1.0, 1.0]), faces[:, ::-1].copy(),
                        area_normalize=True, center=True)
        if reuse_spectrum:  # the mirror is an isometry: same cotangent weights and masses
            mesh2.stiffness, mesh2.mass = mesh1.stiffness.copy(), mesh1.mass.copy()
            mesh2._laplacian_method = mesh1._laplacian_method
            mesh2.eigenvalues = mesh1.eigenvalues.copy()
            mesh2.eigenvectors = mesh1.eigenvectors.copy()
        else:
            mesh2.process(k_process, verbose=verbose)
    else:
        mesh2 = mesh1
    t["spectrum"] = time.perf_counter() - t0

    model = FunctionalMapping(mesh1, mesh2)
    model.preprocess(n_descr=n_descr, descr_type="WKS", subsample_step=subsample_step,
                     k_process=k_process, k_descr=n_descr, verbose=verbose)
    t1 = time.perf_counter()
    t["descriptors"] = t1 - t0 - t["spectrum"]
    model.fit(K=k_fit, w_descr=w_descr, w_lap=w_lap, w_dcomm=w_dcomm, w_orient=w_orient,
              orient_reversing=not mirror, verbose=verbose)
    t2 = time.perf_counter()
    t["fit"] = t2 - t1
    FM = model.zoomout_refine(nit=nit, step=zoomout_step, verbose=verbose) if nit else model.FM_12
    p2p_21 = np.asarray(model.get_p2p(FM), dtype=np.int64)  # [V] mesh2 -> mesh1
    t["zoomout"] = time.perf_counter() - t2
    t["total"] = time.perf_counter() - t0
    if timings is not None:
        timings.update(t)
    return p2p_21


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("mesh")
    parser.add_argument("--k-fit", type=int, default=20)
    parser.add_argument("--k-final", type=int, default=100)
    parser.add_argument("--no-mirror", action="store_true")
    args = parser.parse_args()
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
    from symtorch.eval.benchmarks import load_mesh

    verts, faces = load_mesh(args.mesh)
    timings: dict = {}
    p2p = pyfm_reflection(verts, faces, k_fit=args.k_fit, k_final=args.k_final,
                          mirror=not args.no_mirror, timings=timings)
    moved = float((p2p != np.arange(len(p2p))).mean())
    print(f"V={len(p2p)} moved={moved:.3f} " + " ".join(f"{k}={v:.2f}s" for k, v in timings.items()))


if __name__ == "__main__":
    main()
