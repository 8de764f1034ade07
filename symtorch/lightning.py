"""Lightning integration: :class:`SymmetryDataModule` (needs ``pip install symtorch[lightning]``).

``lightning`` is imported only when ``SymmetryDataModule`` is first used, so ``import symtorch``
stays light; without lightning that first use raises an ``ImportError`` with the install command.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence

import torch
from torch import Tensor

__all__ = ["SymmetryDataModule"]

_HINT = "SymmetryDataModule needs lightning: pip install symtorch[lightning]"


def split_indices(n: int, split: Sequence[float], seed: int) -> list[list[int]]:
    """Shuffle ``range(n)`` with a seeded generator and cut it by the fractions (or counts) ``split``.

    The last part takes the rounding remainder; fractions must sum to 1, counts to ``n``.
    """
    if any(s < 0 for s in split):
        raise ValueError(f"split must be non-negative, got {tuple(split)}")
    if all(float(s).is_integer() and s >= 1 or s == 0 for s in split) and sum(split) == n:
        counts = [int(s) for s in split]
    elif abs(sum(split) - 1.0) < 1e-6:
        counts = [int(round(s * n)) for s in split[:-1]]
        counts.append(n - sum(counts))
    else:
        raise ValueError(f"split must be fractions summing to 1 or counts summing to {n}, "
                         f"got {tuple(split)}")
    if counts[-1] < 0:
        raise ValueError(f"split {tuple(split)} asks for more than {n} shapes")
    order = torch.randperm(n, generator=torch.Generator().manual_seed(seed)).tolist()
    parts, start = [], 0
    for c in counts:
        parts.append(sorted(order[start:start + c]))
        start += c
    return parts


def _build():
    try:
        import lightning as L
    except ImportError as err:  # pragma: no cover - depends on the environment
        raise ImportError(_HINT) from err
    from torch.utils.data import DataLoader, Subset

    from .data import (Compose, ComputeDescriptors, ComputeSpectrum, DetectSymmetries, MeshDataset,
                       NormalizeArea, PairDataset, RandomEigenSigns, RandomSymmetry, SetSymmetries,
                       SymmetryFromCorrespondence, pad_collate)
    from .data.dataset import PAIR_MODES
    from .data.symmetry import AUGMENT_MODES

    class SymmetryDataModule(L.LightningDataModule):
        """Shapes (or pairs of shapes) of one mesh folder, with spectra, descriptors and symmetries.

        ``prepare_data`` runs the precompute (:class:`~symtorch.data.MeshDataset` cache) and assigns no
        state; ``setup`` loads the cache and splits the *shapes* into train / val / test with a seeded
        ``torch.Generator``, so validation and test pairs only involve held-out shapes. Batches come
        from :func:`~symtorch.data.pad_collate`.

        Args:
            root: folder of meshes.
            processed_dir: cache folder (default: ``symtorch.data.default_cache_dir(root)``).
            names: mesh names to use (default: all).
            ground_truth: ``None``, ``"template"`` or ``"vts"`` (see ``symtorch.data.read_sample``).
            k: eigenpairs per shape (``ComputeSpectrum``).
            n_hks, n_wks: descriptor sizes (``ComputeDescriptors``); both 0 skips descriptors.
            normalize_area: scale each shape to unit area first (``NormalizeArea``).
            symmetries: ``None``; ``"detect"`` (``DetectSymmetries(**detect_kwargs)`` on each shape);
                ``"correspondence"`` (``SymmetryFromCorrespondence``: the reflection of the symmetric
                ground truth, needs ``ground_truth="vts"`` with ``.sym.vts`` files); or a ``[G, V]``
                long tensor of vertex maps shared by every shape (``SetSymmetries``: one template,
                e.g. SCAPE).
            detect_kwargs: keywords of ``DetectSymmetries``.
            pre_transform: replaces the pre-transform built from the knobs above.
            augment_symmetry: train shapes get ``RandomSymmetry(mode=...)`` (needs ``symmetries``):
                ``"relabel"`` (or True) composes their ground truth with a random symmetry,
                ``"mirror"`` also mirrors them when the element reverses orientation (the ground
                truth stays orientation preserving); False: no symmetry augmentation.
            augment_signs: train shapes get ``RandomEigenSigns``.
            train_transform: further transform of train shapes (after the two above).
            pairs: items are pairs (``PairDataset``, ordered pairs within a split) or single shapes.
            pair_mode: which pairs within a split: ``"all"`` or ``"same_class"`` (TOSCA: cat with
                cat, ...; see ``PairDataset``).
            split: fractions (summing to 1) or counts of shapes for train, val, test.
            seed: seed of the split.
            batch_size, num_workers: of every ``DataLoader``.
            force_reload: process the cache again.

        Note:
            The random augmentations draw from torch's global generator, which the ``DataLoader`` seeds
            differently in each worker (a ``torch.Generator`` held by a transform would be copied into
            every worker and repeat the same draws); seed runs with ``lightning.seed_everything``.
        """

        def __init__(self, root, *, processed_dir=None, names: Sequence[str] | None = None,
                     ground_truth: str | None = None, k: int = 30, n_hks: int = 16, n_wks: int = 16,
                     normalize_area: bool = True, symmetries: str | Tensor | None = None,
                     detect_kwargs: dict | None = None,
                     pre_transform: Callable[[dict], dict] | None = None,
                     augment_symmetry: bool | str = False, augment_signs: bool = False,
                     train_transform: Callable[[dict], dict] | None = None, pairs: bool = True,
                     pair_mode: str = "all",
                     split: Sequence[float] = (0.8, 0.1, 0.1), seed: int = 0, batch_size: int = 1,
                     num_workers: int = 0, force_reload: bool = False):
            super().__init__()
            if isinstance(symmetries, str) and symmetries not in ("detect", "correspondence"):
                raise ValueError(f"symmetries must be None, 'detect', 'correspondence' or a [G, V] "
                                 f"tensor, got {symmetries!r}")
            if pair_mode not in PAIR_MODES:
                raise ValueError(f"pair_mode must be one of {PAIR_MODES}, got {pair_mode!r}")
            if augment_symmetry is True:
                augment_symmetry = "relabel"
            if augment_symmetry not in (False, None) and augment_symmetry not in AUGMENT_MODES:
                raise ValueError(f"augment_symmetry must be False, True or one of {AUGMENT_MODES}, "
                                 f"got {augment_symmetry!r}")
            if augment_symmetry and symmetries is None and pre_transform is None:
                raise ValueError("augment_symmetry needs symmetries ('detect', 'correspondence' or a "
                                 "[G, V] tensor)")
            self.root, self.processed_dir, self.names = root, processed_dir, names
            self.ground_truth, self.k, self.n_hks, self.n_wks = ground_truth, k, n_hks, n_wks
            self.normalize_area, self.symmetries = normalize_area, symmetries
            self.detect_kwargs = dict(detect_kwargs or {})
            self._pre_transform = pre_transform
            self.augment_symmetry = augment_symmetry or False
            self.augment_signs = augment_signs
            self.train_transform, self.pairs, self.pair_mode = train_transform, pairs, pair_mode
            self.split, self.seed = tuple(split), seed
            self.batch_size, self.num_workers, self.force_reload = batch_size, num_workers, force_reload
            self.train_set = self.val_set = self.test_set = None

        @property
        def pre_transform(self) -> Callable[[dict], dict]:
            """The cached pre-transform: the one given, or the one built from the knobs."""
            if self._pre_transform is not None:
                return self._pre_transform
            steps = [NormalizeArea()] if self.normalize_area else []
            steps.append(ComputeSpectrum(self.k))
            if self.n_hks or self.n_wks:
                steps.append(ComputeDescriptors(self.n_hks, self.n_wks))
            if isinstance(self.symmetries, str) and self.symmetries == "correspondence":
                steps.append(SymmetryFromCorrespondence())
            elif isinstance(self.symmetries, str):
                steps.append(DetectSymmetries(**self.detect_kwargs))
            elif self.symmetries is not None:
                steps.append(SetSymmetries(self.symmetries))
            return Compose(steps)

        def _augmentation(self) -> Callable[[dict], dict] | None:
            steps = [RandomSymmetry(mode=self.augment_symmetry)] if self.augment_symmetry else []
            if self.augment_signs:
                steps.append(RandomEigenSigns())
            if self.train_transform is not None:
                steps.append(self.train_transform)
            return Compose(steps) if steps else None

        def _dataset(self, transform=None, force_reload=False) -> MeshDataset:
            return MeshDataset(self.root, self.pre_transform, transform,
                               processed_dir=self.processed_dir, names=self.names,
                               ground_truth=self.ground_truth, force_reload=force_reload)

        def prepare_data(self) -> None:
            self._dataset(force_reload=self.force_reload)  # builds the cache; keeps no state

        def setup(self, stage: str | None = None) -> None:
            plain = self._dataset()
            augment = self._augmentation()
            train_base = self._dataset(augment) if augment is not None else plain
            idx_train, idx_val, idx_test = split_indices(len(plain), self.split, self.seed)
            wrap = (lambda d: PairDataset(d, pairs=self.pair_mode)) if self.pairs else (lambda d: d)
            self.train_set = wrap(Subset(train_base, idx_train))
            self.val_set = wrap(Subset(plain, idx_val))
            self.test_set = wrap(Subset(plain, idx_test))

        def _loader(self, dataset, shuffle: bool) -> DataLoader:
            return DataLoader(dataset, batch_size=self.batch_size, shuffle=shuffle,
                              collate_fn=pad_collate, num_workers=self.num_workers,
                              persistent_workers=self.num_workers > 0)

        def train_dataloader(self) -> DataLoader:
            return self._loader(self.train_set, shuffle=True)

        def val_dataloader(self) -> DataLoader:
            return self._loader(self.val_set, shuffle=False)

        def test_dataloader(self) -> DataLoader:
            return self._loader(self.test_set, shuffle=False)

        def predict_dataloader(self) -> DataLoader:
            return self._loader(self.test_set, shuffle=False)

    SymmetryDataModule.__module__ = __name__
    return SymmetryDataModule


def __getattr__(name: str):
    if name == "SymmetryDataModule":
        cls = _build()
        globals()[name] = cls  # built once; later lookups (and pickling) find it directly
        return cls
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
