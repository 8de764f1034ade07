"""SymmetryDataModule: seeded splits, lazy import, and a fast_dev_run through lightning.Trainer."""
import sys

import pytest
import torch

from symtorch.data import ComputeSpectrum
from symtorch.io import write_mesh
from symtorch.losses import fmap_loss, orthogonality_loss, symmetry_equivariance_loss
from shapes import mirror_mesh

L = pytest.importorskip("lightning")
from symtorch.lightning import SymmetryDataModule, split_indices  # noqa: E402


@pytest.fixture()
def folder(tmp_path):
    root = tmp_path / "meshes"
    root.mkdir()
    verts, faces, mirror = mirror_mesh(1)
    for i in range(5):
        write_mesh(root / f"m{i}.off", verts * torch.tensor([1.0, 1.0 + 0.05 * i, 1.0]), faces)
    return root, torch.stack([torch.arange(verts.shape[0]), mirror])


class TinyFmapNet(L.LightningModule):
    """Per-vertex linear features -> least-squares functional map, trained against the ground truth."""

    def __init__(self):
        super().__init__()
        self.lin = torch.nn.Linear(8, 8)
        self.seen_devices = set()  # where the training steps' maps were computed

    def fmap(self, batch):
        def coefs(s):
            feat = self.lin(s["hks"].float())
            return s["evecs"].float().mT @ (s["mass"].float()[..., None] * feat)  # [B, K, D]

        A, B = coefs(batch["x"]), coefs(batch["y"])
        # C A = B in least squares: C = B A^+  ([B, K_y, K_x])
        return torch.linalg.lstsq(A.mT, B.mT).solution.mT

    def training_step(self, batch, _):
        C = self.fmap(batch)
        self.seen_devices.add(C.device.type)
        sx, sy = batch["x"]["sym_fmap"].float(), batch["y"]["sym_fmap"].float()
        return (fmap_loss(C, batch["fmap_xy"].float()) + 0.1 * orthogonality_loss(C)
                + 0.1 * symmetry_equivariance_loss(C, sx, sy))

    def validation_step(self, batch, _):
        loss = fmap_loss(self.fmap(batch), batch["fmap_xy"].float())
        self.log("val_loss", loss, batch_size=batch["fmap_xy"].shape[0])

    def configure_optimizers(self):
        return torch.optim.Adam(self.parameters(), lr=1e-3)


def test_fast_dev_run(folder, tmp_path, device):
    """A training and a validation step through ``lightning.Trainer``, on CPU and on a GPU: the
    padded batches (``pad_collate``) reach the model on its device."""
    root, sym = folder
    dm = SymmetryDataModule(root, processed_dir=tmp_path / "cache", ground_truth="template", k=6,
                            n_hks=8, n_wks=0, symmetries=sym, augment_symmetry=True,
                            augment_signs=True, split=(3, 2, 0), batch_size=2, seed=1)
    trainer = L.Trainer(fast_dev_run=True, accelerator="gpu" if device.type == "cuda" else "cpu", devices=1,
                        logger=False,
                        enable_checkpointing=False, enable_progress_bar=False,
                        enable_model_summary=False)
    model = TinyFmapNet()
    trainer.fit(model, datamodule=dm)
    assert model.seen_devices == {device.type}
    assert len(dm.train_set) == 6 and len(dm.val_set) == 2 and len(dm.test_set) == 0
    assert (tmp_path / "cache" / "meta.json").exists()


def test_setup_splits_shapes_with_a_seed(folder, tmp_path):
    root, _ = folder
    kw = dict(processed_dir=tmp_path / "cache", k=4, n_hks=0, n_wks=0, pairs=False)
    dm = SymmetryDataModule(root, split=(0.6, 0.2, 0.2), seed=3, **kw)
    dm.prepare_data()
    assert dm.train_set is None  # prepare_data assigns no state
    dm.setup("fit")
    names = [[s["name"] for s in d] for d in (dm.train_set, dm.val_set, dm.test_set)]
    assert sorted(sum(names, [])) == [f"m{i}" for i in range(5)] and list(map(len, names)) == [3, 1, 1]
    dm2 = SymmetryDataModule(root, split=(0.6, 0.2, 0.2), seed=3, **kw)
    dm2.setup("fit")
    assert [s["name"] for s in dm2.train_set] == names[0]
    batch = next(iter(dm.train_dataloader()))
    assert batch["evecs"].shape == (1, 42, 4)
    assert repr(dm.pre_transform) == ("Compose([\n  NormalizeArea(center=True),\n"
                                      f"  {ComputeSpectrum(k=4)!r},\n])")


def test_split_indices():
    a = split_indices(10, (0.8, 0.1, 0.1), seed=0)
    assert list(map(len, a)) == [8, 1, 1] and sorted(sum(a, [])) == list(range(10))
    assert a == split_indices(10, (0.8, 0.1, 0.1), seed=0) != split_indices(10, (0.8, 0.1, 0.1), 1)
    assert list(map(len, split_indices(10, (7, 2, 1), seed=0))) == [7, 2, 1]
    with pytest.raises(ValueError, match="fractions summing to 1 or counts summing to 10"):
        split_indices(10, (0.5, 0.1), seed=0)
    with pytest.raises(ValueError, match="split must be non-negative"):
        split_indices(10, (1.2, -0.2), seed=0)


def test_errors(folder):
    root, _ = folder
    with pytest.raises(ValueError, match="augment_symmetry needs symmetries"):
        SymmetryDataModule(root, augment_symmetry=True)
    with pytest.raises(ValueError, match="symmetries must be None, 'detect', 'correspondence' or a \\[G, V\\] tensor"):
        SymmetryDataModule(root, symmetries="template")
    with pytest.raises(ValueError, match="augment_symmetry must be False, True or one of"):
        SymmetryDataModule(root, symmetries="detect", augment_symmetry="move")
    with pytest.raises(ValueError, match="pair_mode must be one of \\('all', 'same_class'\\)"):
        SymmetryDataModule(root, pair_mode="class")


def test_mirror_augmentation_and_pair_mode(folder, tmp_path):
    """augment_symmetry='mirror' mirrors train shapes (faces rewound) and keeps the pairs' ground
    truth a bijection; pair_mode='same_class' pairs shapes whose names differ only in digits."""
    root, sym = folder
    dm = SymmetryDataModule(root, processed_dir=tmp_path / "cache", ground_truth="template", k=6,
                            n_hks=0, n_wks=0, symmetries=sym, augment_symmetry="mirror",
                            pair_mode="same_class", split=(3, 2, 0), seed=1)
    dm.prepare_data()
    dm.setup("fit")
    assert len(dm.train_set) == 6 and len(dm.val_set) == 2
    base = dm.val_set.dataset.dataset[0]["faces"]
    rewound = 0
    for _ in range(4):
        for item in dm.train_set:
            for s in (item["x"], item["y"]):
                assert s["sym_reverses"].tolist() == [False, True]
                rewound += bool(torch.equal(s["faces"], base[:, [0, 2, 1]]))
            assert torch.equal(item["p2p_yx"].sort().values, torch.arange(len(item["p2p_yx"])))
    assert 0 < rewound < 48


def test_lazy_import_hint(monkeypatch):
    import symtorch.lightning as module

    monkeypatch.setitem(sys.modules, "lightning", None)  # as if it were not installed
    with pytest.raises(ImportError, match="pip install symtorch\\[lightning\\]"):
        module._build()
