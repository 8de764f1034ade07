"""symtorch.detect.fmap_candidate: the orientation-reversing functional map of a shape onto itself,
the reflection path's candidate that needs no point pairs."""
import pytest
import torch

from symtorch import laplacian_spectrum
from symtorch.descriptors import descriptors
from symtorch.detect import ReflectionConfig
from symtorch.detect.fmap_candidate import (FmapWeights, fmap_energy_terms, orientation_reversing_fmap,
                                            reversing_fmap_candidate)
from symtorch.detect.reflection import SampleSet, fmap_finalist, reflection_basis, refine_and_verify
from symtorch.geodesics import GeodesicSolver
from symtorch.maps import fmap_to_p2p
from symtorch.orientation import orientation_operators


def _energy(C, A, lam, P, O, w):
    k, D = A.shape
    L = torch.diag(lam)
    return (w.descriptors / (k * D) * (C @ A - A).square().sum()
            + w.laplacian / (k * k) * (C @ L - L @ C).square().sum()
            + w.commutativity / (D * k * k) * (C @ P - P @ C).square().sum()
            + w.orientation / (D * k * k) * (C @ O + O @ C).square().sum())


def test_closed_form_is_the_energy_minimum_batched_or_not():
    g = torch.Generator().manual_seed(0)
    k, D = 6, 4
    A = torch.randn(k, D, generator=g, dtype=torch.float64)
    lam = torch.rand(k, generator=g, dtype=torch.float64)
    P = torch.randn(D, k, k, generator=g, dtype=torch.float64)
    O = torch.randn(D, k, k, generator=g, dtype=torch.float64)
    w = FmapWeights(1.0, 0.3, 0.7, 0.9)
    C = orientation_reversing_fmap(A, lam, P, O, w).requires_grad_(True)
    grad, = torch.autograd.grad(_energy(C, A, lam, P, O, w), C)
    assert float(grad.abs().max()) < 1e-12  # the gradient vanishes: the least-squares minimum
    nudged = C.detach() + 1e-3 * torch.randn(k, k, generator=g, dtype=torch.float64)
    assert float(_energy(nudged, A, lam, P, O, w)) > float(_energy(C.detach(), A, lam, P, O, w))
    batch = orientation_reversing_fmap(torch.stack([A, 2 * A]), torch.stack([lam, lam]),
                                       torch.stack([P, P]), torch.stack([O, -O]), w)
    assert torch.allclose(batch[0], C.detach(), atol=1e-12)
    # O -> -O leaves the orientation term's square unchanged; A -> 2A changes the solution
    assert batch.shape == (2, k, k) and not torch.allclose(batch[1], batch[0])


def test_without_orientation_term_the_identity_is_the_answer():
    """Descriptors and commutativity alone are met exactly by the identity; the orientation
    term is what asks for a reflection."""
    g = torch.Generator().manual_seed(1)
    k, D = 5, 3
    A = torch.randn(k, D, generator=g, dtype=torch.float64)
    P = torch.randn(D, k, k, generator=g, dtype=torch.float64)
    P = P + P.mT
    C = orientation_reversing_fmap(A, torch.rand(k, generator=g, dtype=torch.float64), P,
                                   torch.zeros(D, k, k, dtype=torch.float64),
                                   FmapWeights(1.0, 0.1, 1.0, 0.0))
    assert torch.allclose(C, torch.eye(k, dtype=torch.float64), atol=1e-8)


def test_candidate_on_a_mirror_symmetric_mesh_is_its_reflection(mirror3, one_thread):
    v, f, mirror = mirror3
    sp = laplacian_spectrum(v, f, k=40)
    basis = reflection_basis(sp.evals, 6, 30, 30, 0)
    desc = descriptors(sp.evals, sp.evecs)
    vu = v * sp.scale
    C = reversing_fmap_candidate(vu, f, sp.evecs, sp.evals, sp.mass, desc, basis.bands, 20)
    K = C.shape[0]
    assert torch.allclose(C @ C.T, torch.eye(K, dtype=C.dtype), atol=1e-8)  # projected: orthogonal
    assert torch.allclose(C, C.T, atol=1e-8)                                 # and an involution
    assert float((C - torch.eye(K, dtype=C.dtype)).abs().max()) > 0.5        # not the identity
    # its vertex map, before any refinement, is already the mirror on most vertices
    p2p = fmap_to_p2p(C, sp.evecs[:, :K])
    assert float((p2p == mirror).double().mean()) > 0.5
    # refined and verified as the reflection path does: the exact mirror, accepted
    cfg = ReflectionConfig()
    samples = SampleSet(vu, f, sp, GeodesicSolver(vu, f), cfg)
    (key, C0), = fmap_finalist(vu, f, sp, desc, basis, cfg, lambda stage: None)
    assert key[0] == -1 and C0.shape[0] == K
    found = refine_and_verify(C0, samples, desc, basis, cfg, lambda stage: None)
    assert found.checks.accepted and float((found.p2p == mirror).double().mean()) > 0.99


def test_orientation_operators_are_the_training_layers(mirror3):
    """One implementation: the candidate's operators are symtorch.orientation's."""
    v, f, _ = mirror3
    sp = laplacian_spectrum(v, f, k=12)
    desc = descriptors(sp.evals, sp.evecs)[:, :3]
    O = orientation_operators(v * sp.scale, f, sp.evecs, sp.mass, desc)
    A, lam, P, O2 = fmap_energy_terms(sp.evecs, sp.evals, sp.mass, desc, O)
    assert O2 is O and A.shape == (12, 3) and P.shape == (3, 12, 12) and float(lam.max()) == 1.0


def test_detection_with_and_without_the_candidate_finds_the_mirror(mirror3, one_thread):
    from symtorch import detect_symmetries
    from symtorch.detect import DetectConfig

    v, f, mirror = mirror3
    for on in (True, False):
        cfg = DetectConfig(reflection=ReflectionConfig(fmap_candidate=on))
        res = detect_symmetries(v, f, mode="reflection", config=cfg)
        assert torch.equal(res.reflection.p2p, mirror)
        finalists = res.diagnostics.reflection.finalists
        assert any(key[0] == -1 for key in finalists) == on
