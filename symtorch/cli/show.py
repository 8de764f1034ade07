"""``symtorch show``: pictures of the detected symmetries (paper Fig. 1 and 9) and the group table.

A smooth, non-symmetric function ``f`` on the shape (the geodesic distance from one vertex, drawn as
coloured rings) is shown as is, then transferred through each symmetry ``g``: panel ``g`` colours
vertex ``i`` by ``f(g(i)) = f[p2p_g[i]]`` (``f∘g``). For a true symmetry the rings keep their shape and
move to the image of the source point. The last panel is the group table, ``table[a][b] = a∘b``.

Rendering is off-screen with matplotlib (Agg): orthographic views in the shape's principal frame,
each element seen from several sides (turned 0°, 90° and 180° about the vertical axis; front and
back only for groups of more than four elements), flat-shaded faces drawn back to front, about
1600 px wide or more; meshes above ``max_faces`` are coarsened by vertex clustering for the picture
only. ``--glb`` writes the same colourings as vertex-coloured meshes side by side, for
any glTF viewer.

Functions: :func:`source_vertex`, :func:`transfer`, :func:`render_figure`, :func:`export_glb`.
"""
from __future__ import annotations

import io
import os
import time

import numpy as np

__all__ = ["source_vertex", "colour_function", "transfer", "element_labels", "view_rotation",
           "render_figure", "save_png", "export_glb", "register_cli"]

_N_RINGS = 7  # iso-distance rings drawn over the colour ramp


def source_vertex(verts: np.ndarray, p2ps: np.ndarray) -> int:
    """A vertex far from all its images, so that ``f`` = distance from it is visibly not symmetric.

    Args:
        verts: [V, 3]; p2ps: [G, V] vertex maps, identity first.

    Returns:
        argmax over vertices of the smallest distance to an image ``g(i)``, ``g`` not the identity; with
        no symmetry, the vertex farthest from the centroid.
    """
    c = verts - verts.mean(0)
    if len(p2ps) < 2:
        return int(np.argmax((c ** 2).sum(1)))
    d = np.stack([np.linalg.norm(verts - verts[p], axis=1) for p in p2ps[1:]]).min(0)  # [V]
    # among the far-moving vertices, prefer one far from the centre (a limb tip reads best)
    score = d / (d.max() + 1e-30) + 0.25 * np.sqrt((c ** 2).sum(1)) / np.sqrt((c ** 2).sum(1)).max()
    return int(np.argmax(score))


def colour_function(verts: np.ndarray, faces: np.ndarray, source: int) -> np.ndarray:
    """[V] geodesic distance from ``source`` scaled to [0, 1] (heat method; graph distance fallback)."""
    try:
        from ..geodesics import GeodesicSolver

        f = np.asarray(GeodesicSolver(verts, faces).distances_from([source]), dtype=np.float64)[0]
        if not np.isfinite(f).all():
            raise ValueError("non-finite distances")
    except Exception:  # noqa: BLE001 -- a picture still needs a smooth function
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import dijkstra

        e = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
        w = np.linalg.norm(verts[e[:, 0]] - verts[e[:, 1]], axis=1)
        g = coo_matrix((w, (e[:, 0], e[:, 1])), shape=(len(verts),) * 2)
        f = dijkstra(g, directed=False, indices=source)
        f[~np.isfinite(f)] = np.nanmax(f[np.isfinite(f)])
    return (f - f.min()) / max(float(np.ptp(f)), 1e-30)


def transfer(f: np.ndarray, p2p: np.ndarray) -> np.ndarray:
    """``f∘g``: vertex i gets ``f[p2p[i]]``, the value at its image (``p2p[i]`` = g(i))."""
    return np.asarray(f)[np.asarray(p2p)]


def element_labels(kinds: list[str], orders: list[int]) -> list[str]:
    """Short names: ``e`` for the identity, ``s1, s2..`` reflections, ``r1..`` rotations, ``m1..``
    other elements (rotoreflections)."""
    counts: dict[str, int] = {}
    out = []
    for kind, order in zip(kinds, orders):
        if kind == "identity":
            out.append("e")
            continue
        letter = {"reflection": "s", "rotation": "r"}.get(kind, "m")
        counts[letter] = counts.get(letter, 0) + 1
        out.append(f"{letter}{counts[letter]}")
    return out


def _frame(verts: np.ndarray) -> tuple[np.ndarray, float]:
    """The shape's principal frame as (base [3, 3]: screen x, screen y = up, depth; elevation in degrees).

    An elongated shape (a figure) stands on its longest axis, seen along its shortest one; "up" points
    along the + direction of the file's coordinate axis nearest to it (files are usually modelled with
    + up). A disc-like shape (a table: two long axes of similar length, a short one) stands on its short
    axis, its long tail (the legs) down, and is seen from above.
    """
    c = verts - verts.mean(0)
    _, sv, vt = np.linalg.svd(c, full_matrices=False)  # rows: principal axes, longest first
    tail = lambda a: a if np.sum((c @ a) ** 3) > 0 else -a  # noqa: E731 -- towards the long tail
    if sv[1] > 0.8 * sv[0] and sv[2] < 0.8 * sv[1]:  # disc-like
        up, toward, elevation = -tail(vt[2]), vt[1], 35
    else:
        up, toward, elevation = vt[0] if vt[0][np.argmax(np.abs(vt[0]))] > 0 else -vt[0], -tail(vt[2]), 20
    return np.stack([np.cross(up, toward), up, toward]), elevation  # right-handed


def _rot(axis: int, deg: float) -> np.ndarray:
    t = np.radians(deg)
    ca, sa = np.cos(t), np.sin(t)
    i, j = [(1, 2), (0, 2), (0, 1)][axis]
    R = np.eye(3)
    R[i, i], R[i, j], R[j, i], R[j, j] = ca, -sa, sa, ca
    return R


def view_rotation(verts: np.ndarray, turn: float = 0.0) -> np.ndarray:
    """[3, 3] rotation to screen coordinates: a 3/4 view in the principal frame, turned ``turn``
    degrees about the vertical axis (0, 90, 180: the sides a figure is judged from)."""
    base, elevation = _frame(verts)
    return _rot(0, elevation) @ _rot(1, turn - 30) @ base


def _coarsen(verts, faces, max_faces):
    """Vertex clustering on a grid until at most ``max_faces`` faces remain: (verts, faces, labels)
    with ``labels[i]`` the cluster of original vertex i (to average per-vertex colours)."""
    lo, span = verts.min(0), np.ptp(verts, axis=0).max()
    cells = int(np.sqrt(max_faces)) * 2
    while True:
        q = np.floor((verts - lo) / span * cells).astype(np.int64)
        _, labels = np.unique(q, axis=0, return_inverse=True)
        labels = labels.reshape(-1)
        f = labels[faces]
        f = f[(f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])]  # drop collapsed
        if len(f) <= max_faces or cells < 8:
            break
        cells = int(cells * 0.8)
    n = labels.max() + 1
    counts = np.bincount(labels, minlength=n)[:, None]
    v = np.stack([np.bincount(labels, weights=verts[:, d], minlength=n) for d in range(3)], 1) / counts
    return v, f, labels


def _draw_shape(ax, verts, faces, values, R, cmap):
    from matplotlib.collections import PolyCollection

    p = verts @ R.T  # [V, 3] screen x, y, depth
    tri = p[faces]  # [F, 3, 3]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True) + 1e-30
    light = np.array([0.3, 0.5, 0.81])
    shade = 0.35 + 0.65 * np.abs(n @ (light / np.linalg.norm(light)))  # two-sided
    val = values[faces].mean(1)
    rings = 0.8 + 0.2 * np.cos(2 * np.pi * _N_RINGS * val)  # iso-distance rings
    rgb = cmap(val)[:, :3] * (shade * rings)[:, None]
    order = np.argsort(tri[:, :, 2].mean(1))  # back to front
    coll = PolyCollection(tri[order, :, :2], facecolors=np.clip(rgb[order], 0, 1),
                          edgecolors="none", antialiased=False)
    ax.add_collection(coll)
    lo, hi = p[:, :2].min(0), p[:, :2].max(0)
    pad = 0.03 * (hi - lo).max()
    ax.set_xlim(lo[0] - pad, hi[0] + pad)
    ax.set_ylim(lo[1] - pad, hi[1] + pad)
    ax.set_aspect("equal")
    ax.axis("off")


def _draw_table(ax, table: np.ndarray, labels: list[str]) -> None:
    G = len(labels)
    cmap = _categorical(G)
    ax.imshow(table, cmap=cmap, vmin=-0.5, vmax=G - 0.5)
    size = 10 if G <= 4 else 8 if G <= 8 else 6 if G <= 12 else 4
    if G <= 24:
        for a in range(G):
            for b in range(G):
                t = int(table[a, b])
                ax.text(b, a, labels[t] if t >= 0 else "?", ha="center", va="center", fontsize=size)
    ax.set_xticks(range(G), labels, fontsize=size, rotation=90 if G > 8 else 0)
    ax.set_yticks(range(G), labels, fontsize=size)
    ax.xaxis.tick_top()
    ax.set_xlabel("b (applied first)", fontsize=8)
    ax.set_ylabel("a", fontsize=8)
    ax.set_title("group table  a∘b", fontsize=9, pad=18 if G <= 8 else 28)


def _categorical(G: int):
    from matplotlib.colors import ListedColormap

    import matplotlib

    base = matplotlib.colormaps["Pastel1" if G <= 9 else "tab20"]
    return ListedColormap([base(i % base.N) for i in range(max(G, 1))])


def _colour(verts, faces, p2ps, source, colour) -> tuple[np.ndarray, int]:
    """(f, its source): ``colour`` as given (source: where it is 0), else solved from ``source``."""
    if colour is not None:
        f = np.asarray(colour, dtype=np.float64)
        return f, int(np.argmin(f)) if source is None else source
    source = source_vertex(verts, p2ps) if source is None else source
    return colour_function(verts, faces, source), source


def _layout(n_elements: int, n_views: int) -> int:
    """Elements per row: one with three views or more, else two (about 1600-2200 px wide)."""
    return 1 if n_views >= 3 or n_elements == 1 else 2


def render_figure(verts, faces, p2ps, kinds, orders, scores, table, *, title: str = "",
                  turns: tuple[float, ...] | None = None, max_faces: int = 30000,
                  panel_inches: float = 4.5, dpi: int = 120, source: int | None = None,
                  colour: np.ndarray | None = None):
    """The figure: ``f``, then ``f∘g`` for each symmetry, each from several sides; then the group table.

    Args:
        verts: [V, 3]; faces: [F, 3]; p2ps: [G, V] vertex maps, identity first.
        kinds, orders, scores: per element (``SymmetryResult.symmetries``).
        table: [G, G] group table (``table[a, b] = a∘b``), or None.
        turns: the views of each element, in degrees about the vertical axis (``view_rotation``);
            default (0, 90, 180), or (0, 180) for more than four elements.
        panel_inches, dpi: width of one view and resolution (defaults: 540 px a view).
        source: the vertex ``f`` is the distance from; default :func:`source_vertex`.
        colour: [V] ``f`` itself when already computed (:func:`colour_function`); the source
            marked is then its minimum unless ``source`` is given.

    Returns:
        a matplotlib ``Figure`` (Agg; the caller saves it).
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure

    verts, faces, p2ps = np.asarray(verts, float), np.asarray(faces), np.asarray(p2ps)
    f, source = _colour(verts, faces, p2ps, source, colour)
    G = len(p2ps)
    turns = tuple(turns) if turns is not None else ((0.0, 90.0, 180.0) if G <= 4 else (0.0, 180.0))
    rotations = [view_rotation(verts, t) for t in turns]
    dv, df, labels = verts, faces, None
    if len(faces) > max_faces:
        dv, df, labels = _coarsen(verts, faces, max_faces)
    # panels as tall as the shape needs in its tallest view (a standing figure), within limits
    aspect = max(float(np.ptp(verts @ R[1]) / max(np.ptp(verts @ R[0]), 1e-30)) for R in rotations)
    panel_h = panel_inches * min(max(aspect, 0.6), 1.8)
    per_row = _layout(G, len(turns))
    cols = per_row * len(turns)
    rows = -(-G // per_row)
    table_h = min(panel_inches * 1.2, 1.2 + 0.35 * G) if table is not None else 0.0
    height = panel_h * rows + table_h + 0.6
    fig = Figure(figsize=(panel_inches * cols, height), dpi=dpi)
    fig.suptitle(title, fontsize=14)
    grid = fig.add_gridspec(rows + (table is not None), cols,
                            height_ratios=[panel_h] * rows + ([table_h] if table is not None else []))
    cmap = matplotlib.colormaps["turbo"]
    names = element_labels(kinds, orders)
    for g in range(G):
        vals = transfer(f, p2ps[g])
        if labels is not None:  # average per cluster for the coarse picture
            n = labels.max() + 1
            vals = np.bincount(labels, weights=vals, minlength=n) / np.bincount(labels, minlength=n)
        if g == 0:
            heading = "f (distance from ○)"
        else:
            order = f" of order {orders[g]}" if kinds[g] != "reflection" else ""
            heading = f"f∘{names[g]}: {kinds[g]}{order} (score {scores[g]:.2f})"
        for v, (turn, R) in enumerate(zip(turns, rotations)):
            ax = fig.add_subplot(grid[g // per_row, (g % per_row) * len(turns) + v])
            _draw_shape(ax, dv, df, vals, R, cmap)
            if g == 0:
                src = verts[source] @ R.T
                ax.plot([src[0]], [src[1]], "o", ms=8, mfc="white", mec="black")
            ax.set_title(f"{heading}, turned {turn:g}°" if v == 0 else f"turned {turn:g}°",
                         fontsize=12 if v == 0 else 10, loc="left" if v == 0 else "center")
    if table is not None:
        ax = fig.add_subplot(grid[rows, : min(cols, 2)])
        _draw_table(ax, np.asarray(table), names)
    fig.tight_layout(rect=(0, 0, 1, 1 - 0.5 / height))  # room for the title
    return fig


def save_png(fig, path: str, colours: int = 128) -> None:
    """Save as a palette PNG (small enough to commit), atomically."""
    from PIL import Image

    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    buf.seek(0)
    img = Image.open(buf).convert("RGB").quantize(colours, method=Image.Quantize.MEDIANCUT)
    out = io.BytesIO()
    img.save(out, format="PNG", optimize=True)
    _write_atomic(path, out.getvalue())


def export_glb(path: str, verts, faces, p2ps, names: list[str], source: int | None = None,
               colour: np.ndarray | None = None) -> None:
    """Write the colourings (``f`` and each ``f∘g``) as vertex-coloured meshes side by side, GLB
    (``source``, ``colour`` as in :func:`render_figure`)."""
    import matplotlib
    import trimesh

    verts, faces, p2ps = np.asarray(verts, float), np.asarray(faces), np.asarray(p2ps)
    f, _ = _colour(verts, faces, p2ps, source, colour)
    cmap = matplotlib.colormaps["turbo"]
    step = 1.2 * float(np.ptp(verts[:, 0]))
    scene = trimesh.Scene()
    for g, name in enumerate(names):
        vals = transfer(f, p2ps[g])
        rgba = (np.clip(cmap(vals) * (0.8 + 0.2 * np.cos(2 * np.pi * _N_RINGS * vals))[:, None], 0, 1)
                * 255).astype(np.uint8)
        rgba[:, 3] = 255
        mesh = trimesh.Trimesh(verts + [g * step, 0, 0], faces, vertex_colors=rgba, process=False)
        scene.add_geometry(mesh, node_name=f"f_{name}", geom_name=f"f_{name}")
    _write_atomic(path, scene.export(file_type="glb"))


def _write_atomic(path: str, data: bytes) -> None:
    from ..io import _write_bytes
    from .main import make_parent

    make_parent(path)
    _write_bytes(path, data)


def _cmd_show(args) -> int:
    from .main import _progress, check_basis_args, check_output_path, load_triangle_mesh, run_detector

    t0 = time.perf_counter()
    check_basis_args(args)
    for path in (args.out, args.glb):
        check_output_path(path)
    verts, faces, label = load_triangle_mesh(args, "`show`", "; detecting")
    kw = {k: v for k, v in (("k", args.k), ("k_refine", args.k_refine)) if v is not None}
    res = run_detector(verts, faces, label, **kw)
    p2ps = res.p2ps.cpu().numpy()
    kinds = [s.kind for s in res.symmetries]
    orders = [int(s.order) for s in res.symmetries]
    scores = [float(s.score) for s in res.symmetries]
    table = res.group.table.cpu().numpy()
    name = res.group.name
    group = f"group {name}" if name else "group"
    _progress(f"{group} of order {len(kinds)}: {', '.join(kinds)} ({time.perf_counter() - t0:.1f}s)")
    shown = os.path.basename(label) if not label.startswith("demo:") else label
    out = args.out
    if out is None and args.glb is None:
        stem = label.split(":", 1)[1] if label.startswith("demo:") else \
            os.path.splitext(os.path.basename(label))[0]
        out = f"{stem}_symmetries.png"
    colour = colour_function(np.asarray(verts, float), np.asarray(faces),
                             source_vertex(np.asarray(verts, float), p2ps))  # once for both outputs
    if out is not None:
        fig = render_figure(verts, faces, p2ps, kinds, orders, scores, table, colour=colour,
                            title=f"{shown}: {group} of order {len(kinds)}", dpi=args.dpi,
                            max_faces=args.max_faces)
        save_png(fig, out)
        _progress(f"figure -> {out} ({os.path.getsize(out) // 1024} KB)")
    if args.glb is not None:
        export_glb(args.glb, verts, faces, p2ps, element_labels(kinds, orders), colour=colour)
        _progress(f"coloured meshes -> {args.glb}")
    return 0


def register_cli(subparsers) -> None:
    """Add ``symtorch show MESH`` to the ``symtorch`` command line."""
    from .main import add_shape_arguments, add_thread_argument

    p = subparsers.add_parser(
        "show", help="picture of the detected symmetries and the group table (PNG, GLB)",
        description="Detect the symmetries, then draw a non-symmetric function f and, for each "
                    "symmetry g, f transferred through it (f∘g), next to the group table.")
    add_shape_arguments(p)
    p.add_argument("--out", help="PNG to write (default <mesh name>_symmetries.png unless --glb)")
    p.add_argument("--glb", help="also write the coloured meshes to this .glb (any 3D viewer)")
    p.add_argument("--k", type=int, default=None, help="coarse basis size of the detector (default 6)")
    p.add_argument("--k-refine", type=int, default=None,
                   help="refined basis size of the detector (default 100)")
    p.add_argument("--dpi", type=int, default=120,
                   help="resolution of the PNG (default 120: about 540 px a view, 1600 px or more wide)")
    p.add_argument("--max-faces", type=int, default=30000,
                   help="coarsen larger meshes for the picture (default 30000)")
    add_thread_argument(p)
    p.set_defaults(func=_cmd_show)
