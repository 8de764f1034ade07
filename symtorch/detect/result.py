"""Result types of symmetry detection."""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import torch
from torch import Tensor

from ..spectrum import Spectrum


@dataclass(frozen=True)
class Symmetry:
    """One detected symmetry.

    Attributes:
        C: [K, K] block-orthogonal pull-back matrix (ALGORITHM §2).
        p2p: [V] long, ``p2p[i]`` is the image of vertex ``i``.
        kind: 'identity' | 'reflection' | 'rotation' | 'rotoreflection'.
        order: smallest n with ``C^n ≈ I``.
        score: confidence in [0, 1]; higher is better.
    """

    C: Tensor
    p2p: Tensor
    kind: str
    order: int
    score: float


@dataclass(frozen=True)
class SymmetryResult:
    """Every symmetry found on one shape, identity first, then best first.

    Attributes:
        symmetries: the group elements.
        spectrum: the basis the matrices live in (``evecs [V, K]``).
        bands: eigenvalue bands of the basis (index ranges, covering ``0..K-1``).
        group: name, order, table, inverses, orders (``symtorch.groups`` ``GroupInfo.to_dict()``), or {}.
        continuous: True when the shape has a continuous symmetry (then ``symmetries`` is the identity).
        timings: seconds per stage.
        info: diagnostics (candidate counts, scores of rejected candidates, ...).
    """

    symmetries: list[Symmetry]
    spectrum: Spectrum
    bands: list[range]
    group: dict[str, Any] = field(default_factory=dict)
    continuous: bool = False
    timings: dict[str, float] = field(default_factory=dict)
    info: dict[str, Any] = field(default_factory=dict)

    def to(self, device: torch.device | str) -> SymmetryResult:
        """The result with its matrices, maps and spectrum on ``device`` (itself when already there)."""
        device = torch.empty(0, device=device).device  # 'cuda' -> 'cuda:0', as tensors report it
        tensors = [self.spectrum.evecs] + [t for s in self.symmetries for t in (s.C, s.p2p)]
        if all(t.device == device for t in tensors):
            return self
        return replace(self, spectrum=self.spectrum.to(device),
                       symmetries=[replace(s, C=s.C.to(device), p2p=s.p2p.to(device)) for s in self.symmetries])

    @property
    def fmaps(self) -> Tensor:
        """[G, K, K] the matrices, identity first."""
        return torch.stack([s.C for s in self.symmetries])

    @property
    def p2ps(self) -> Tensor:
        """[G, V] the vertex maps, identity first."""
        return torch.stack([s.p2p for s in self.symmetries])

    @property
    def reflection(self) -> Symmetry | None:
        """The best orientation-reversing involution, if any."""
        return next((s for s in self.symmetries if s.kind == "reflection"), None)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary (no matrices): the schema of ``symtorch detect``.

        ``symmetries[i]`` is group element ``i``: the indices of ``group["table"]``,
        ``group["inverses"]`` and ``group["orders"]`` refer to it, and it carries its ``kind``, ``order``,
        ``score`` and vertex map ``p2p``. ``group["elements"]`` repeats, per element, its kind, order,
        inverse and orientation next to the table; ``group["table_paper"]`` is the table in the layout
        of the paper's Table 3 (``table.T``: entry (i, j) is "g_i, then g_j").
        """
        group = dict(self.group) if self.group else {"order": len(self.symmetries), "name": None}
        if "table" in group:
            inv, rev = group.get("inverses", []), group.get("reversing", [])
            group["table_paper"] = [list(col) for col in zip(*group["table"])]
            group["elements"] = [
                {"index": i, "kind": s.kind, "order": s.order, "score": round(float(s.score), 6),
                 **({"inverse": inv[i]} if i < len(inv) else {}),
                 **({"reversing": bool(rev[i])} if i < len(rev) else {})}
                for i, s in enumerate(self.symmetries)]
        return {
            "n_vertices": int(self.spectrum.evecs.shape[0]),
            "k": int(self.spectrum.evecs.shape[1]),
            "bands": [[b.start, b.stop] for b in self.bands],
            "continuous": self.continuous,
            "symmetries": [{"kind": s.kind, "order": s.order, "score": round(float(s.score), 6),
                            "p2p": s.p2p.tolist()} for s in self.symmetries],
            "group": group,
            "timings": {k: round(v, 4) for k, v in self.timings.items()},
        }
