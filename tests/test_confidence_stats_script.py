"""scripts/confidence_stats.py: the AUROC it reports and the cached diagnostics' round trip."""
import json
import math

import numpy as np

from symtorch.detect import DetectConfig
from symtorch.detect.confidence import reflection_confidence
from symtorch.detect.result import Checks, ReflectionDiagnostics, Trial
from script_loader import load_script



def _load_script():
    return load_script("confidence_stats")


def test_auroc_counts_pairs_and_ties():
    cs = _load_script()
    assert cs.auroc(np.array([0.9, 0.8]), np.array([0.1, 0.2])) == 1.0
    assert cs.auroc(np.array([0.1]), np.array([0.9])) == 0.0
    assert cs.auroc(np.array([0.5, 0.5]), np.array([0.5])) == 0.5
    assert cs.auroc(np.array([0.9, 0.3]), np.array([0.5])) == 0.5  # one pair each way
    assert math.isnan(cs.auroc(np.array([0.9]), np.array([])))


def test_diagnostics_survive_the_json_cache():
    cs = _load_script()
    d = ReflectionDiagnostics(n_extrema=6, n_seeds=4, n_candidates=2, k0=[6], k_refine=100,
                              candidate_scores=[0.1, 0.3], trials=[Trial(0.2, math.inf), Trial(-0.9, 0.2)],
                              chosen=(1, 6), checks=Checks(0.96, 0.2, 0.4, -0.9, 0.1, True, 0.04),
                              second_chosen=(0, 6), agreement=(0.3, 0.6))
    back = cs.diagnostics_from_json(json.loads(json.dumps(cs.diagnostics_to_json(d))))
    assert back == d and reflection_confidence(back) == 0.3


def test_cache_key_ignores_the_threshold_only():
    cs = _load_script()
    assert cs.cache_key(DetectConfig()) == cs.cache_key(DetectConfig(min_confidence=0.9))
    assert cs.cache_key(DetectConfig()) != cs.cache_key(DetectConfig(k_refine=60))
