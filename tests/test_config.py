"""symtorch.detect.config: the knobs of each path, validated, and the keyword shortcuts."""
import dataclasses

import pytest

from symtorch.detect import DetectConfig, GroupConfig, ReflectionConfig


def test_configs_are_frozen_with_the_benchmarked_defaults():
    cfg = DetectConfig()
    with pytest.raises(dataclasses.FrozenInstanceError):
        cfg.k_refine = 40
    assert (cfg.k, cfg.k_refine, cfg.group_tol) == (6, 100, 0.06)
    # the threshold BENCHMARKS.md "Confidence" reports, and the second opinion it needs
    assert cfg.min_confidence == 0.37 and cfg.reflection.second_opinion
    assert cfg.reflection == ReflectionConfig() and cfg.group == GroupConfig()


def test_group_basis_follows_the_shared_sizes():
    assert DetectConfig().group_basis == (20, 40)
    assert DetectConfig(k=30, k_refine=32).group_basis == (30, 32)
    assert DetectConfig(k=(6, 24)).group_basis == (24, 40)  # several coarse starts: the largest


def test_keyword_shortcuts_set_the_fields_they_name():
    cfg = DetectConfig().with_keywords(k_refine=60, group_tol=0.0, n_samples=300, n_refine=4,
                                       block_refine=True)
    assert cfg.k_refine == 60 and cfg.group_tol == 0.0
    assert cfg.reflection.n_samples == 300 and cfg.reflection.n_candidates == 4 and cfg.reflection.block_refine
    assert cfg.group.n_samples == GroupConfig().n_samples  # the legacy keywords reach the reflection path only
    assert DetectConfig().with_keywords() == DetectConfig()
    with pytest.raises(TypeError, match="unexpected keyword.*bandwidth"):
        DetectConfig().with_keywords(bandwidth=1.0)  # a group knob: GroupConfig(bandwidth=...)


def test_invalid_choices_are_refused():
    with pytest.raises(ValueError, match="verify must be"):
        ReflectionConfig(verify="both")
    with pytest.raises(ValueError, match="max_local_errors must be at least 0"):
        ReflectionConfig(max_local_errors=-1)
    with pytest.raises(ValueError, match="refine must be"):
        GroupConfig(refine="lbfgs")
    with pytest.raises(ValueError, match="near_mirrors must be 'drop' or 'keep'"):
        GroupConfig(near_mirrors="flag")
    with pytest.raises(ValueError, match="merged_gap must be at least 0"):
        GroupConfig(merged_gap=-0.5)
    with pytest.raises(ValueError, match="merged_relative_tol must be at least 0"):
        GroupConfig(merged_relative_tol=-1.0)
    with pytest.raises(ValueError, match="merged_n_sources must be at least 1"):
        GroupConfig(merged_n_sources=0)
    with pytest.raises(ValueError, match="merged_max_missing must be at least 0"):
        GroupConfig(merged_max_missing=-1)
    with pytest.raises(ValueError, match=r"persistence must be in \[0, 1\)"):
        GroupConfig(persistence=1.0)
    with pytest.raises(ValueError, match=r"max_level_change must be in \(0, 1\]"):
        GroupConfig(max_level_change=0.0)
