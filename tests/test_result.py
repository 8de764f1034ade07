"""symtorch.detect.result: the result record, its JSON form, and the typed diagnostics."""
import json
from dataclasses import replace

import torch

from symtorch.detect.result import (Checks, Diagnostics, GroupDiagnostics, ReflectionDiagnostics, Symmetry,
                                    SymmetryResult, Trial)
from symtorch.groups import group_info
from symtorch.spectrum import Spectrum


def _result(diagnostics=None) -> SymmetryResult:
    V, K = 5, 3
    spec = Spectrum(torch.arange(K, dtype=torch.float64), torch.eye(V, K, dtype=torch.float64),
                    torch.ones(V, dtype=torch.float64), 1.0)
    flip = torch.diag(torch.tensor([1.0, -1.0, 1.0], dtype=torch.float64))
    syms = [Symmetry(torch.eye(K, dtype=torch.float64), torch.arange(V), "identity", 1, 1.0),
            Symmetry(flip, torch.tensor([4, 3, 2, 1, 0]), "reflection", 2, 0.9)]
    group = group_info(torch.tensor([[0, 1], [1, 0]]), torch.tensor([False, True]))
    return SymmetryResult(syms, spec, [range(0, 1), range(1, 2), range(2, 3)], group=group,
                          diagnostics=diagnostics)


def test_to_dict_is_json_with_the_paper_layout():
    d = json.loads(json.dumps(_result().to_dict()))
    assert d["k"] == 3 and d["n_vertices"] == 5 and d["bands"] == [[0, 1], [1, 2], [2, 3]]
    assert [s["kind"] for s in d["symmetries"]] == ["identity", "reflection"]
    g = d["group"]
    assert g["name"] == "Cs" and g["table_paper"] == [[0, 1], [1, 0]]
    assert [e["inverse"] for e in g["elements"]] == [0, 1] and g["elements"][1]["reversing"] is True


def test_fields_and_aliases():
    res = _result()
    assert res.fmaps.shape == (2, 3, 3) and res.p2ps.shape == (2, 5)
    assert res.reflection is res.symmetries[1] and res.reflection.C is res.reflection.fmap
    assert res.to("cpu") is res  # already there
    assert res.info == {}


def test_diagnostics_as_a_plain_dict():
    checks = Checks(0.9, 0.3, 0.5, -0.95, 0.1, True)
    refl = ReflectionDiagnostics(n_extrema=5, n_seeds=12, n_candidates=3, k0=[6], k_refine=100,
                                 candidate_scores=[0.01, 0.02], trials=[Trial(-0.95, 0.3)], chosen=(0, 6),
                                 checks=checks)
    group = GroupDiagnostics(k0=20, k_refine=40, m=2, bands0=[1, 2], name="Cs", order=2,
                             reason="2 elements verified in the coarse basis, fewer than the 3 asked for")
    d = Diagnostics("reflection", reflection=refl, group=group).to_dict()
    assert d["distortion"] == 0.3 and d["orientation"] == -0.95 and d["trials"] == [(-0.95, 0.3)]
    assert "guided" not in d
    assert d["group_path"] == {"name": "Cs", "order": 2, "reason": group.reason}
    g = Diagnostics("group", group=group).to_dict()
    assert g["path"] == "group" and g["m"] == 2 and "n_clusters" not in g  # stages that did not run


def test_confidence_and_uncertain_in_the_result_and_its_json():
    res = _result()
    identity, refl = res.symmetries
    assert refl.confidence == refl.score == 0.9 and not refl.uncertain  # no confidence given: the score
    assert not res.uncertain and res.min_confidence is None
    flagged = replace(res, symmetries=[identity, replace(refl, confidence=0.2, uncertain=True)],
                      min_confidence=0.5)
    assert flagged.uncertain
    torch.testing.assert_close(flagged.confidences, torch.tensor([1.0, 0.2], dtype=torch.float64))
    d = json.loads(json.dumps(flagged.to_dict()))
    assert d["uncertain"] is True and d["min_confidence"] == 0.5
    assert [s["confidence"] for s in d["symmetries"]] == [1.0, 0.2]
    assert [s["uncertain"] for s in d["symmetries"]] == [False, True]
    assert [e["uncertain"] for e in d["group"]["elements"]] == [False, True]


def test_agreement_and_second_opinion_in_the_diagnostics_dict():
    refl = ReflectionDiagnostics(n_extrema=5, n_seeds=12, n_candidates=3, k0=[6], k_refine=100,
                                 candidate_scores=[0.01], trials=[Trial(-0.95, 0.3)], chosen=(1, 6),
                                 checks=Checks(0.9, 0.3, 0.5, -0.95, 0.1, True, 0.05),
                                 second_chosen=(0, 6), agreement=(0.25, 0.5))
    d = Diagnostics("reflection", reflection=refl).to_dict()
    assert d["second_chosen"] == (0, 6) and d["agreement"] == [0.25, 0.5]
    assert d["involution_error"] == 0.05
